"""The interactive viewer: a GLFW window, the RayGS renderer, and an imgui panel on top.

One frame: poll input -> move the camera -> ask the background sorter for this
view (never waiting) -> draw the newest finished order into a float target ->
show it letterboxed in the window -> panel -> swap. Screenshots re-render the
same view offscreen with an exact sort, so they reproduce headlessly from their
sidecar (``raygs-viewer render --sidecar``).

In the stereo preview the view is the midpoint between the eyes, at the headset
preset's per-eye size and field of view: one sort culled for both eyes, each eye
drawn offscreen, the lens preview and the layout composed into one image that the
present pass scales into the window (see :mod:`raygs_viewer.camera.stereo`).

In the A/B split view both sides render the whole viewport with the same order
(sorted with the more conservative cull of the two) into their own targets; the
present pass shows the left target left of the divider and the right one right of it.
"""

from __future__ import annotations

import itertools
import math
import os
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_key
from raygs_viewer.camera.stereo import (
    DEFAULT_CONVERGENCE,
    DEFAULT_HEADSET,
    DEFAULT_IPD,
    DEFAULT_SCENE_SCALE,
    PRESETS,
    HeadsetPreset,
    StereoRig,
    StereoView,
    composed_size,
    custom_preset,
    eye_cameras,
)
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import (
    ACCURACY_PRESETS,
    DEFAULT_P_MIN,
    MODE_LABELS,
    RENDER_MODES,
    RenderSettings,
    apply_preset,
)
from raygs_viewer.viewer.window import Window, glfw, imgui  # noqa: I001  (imgui before glfw: see window)

LETTERBOX_GREY = 0.12
#: The A/B divider's position, as a fraction of the viewport's width, stays in this range.
SPLIT_RANGE = (0.02, 0.98)
#: The divider can be grabbed this many screen pixels either side of it.
SPLIT_GRAB = 6.0
#: The right side's preset when the split view is first switched on.
DEFAULT_SPLIT_PRESET = "GS"
_DEFAULTS = RenderSettings()
#: The RenderSettings fields beyond p_min, background and sh_degree; ViewerOptions and
#: PanelState carry them under the same names.
ACCURACY_FIELDS = ("mode", "mip", "mip_sigma2", "mip_modulation", "gs_compensation", "supersample",
                   "alpha_clamp", "transmittance_cutoff")


@dataclass(frozen=True)
class ViewerOptions:
    """Everything ``raygs-viewer view`` takes from the command line.

    scene: a .ply/.splat path or "demo". cameras: training cameras.json (None: look
    next to the scene). camera/camera_index: the start view (a cameras.json and an
    index into it). width, height: window size in screen coordinates. frames: quit
    after that many frames (None: run until closed). screenshot: save the last frame
    there (PNG, with a .json sidecar beside it). screenshot_dir: where F12 and the
    panel button save. screenshot_scale: offscreen render scale of those. platform:
    GLFW platform ("auto", "x11", "wayland", "null"; auto picks null without a display).
    p_min ... transmittance_cutoff: the start values of the panel's render settings
    (the RenderSettings fields of the same names; sh_degree None: the scene's).
    """

    scene: str = "demo"
    cameras: str | None = None
    camera: str | None = None
    camera_index: int = 0
    width: int = 1280
    height: int = 720
    p_min: float = DEFAULT_P_MIN
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sh_degree: int | None = None
    mode: str = _DEFAULTS.mode
    mip: bool = _DEFAULTS.mip
    mip_sigma2: float = _DEFAULTS.mip_sigma2
    mip_modulation: bool = _DEFAULTS.mip_modulation
    gs_compensation: bool = _DEFAULTS.gs_compensation
    supersample: int = _DEFAULTS.supersample
    alpha_clamp: bool = _DEFAULTS.alpha_clamp
    transmittance_cutoff: bool = _DEFAULTS.transmittance_cutoff
    frames: int | None = None
    screenshot: str | None = None
    screenshot_dir: str = "screenshots"
    screenshot_scale: float = 1.0
    vsync: bool = True
    navigation: str = "fly"   # "fly" or "orbit"
    up_axis: str = "-y"       # one of controls.UP_AXES
    platform: str = "auto"
    turntable: float = 0.0    # degrees per frame about the up axis (orbit mode); 0: off
    window_screenshot: str | None = None  # PNG of the whole window, panel included, at the end
    general: bool = False     # the all-features shader variant (GLRenderer(general=)), to compare
    stereo: bool = False      # start in the stereo preview; the fields below are its start values
    ipd: float = DEFAULT_IPD
    convergence: float = DEFAULT_CONVERGENCE
    scene_scale: float = DEFAULT_SCENE_SCALE
    stereo_layout: str = "sbs"
    lens_preview: bool = False
    headset: HeadsetPreset = PRESETS[DEFAULT_HEADSET]
    save_eyes: bool = False   # stereo screenshots also save each eye

    def settings(self) -> RenderSettings:
        """The start settings (UserError when a value is out of range)."""
        return RenderSettings(p_min=self.p_min, background=tuple(self.background), sh_degree=self.sh_degree,
                              **{name: getattr(self, name) for name in ACCURACY_FIELDS})


