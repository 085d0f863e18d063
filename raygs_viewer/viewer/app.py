"""The interactive viewer: a GLFW window, the RayGS renderer, and an imgui panel on top.

One frame: poll input -> move the camera -> ask the background sorter for this
view (never waiting) -> panel -> draw the newest finished order into the window's
frame unless it already holds it -> show it letterboxed -> swap. Screenshots
re-render the same view offscreen with an exact sort, so they reproduce headlessly
from their sidecar (``raygs-viewer render --sidecar``).

:class:`Viewer` keeps the loop and wires the parts together: the state (``state``),
input (``input``), the camera (``view_control``), loading (``loading``), drawing
(``drawing``, with ``render.gl.mono_frame`` and ``render.gl.stereo_frame``), the
panel (``panel``), the split view's overlay (``overlay``), screenshots
(``screenshots``), the camera path with its playback and video (``path_widget``), the
view mode (``state.ViewMode``), and picking points by double-click and measuring
between them (``pick_tool``, ``measure``).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable

import moderngl
import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.path import CameraPath
from raygs_viewer.camera.pinhole import Camera, load_camera
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.capture.image_io import check_output_path, save_image
from raygs_viewer.capture.path_file import PathDocument
from raygs_viewer.capture.screenshot import check_screenshot_path
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.lod_view import lod_settings_given
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene, load_now
from raygs_viewer.scene.progress import ProgressCallback
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.worker import BackgroundSorter
from raygs_viewer.viewer.drawing import SceneDrawer, request_sort
from raygs_viewer.viewer.input import InputHandler
from raygs_viewer.viewer.loading import SceneOpener, scene_title
from raygs_viewer.viewer.lod_window import WindowLod, first_levels, window_settings
from raygs_viewer.viewer.measure import MeasureWidget
from raygs_viewer.viewer.overlay import draw_split_overlay
from raygs_viewer.viewer.panel import draw_panel
from raygs_viewer.viewer.panel.geometry import draw_geometry_section
from raygs_viewer.viewer.panel.lod import draw_lod_section
from raygs_viewer.viewer.panel.measure import draw_measure_section
from raygs_viewer.viewer.panel.order import draw_order_section
from raygs_viewer.viewer.panel.path import draw_path_section
from raygs_viewer.viewer.panel.render import draw_render_section
from raygs_viewer.viewer.panel.scene import draw_scene_section
from raygs_viewer.viewer.panel.screenshot import draw_screenshot_section
from raygs_viewer.viewer.panel.statistics import draw_statistics
from raygs_viewer.viewer.panel.stereo import draw_stereo_section
from raygs_viewer.viewer.panel.training import draw_training_section
from raygs_viewer.viewer.panel.view import draw_view_section
from raygs_viewer.viewer.path_widget import PathWidget, scene_argument
from raygs_viewer.viewer.photo_view import PhotoCompare, blocked_reason
from raygs_viewer.viewer.pick_tool import PickTool
from raygs_viewer.viewer.screenshots import Saved, ShownView, saved_message, sidecar_extra, take_screenshots
from raygs_viewer.viewer.state import (
    PanelState,
    ScreenshotOptions,
    SplitView,
    StereoPreview,
    ViewerOptions,
    ViewMode,
)
from raygs_viewer.viewer.stats import FrameStats, summary
from raygs_viewer.viewer.view_control import ViewControl
from raygs_viewer.viewer.window import Window, choose_platform


class Viewer:
    """The application: owns the window, the scene on the GPU, the sorter and the panel.

    ``frame()`` runs one iteration of the loop; ``run()`` loops until the window
    closes. Tests drive ``frame()`` directly and queue input in ``input_script``,
    which is called with the viewer after the GLFW backend has read the devices and
    before imgui starts the frame (the place synthetic imgui events must go).

    ``renderer_factory(ctx, scene, general=)`` and ``sorter_factory(depth_sorter)``
    make each scene's renderer and background sorter (tests pass instrumented ones).
    ``settings`` is the one RenderSettings (the left side's in the split view); the
    panel replaces it whole on every edit.
    """

    def __init__(self, options: ViewerOptions, loaded: LoadedScene, start_camera: Camera | None = None, *,
                 renderer_factory: Callable[..., GLRenderer] = GLRenderer,
                 sorter_factory: Callable[..., BackgroundSorter] = BackgroundSorter):
        self.options = options
        self.window = Window(f"raygs-viewer — {scene_title(loaded.path)}", options.width, options.height,
                             options.platform, options.vsync)
        self.ctx = self.window.ctx
        self.renderer_factory, self.sorter_factory = renderer_factory, sorter_factory
        self.settings: RenderSettings = options.settings
        # Copies: the panel edits the viewer's state, never the options.
        self.stereo: StereoPreview = replace(options.stereo)
        self.screenshots: ScreenshotOptions = replace(options.screenshots)
        self.split = SplitView()
        self.view_mode = ViewMode()
        self.panel = PanelState()
        self.stats = FrameStats()
        self.scenes = SceneOpener(self.panel, options.source)
        self.window.set_drop_callback(self.scenes.drop)
        self.lod = WindowLod(self)
        self.drawer = SceneDrawer(self.ctx)
        self.photo = PhotoCompare(self.ctx, options.images)
        self.camera_path = PathWidget(self.panel, self)
        self.measure = MeasureWidget(self.panel, self)
        self.picker = PickTool(self, self.measure)
        self.input = InputHandler({
            "quit": self.window.request_close, "screenshot": self.request_screenshot,
            "switch_navigation": lambda: self.view.switch_mode(),
            "next_camera": lambda: self.view.step_training_camera(+1),
            "previous_camera": lambda: self.view.step_training_camera(-1),
            "reset_view": self.reset_view, "toggle_panel": self.panel.toggle,
            "add_keyframe": self.camera_path.add_view}, self.picker.click, self.picker.double_click)
        self.frame_index = 0
        self.input_script: Callable[[Viewer], None] | None = None
        self.fixed_dt: float | None = None  # tests: a deterministic frame time
        self.loaded: LoadedScene | None = None
        self.renderer: GLRenderer | None = None
        self.sorter: BackgroundSorter | None = None
        self.exact_sorter: DepthSorter | None = None  # what the sort thread runs; screenshots sort with it too
        self.view: ViewControl | None = None
        self.camera: Camera | None = None   # the view of the last frame, viewport-sized
        self.viewport = (0, 0, 1, 1)
        self.shown_stereo: StereoView | None = None  # the stereo view of the last frame (None: mono)
        self.screenshot_requested = False
        self.capture_window_next = False    # set to keep the next frame's window image
        self.wait_for_sort = False          # set for the last frame of a scripted run
        self.window_capture: np.ndarray | None = None
        self.last_screenshots: list[Saved] = []  # every file pair of the last capture
        #: The split view's divider and side labels as drawn last frame, (x0, y0, x1, y1)
        #: in screen coordinates (imgui's), for tests; empty without the split view.
        self.overlay_rects: dict[str, tuple[float, float, float, float]] = {}
        try:
            self._install(loaded, start_camera)
            problem = self.renderer.supports(self.settings)
            if problem:  # e.g. --transmittance-cutoff without framebuffer fetch
                raise UserError(problem)
        except BaseException:  # e.g. a scene too large for this GPU: no window left behind
            self.scenes.close()
            self.window.close()
            raise

    # -- scene and view ----------------------------------------------------------------
    def _install(self, loaded: LoadedScene, start_camera: Camera | None = None) -> None:
        """Puts a loaded scene on the GPU; on failure the current scene stays."""
        if self.lod.refines(loaded):  # a streamed SOG's next level: the view stays
            return self.lod.refine(loaded)
        self.swap_scene(loaded.scene)
        self.loaded = loaded
        self.lod.installed()
        self.settings = opened_settings(self.settings, self.options.settings, loaded)
        # A new scene keeps the user's navigation choices.
        choices = self.options.navigation if self.view is None else self.view.choices()
        self.view = ViewControl(loaded, start_camera, choices, self.options.width / self.options.height, self.panel)
        self.camera_path.dolly_distance = float(self.view.radius)
        self.window.set_title(f"raygs-viewer — {scene_title(loaded.path)}")

    def swap_scene(self, scene) -> None:
        """``scene`` on the GPU with its own sorter; a UserError (too large for this GPU) changes nothing."""
        renderer = self.renderer_factory(self.ctx, scene, general=self.options.general)
        if self.renderer is not None:
            self.renderer.release()
        if self.sorter is not None:
            self.sorter.close()  # and, on its thread, the exact sorter it runs
        self.renderer, self.exact_sorter = renderer, DepthSorter(scene)
        self.sorter = self.sorter_factory(self.exact_sorter)
        self.stats.request_frames.clear()
        self.drawer.forget()
        self.photo.forget_scene()

    def right_settings(self) -> RenderSettings | None:
        """The split view's right side; None when it is off (it is off in the stereo preview)."""
        return None if self.stereo.on else self.split.right(self.settings)

    def set_settings(self, settings: RenderSettings) -> None:
        self.settings = settings

    def reset_view(self) -> None:
        width, height = self.window.framebuffer_size()
        aspect = width / height if width > 0 and height > 0 else self.options.width / self.options.height
        self.view.reset(aspect, self.shown_stereo)

    def request_screenshot(self) -> None:
        """Saves a screenshot at the end of the next frame."""
        self.screenshot_requested = True

    # -- frame -------------------------------------------------------------------------
    def frame(self) -> None:
        """One iteration of the loop (see the module docstring)."""
        dt = self.stats.tick(self.fixed_dt)
        self.frame_index += 1
        self.window.poll_events()
        self.scenes.poll(self._install)
        width, height = self.window.framebuffer_size()
        if width <= 0 or height <= 0:  # minimised: nothing to draw, do not spin
            if self.options.frames is None:
                self.window.wait_events(0.1)
            return
        self.window.begin_frame()
        if self.input_script is not None:
            self.input_script(self)
        imgui.new_frame()
        self.input.handle(dt, self.view.navigator, self.camera, self.viewport,
                          self.split if self.right_settings() is not None else None)
        self.view.navigator.advance(dt)
        if self.options.navigation.turntable:
            self.view.turn(self.options.navigation.turntable)
        self.camera_path.frame(self.fixed_dt, self.stats.all_frame_times[-1] if self.stats.all_frame_times else 0.0)

        settings, right = self.settings, self.right_settings()
        stereo = self.stereo.frame_view(self.shown_stereo, self.panel)
        camera, self.viewport, cull_cameras = self.view.camera(width, height, stereo)
        self.camera, self.shown_stereo = camera, stereo
        # wait_for_sort: only the last frame of a scripted run, whose capture must show the finished view.
        result, key = request_sort(self.sorter, self.stats, camera, settings, right, cull_cameras, self.frame_index,
                                   self.wait_for_sort, self.lod.for_frame())
        result = self.lod.shown(result)  # after a streamed SOG's level arrives: the last order until its first

        if self.panel.show_panel:
            draw_panel(self.panel, panel_sections(self))
        self.overlay_rects = {} if right is None else draw_split_overlay(
            self.viewport, self.split, self.settings, self.input.dragging_divider)
        self.camera_path.draw_overlay(camera, self.viewport, self.view.radius, stereo is not None)
        self.measure.draw_overlay(camera, self.viewport, self.view.radius, stereo is not None)
        imgui.render()

        orders, serial = self.stats.order_to_draw(result, key, self.frame_index, camera)
        draws = self.stats.draws
        self.drawer.draw(self.renderer, camera, settings, right, stereo, orders, serial, self.stats, self.panel,
                         *self.view_mode.side_views(self.panel, split=right is not None))
        blocked = blocked_reason(stereo is not None, right is not None, self.view_mode.channel)
        if message := self.photo.after_draw(self.view, self.loaded, camera, self.drawer.mono, blocked,
                                            drew=self.stats.draws != draws):
            self.panel.note(message)
        self.drawer.mono.present(self.ctx.screen, (width, height), self.viewport, self.split.column(self.viewport[2]))
        if self.capture_window_next:
            self.capture_window_next = False
            self.window_capture = self.capture_window()
        self.window.end_frame()
        if self.screenshot_requested:
            self.screenshot_requested = False
            try:
                self.save_screenshot()
                self.panel.message, self.panel.error = saved_message(self.last_screenshots), ""
            except (UserError, MemoryError, moderngl.Error) as exc:
                self.panel.error = f"error: screenshot not saved: {one_line(exc)}"

    def capture_window(self, overlay: bool = True) -> np.ndarray:
        """(H, W, 3) uint8, top row first: the window as shown, panel included;
        ``overlay=False``: without anything imgui draws (panel, divider, labels)."""
        return self.drawer.mono.capture(self.window.framebuffer_size(), self.viewport,
                                        self.split.column(self.viewport[2]),
                                        self.window.draw_imgui if overlay else None)

    # -- screenshots -------------------------------------------------------------------
    @property
    def last_screenshot(self) -> Saved | None:
        """The (png, json) pair of the last capture: the left side's, or the stereo pair's."""
        return self.last_screenshots[0] if self.last_screenshots else None

    def save_screenshot(self, path: str | Path | None = None) -> Saved:
        """Re-renders the last frame's view offscreen (see :mod:`.screenshots`) and saves
        it; returns ``last_screenshot``."""
        if self.camera is None:
            raise UserError("nothing has been drawn yet")
        self.photo.check_screenshot()
        self.lod.check_screenshot()
        shown = ShownView(self.camera, self.settings, self.split if self.right_settings() is not None else None,
                          self.shown_stereo, self.drawer.shown_view, self.drawer.shown_right_view)
        extra = sidecar_extra(self.view.navigator, self.loaded, self.view.training_index,
                              context_description(self.ctx))
        self.last_screenshots = take_screenshots(self.renderer, self.exact_sorter, self.loaded, shown, self.screenshots,
                                                 self.stereo.save_eyes, extra, path, self.lod.request())
        return self.last_screenshot

    # -- what the camera path reads (path_widget.PathHost) ------------------------------
    def view_aspect(self) -> float:
        _, _, width, height = self.viewport
        return width / height if width > 0 and height > 0 else self.options.width / self.options.height

    def path_document(self, path: CameraPath) -> PathDocument:
        """``path`` with what renders it as the window shows it: the view's size (in
        stereo, the headset's per eye), the render settings (the left side's), the
        stereo view when the preview is on, the scene."""
        width, height = (self.camera.width, self.camera.height) if self.camera is not None else self.viewport[2:]
        return PathDocument(path, width, height, self.settings, self.shown_stereo,
                            scene_argument(self.loaded), self.loaded.content_sha256,
                            scene_axes=self.loaded.scene.axes)  # a .spz's: render-path reads it in the same axes

    # -- loop ------------------------------------------------------------------------
    def run(self) -> None:
        options = self.options
        while not self.window.should_close:
            last = options.frames is not None and self.frame_index + 1 >= options.frames
            self.capture_window_next |= last and options.window_screenshot is not None
            self.wait_for_sort = last
            if last:  # a scripted run ends on every level of a streamed SOG its settings want
                self.lod.read_all()
            self.frame()
            if last:
                break
        save_scripted_outputs(self)

    def close(self) -> None:
        if self.window is None:
            return
        self.camera_path.close()
        self.scenes.close()
        if self.sorter is not None:
            self.sorter.close()
        self.window.make_current()
        if self.renderer is not None:
            self.renderer.release()
        self.drawer.release()
        self.window.close()
        self.window = None


def save_scripted_outputs(viewer: Viewer) -> None:
    """What a run writes once its last frame is drawn: ``--screenshot`` (PNG and
    sidecar) and ``--window-screenshot`` (the window, panel included)."""
    options = viewer.options
    if options.screenshot is not None:
        viewer.save_screenshot(options.screenshot)
    if options.window_screenshot is not None and viewer.window_capture is not None:
        save_image(options.window_screenshot, viewer.window_capture.astype(np.float32) / 255.0)


def run_summary(viewer: Viewer) -> str:
    """One line of ``viewer``'s frame statistics, printed after a scripted run."""
    timer, post = viewer.drawer.timer, viewer.drawer.post_timer
    timer.flush()
    post.flush()
    return summary(viewer.stats, viewer.frame_index, viewer.camera, viewer.shown_stereo, timer.history, post.history,
                   viewer.loaded.scene.count, viewer.renderer.general)


def opened_settings(settings: RenderSettings, start: RenderSettings, loaded: LoadedScene) -> RenderSettings:
    """``settings`` for a newly opened scene: its SH degree (the command line's None:
    every scene's own; else the panel's, capped at this scene's), and a streamed SOG's
    level-of-detail settings (``lod_window.window_settings``)."""
    degree = loaded.scene.sh_degree
    if start.sh_degree is not None:
        degree = min(settings.sh_degree, degree)
    return window_settings(replace(settings, sh_degree=degree), start, loaded)


def panel_sections(viewer: Viewer) -> list[Callable[[], None]]:
    """Each panel section with the part of ``viewer``'s state it edits (read when it is
    drawn: an edit shows in the sections below it at once)."""
    loaded, renderer, view, stats = viewer.loaded, viewer.renderer, viewer.view, viewer.stats
    return [
        lambda: draw_statistics(stats, loaded.scene.count, viewer.sorter, renderer.counters, renderer.general),
        lambda: draw_scene_section(loaded, viewer.panel, viewer.scenes.open, viewer.scenes.loader,
                                   lambda axes: viewer.scenes.switch_axes(loaded, axes)),
        lambda: draw_lod_section(viewer.lod, viewer.settings, viewer.set_settings, stats, viewer.scenes.loader),
        lambda: draw_render_section(viewer.settings, viewer.set_settings, loaded.scene.sh_degree, renderer.supports,
                                    viewer.window, viewer.stereo, viewer.split, viewer.panel.note),
        lambda: draw_order_section(viewer.settings, viewer.set_settings, stats, viewer.right_settings() is not None),
        lambda: draw_stereo_section(viewer.stereo, stats),
        lambda: draw_view_section(view.navigator, view.lens.fov_y_degrees, view.set_fov, viewer.reset_view),
        lambda: draw_training_section(loaded, view.training_index, view.select_training_camera,
                                      view.step_training_camera, viewer.photo),
        lambda: draw_screenshot_section(viewer.screenshots, viewer.camera, viewer.shown_stereo is not None,
                                        viewer.stereo.save_eyes, viewer.split.on and viewer.shown_stereo is None,
                                        viewer.request_screenshot),
        lambda: draw_geometry_section(viewer.view_mode, viewer.drawer.view_range, viewer.picker.last,
                                      viewer.measure.scale, viewer.stereo,
                                      viewer.split.on and viewer.shown_stereo is None),
        lambda: draw_path_section(viewer.camera_path),
        lambda: draw_measure_section(viewer.measure),
    ]


def load_start_scene(options: ViewerOptions, progress: ProgressCallback | None = None) -> LoadedScene:
    """The scene the window opens with, read before it opens so that a bad file fails on
    the command line: a streamed SOG up to its coarsest level (or --lod N's), the window
    reads the rest."""
    source = options.source
    loaded = load_now(source.with_levels(first_levels(source, options.settings)), progress)
    given = lod_settings_given(options.settings)
    if loaded.lod is None and given:  # start values of the panel: kept for a streamed SOG opened later
        loaded.warnings.append(f"{', '.join(given)}: not for this scene, which is not a streamed SOG "
                               "(lod-meta.json); kept for one opened later")
    return loaded


def start_camera(options: ViewerOptions) -> Camera | None:
    return None if options.camera is None else load_camera(options.camera, options.camera_index)


def run_viewer(options: ViewerOptions, progress: ProgressCallback | None = None) -> int:
    """Opens the window and runs until it is closed (or ``options.frames`` have been
    drawn); returns the exit status. Bad input found before the window opens (scene,
    cameras, screenshot path) raises UserError, so the CLI exits with status 2.
    ``progress`` follows the scene's load, before the window opens."""
    if choose_platform(options.platform) == "null" and options.frames is None and options.platform == "auto":
        # An invisible window that runs until killed would look like a hang.
        raise UserError("no display (DISPLAY and WAYLAND_DISPLAY are unset): run on a desktop, or add "
                        "--frames N --screenshot shot.png for a headless capture")
    if options.screenshot is not None:
        check_screenshot_path(options.screenshot)
    if options.window_screenshot is not None:
        if not options.window_screenshot.lower().endswith(".png"):
            raise UserError(f"{options.window_screenshot}: the window screenshot must be a .png")
        check_output_path(options.window_screenshot)
    loaded = load_start_scene(options, progress)
    for warning in loaded.warnings:
        print(f"warning: {warning}", flush=True)
    viewer = Viewer(options, loaded, start_camera(options))
    try:
        viewer.run()
        if options.frames is not None:
            print(run_summary(viewer), flush=True)
        if viewer.last_screenshot is not None and options.screenshot is not None:
            for png, sidecar in viewer.last_screenshots:
                print(f"{png} (+ {sidecar.name})")
    finally:
        viewer.close()
    return 0


__all__ = ["Viewer", "load_start_scene", "run_summary", "run_viewer", "start_camera"]
