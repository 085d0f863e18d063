"""Where the window looks from and how: the navigator (pose, fly or orbit), the lens
(a free field of view or a training camera's intrinsics), the training camera flown
to, and the camera each frame draws, mono or the midpoint between the stereo eyes."""

from __future__ import annotations

import math

# A flight's in-between poses slerp through scipy, which camera.navigation imports only
# when a flight first needs it (0.4 s: the command line's commands never fly). The window
# loads it when it opens, not in the frame of its first flight.
import scipy.spatial.transform  # noqa: F401

from raygs_viewer.camera.lens import Lens, letterbox
from raygs_viewer.camera.navigation import (
    LOOK_RADIANS_PER_PIXEL,
    Navigator,
    Pose,
    framing_pose,
    scene_bounds,
)
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoView, composed_size, eye_cameras, preview_camera
from raygs_viewer.camera.up_axis import cameras_up
from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.frame import Framing
from raygs_viewer.viewer.state import Message, NavigationChoices, note

#: The up axis where neither the command line nor the training cameras give one: COLMAP's and INRIA's.
DEFAULT_UP = "-y"
#: ``up_source`` of an up axis picked in the panel's combo.
PANEL_UP = "chosen in the panel"


def start_up(choices: NavigationChoices, cameras: list[Camera]) -> tuple[str, str]:
    """(up axis, where it came from): the one chosen (``choices.up_source``), else the
    training cameras' (``up_axis.cameras_up``), else :data:`DEFAULT_UP`."""
    if choices.up_axis is not None:
        return choices.up_axis, choices.up_source
    derived = cameras_up(cameras)
    if derived is not None:
        return derived, f"from the {len(cameras)} training camera{'s' if len(cameras) != 1 else ''}"
    return DEFAULT_UP, "default" if not cameras else "default: the training cameras agree on no axis"


class ViewControl:
    """One per scene: the scene's bounds (``center``, ``radius``) frame it and bound
    navigation. ``training_index``: the training camera flown to last (None: a free
    view). ``up_source``: where the navigator's up axis came from (:func:`start_up`, or
    the panel)."""

    def __init__(self, loaded: LoadedScene, start_camera: Camera | None, choices: NavigationChoices,
                 aspect: float):
        """The first training view, filling the window with its vertical field of view,
        unless ``start_camera`` is given; without either a view framing the scene for
        a window of ``aspect`` (width / height)."""
        self.cameras = loaded.cameras
        self.aspect = aspect
        self.center, self.radius = scene_bounds(loaded.framed)
        self.training_index: int | None = None
        up, self.up_source = start_up(choices, loaded.cameras)
        self._up_chosen = choices.up_axis is not None
        if start_camera is not None:
            pose, self.lens = Pose.from_camera(start_camera), Lens.of_camera(start_camera)
        elif loaded.cameras:
            first = loaded.cameras[0]
            pose, self.lens = Pose.from_camera(first), Lens().with_fov(Lens.of_camera(first).fov_y_degrees)
        else:
            self.lens = Lens()
            pose = framing_pose(self.center, self.radius, up, self.lens.fov_y_degrees, aspect)
        self.navigator = Navigator(pose, self.center, self.radius, up=up, mode=choices.mode)

    def choices(self) -> NavigationChoices:
        """What the next scene keeps: the navigator's mode, and its up axis where one was
        chosen (an up axis from these cameras, or the default, is found anew for the next)."""
        if not self._up_chosen:
            return NavigationChoices(mode=self.navigator.mode)
        return NavigationChoices(mode=self.navigator.mode, up_axis=self.navigator.up, up_source=self.up_source)

    def set_up(self, up: str) -> None:
        """The panel's choice of up axis (navigation.Navigator.set_up)."""
        self.navigator.set_up(up)
        self.up_source, self._up_chosen = PANEL_UP, True

    def switch_mode(self) -> None:
        """Fly to orbit and back."""
        self.navigator.set_mode("orbit" if self.navigator.mode == "fly" else "fly")

    def select_training_camera(self, index: int) -> Message | None:
        """Flies to training camera ``index`` (wrapping) and renders with its intrinsics;
        says so where the scene has none."""
        cameras = self.cameras
        if not cameras:
            return note("this scene has no training cameras")
        index %= len(cameras)
        self.training_index = index
        self.lens = Lens.of_camera(cameras[index])
        self.navigator.fly_to(Pose.from_camera(cameras[index]))
        return None

    def step_training_camera(self, step: int) -> Message | None:
        """Flies to the next (+1) or previous (-1) training camera."""
        start = self.training_index if self.training_index is not None else (-1 if step > 0 else 0)
        return self.select_training_camera(start + step)

    def set_fov(self, fov_y_degrees: float) -> None:
        """A free lens of this vertical field of view."""
        self.training_index = None
        self.lens = self.lens.with_fov(fov_y_degrees)

    def reset(self, window: tuple[int, int], stereo: StereoView | None) -> None:
        """Frames the scene again with a free lens of the same field of view, for a view
        area of ``window`` = (width, height) (none yet: of the aspect the view was made
        for), or for the eyes of ``stereo``'s headset."""
        self.set_fov(self.lens.fov_y_degrees)
        fov, (width, height) = self.lens.fov_y_degrees, window
        aspect = width / height if width > 0 and height > 0 else self.aspect
        if stereo is not None:  # frame the scene for the eyes, not the window
            fov, aspect = stereo.headset.fov_y, stereo.headset.width / stereo.headset.height
        self.navigator.reset(framing_pose(self.center, self.radius, self.navigator.up, fov, aspect))

    def advance(self, dt: float, turntable: float = 0.0) -> None:
        """Moves the view on by a frame of ``dt`` seconds (a flight, the keys held), and with
        ``turntable`` orbits the target by that many degrees per frame (not per second),
        so a scripted run draws the same views on any machine."""
        self.navigator.advance(dt)
        if not turntable:
            return
        if self.navigator.mode != "orbit":
            self.navigator.set_mode("orbit")
        self.navigator.rotate(math.radians(turntable) / LOOK_RADIANS_PER_PIXEL, 0.0)

    def camera(self, area: Viewport, stereo: StereoView | None, headset_size: bool = False) -> Framing:
        """Where a frame shown in ``area`` (the view area: x, y, w, h of the window's
        framebuffer, from the top-left) looks from: the camera of the lens's viewport in
        it, or in stereo the midpoint between the eyes at the headset's field of view and
        at the size the area can show both (``stereo.preview_camera``; ``headset_size``:
        at the headset's own per-eye size), the composed image letterboxed in the area;
        and the eye cameras (made here only: the frame's sort culls for them and the
        stereo frame draws them)."""
        ax, ay, width, height = area
        if stereo is None:
            x, y, w, h = self.lens.viewport(width, height)
            return Framing(self.lens.camera(self.navigator.pose, width, height), (ax + x, ay + y, w, h), None)
        camera = stereo.headset.camera(self.lens.camera(self.navigator.pose, width, height))
        if not headset_size:
            camera = preview_camera(camera, width, height, stereo.layout)
        shown_width, shown_height = composed_size(camera.width, camera.height, stereo.layout)
        x, y, w, h = letterbox(width, height, shown_width / shown_height)
        return Framing(camera, (ax + x, ay + y, w, h), eye_cameras(camera, stereo.rig))