@dataclass
class PanelState:
    """What the panel edits; read by the frame each time (panel edits apply next frame).

    p_min ... transmittance_cutoff are the RenderSettings fields of the same names (the
    left side's in the split view). split_view: show the A/B split view; split_preset:
    the right side's ACCURACY_PRESETS entry, applied to the panel's settings;
    split_fraction: where the divider is, as a fraction of the viewport's width.
    stereo ... save_eyes: the stereo preview (ViewerOptions' fields of the same names);
    headset: a PRESETS key or "custom", whose per-eye size and field of view are
    custom_size and custom_fov."""

    p_min: float
    background: list[float]
    sh_degree: int
    mode: str = _DEFAULTS.mode
    mip: bool = _DEFAULTS.mip
    mip_sigma2: float = _DEFAULTS.mip_sigma2
    mip_modulation: bool = _DEFAULTS.mip_modulation
    gs_compensation: bool = _DEFAULTS.gs_compensation
    supersample: int = _DEFAULTS.supersample
    alpha_clamp: bool = _DEFAULTS.alpha_clamp
    transmittance_cutoff: bool = _DEFAULTS.transmittance_cutoff
    split_view: bool = False
    split_preset: str = DEFAULT_SPLIT_PRESET
    split_fraction: float = 0.5
    stereo: bool = False
    ipd: float = DEFAULT_IPD
    convergence: float = DEFAULT_CONVERGENCE
    scene_scale: float = DEFAULT_SCENE_SCALE
    stereo_layout: str = "sbs"
    lens_preview: bool = False
    headset: str = DEFAULT_HEADSET
    custom_size: list[int] = field(default_factory=lambda: [PRESETS["generic90"].width, PRESETS["generic90"].height])
    custom_fov: list[float] = field(default_factory=lambda: [PRESETS["generic90"].fov_x, PRESETS["generic90"].fov_y])
    save_eyes: bool = False
    screenshot_scale: float = 1.0
    screenshot_dir: str = "screenshots"
    open_path: str = ""
    show_panel: bool = True
    message: str = ""
    error: str = ""


@dataclass
class FrameStats:
    """Statistics for the panel (the last 60 frames) and for the summary of a scripted
    run (the whole history); times in seconds."""

    all_frame_times: deque = field(default_factory=lambda: deque(maxlen=10000))
    all_sort_times: deque = field(default_factory=lambda: deque(maxlen=10000))
    sort_seconds: float = float("nan")
    gpu_seconds: float = float("nan")     # the scene's draw: both sides in the split view, both eyes in stereo
    post_seconds: float = float("nan")    # stereo: lens preview and layout
    visible: int = 0
    order_age: int = 0          # frames since the drawn order's view was current; 0: up to date
    drawn_serial: int = 0       # sort request whose order the last draw used
    draws: int = 0              # frames that re-rendered the scene (others reused the image)
    frames_with_sort_running: int = 0  # frames completed while a sort was in progress

    @property
    def recent_frame_times(self) -> list[float]:
        return list(itertools.islice(reversed(self.all_frame_times), 60))

    @property
    def fps(self) -> float:
        recent = self.recent_frame_times
        return len(recent) / sum(recent) if recent and sum(recent) > 0 else 0.0

    @property
    def frame_ms(self) -> float:
        recent = self.recent_frame_times
        return 1000 * float(np.median(recent)) if recent else float("nan")


def _cameras_key(cameras) -> tuple | None:
    return None if cameras is None else tuple(camera_key(c) for c in cameras)


def _panel_stereo(options: ViewerOptions) -> dict:
    """PanelState's stereo fields from the options; a custom headset fills the custom fields."""
    headset = options.headset
    values = {name: getattr(options, name) for name in ("stereo", "ipd", "convergence", "scene_scale",
                                                        "stereo_layout", "lens_preview", "save_eyes")}
    if headset.name == "custom" or headset.name not in PRESETS:
        values.update(headset="custom", custom_size=[headset.width, headset.height],
                      custom_fov=[headset.fov_x, headset.fov_y])
    else:
        values["headset"] = headset.name
    return values


