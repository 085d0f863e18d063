"""The interactive viewer: a GLFW window, the RayGS renderer, and an imgui panel on top.

One frame: poll input -> move the camera -> the frame's inputs, made once as one value
(``frame.Frame``: camera, viewport, eyes, settings, the split side, the level-of-detail
request and the sort request) -> ask the background sorter for its sort (never
waiting) -> panel -> the channel views -> draw the newest finished order into the
window's frame unless it already holds it -> show it letterboxed -> swap. The last
frame's value stays as ``Viewer.shown``. Screenshots re-render the same view offscreen
with an exact sort, so they reproduce headlessly from their sidecar
(``raygs-viewer render --sidecar``).

:class:`Viewer` keeps the loop and wires the parts together: the state (``state``),
input (``input``), the camera (``view_control``), loading (``loading``), the scene
shown with its sorters and level of detail (``shown_scene``, ``lod_window``), drawing
(``drawing``, with ``render.gl.mono_frame`` and ``render.gl.stereo_frame``), the
panel (``panel``), the split view's overlay (``overlay``), screenshots and the
window's image (``screenshots``), the camera path with its playback and video
(``path_widget``), the view mode (``state.ViewMode``), and picking points by
double-click and measuring between them (``pick_tool``, ``measure``).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.capture.image_io import check_output_path, save_image
from raygs_viewer.capture.screenshot import check_screenshot_path
from raygs_viewer.capture.sidecar import load_camera_source
from raygs_viewer.errors import UserError
from raygs_viewer.photos.evaluate import evaluation_settings, render_view
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.render.gl.probe import Probe
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.lod_view import lod_settings_given
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene, load_now
from raygs_viewer.scene.progress import ProgressCallback
from raygs_viewer.sort.request import SortResult
from raygs_viewer.sort.worker import BackgroundSorter
from raygs_viewer.viewer.auto_defaults import AutoDefaults
from raygs_viewer.viewer.drawing import SceneDrawer, request_sort
from raygs_viewer.viewer.edit_tool import EditTool
from raygs_viewer.viewer.feedback import Feedback
from raygs_viewer.viewer.file_dialog import FileDialog
from raygs_viewer.viewer.frame import NO_VIEWPORT, Frame
from raygs_viewer.viewer.input import InputHandler
from raygs_viewer.viewer.loading import SceneOpener, scene_title
from raygs_viewer.viewer.lod_window import first_levels, lod_request, refines, window_fits, window_settings
from raygs_viewer.viewer.measure import MeasureWidget
from raygs_viewer.viewer.overlay import draw_split_overlay
from raygs_viewer.viewer.path_widget import PathWidget
from raygs_viewer.viewer.panel_sections import panel_sections
from raygs_viewer.viewer.photo_view import PhotoCompare, blocked_reason
from raygs_viewer.viewer.remembered import Remembered
from raygs_viewer.viewer.pick_tool import PickTool
from raygs_viewer.viewer.shown_scene import ShownScene
from raygs_viewer.viewer.side_panel import SidePanel
from raygs_viewer.viewer.screenshots import Captures, Saved, Shot, ShownView, sidecar_extra
from raygs_viewer.viewer.state import (
    PanelState,
    SplitView,
    StereoPreview,
    ViewerOptions,
    ViewMode,
)
from raygs_viewer.viewer.stats import FrameStats, summary
from raygs_viewer.viewer.thumbnails import Thumbnails
from raygs_viewer.viewer.training_frustums import TrainingFrustums
from raygs_viewer.viewer.view_control import ViewControl
from raygs_viewer.viewer.window import Window, choose_platform


class Viewer:
    """The application: owns the window, the scene shown (``scene``: as read, on the GPU,
    its sorters and its level of detail) and the panel.

    ``frame()`` runs one iteration of the loop; ``run()`` loops until the window
    closes. Tests drive ``frame()`` directly and queue input in ``input_script``,
    which is called with the viewer after the GLFW backend has read the devices and
    before imgui starts the frame (the place synthetic imgui events must go).

    ``renderer_factory(ctx, scene, general=)``, ``sorter_factory(depth_sorter)``, ``probe_factory(ctx)``:
    each scene's renderer and sorter, the probe of a new GL (tests pass instrumented ones).
    ``settings`` is the one RenderSettings (the left side's in the split view); the
    panel replaces it whole on every edit. ``shown``: the last frame's inputs
    (:class:`~raygs_viewer.viewer.frame.Frame`; None before the first).
    """

    def __init__(self, options: ViewerOptions, loaded: LoadedScene, start_camera: Camera | None = None, *,
                 renderer_factory: Callable[..., GLRenderer] = GLRenderer, probe_factory: Callable[..., Probe] = Probe,
                 sorter_factory: Callable[..., BackgroundSorter] = BackgroundSorter):
        self.options = options
        self.window = Window(f"raygs-viewer — {scene_title(loaded.path)}", options.width, options.height,
                             options.platform, options.vsync)
        self.ctx = self.window.ctx
        self.auto = AutoDefaults(self.ctx, options.sort, options.auto_precision, options.frames is None, probe_factory)
        self.settings: RenderSettings = self.auto.settings(options.settings, options.settings)
        # Copies: the panel edits the viewer's state, never the options.
        self.stereo: StereoPreview = replace(options.stereo)
        self.captures = Captures(replace(options.screenshots))
        self.split = SplitView()
        self.view_mode = ViewMode()
        self.panel = PanelState()
        self.side_panel = SidePanel(self.panel, Remembered())
        self.stats = FrameStats()
        self.scenes = SceneOpener(self.panel, options.source, window_fits(self.ctx, self.panel),
                                  lambda: self.edit_tool.exporter.unsaved())
        self.window.set_drop_callback(self.scenes.drop)
        self.scene = ShownScene(self.ctx, options.general, renderer_factory, sorter_factory, self.scenes, self._forget,
                                lambda count: self.auto.sort_choice(count).value)
        self.drawer = SceneDrawer(self.ctx)
        self.file_dialog = FileDialog()
        self.feedback = Feedback()
        # At a training camera's own size the Photo view renders as ``evaluate`` does, with the
        # panel's settings over the dataset's background, so the two measure one PSNR.
        self.photo = PhotoCompare(self.ctx, options.images, lambda view, dataset: render_view(
            self.scene.renderer, self.scene.direct_sorter, view, evaluation_settings(self.settings, dataset)))
        self.camera_path = PathWidget(self.panel, self)
        self.measure = MeasureWidget(self.panel, self)
        self.frustums = TrainingFrustums(Thumbnails(self.ctx, self.photo.dataset))
        self.picker = PickTool(self, self.measure, self.frustums)
        self.edit_tool = EditTool(self)
        self.input = InputHandler({
            "quit": self.window.request_close, "screenshot": self.captures.request,
            "switch_navigation": lambda: self.view.switch_mode(),
            "next_camera": lambda: self.view.step_training_camera(+1),
            "previous_camera": lambda: self.view.step_training_camera(-1),
            "reset_view": self.reset_view, "toggle_panel": self.panel.toggle,
            "add_keyframe": self.camera_path.add_view}, self.picker.click, self.picker.double_click)
        self.frame_index = 0
        self.input_script: Callable[[Viewer], None] | None = None
        self.fixed_dt: float | None = None  # tests: a deterministic frame time
        self.loaded: LoadedScene | None = None
        self.view: ViewControl | None = None
        self.shown: Frame | None = None
        self.wait_for_sort = False          # set for the last frame of a scripted run
        #: The split view's divider and side labels as drawn last frame, (x0, y0, x1, y1)
        #: in screen coordinates (imgui's), for tests; empty without the split view.
        self.overlay_rects: dict[str, tuple[float, float, float, float]] = {}
        try:
            self.auto.check(self.ctx)  # before any scene, in one line
            self._install(loaded, start_camera)
            if problem := self.scene.renderer.supports(self.settings):  # e.g. --transmittance-cutoff, no fetch
                raise UserError(problem)
        except BaseException:  # e.g. a scene too large for this GPU: no window left behind
            self.scenes.close()
            self.window.close()
            raise

    # -- what the panel, the picker, the path and the tests read ------------------------
    @property
    def camera(self) -> Camera | None:
        """The view of the last frame (viewport-sized; in stereo the eyes' midpoint)."""
        return None if self.shown is None else self.shown.camera

    @property
    def viewport(self) -> Viewport:
        return NO_VIEWPORT if self.shown is None else self.shown.viewport

    @property
    def shown_stereo(self) -> StereoView | None:
        """The stereo view of the last frame (None: mono)."""
        return None if self.shown is None else self.shown.stereo

    # -- scene and view ----------------------------------------------------------------
    def _install(self, loaded: LoadedScene, start_camera: Camera | None = None) -> None:
        """Puts a loaded scene on the GPU; on failure the current scene stays."""
        if refines(self.loaded, loaded):  # a streamed SOG's next level: the view stays
            if refined := self.scene.refine(self.loaded, loaded, self.settings, self.options.settings):
                self.settings, self.loaded = refined.settings, refined.loaded
                self.edit_tool.grown(self.loaded.scene)
            return
        self.scene.open(loaded.scene)
        self.loaded = loaded
        self.edit_tool.opened(loaded.scene)
        self.settings = opened_settings(self.settings, self.options.settings, loaded)
        # A new scene keeps the user's navigation choices.
        choices = self.options.navigation if self.view is None else self.view.choices()
        _, _, width, height = self.view_area()
        self.view = ViewControl(loaded, start_camera, choices, width / height, self.panel)
        self.camera_path.dolly_distance = float(self.view.radius)
        self.window.set_title(f"raygs-viewer — {scene_title(loaded.path)}")

    def _forget(self, kept: SortResult | None) -> None:
        """Another scene is on the GPU (``ShownScene``); ``kept``: the result drawn on until its first."""
        self.stats.new_sorter(kept, self.frame_index)
        self.drawer.forget()
        self.photo.forget_scene()
        self.frustums.forget()

    def right_settings(self) -> RenderSettings | None:
        """The split view's right side; None when it is off (it is off in the stereo preview)."""
        return None if self.stereo.on else self.split.right(self.settings)

    def set_settings(self, settings: RenderSettings) -> None:
        self.settings = settings

    def reset_view(self) -> None:
        self.view.reset(self.view_area()[2:], self.shown_stereo)

    def view_area(self) -> Viewport:
        """The part of the window the view is laid out in: beside the panel while it is
        shown (``layout.view_area``)."""
        return self.side_panel.view_area(self.window.framebuffer_size(),
                                         imgui.get_io().display_framebuffer_scale.x or 1.0)

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
        self.feedback.watch(self.panel)  # what the last frame's actions said
        if imgui.is_mouse_clicked(0):
            self.feedback.clicked()
        self.edit_tool.frame()
        self.input.handle(dt, self.view.navigator, self.camera, self.viewport,
                          self.split if self.right_settings() is not None else None,
                          mouse_taken=self.edit_tool.take_mouse(self.shown))
        self.view.advance(dt, self.options.navigation.turntable)
        self.camera_path.frame(self.fixed_dt, self.stats.all_frame_times[-1] if self.stats.all_frame_times else 0.0)

        stereo = self.stereo.frame_view(self.shown_stereo, self.panel)
        lod = self.scene.lod_for_frame(self.loaded, self.settings)
        framing = self.view.camera(self.view_area(), stereo, self.stereo.headset_size)
        frame = self.shown = Frame.make(self.frame_index, framing, stereo, self.settings, self.right_settings(), lod,
                                        self.edit_tool.deleted)
        # wait_for_sort: only the last frame of a scripted run, whose capture must show the finished view.
        # After a streamed SOG's level arrives: the last order until its first.
        result = self.scene.shown(request_sort(self.scene.sorter, self.stats, frame, self.wait_for_sort))

        self.side_panel.draw(panel_sections(self))
        self.overlay_rects = {} if not frame.split else draw_split_overlay(
            frame.viewport, self.split, self.settings, self.input.dragging_divider)
        self.frustums.draw(frame, self.loaded, self.view.radius, hover=not self.measure.on)  # under the path's lines
        self.camera_path.draw_overlay(frame, self.view.radius)
        self.measure.draw_overlay(frame, self.view.radius)
        self.edit_tool.draw_overlay(frame, self.view.radius)
        width_shown = imgui.get_io().display_size.x
        left = self.side_panel.notes_left(width_shown)
        self.feedback.draw(left, 10.0, width_shown - left - 10.0)
        imgui.render()

        frame = self.shown = frame.with_views(*self.view_mode.side_views(self.panel, split=frame.split))
        orders, serial = self.stats.order_to_draw(result, frame, sort_timer=self.scene.sort_timer)
        self.edit_tool.show_selection(self.scene.renderer)
        draws = self.stats.draws
        self.drawer.draw(self.scene.renderer, frame, orders, serial, self.stats, self.panel)
        blocked = blocked_reason(frame.stereo is not None, frame.split, self.view_mode.channel)
        if message := self.photo.after_draw(self.view, self.loaded, frame.camera, self.drawer.mono, blocked,
                                            drew=self.stats.draws != draws):
            self.panel.note(message)
        self.drawer.mono.present(self.ctx.screen, (width, height), frame.viewport,
                                 self.split.column(frame.viewport[2]))
        self.captures.frame_shown(self.capture_window)
        self.window.end_frame()
        self.captures.frame_done(self.save_screenshot, self.panel)
        if self.auto.step():  # this GL's profile is measured: its sort for the scene shown, its blend
            self.settings = self.auto.apply(self.scene, self.settings, self.options.settings, self.panel)

    def capture_window(self, overlay: bool = True) -> np.ndarray:
        """(H, W, 3) uint8, top row first: the window as shown, panel included;
        ``overlay=False``: without anything imgui draws (panel, divider, labels)."""
        return self.drawer.mono.capture(self.window.framebuffer_size(), self.viewport,
                                        self.split.column(self.viewport[2]),
                                        self.window.draw_imgui if overlay else None)

    def save_screenshot(self, path: str | Path | None = None) -> Saved:
        """Re-renders the last frame's view offscreen (:mod:`.screenshots`, :func:`window_shot`)
        and saves it; returns the (png, json) pair, the left side's or the stereo pair's."""
        frame = self.shown
        if frame is None:
            raise UserError("nothing has been drawn yet")
        self.photo.check_screenshot()
        self.scene.lod.check_screenshot()
        shot = window_shot(self, frame)
        self.scene.renderer.set_selection(None)  # a screenshot shows the scene, not the selection's tint
        return self.captures.take(self.scene.renderer, self.scene.direct_sorter, shot, path)

    # -- loop ------------------------------------------------------------------------
    def run(self) -> None:
        """Frames until the window closes or ``options.frames`` are drawn; the last keeps
        the window's image for ``--window-screenshot``."""
        options = self.options
        while not (self.window.should_close and self.edit_tool.exporter.may_close()):
            last = options.frames is not None and self.frame_index + 1 >= options.frames
            self.captures.keep_window |= last and options.window_screenshot is not None
            self.wait_for_sort = last
            if last:  # a scripted run ends on every level of a streamed SOG its settings want
                self.scene.read_all(self.loaded, self.settings)
            self.frame()
            if last:
                break

    def summary(self) -> str:
        """One line of the frame statistics, printed after a scripted run."""
        return summary(self.stats, self.frame_index, self.camera, self.shown_stereo, *self.drawer.gpu_times(),
                       self.loaded.scene.count, self.scene.renderer.general)

    def close(self) -> None:
        if self.window is None:
            return
        self.side_panel.close()  # a drag of its edge the window closes in
        self.camera_path.close()
        self.scenes.close()
        self.window.make_current()
        self.auto.close()  # a probe under way: its GL objects, while the context lives
        self.scene.close()
        self.frustums.release()
        self.drawer.release()
        self.window.close()
        self.window = None


def window_shot(viewer: Viewer, frame: Frame) -> Shot:
    """The screenshot of ``frame`` as ``viewer`` shows it: the view, the scene, its level
    choice, the eyes to save, the window's details, and the edits (the rows deleted)."""
    v = viewer
    shown = ShownView(frame.full_camera, v.settings, frame.stereo, v.drawer.shown_view,
                      v.split if v.right_settings() is not None else None, v.drawer.shown_right_view)
    extra = sidecar_extra(v.view.navigator, v.loaded, v.view.training_index, context_description(v.ctx))
    return Shot(shown, v.loaded, lod_request(v.loaded, v.settings), v.stereo.save_eyes, extra,
                v.edit_tool.deleted, v.edit_tool.sidecar_entry())


def opened_settings(settings: RenderSettings, start: RenderSettings, loaded: LoadedScene) -> RenderSettings:
    """``settings`` for a newly opened scene: its SH degree (the command line's None:
    every scene's own; else the panel's, capped at this scene's), and a streamed SOG's
    level-of-detail settings (``lod_window.window_settings``)."""
    degree = loaded.scene.sh_degree
    if start.sh_degree is not None:
        degree = min(settings.sh_degree, degree)
    return window_settings(replace(settings, sh_degree=degree), start, loaded)


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
    """The start view of ``--camera``: a cameras.json's camera, or a screenshot sidecar's
    (the view of a screenshot, to go on from)."""
    return None if options.camera is None else load_camera_source(options.camera, options.camera_index)


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
        captures = viewer.captures
        if options.screenshot is not None:
            viewer.save_screenshot(options.screenshot)
        if options.window_screenshot is not None and captures.window is not None:
            save_image(options.window_screenshot, captures.window.astype(np.float32) / 255.0)
        if options.frames is not None:
            print(viewer.summary(), flush=True)
        if captures.last is not None and options.screenshot is not None:
            for png, sidecar in captures.saved:
                print(f"{png} (+ {sidecar.name})")
    finally:
        viewer.close()
    return 0


__all__ = ["Viewer", "load_start_scene", "run_viewer", "start_camera"]
