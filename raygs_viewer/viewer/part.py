"""The protocol of the window's parts, and the values that cross it.

A part (the camera path, the measure tool, picking, the edit tool, the training
frustums, the photo view, the level of detail, the statistics, screenshots, the stereo
preview) keeps its own state and no reference to the viewer or to another part. The
viewer hands it what it needs as arguments (the :class:`~raygs_viewer.viewer.frame.Frame`,
the scene shown as a :class:`SceneView`) and it answers with values: a :class:`Reply`
of :class:`~raygs_viewer.viewer.state.Message` lines for the panel and requests the
viewer carries out (fly to a training camera, aim at a point, open a scene, ...). So a
part reads and changes only itself, and a second frame driver (a headset's) can drive the
same parts.

Each part implements the hooks of :class:`Part` it needs; ``app.Viewer.frame`` calls
each hook on its parts in the one order ``window_state.WindowState.parts`` writes down
(splatviz's list of widgets; moderngl-window's event hooks).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal, Union

import numpy as np

from raygs_viewer.camera.stereo import StereoRig
from raygs_viewer.capture.measure_file import MeasureScale
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import Order
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.picking import Picked
from raygs_viewer.viewer.state import Message


@dataclass(frozen=True, eq=False)
class SceneView:
    """The scene the window shows, as the parts see it: as read (``loaded``), on the GPU
    (``renderer``), its direct sorter (``sorter``: sorts on the caller's thread and
    returns the order, for screenshots, picks and selections), the rows deleted in the
    window (None: none), the orders the last frame drew by sort key (empty before the
    first), and the radius of its bounds (what overlays are sized by)."""

    loaded: LoadedScene
    renderer: GLRenderer
    sorter: DepthSorter | GpuSorter
    deleted: DeletedRows | None
    orders: Mapping[str, Order]
    radius: float


@dataclass(frozen=True, eq=False)
class Shown:
    """What the pointer is over at a frame's start: the last frame drawn (None before the
    first), the scene it shows, in the split view the divider (the first column of its
    right side, in the frame camera's pixels), and the last frame's time (seconds: what
    work beside the frames may take a frame)."""

    frame: Frame | None
    scene: SceneView
    divider: int | None = None
    frame_seconds: float = 0.05


@dataclass(frozen=True, eq=False)
class Pointing:
    """What the pointer's clicks do this frame: whether the measure tool takes them (its
    clicks are points, its double-clicks nothing; nothing else hovers or flies) and its
    scale (the messages' unit), whether a double-click in the stereo preview sets the
    convergence and the rig it sets it on, whether the view is flying (the second press
    of a double-click on a frustum) and whether it orbits (what aiming at a point does),
    and the split view's divider (the first column of its right side; None: no split view)."""

    measuring: bool = False
    scale: MeasureScale | None = None
    converge: bool = False
    rig: StereoRig = StereoRig()
    flying: bool = False
    orbiting: bool = False
    divider: int | None = None


# -- requests: what a part asks of the window ------------------------------------------
#: The keyboard's shortcuts (``input.SHORTCUTS``), each a request of its own.
Shortcut = Literal["quit", "screenshot", "add_keyframe", "switch_navigation", "next_camera", "previous_camera",
                   "reset_view", "toggle_panel"]


@dataclass(frozen=True)
class Press:
    """A shortcut's key went down, or the panel's button that does the same was pressed
    (Reset view, previous and next training camera, Save screenshot)."""

    shortcut: Shortcut


@dataclass(frozen=True)
class Click:
    """A click (``double`` False) or a double-click on the view at screen position (x, y)."""

    x: float
    y: float
    double: bool = False


@dataclass(frozen=True)
class FlyTo:
    """Fly to training camera ``index`` (wrapping), and render with its intrinsics."""

    index: int


@dataclass(frozen=True, eq=False)
class AimAt:
    """Aim the view at a world point (orbit around it, or turn to face it)."""

    point: np.ndarray


@dataclass(frozen=True)
class Converge:
    """Set the stereo rig's convergence (metres)."""

    metres: float


@dataclass(frozen=True, eq=False)
class MeasurePoint:
    """A point picked for the measure tool."""

    picked: Picked


@dataclass(frozen=True)
class OpenScene:
    """Open a scene file (with ``cameras``, a cameras.json, instead of one found beside it)."""

    path: str
    cameras: str | None = None


@dataclass(frozen=True)
class ReadAxes:
    """Read .spz scenes that declare no axes in ``axes`` ("rub" or "rdf") from now on,
    and the one shown again."""

    axes: str


@dataclass(frozen=True)
class ColourByLevel:
    """Colour a streamed SOG's gaussians by their level (on) or by their own colours."""

    on: bool


#: What the Headset section's buttons ask: open a session with its choices (Enter), ask
#: the runtime to end it (Leave), put the room back at the desktop view (Recentre).
HeadsetAction = Literal["enter", "leave", "recentre"]


@dataclass(frozen=True)
class Headset:
    """One of the Headset section's buttons (``HeadsetMode.act`` carries it out)."""

    action: HeadsetAction


Request = Union[Press, Click, FlyTo, AimAt, Converge, MeasurePoint, OpenScene, ReadAxes, ColourByLevel, Headset]


@dataclass(frozen=True)
class Reply:
    """What a part answers: ``messages`` for the panel, in order; ``requests`` for the
    window, in order; ``took_mouse``: the part draws with the mouse this frame (the
    parts after it, and the camera, leave the buttons alone); ``took_keys``: the keys
    whose press this frame the part answered (their shortcuts do nothing: Escape
    cancels a selection being weighed, it does not quit)."""

    messages: tuple[Message, ...] = ()
    requests: tuple[Request, ...] = ()
    took_mouse: bool = False
    took_keys: tuple = ()

    @classmethod
    def of(cls, *said: Message | Request | tuple | None, took_mouse: bool = False, took_keys: tuple = ()) -> Reply:
        """A reply of the messages and requests in ``said``, in order (a tuple: each of its
        items; None: nothing)."""
        items = [item for entry in said if entry is not None
                 for item in (entry if isinstance(entry, tuple) else (entry,)) if item is not None]
        return cls(tuple(item for item in items if isinstance(item, Message)),
                   tuple(item for item in items if not isinstance(item, Message)), took_mouse, took_keys)

    def __add__(self, other: Reply) -> Reply:
        return Reply(self.messages + other.messages, self.requests + other.requests,
                     self.took_mouse or other.took_mouse, self.took_keys + other.took_keys)


NO_REPLY = Reply()


class Part:
    """A part of the window. The viewer calls each hook on every part, in the order of
    its parts; a part overrides the hooks it needs (the defaults do nothing).

    - :meth:`scene_shown`: a scene is shown (``grown``: a streamed SOG's finer level of
      the same scene, whose rows keep their place).
    - :meth:`act`: at the frame's start, before the camera moves: the keys, the mouse
      (a part that takes it answers ``took_mouse``; those after it get ``mouse_free``
      False), what finished in the background.
    - :meth:`overlay`: the frame is made: what the part draws over the view (``pointing``:
      what the pointer's clicks do).
    - :meth:`close`: the window closes."""

    def scene_shown(self, loaded: LoadedScene, grown: bool) -> Reply:
        return NO_REPLY

    def act(self, shown: Shown, mouse_free: bool) -> Reply:
        return NO_REPLY

    def overlay(self, frame: Frame, scene: SceneView, pointing: Pointing) -> Reply:
        return NO_REPLY

    def close(self) -> None:
        pass