class Viewer:
    """The application: owns the window, the scene on the GPU, the sorter and the panel.

    ``frame()`` runs one iteration of the loop; ``run()`` loops until the window
    closes. Tests drive ``frame()`` directly and queue input in ``input_script``,
    which is called with the viewer after the GLFW backend has read the devices and
    before imgui starts the frame (the place synthetic imgui events must go).
    """

    def __init__(self, options: ViewerOptions, loaded, start_camera: Camera | None = None, sorter_factory=None):
        from raygs_viewer.scene.loader import SceneLoader

        self.options = options
        self.window = Window(f"raygs-viewer — {_scene_title(loaded.path)}", options.width,
                                       options.height, options.platform, options.vsync)
        self.ctx = self.window.ctx
        self.window.set_drop_callback(self.on_drop)
        self.panel = PanelState(p_min=options.p_min, background=list(options.background),
                                sh_degree=3 if options.sh_degree is None else options.sh_degree,
                                screenshot_scale=options.screenshot_scale,
                                screenshot_dir=options.screenshot_dir,
                                **{name: getattr(options, name) for name in ACCURACY_FIELDS},
                                **_panel_stereo(options))
        self.stats = FrameStats()
        self.frame_index = 0
        self.input_script: Callable[["Viewer"], None] | None = None
        self.fixed_dt: float | None = None  # tests: a deterministic frame time
        self.sorter_factory = sorter_factory  # tests: wraps the sorter to instrument it
        self.loader = SceneLoader()
        self.loaded = None
        self.navigator = None
        self.renderer = None
        self.sorter = None
        self.camera: Camera | None = None   # the view of the last frame, viewport-sized
        self.viewport = (0, 0, 1, 1)
        self.training_index: int | None = None
        self.screenshot_requested = False
        self.capture_window_next = False    # set to keep the next frame's window image
        self.wait_for_sort = False          # set for the last frame of a scripted run
        self.window_capture: np.ndarray | None = None
        self.last_screenshot: tuple[Path, Path] | None = None
        self.last_screenshots: list[tuple[Path, Path]] = []  # every file pair of the last capture
        #: The split view's divider and side labels as drawn last frame, (x0, y0, x1, y1)
        #: in screen coordinates (imgui's), for tests; empty without the split view.
        self.overlay_rects: dict[str, tuple[float, float, float, float]] = {}
        self.dragging_divider = False
        self._split_drawn = False   # whether the targets hold a split view (what present shows)
        self._draw_error: str | None = None
        self._request_frames: dict[int, int] = {}
        self._drawn_key = None
        self._target = None         # the scene (the left side in the split view)
        self._target_right = None   # the split view's right side
        self._stereo_frame = None   # the stereo preview's targets (render.stereo_frame.StereoFrame)
        self._stereo_drawn = False  # whether the last draw was stereo (what present shows)
        self._stereo_error: str | None = None  # the panel's error about the stereo values, while it stands
        self.shown_stereo: StereoView | None = None  # the stereo view of the last frame (None: mono)
        self._present = self.ctx.program(*_present_shaders())
        self._present_vao = self.ctx.vertex_array(self._present, [])
        self._timer = GpuTimer(self.ctx)
        self._post_timer = GpuTimer(self.ctx)
        self._last_time = None
        try:
            self._install(loaded, start_camera)
            problem = self.renderer.supports(self.settings())
            if problem:  # e.g. --transmittance-cutoff without framebuffer fetch
                raise UserError(problem)
        except BaseException:  # e.g. a scene too large for this GPU: no window left behind
            self.loader.close()
            self.window.close()
            raise
        if options.navigation == "orbit":
            self.navigator.set_mode("orbit")

    # -- scene ---------------------------------------------------------------------
    def _install(self, loaded, start_camera: Camera | None = None) -> None:
        """Puts a loaded scene on the GPU; on failure the current scene stays."""
        from raygs_viewer.camera.navigation import Navigator, Pose, framing_pose, scene_bounds
        from raygs_viewer.camera.lens import Lens
        from raygs_viewer.render.gl.renderer import GLRenderer
        from raygs_viewer.sort.worker import BackgroundSorter

        renderer = GLRenderer(self.ctx, loaded.scene, general=self.options.general)  # UserError (too large) leaves everything as it was
        if self.renderer is not None:
            self.renderer.release()
        if self.sorter is not None:
            self.sorter.close()
        self.renderer = renderer
        self.sorter = (self.sorter_factory or BackgroundSorter)(renderer.sorter)
        self._request_frames.clear()
        self._drawn_key = None
        self.loaded = loaded
        self.training_index = None
        self.panel.sh_degree = min(self.panel.sh_degree, loaded.scene.sh_degree) if self.options.sh_degree is not None \
            else loaded.scene.sh_degree
        self.center, self.radius = scene_bounds(loaded.scene.positions)
        # A new scene keeps the user's navigation choices.
        up = self.options.up_axis if self.navigator is None else self.navigator.up
        mode = self.options.navigation if self.navigator is None else self.navigator.mode
        if start_camera is not None:
            pose, self.lens = Pose.from_camera(start_camera), Lens.of_camera(start_camera)
        elif loaded.cameras:
            # The first training view, filling the window with its vertical field of view.
            first = loaded.cameras[0]
            pose, self.lens = Pose.from_camera(first), Lens().with_fov(Lens.of_camera(first).fov_y_degrees)
        else:
            self.lens = Lens()
            pose = framing_pose(self.center, self.radius, up, self.lens.fov_y_degrees,
                                self.options.width / self.options.height)
        self.navigator = Navigator(pose, self.center, self.radius, up=up, mode=mode)
        if self.window is not None:
            glfw.set_window_title(self.window.handle, f"raygs-viewer — {_scene_title(loaded.path)}")

    def open_scene(self, path: str) -> None:
        """Starts loading ``path`` in the background; the current scene stays until it is ready."""
        path = path.strip()
        if not path:
            self.panel.error = "error: no file given"
            return
        self.panel.error = ""
        self.panel.message = f"loading {path} ..."
        self.loader.start(path)

    def on_drop(self, paths: list[str]) -> None:
        if paths:
            self.open_scene(paths[0])
            if len(paths) > 1:
                self.panel.message = f"{len(paths)} files dropped; opening the first"

    def _poll_loader(self) -> None:
        result = self.loader.poll()
        if result is None:
            return
        if isinstance(result, UserError):
            self.panel.error = f"error: {str(result).splitlines()[0]}"
            self.panel.message = ""
            return
        if result.scene.count == 0:
            # scene_io accepts an empty file, and one whose every gaussian is invalid, as an
            # empty scene; swapping the shown scene for a black window is never what was meant.
            why = "; ".join(result.warnings)
            self.panel.error = f"error: {result.path}: no gaussians to show" + (f" ({why})" if why else "")
            self.panel.message = ""
            return
        try:
            self._install(result)
        except (UserError, MemoryError, moderngl.Error) as exc:  # e.g. too large for this GPU
            self.panel.error = f"error: {result.path}: {_one_line(exc)}"
            self.panel.message = ""
            return
        self.panel.error = ""
        self.panel.message = "; ".join(["loaded " + _scene_title(result.path)] + list(result.warnings))

    # -- view ------------------------------------------------------------------------
    def settings(self) -> RenderSettings:
        """The panel's render settings (the left side's in the split view)."""
        panel = self.panel
        return RenderSettings(p_min=panel.p_min, background=tuple(panel.background), sh_degree=panel.sh_degree,
                              **{name: getattr(panel, name) for name in ACCURACY_FIELDS})

    def right_settings(self) -> RenderSettings | None:
        """The split view's right side: the panel's settings with its preset applied;
        None when the split view is off (it is off in the stereo preview)."""
        if not self.panel.split_view or self.panel.stereo:
            return None
        return apply_preset(self.settings(), self.panel.split_preset)

    def headset(self) -> HeadsetPreset:
        """The panel's headset preset (UserError for custom values out of range)."""
        panel = self.panel
        if panel.headset == "custom":
            return custom_preset(*panel.custom_size, *panel.custom_fov)
        return PRESETS[panel.headset]

    def stereo_view(self) -> StereoView | None:
        """The panel's stereo preview; None when it is off."""
        from raygs_viewer.camera.lens_model import DEFAULT_LENS
        panel = self.panel
        if not panel.stereo:
            return None
        return StereoView(StereoRig(panel.ipd, panel.convergence, panel.scene_scale), panel.stereo_layout,
                          DEFAULT_LENS if panel.lens_preview else None, self.headset())

    def split_column(self, width: int | None = None) -> int:
        """The first viewport column (framebuffer pixels) of the split view's right side."""
        width = self.viewport[2] if width is None else width
        return int(round(self.panel.split_fraction * width))

    def select_training_camera(self, index: int) -> None:
        """Flies to training camera ``index`` (wrapping) and renders with its intrinsics."""
        from raygs_viewer.camera.navigation import Pose
        from raygs_viewer.camera.lens import Lens
        cameras = self.loaded.cameras
        if not cameras:
            self.panel.message = "this scene has no training cameras"
            return
        index %= len(cameras)
        self.training_index = index
        self.lens = Lens.of_camera(cameras[index])
        self.navigator.fly_to(Pose.from_camera(cameras[index]))

    def step_training_camera(self, step: int) -> None:
        start = self.training_index if self.training_index is not None else (-1 if step > 0 else 0)
        self.select_training_camera(start + step)

    def reset_view(self) -> None:
        from raygs_viewer.camera.navigation import framing_pose
        self.training_index = None
        self.lens = self.lens.with_fov(self.lens.fov_y_degrees)  # free lens, same field of view
        width, height = self.window.framebuffer_size()
        aspect = width / height if width > 0 and height > 0 else self.options.width / self.options.height
        fov = self.lens.fov_y_degrees
        if self.shown_stereo is not None:  # frame the scene for the eyes, not the window
            headset = self.shown_stereo.headset
            fov, aspect = headset.fov_y, headset.width / headset.height
        self.navigator.reset(framing_pose(self.center, self.radius, self.navigator.up, fov, aspect))

    def set_fov(self, fov_y_degrees: float) -> None:
        self.training_index = None
        self.lens = self.lens.with_fov(fov_y_degrees)

    # -- input -----------------------------------------------------------------------
    def _handle_input(self, dt: float) -> None:
        io = imgui.get_io()
        key = imgui.Key
        nav = self.navigator
        if not io.want_capture_keyboard:
            pressed = lambda *keys: any(imgui.is_key_pressed(k, False) for k in keys)  # noqa: E731
            down = lambda k: 1.0 if imgui.is_key_down(k) else 0.0  # noqa: E731
            if pressed(key.escape):
                self.window.request_close()
            if pressed(key.f12):
                self.screenshot_requested = True
            if pressed(key.tab):
                nav.set_mode("orbit" if nav.mode == "fly" else "fly")
            if pressed(key.n, key.page_down):
                self.step_training_camera(+1)
            if pressed(key.p, key.page_up):
                self.step_training_camera(-1)
            if pressed(key.r, key.home):
                self.reset_view()
            if pressed(key.h, key.f1):
                self.panel.show_panel = not self.panel.show_panel
            right = down(key.d) - down(key.a)
            upward = down(key.e) - down(key.q)
            forward = down(key.w) - down(key.s)
            if right or upward or forward:
                nav.move(dt, right, upward, forward, fast=io.key_shift, slow=io.key_ctrl)
        if self._divider_input(io):
            return  # the mouse drags the split view's divider, not the camera
        if not io.want_capture_mouse:
            dx, dy = io.mouse_delta.x, io.mouse_delta.y
            if not (math.isfinite(dx) and math.isfinite(dy)):
                dx = dy = 0.0
            left, right_button, middle = (imgui.is_mouse_down(b) for b in (0, 1, 2))
            wheel = io.mouse_wheel
            if nav.mode == "fly":
                if (left or right_button) and (dx or dy):
                    nav.look(dx, dy)
                if wheel:
                    nav.scale(wheel)
            else:
                panning = right_button or middle or (left and io.key_shift)
                if panning and (dx or dy):
                    scale = io.display_framebuffer_scale
                    # The image's focal length in window pixels (the stereo preview is scaled).
                    focal = (self.camera.fy * self.viewport[3] / self.camera.height if self.camera is not None
                             else 1000.0)
                    nav.pan(dx * scale.x, dy * scale.y, focal)
                elif left and (dx or dy):
                    nav.rotate(dx, dy)
                if wheel:
                    nav.zoom(wheel)

    def _divider_input(self, io) -> bool:
        """The split view's divider: a left press within SPLIT_GRAB screen pixels of it
        (not on the panel) grabs it, and it follows the mouse until the button is
        released. True while the mouse belongs to the divider (the camera ignores it)."""
        if self.right_settings() is None:  # no split view (or the stereo preview, which has none)
            self.dragging_divider = False
            return False
        scale = io.display_framebuffer_scale
        sx, sy = (scale.x or 1.0), (scale.y or 1.0)
        vx, vy, vw, vh = self.viewport
        mx, my = io.mouse_pos.x, io.mouse_pos.y
        finite = math.isfinite(mx) and math.isfinite(my) and abs(mx) < 1e30 and abs(my) < 1e30
        if self.dragging_divider:
            if not imgui.is_mouse_down(0):
                self.dragging_divider = False
            elif finite and vw > 0:
                low, high = SPLIT_RANGE
                self.panel.split_fraction = min(max((mx * sx - vx) / vw, low), high)
            imgui.set_mouse_cursor(imgui.MouseCursor_.resize_ew.value)
            return True
        if io.want_capture_mouse or not finite:
            return False
        divider = (vx + self.split_column(vw)) / sx
        if abs(mx - divider) <= SPLIT_GRAB and vy / sy <= my <= (vy + vh) / sy:
            imgui.set_mouse_cursor(imgui.MouseCursor_.resize_ew.value)
            if imgui.is_mouse_clicked(0):
                self.dragging_divider = True
                return True
        return False

    def _turn(self, degrees: float) -> None:
        """Turntable: orbit the target by a fixed angle per frame (not per second), so a
        scripted run draws the same views on any machine."""
        from raygs_viewer.camera.navigation import LOOK_RADIANS_PER_PIXEL
        if self.navigator.mode != "orbit":
            self.navigator.set_mode("orbit")
        self.navigator.rotate(math.radians(degrees) / LOOK_RADIANS_PER_PIXEL, 0.0)

    # -- frame -----------------------------------------------------------------------
    def frame(self) -> None:
        """One iteration of the loop (see the module docstring)."""

        now = time.perf_counter()
        if self._last_time is not None:
            self.stats.all_frame_times.append(now - self._last_time)
        dt = self.fixed_dt if self.fixed_dt is not None else (
            min(now - self._last_time, 0.1) if self._last_time is not None else 0.0)
        self._last_time = now
        self.frame_index += 1
        glfw.poll_events()
        self._poll_loader()
        width, height = self.window.framebuffer_size()
        if width <= 0 or height <= 0:  # minimised: nothing to draw, do not spin
            if self.options.frames is None:
                glfw.wait_events_timeout(0.1)
            return
        self.window.begin_frame()
        if self.input_script is not None:
            self.input_script(self)
        imgui.new_frame()
        self._handle_input(dt)
        self.navigator.advance(dt)
        if self.options.turntable:
            self._turn(self.options.turntable)

        settings, right = self.settings(), self.right_settings()
        stereo = self._current_stereo_view()
        if stereo is None:
            x, y, w, h = self.viewport = self.lens.viewport(width, height)
            camera = self.camera = self.lens.camera(self.navigator.pose, width, height)  # viewport-sized
            cull_cameras = None
        else:
            from raygs_viewer.camera.lens import letterbox
            # The midpoint between the eyes, at the headset's per-eye size and field of view.
            camera = self.camera = stereo.headset.camera(self.lens.camera(self.navigator.pose, width, height))
            shown_width, shown_height = composed_size(camera.width, camera.height, stereo.layout)
            x, y, w, h = self.viewport = letterbox(width, height, shown_width / shown_height)
            cull_cameras = eye_cameras(camera, stereo.rig)
        self.shown_stereo = stereo
        p_min, dilation = sort_cull(camera, settings, right)  # the eyes share the midpoint's fx, fy
        serial = self.sorter.request(camera, p_min, dilation, cull_cameras)
        self._request_frames.setdefault(serial, self.frame_index)
        if self.wait_for_sort:
            # Only the last frame of a scripted run: its capture must show the finished view.
            self.sorter.wait(serial, timeout=120)
        result = self.sorter.latest()
        if self.sorter.started > self.sorter.finished:
            self.stats.frames_with_sort_running += 1

        if self.panel.show_panel:
            from raygs_viewer.viewer.panel import draw_panel
            # Tab is the fly/orbit key. imgui would also tab into the panel (focused from
            # its first frame): a slider tabbed into turns into a text field that then
            # takes every key, so WASD, R and Tab itself stop reaching the camera.
            imgui.push_item_flag(imgui.ItemFlags_.no_tab_stop.value, True)
            draw_panel(self)
            imgui.pop_item_flag()
        self._draw_split_overlay(right)
        imgui.render()

        self._draw_scene(camera, settings, right, stereo, result, (p_min, dilation, _cameras_key(cull_cameras)))
        self._split_drawn = right is not None
        self._present_image(self.ctx.screen, width, height, x, y, w, h)
        if self.capture_window_next:
            self.capture_window_next = False
            self.window_capture = self._capture_window(width, height, x, y, w, h)
        self.window.end_frame()
        if self.screenshot_requested:
            self.screenshot_requested = False
            try:
                self.save_screenshot()
                self.panel.message, self.panel.error = _saved_message(self.last_screenshots), ""
            except (UserError, MemoryError, moderngl.Error) as exc:
                self.panel.error = f"error: screenshot not saved: {_one_line(exc)}"

    def _current_stereo_view(self) -> StereoView | None:
        """The stereo view to draw this frame; a custom headset out of range shows its
        error in the panel and the preview keeps the last frame's view."""
        try:
            view = self.stereo_view()
        except UserError as exc:
            self.panel.error = self._stereo_error = f"error: {_one_line(exc)}"
            return self.shown_stereo if self.panel.stereo else None
        if self._stereo_error is not None:  # valid again: its error goes
            if self.panel.error == self._stereo_error:
                self.panel.error = ""
            self._stereo_error = None
        return view

    def _draw_split_overlay(self, right: RenderSettings | None) -> None:
        """The split view's divider line and a label on each side, on imgui's background
        draw list (over the scene, under the panel)."""
        self.overlay_rects = {}
        if right is None:
            return
        io = imgui.get_io()
        scale = io.display_framebuffer_scale
        sx, sy = (scale.x or 1.0), (scale.y or 1.0)
        vx, vy, vw, vh = self.viewport
        draw = imgui.get_background_draw_list()
        divider = (vx + self.split_column(vw)) / sx
        top, bottom = vy / sy, (vy + vh) / sy
        grabbed = self.dragging_divider
        draw.add_line((divider, top), (divider, bottom), imgui.IM_COL32(255, 255, 255, 255 if grabbed else 200),
                      2.0 if grabbed else 1.0)
        self.overlay_rects["divider"] = (divider - 2.0, top, divider + 2.0, bottom)
        labels = {"left label": f"A: {describe_settings(self.settings())}",
                  "right label": f"B: {self.panel.split_preset}"}
        pad = 4.0
        for name, text in labels.items():
            size = imgui.calc_text_size(text)
            width = size.x + 2 * pad
            if name == "left label":  # beside the divider, kept inside the image
                x0 = max(divider - 8.0 - width, vx / sx + 4.0)
            else:
                x0 = min(divider + 8.0, (vx + vw) / sx - 4.0 - width)
            y0 = top + 8.0
            rect = (x0, y0, x0 + width, y0 + size.y + 2 * pad)
            draw.add_rect_filled(rect[:2], rect[2:], imgui.IM_COL32(0, 0, 0, 160), 3.0)
            draw.add_text((x0 + pad, y0 + pad), imgui.IM_COL32(255, 255, 255, 255), text)
            self.overlay_rects[name] = rect

    def _draw_scene(self, camera: Camera, settings: RenderSettings, right: RenderSettings | None,
                    stereo: StereoView | None, result, cull: tuple) -> None:
        """Draws the newest order into the target(s) unless view, settings and order
        are what the targets already hold. ``cull``: the (p_min, dilation, cull
        cameras' key) this frame's sort was asked for, to tell whether the drawn order
        is up to date."""
        if result is None:
            self.stats.order_age = self.frame_index - min(self._request_frames.values(), default=self.frame_index)
            order, serial = np.zeros(0, np.uint32), 0
        else:
            order, serial = result.order, result.serial
            for older in [n for n in self._request_frames if n < serial]:  # answered or skipped
                del self._request_frames[older]
            current = (camera_key(result.camera) == camera_key(camera)
                       and (result.p_min, result.dilation, _cameras_key(result.cull_cameras)) == cull)
            self.stats.order_age = 0 if current else self.frame_index - self._request_frames.get(serial, self.frame_index)
            if serial != self.stats.drawn_serial:
                self.stats.all_sort_times.append(result.seconds)
            self.stats.sort_seconds = result.seconds
            self.stats.visible = int(order.size)
        key = (camera_key(camera), settings, right, stereo, serial)
        if stereo is None:
            target = self._target_for(camera.width, camera.height)
            right_target = self._target_for(camera.width, camera.height, "_target_right") if right is not None else None
        elif self._stereo_frame is None:
            from raygs_viewer.render.gl.stereo_frame import StereoFrame
            self._stereo_frame = StereoFrame(self.ctx)
        if key == self._drawn_key:
            # Nothing changed: the image in the target is still right. The GPU is idle
            # as far as this view goes, so the last timings can be read without stalling.
            self._timer.flush()
            self._post_timer.flush()
            self.stats.gpu_seconds, self.stats.post_seconds = self._timer.seconds, self._post_timer.seconds
            return
        try:
            if stereo is None:
                with self._timer.measure():  # the whole frame's GPU time, both sides in the split view
                    self.renderer.render_into(target, camera, settings, order)
                    if right is not None:
                        self.renderer.render_into(right_target, camera, right, order)
            else:
                with self._timer.measure():  # both eyes: what the frame-budget meter compares
                    self._stereo_frame.draw_eyes(self.renderer, camera, settings, stereo.rig, order)
                with self._post_timer.measure():
                    self._stereo_frame.finish(stereo)
            self._stereo_drawn = stereo is not None
        except UserError as exc:  # settings this GPU cannot render (the panel greys those out)
            self.panel.error = self._draw_error = f"error: {_one_line(exc)}"
            self._drawn_key = None
            return
        if self._draw_error is not None:  # renderable again: the draw's own error goes
            if self.panel.error == self._draw_error:
                self.panel.error = ""
            self._draw_error = None
        self.stats.gpu_seconds, self.stats.post_seconds = self._timer.seconds, self._post_timer.seconds
        self.stats.drawn_serial = serial
        self.stats.draws += 1
        self._drawn_key = key

    def _target_for(self, width: int, height: int, attribute: str = "_target"):
        """The float target kept in ``attribute`` ("_target", or "_target_right" for the
        split view's right side), made anew when the size changes."""
        target = getattr(self, attribute)
        if target is None or target.size != (width, height):
            target = sized(target, self.ctx, width, height)
            setattr(self, attribute, target)
            self._drawn_key = None
        return target

    def _capture_window(self, width: int, height: int, x: int, y: int, w: int, h: int,
                        overlay: bool = True) -> np.ndarray:
        """(H, W, 3) uint8, top row first: the window as shown, panel included, composed
        again into an offscreen target (reading the default framebuffer is not portable).
        ``overlay=False``: the present pass alone, without what imgui draws (panel,
        split-view divider and labels)."""
        capture = FloatTarget(self.ctx, width, height, dtype="f1")
        try:
            self._present_image(capture.fbo, width, height, x, y, w, h)
            if overlay:
                imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
            capture.use()  # imgui's backend restores the binding it found; read what it drew
            return capture.read(components=3)
        finally:
            capture.release()
            self.ctx.screen.use()

    def _present_image(self, screen, width: int, height: int, x: int, y: int, w: int, h: int) -> None:
        ctx = self.ctx
        screen.use()
        screen.viewport = (0, 0, width, height)
        ctx.clear(LETTERBOX_GREY, LETTERBOX_GREY, LETTERBOX_GREY, 1.0)
        lower = height - y - h  # the viewport's y counts from the top, GL's from the bottom
        screen.viewport = (x, lower, w, h)
        ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        shown = self._stereo_frame.image if self._stereo_drawn else self._target
        if shown is None:  # nothing drawn yet (the first draw failed): the grey alone
            screen.viewport = (0, 0, width, height)
            return
        split = not self._stereo_drawn and self._split_drawn and self._target_right is not None \
            and self._target_right.size == shown.size
        shown.texture.use(0)
        (self._target_right if split else shown).texture.use(1)
        self._present["u_image"].value = 0
        self._present["u_right"].value = 1
        # Viewport columns from split_column() on show the right image (2: none).
        self._present["u_split"].value = self.split_column(w) / w if split else 2.0
        self._present["u_footprint"].value = (shown.size[0] / w, shown.size[1] / h)
        self._present_vao.render(moderngl.TRIANGLES, vertices=3)
        screen.viewport = (0, 0, width, height)

    # -- screenshots -------------------------------------------------------------------
    def save_screenshot(self, path: str | Path | None = None) -> tuple[Path, Path]:
        """Re-renders the last frame's view offscreen at the panel's scale (exact sort,
        no panel) and saves PNG + JSON sidecar; never overwrites anything. Returns the
        (png, json) pair; ``last_screenshots`` lists every pair written.

        In the split view each side is saved whole, with its own settings and sidecar:
        ``<name>-left.png`` and ``<name>-right.png`` (each reproducible with
        ``render --sidecar``); the returned pair is the left side's.

        In the stereo preview: the side-by-side pair of eyes at the headset's size times
        the scale, and with "save each eye" also each eye: ``<name>-pair.png``,
        ``<name>-left.png``, ``<name>-right.png``; the returned pair is the pair's."""
        from raygs_viewer.capture.screenshot import (
            render_tiled,
            save_screenshot,
            save_screenshots,
            scaled_camera,
        )
        from raygs_viewer.capture.sidecar import build_sidecar
        from raygs_viewer.render.gl.context import context_description

        if self.camera is None:
            raise UserError("nothing has been drawn yet")
        scale = self.panel.screenshot_scale
        camera = scaled_camera(self.camera, scale)
        scene_path = self.loaded.path if self.loaded.path == "demo" else os.path.abspath(self.loaded.path)
        extra = {"navigation": self.navigator.mode, "up_axis": self.navigator.up,
                 "training_camera": self.training_index,
                 "training_camera_name": (self.loaded.camera_names[self.training_index]
                                          if self.training_index is not None else None),
                 "gl": context_description(self.ctx)}
        settings = self.settings()
        if self.shown_stereo is not None:
            shots = self._stereo_shots(camera, settings, self.shown_stereo, scene_path, scale, extra)
        else:
            sides = [("left", settings)]
            right = self.right_settings()
            if right is not None:
                sides.append(("right", right))
            shots = []
            for side, side_settings in sides:
                image = render_tiled(self.renderer, camera, side_settings)
                side_extra = extra if right is None else {**extra, "split_view": {
                    "side": side, "preset": self.panel.split_preset if side == "right" else None,
                    "divider": self.panel.split_fraction}}
                sidecar = build_sidecar(scene_path=scene_path, scene_sha256=self.loaded.sha256,
                                        scene=self.loaded.scene, camera=camera, settings=side_settings, scale=scale,
                                        window_camera=self.camera, extra=side_extra)
                shots.append((image, sidecar, side))
        if len(shots) == 1:
            image, sidecar, _ = shots[0]
            if path is not None:
                saved = [save_screenshot(image, sidecar, path=Path(path))]
            else:
                saved = [save_screenshot(image, sidecar, folder=Path(self.panel.screenshot_dir))]
        elif path is not None:
            saved = save_screenshots(shots, path=Path(path))
        else:
            saved = save_screenshots(shots, folder=Path(self.panel.screenshot_dir))
        self.last_screenshots = saved
        self.last_screenshot = saved[0]
        return saved[0]

    def _stereo_shots(self, camera: Camera, settings: RenderSettings, stereo: StereoView, scene_path: str,
                      scale: float, extra: dict) -> list[tuple[np.ndarray, dict, str]]:
        """The side-by-side pair whatever the window's layout (the sidecar notes that
        layout), and each eye when the panel asks; every image with its own sidecar."""
        from dataclasses import replace

        from raygs_viewer.render.gl.stereo_frame import render_stereo_view
        from raygs_viewer.capture.sidecar import build_sidecar
        pair = replace(stereo, layout="sbs")
        image, left, right = render_stereo_view(self.renderer, camera, settings, pair)
        shots = [(image, pair, "pair")]
        if self.panel.save_eyes:
            shots += [(left, replace(stereo, layout="left"), "left"), (right, replace(stereo, layout="right"), "right")]
        return [(image, build_sidecar(scene_path=scene_path, scene_sha256=self.loaded.sha256, scene=self.loaded.scene,
                                      camera=camera, settings=settings, scale=scale, window_camera=self.camera,
                                      extra={**extra, "stereo_window_layout": stereo.layout}, stereo=view), tag)
                for image, view, tag in shots]

    # -- loop ------------------------------------------------------------------------
    def run(self) -> None:
        options = self.options
        while not self.window.should_close:
            last = options.frames is not None and self.frame_index + 1 >= options.frames
            self.capture_window_next |= last and options.window_screenshot is not None
            self.wait_for_sort = last
            self.frame()
            if last:
                break
        if options.screenshot is not None:
            self.save_screenshot(options.screenshot)
        if options.window_screenshot is not None and self.window_capture is not None:
            from raygs_viewer.capture.image_io import save_image
            save_image(options.window_screenshot, self.window_capture.astype(np.float32) / 255.0)

    def summary(self) -> str:
        """One line of frame statistics, printed after a scripted run."""
        def median_ms(values) -> str:
            return f"{1000 * float(np.median(values)):.1f} ms" if values else "n/a"
        stats = self.stats
        self._timer.flush()
        self._post_timer.flush()
        frame = float(np.median(stats.all_frame_times)) if stats.all_frame_times else float("nan")
        if self.shown_stereo is not None:
            return (f"{self.frame_index} frames ({stats.draws} drawn), stereo {self.shown_stereo.headset.name} "
                    f"{camera_size(self.camera)} per eye: median frame {median_ms(stats.all_frame_times)}, "
                    f"both eyes GPU {median_ms(self._timer.history)}, lens+layout "
                    f"{median_ms(self._post_timer.history)}, sort {median_ms(stats.all_sort_times)}, "
                    f"{stats.visible:,} of {self.loaded.scene.count:,} visible")
        return (f"{self.frame_index} frames ({stats.draws} drawn) at {camera_size(self.camera)}: "
                f"median frame {median_ms(stats.all_frame_times)} ({1 / frame if frame > 0 else 0:.1f} fps), "
                f"GPU {median_ms(self._timer.history)}, sort {median_ms(stats.all_sort_times)}, "
                f"{stats.visible:,} of {self.loaded.scene.count:,} visible"
                + (", general shaders" if self.renderer.general else ""))

    def close(self) -> None:
        if self.window is None:
            return
        self.loader.close()
        if self.sorter is not None:
            self.sorter.close()
        glfw.make_context_current(self.window.handle)
        if self.renderer is not None:
            self.renderer.release()
        release_all(self._target, self._target_right)
        self._target = self._target_right = None
        if self._stereo_frame is not None:
            self._stereo_frame.release()
            self._stereo_frame = None
        self._present_vao.release()
        self._present.release()
        self.window.close()
        self.window = None


