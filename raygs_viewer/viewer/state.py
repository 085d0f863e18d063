"""The viewer's state besides its render settings, one small dataclass per concern.

The render settings are one :class:`~raygs_viewer.render.settings.RenderSettings`, held
by the viewer and replaced whole on every edit. What is not a render setting lives
here: the A/B split view, the stereo preview, the view mode (which channel the window
shows), the screenshot options, the navigation choices and the panel's own state.
:class:`ViewerOptions` holds the start value of each.
The panel, the keys and the mouse edit the viewer's copies; the frame reads them each
time, so an edit shows from the next frame on.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from operator import attrgetter
from typing import Literal

from raygs_viewer.camera.lens_model import DEFAULT_LENS
from raygs_viewer.camera.stereo import (
    DEFAULT_HEADSET,
    PRESETS,
    HeadsetPreset,
    StereoRig,
    StereoView,
    check_layout,
    custom_preset,
)
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.channel_pictures import ALPHA_THRESHOLD, ChannelView
from raygs_viewer.render.settings import RenderSettings, apply_preset
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.viewer.layout import PANEL_WIDTH

#: The right side's preset when the split view is first switched on.
DEFAULT_SPLIT_PRESET = "GS"
#: What a custom headset starts from in the panel.
CUSTOM_START = PRESETS["generic90"]


@dataclass
class SplitView:
    """The A/B split view: left of the divider the render settings, right of them the
    ACCURACY_PRESETS entry ``preset`` applied to them. fraction: where the divider is,
    as a fraction of the viewport's width."""

    on: bool = False
    preset: str = DEFAULT_SPLIT_PRESET
    fraction: float = 0.5

    def right(self, settings: RenderSettings) -> RenderSettings | None:
        """The right side's settings; None when the split view is off."""
        return apply_preset(settings, self.preset) if self.on else None

    def column(self, width: int) -> int:
        """The first column of the right side in a viewport ``width`` pixels wide."""
        return int(round(self.fraction * width))


#: The headset mirror's choices: both eyes side by side, or the left alone.
MIRRORS = ("both", "left")
#: How the right stick turns the world: a step at a time, or continuously.
TURNS = ("snap", "smooth")


@dataclass
class HeadsetChoices:
    """The headset's options (``view --xr``, the panel's Headset section).

    enter: open a session when the window opens (``--xr``). scale: each eye's size as a
    fraction of the runtime's recommended size (the panel's resolution scale; a new
    session takes it). depth: submit each eye's depth where the runtime takes it (off
    by default: the median depth costs several colour frames, docs/xr.md).
    mirror: what the desktop window shows of the eyes (:data:`MIRRORS`). turn: the right
    stick's turning (:data:`TURNS`)."""

    enter: bool = False
    scale: float = 1.0
    depth: bool = False
    mirror: str = "both"
    turn: str = "snap"


@dataclass
class StereoPreview:
    """The stereo preview (see :mod:`raygs_viewer.camera.stereo`): on or off, the rig,
    the layout, whether the lens preview is applied, and the headset: a PRESETS key, or
    "custom", then custom_size ([width, height] per eye) and custom_fov ([horizontal,
    vertical] degrees) describe it. save_eyes: stereo screenshots also save each eye.
    converge_on_pick: a double-click on the preview sets the convergence to the picked
    point's depth (instead of aiming the view at it). headset_size: the window draws
    each eye at the headset's per-eye size (shrunk to show it) instead of at the size
    the view area can show; screenshots and videos take the headset's size either way.

    ViewerOptions holds the start value; the panel edits the viewer's copy."""

    on: bool = False
    rig: StereoRig = StereoRig()
    layout: str = "sbs"
    lens_preview: bool = False
    headset: str = DEFAULT_HEADSET
    custom_size: list[int] = field(default_factory=lambda: [CUSTOM_START.width, CUSTOM_START.height])
    custom_fov: list[float] = field(default_factory=lambda: [CUSTOM_START.fov_x, CUSTOM_START.fov_y])
    save_eyes: bool = False
    converge_on_pick: bool = False
    headset_size: bool = False

    def __post_init__(self) -> None:
        check_layout(self.layout)

    @classmethod
    def of(cls, headset: HeadsetPreset, **values) -> StereoPreview:
        """A preview of ``headset``: its PRESETS key, or "custom" with its numbers."""
        if headset.name == "custom" or headset.name not in PRESETS:
            return cls(headset="custom", custom_size=[headset.width, headset.height],
                       custom_fov=[headset.fov_x, headset.fov_y], **values)
        return cls(headset=headset.name, **values)

    def headset_preset(self) -> HeadsetPreset:
        """The headset (UserError for custom values out of range)."""
        if self.headset == "custom":
            return custom_preset(*self.custom_size, *self.custom_fov)
        return PRESETS[self.headset]

    def view(self) -> StereoView | None:
        """The stereo view to draw; None when the preview is off."""
        if not self.on:
            return None
        return StereoView(self.rig, self.layout, DEFAULT_LENS if self.lens_preview else None, self.headset_preset())

    def frame_view(self, shown: StereoView | None) -> tuple[StereoView | None, Message]:
        """The stereo view to draw this frame, and what the panel says of it: a custom
        headset out of range is a standing error, and the preview keeps ``shown`` (the
        last frame's)."""
        try:
            view = self.view()
        except UserError as exc:
            return (shown if self.on else None), failed(exc, source="stereo")
        return view, mended("stereo")