def _present_shaders() -> tuple[str, str]:
    from raygs_viewer.render.gl.shaders import shader_source
    return shader_source("present.vert"), shader_source("present.frag")


def sort_cull(camera: Camera, left: RenderSettings, right: RenderSettings | None = None
              ) -> tuple[float, float | None]:
    """(p_min, dilation) of the one sort that serves every side shown: the more
    conservative cull of the two (the smaller p_min; no frustum culling if either side
    needs none, else the larger dilation)."""
    sides = [left] if right is None else [left, right]
    dilations = [side.cull_dilation(camera) for side in sides]
    dilation = None if any(d is None for d in dilations) else max(dilations)
    return min(side.p_min for side in sides), dilation


def describe_settings(settings: RenderSettings) -> str:
    """A short label of the accuracy options, e.g. "RayGS + MIP 0.1 px², 2×2"."""
    parts = [MODE_LABELS[settings.mode]]
    if settings.mip_active:
        parts.append(f"MIP {settings.mip_sigma2:g} px²" + ("" if settings.mip_modulation else " no mod."))
    if settings.mode == "gs" and settings.gs_compensation:
        parts.append("comp.")
    if settings.supersample > 1:
        parts.append(f"{settings.supersample}×{settings.supersample}")
    if settings.alpha_clamp:
        parts.append("alpha clamp")
    if settings.transmittance_cutoff:
        parts.append("T cut-off")
    if settings.p_min != DEFAULT_P_MIN:
        parts.append(f"p_min {settings.p_min:.3g}")
    return " + ".join(parts[:2]) + "".join(f", {part}" for part in parts[2:])