#: Which sides of the split view show the view mode's picture.
VIEW_SIDES = {"both": "both sides", "left": "left side (A)", "right": "right side (B)"}


@dataclass
class ViewMode:
    """What the window shows: ``channel`` (render.channel_pictures.PICTURE_CHANNELS: the
    colour, or a picture of alpha, depth, median depth or normals), the depth pictures'
    range (``automatic``: spanning each image's depths; else ``near`` to ``far``, scene
    units), the space normals are shown in ("camera" or "world") and the alpha below
    which the depth and normal pictures leave a pixel black (0: off). Both stereo eyes
    show it; in the split view ``side`` says which side does ("both", "left", "right":
    e.g. colour on one side, depth on the other); screenshots save what is shown."""

    channel: str = "rgb"
    automatic: bool = True
    near: float = 0.1
    far: float = 10.0
    normal_space: str = "camera"
    alpha_threshold: float = ALPHA_THRESHOLD
    side: str = "both"

    def view(self) -> ChannelView | None:
        """The channel view to draw; None for the colour (the renderer's plain path).
        UserError for a set range that is not near < far."""
        if self.channel == "rgb":
            return None
        return ChannelView(self.channel, None if self.automatic else (self.near, self.far), self.normal_space,
                           self.alpha_threshold)

    def side_views(self, split: bool = True) -> tuple[ChannelView | None, ChannelView | None, Message]:
        """(left, right) views this frame, and what the panel says of them
        (:meth:`frame_view`): in the split view the view on the sides ``side`` names and
        the colour (None) on the other; else the view itself (``side`` names a side of
        the split view only)."""
        view, said = self.frame_view()
        if not split:
            return view, view, said
        return (view if self.side in ("both", "left") else None, view if self.side in ("both", "right") else None,
                said)

    def frame_view(self) -> tuple[ChannelView | None, Message]:
        """The view to draw this frame, and what the panel says of it: a set range that is
        not one is a standing error, and the frame shows the automatic range meanwhile."""
        try:
            view = self.view()
        except UserError as exc:
            return ChannelView(self.channel, None, self.normal_space, self.alpha_threshold), failed(exc, source="view")
        return view, mended("view")


@dataclass
class ScreenshotOptions:
    """Where F12 and the panel's button save (folder), and the offscreen render scale."""

    folder: str = "screenshots"
    scale: float = 1.0


@dataclass(frozen=True)
class NavigationChoices:
    """How the camera starts to move: mode "fly" or "orbit", the world's up axis (one of
    camera.navigation.UP_AXES; None: from the scene's training cameras, else -y, see
    view_control.start_up) and ``up_source``, who chose a given one (the panel says it),
    and turntable: degrees per frame about the up axis in orbit mode (a reproducible
    fly-around; 0: off). A new scene keeps the navigator's mode, and its up axis where
    one was chosen."""

    mode: str = "fly"
    up_axis: str | None = None
    turntable: float = 0.0
    up_source: str = "--up-axis"


#: What a line for the panel does: "note" sets the message line (an error stays), "done"
#: sets it and clears the error line (an action that went well), "error" sets the error
#: line, "mended" ends a standing error (:class:`Message`).
MessageKind = Literal["note", "done", "error", "mended"]


@dataclass(frozen=True)
class Message:
    """A line a part says to the panel (:meth:`PanelState.say`). ``source``: an error of
    a condition that may mend (settings the GPU cannot draw, a custom headset out of
    range, a path edit refused) *stands* until the same source says "mended", unless
    another error has replaced it meanwhile."""

    kind: MessageKind
    text: str = ""
    source: str | None = None


def note(text: str) -> Message:
    """The message line: what an action did besides the obvious."""
    return Message("note", text)