def _saved_message(saved: list[tuple[Path, Path]]) -> str:
    if len(saved) == 1:
        return f"saved {saved[0][0]}"
    return "saved " + " and ".join(str(png) for png, _ in saved) + " (each with its .json sidecar)"


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def camera_size(camera: Camera | None) -> str:
    return "-" if camera is None else f"{camera.width}x{camera.height}"


def _scene_title(path: str) -> str:
    return "demo scene" if path == "demo" else Path(path).name


def start_camera(options: ViewerOptions) -> Camera | None:
    if options.camera is None:
        return None
    from raygs_viewer.camera.pinhole import load_camera
    return load_camera(options.camera, options.camera_index)


def run_viewer(options: ViewerOptions) -> int:
    """Opens the window and runs until it is closed (or ``options.frames`` have been
    drawn); returns the exit status. Bad input found before the window opens (scene,
    cameras, screenshot path) raises UserError, so the CLI exits with status 2."""
    from raygs_viewer.scene.loader import load_now
    from raygs_viewer.viewer.window import choose_platform

    if choose_platform(options.platform) == "null" and options.frames is None and options.platform == "auto":
        # An invisible window that runs until killed would look like a hang.
        raise UserError("no display (DISPLAY and WAYLAND_DISPLAY are unset): run on a desktop, or add "
                        "--frames N --screenshot shot.png for a headless capture")
    if options.screenshot is not None:
        from raygs_viewer.capture.screenshot import check_screenshot_path
        check_screenshot_path(options.screenshot)
    if options.window_screenshot is not None:
        from raygs_viewer.capture.image_io import check_output_path
        if not options.window_screenshot.lower().endswith(".png"):
            raise UserError(f"{options.window_screenshot}: the window screenshot must be a .png")
        check_output_path(options.window_screenshot)
    options.settings()  # out-of-range start settings: UserError before the window opens
    loaded = load_now(options.scene, options.cameras)
    for warning in loaded.warnings:
        print(f"warning: {warning}", flush=True)
    camera = start_camera(options)
    viewer = Viewer(options, loaded, camera)
    try:
        viewer.run()
        if options.frames is not None:
            print(viewer.summary(), flush=True)
        if viewer.last_screenshot is not None and options.screenshot is not None:
            for png, sidecar in viewer.last_screenshots:
                print(f"{png} (+ {sidecar.name})")
    finally:
        viewer.close()
    return 0


__all__ = ["ViewerOptions", "Viewer", "run_viewer", "RENDER_MODES", "ACCURACY_PRESETS", "sort_cull"]