def done(text: str) -> Message:
    """An action went well: the message line says so and the error line is cleared."""
    return Message("done", text)


def failed(why: str | BaseException, action: str | None = None, source: str | None = None) -> Message:
    """The error line: "error: ACTION: WHY" in one line (``why`` an exception or its
    words); with ``source``, an error that stands until that source is mended."""
    text = one_line(why) if isinstance(why, BaseException) else why
    return Message("error", f"error: {action}: {text}" if action else f"error: {text}", source)


def mended(source: str) -> Message:
    """The condition ``source`` stood for is gone: its error goes (unless another replaced it)."""
    return Message("mended", source=source)


def saved(what: str, save: Callable[[], object]) -> Message:
    """Runs ``save`` (which returns where it wrote): the message naming the file, or
    the error saying in one line why ``what`` was not saved."""
    try:
        where = save()
    except UserError as exc:
        return failed(exc, f"{what} not saved")
    return done(f"saved {where}")


def said_lines(said: Iterable[Message | tuple[Message, ...] | None]) -> list[Message]:
    """The messages of ``said`` in order: each message, each message of a tuple, nothing of None."""
    lines = [line for item in said if item is not None for line in (item if isinstance(item, tuple) else (item,))]
    return [line for line in lines if line is not None]


@dataclass
class PanelState:
    """The panel's own state: whether it is shown, its width as last drawn (screen
    units; the user resizes it), the path typed into it, and its two lines, message and
    error, which only :meth:`say` changes."""

    show_panel: bool = True
    width: float = PANEL_WIDTH
    open_path: str = ""
    _message: str = ""
    _error: str = ""
    _standing: dict[str, str] = field(default_factory=dict)
    #: The two lines, read-only: :meth:`say` is the one way to change them.
    message = property(attrgetter("_message"))
    error = property(attrgetter("_error"))

    def toggle(self) -> None:
        self.show_panel = not self.show_panel

    def say(self, *messages: Message | tuple[Message, ...] | None) -> None:
        """Shows each of ``messages`` in turn (a tuple: each of its messages; None: nothing
        to say)."""
        for message in said_lines(messages):
            if message.kind == "note":
                self._message = message.text
            elif message.kind == "done":
                self._message, self._error = message.text, ""
            elif message.kind == "error":
                self._error = message.text
                if message.source is not None:
                    self._standing[message.source] = message.text
            elif message.source is not None:  # mended
                error = self._standing.pop(message.source, None)
                if error is not None and self._error == error:
                    self._error = ""


@dataclass(frozen=True)
class ViewerOptions:
    """Everything ``raygs-viewer view`` takes from the command line.

    source: the scene to open (a file or the demo), its training cameras.json (None:
    look next to the scene) and the axes a .spz that declares none is read in (the
    panel's Scene section switches them; loading.SceneOpener holds the current
    choice). camera/camera_index: the start view (a cameras.json and an
    index into it). width, height: window size in screen coordinates. settings: the
    start render settings (sh_degree None: each scene's own). frames: quit after that
    many frames (None: run until closed). screenshot: save the last frame there (PNG,
    with a .json sidecar beside it). window_screenshot: a PNG of the whole window, panel
    included, at the end. screenshots: where F12 and the panel's button save, and at
    what scale. platform: GLFW platform ("auto", "x11", "wayland", "null"; auto picks
    null without a display). general: the all-features shader variant
    (GLRenderer(general=)), to compare. stereo: the stereo preview's start value.
    images: the training photos' folder for the Photo view (None: the one the model
    folder's cfg_args names). sort: "cpu" (a background thread), "gpu" (in the frame,
    on the GPU: ``render.sorting.SORTS``) or "auto" (the one this GL measured faster:
    ``viewer.auto_defaults``). auto_precision: the blend this GL measured fastest within
    the accuracy study's error instead of ``settings.precision`` (``--precision auto``).
    headset: the OpenXR headset's options (``--xr`` enters it at the start).
    """

    source: SceneSource = SceneSource.demo()
    camera: str | None = None
    camera_index: int = 0
    width: int = 1280
    height: int = 720
    settings: RenderSettings = RenderSettings()
    frames: int | None = None
    screenshot: str | None = None
    window_screenshot: str | None = None
    screenshots: ScreenshotOptions = field(default_factory=ScreenshotOptions)
    vsync: bool = True
    navigation: NavigationChoices = NavigationChoices()
    platform: str = "auto"
    general: bool = False
    stereo: StereoPreview = field(default_factory=StereoPreview)
    images: str | None = None
    sort: str = "cpu"
    auto_precision: bool = False
    headset: HeadsetChoices = field(default_factory=HeadsetChoices)
