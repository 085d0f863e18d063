"""The interactive viewer: a GLFW window, the RayGS renderer, and an imgui panel on top.

:class:`Viewer` keeps the loop and owns the parts, each of which keeps only its own
state (``part``): the edit tool (``edit_tool``, with its export and handles), the
camera path (``path_widget``), the measure tool (``measure``), picking (``pick_tool``),
the training cameras' frustums (``training_frustums``) and the photo view
(``photo_view``); beside them the state (``state``), input (``input``), the camera
(``view_control``), loading (``loading``), the scene shown with its sorters and level
of detail (``shown_scene``, ``lod_window``), drawing (``drawing``, with
``render.gl.mono_frame`` and ``render.gl.stereo_frame``), the frame statistics
(``stats``), the panel (``panel``, composed by ``panel_sections``), the split view's
overlay (``overlay``), and screenshots and the window's image (``screenshots``). The
parts answer with values (``part.Reply``: messages, requests); the viewer says the
messages in the panel (``PanelState.say``) and carries out the requests
(:meth:`Viewer.carry_out`). Each frame is one value (``frame.Frame``), made once; the
last one stays as ``Viewer.shown``. Screenshots re-render the same view offscreen with
an exact sort, so they reproduce headlessly from their sidecar
(``raygs-viewer render --sidecar``).
"""

from __future__ import annotations

import time
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import Callable

import moderngl
import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.capture.image_io import check_output_path, save_image
from raygs_viewer.capture.screenshot import check_screenshot_path
from raygs_viewer.capture.sidecar import load_camera_source
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.photos.evaluate import evaluation_settings, render_view
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.render.gl.probe import Probe
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.lod_view import lod_settings_given
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene, load_now
from raygs_viewer.scene.progress import ProgressCallback
from raygs_viewer.sort.lod_choice import LodRequest
from raygs_viewer.sort.request import SortResult
from raygs_viewer.sort.worker import BackgroundSorter
from raygs_viewer.viewer.auto_defaults import AutoDefaults
from raygs_viewer.viewer.drawing import SceneDrawer, SortAsked, request_sort
from raygs_viewer.viewer.edit_tool import EditTool
from raygs_viewer.viewer.feedback import Feedback
from raygs_viewer.viewer.file_dialog import FileDialog
from raygs_viewer.viewer.frame import NO_VIEWPORT, Frame
from raygs_viewer.viewer.input import InputHandler
from raygs_viewer.viewer.loading import SceneOpener, load_failed, scene_title, shown_message
from raygs_viewer.viewer.lod_window import (
    first_levels,
    lod_request,
    reading,
    refines,
    window_fits,
    window_settings,
)
from raygs_viewer.viewer.measure import MeasureWidget
from raygs_viewer.viewer.overlay import draw_split_overlay
from raygs_viewer.viewer.panel_sections import Draft, panel_sections
from raygs_viewer.viewer.part import (
    AimAt,
    Click,
    ColourByLevel,
    Converge,
    FlyTo,
    MeasurePoint,
    OpenScene,
    Part,
    Pointing,
    Press,
    ReadAxes,
    Reply,
    Request,
    SceneView,
    Shortcut,
    Shown,
)
from raygs_viewer.viewer.path_widget import PathScene, PathWidget
from raygs_viewer.viewer.photo_view import Drawn, PhotoCompare, ScenePhotos, blocked_reason, standing_at
from raygs_viewer.viewer.pick_tool import PickTool
from raygs_viewer.viewer.remembered import Remembered
from raygs_viewer.viewer.screenshots import Captures, Saved, Shot, ShownView, screenshot_said, sidecar_extra
from raygs_viewer.viewer.shown_scene import ShownScene, Swapped
from raygs_viewer.viewer.side_panel import SidePanel
from raygs_viewer.viewer.state import (
    Message,
    PanelState,
    SplitView,
    StereoPreview,
    ViewerOptions,
    ViewMode,
    failed,
    mended,
)
from raygs_viewer.viewer.stats import FrameStats, summary
from raygs_viewer.viewer.thumbnails import Thumbnails
from raygs_viewer.viewer.training_frustums import TrainingFrustums
from raygs_viewer.viewer.view_control import ViewControl
from raygs_viewer.viewer.window import Window, choose_platform


class Viewer:
    """The application: owns the window, the scene shown (``scene``: as read, on the GPU,
    its sorters and its level of detail), the panel and the parts.

    ``frame()`` runs one iteration of the loop; ``run()`` loops until the window
    closes. ``renderer_factory(ctx, scene, general=)``, ``sorter_factory(direct_sorter)``,
    ``probe_factory(ctx)``: each scene's renderer and sorter, the probe of a new GL
    (tests pass instrumented ones); ``clock()``: seconds, what a frame's time is
    measured by (tests pass one that steps by a fixed frame time). ``settings`` is the
    one RenderSettings (the left side's in the split view); the panel returns it edited.
    ``shown``: the last frame (:class:`~raygs_viewer.viewer.frame.Frame`; None before
    the first)."""

    def __init__(self, options: ViewerOptions, loaded: LoadedScene, start_camera: Camera | None = None, *,
                 renderer_factory: Callable[..., GLRenderer] = GLRenderer, probe_factory: Callable[..., Probe] = Probe,
                 sorter_factory: Callable[..., BackgroundSorter] = BackgroundSorter,
                 clock: Callable[[], float] = time.perf_counter):
        self.options, self.clock = options, clock
        # What close() releases and ends, each registered as it is made (undone in reverse).
        self._made = ExitStack()
        self.window = Window(f"raygs-viewer — {scene_title(loaded.path)}", options.width, options.height,
                             options.platform, options.vsync)
        self._made.callback(self.window.close)
        self.ctx = self.window.ctx
        self.auto = AutoDefaults(self.ctx, options.sort, options.auto_precision, options.frames is None, probe_factory)
        self.settings: RenderSettings = self.auto.settings(options.settings, options.settings)
        # Copies: the panel edits the viewer's state, never the options.
        self.stereo: StereoPreview = replace(options.stereo)
        self.captures = Captures(replace(options.screenshots))
        self.split, self.view_mode, self.panel = SplitView(), ViewMode(), PanelState()
        self.stats = FrameStats()
        self.drawer = self._made_here(SceneDrawer(self.ctx), "release")
        self.scene = self._made_here(ShownScene(self.ctx, general=options.general, renderer_factory=renderer_factory,
                                                sorter_factory=sorter_factory, sort_for=self.auto.sort_for), "close")
        self._made.callback(self.auto.close)  # a probe under way: its GL objects, while the context lives
        self.photos = ScenePhotos(options.images)
        self.photo = PhotoCompare(self.ctx, self.photos)
        self.picker, self.input, self.file_dialog, self.feedback = PickTool(), InputHandler(), FileDialog(), Feedback()
        self.frustums = TrainingFrustums(Thumbnails(self.ctx, self.photos.of))
        self.camera_path, self.measure, self.edit_tool = PathWidget(), MeasureWidget(), EditTool()
        #: The parts, in the one order every hook reaches them: the frustums under the
        #: path's lines, the measurements over them, the edit tool's shapes on top (back
        #: to front over the view); and the edit tool takes the mouse last, but before
        #: the camera, which comes after every part.
        self.parts: tuple[Part, ...] = (self.frustums, self.camera_path, self.measure, self.edit_tool)
        for part in self.parts:
            self._made.callback(part.close)
        self._made.callback(self.window.make_current)  # the context current for the releases above
        self.scenes = self._made_here(SceneOpener(options.source, window_fits(self.ctx)), "close")
        self.side_panel = self._made_here(SidePanel(self.panel, Remembered()), "close")  # a drag of its edge
        self.frame_index = 0
        self.loaded: LoadedScene | None = None
        self.view: ViewControl | None = None
        self.shown: Frame | None = None
        self.wait_for_sort = False          # set for the last frame of a scripted run
        #: The split view's divider and side labels as drawn last frame, (x0, y0, x1, y1)
        #: in screen coordinates (imgui's); empty without the split view.
        self.overlay_rects: dict[str, tuple[float, float, float, float]] = {}
        try:
            self.auto.check(self.ctx)  # before any scene, in one line
            self._install(loaded, start_camera)
            if problem := self.scene.renderer.supports(self.settings):  # e.g. --transmittance-cutoff, no fetch
                raise UserError(problem)
        except BaseException:  # e.g. a scene too large for this GPU: no window left behind
            self.close()
            raise

    def _made_here(self, thing, ending: str):
        """``thing``, its method ``ending`` called when the viewer closes."""
        self._made.callback(getattr(thing, ending))
        return thing

    # -- what the panel, the parts and the tests read ------------------------------------
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

    def right_settings(self) -> RenderSettings | None:
        """The split view's right side; None when it is off (it is off in the stereo preview)."""
        return None if self.stereo.on else self.split.right(self.settings)

    def view_area(self) -> Viewport:
        """The part of the window the view is laid out in: beside the panel while it is
        shown (``layout.view_area``)."""
        return self.side_panel.view_area(self.window.framebuffer_size(),
                                         imgui.get_io().display_framebuffer_scale.x or 1.0)

    def scene_view(self) -> SceneView:
        """The scene shown, as the parts see it (the orders of the last frame drawn)."""
        return SceneView(self.loaded, self.scene.renderer, self.scene.direct_sorter, self.edit_tool.deleted,
                         self.drawer.orders, float(self.view.radius))

    def path_scene(self) -> PathScene:
        """What the path widget is handed for an action."""
        return PathScene(self.view, self.loaded, self.settings, self.shown, self.edit_tool.sidecar_entry(self.loaded))

    def pointing(self) -> Pointing:
        """What the pointer's clicks do this frame."""
        navigator, shown = self.view.navigator, self.shown
        return Pointing(self.measure.on, self.measure.scale, self.stereo.converge_on_pick, self.stereo.rig,
                        flying=navigator.animating, orbiting=navigator.mode == "orbit",
                        divider=None if shown is None else self.split.column(shown.camera.width))

    # -- scenes ----------------------------------------------------------------------------
    def _install(self, loaded: LoadedScene, start_camera: Camera | None = None) -> None:
        """Puts a loaded scene on the GPU; on failure the current scene stays."""
        if refines(self.loaded, loaded):  # a streamed SOG's next level: the view stays
            refined, swapped = self.scene.refine(self.loaded, loaded, self.settings, self.options.settings,
                                                 self.scenes.loader)
            self._swapped(swapped)
            if refined is not None:
                self.settings, self.loaded = refined.settings, refined.loaded
                self._scene_shown(grown=True)
            return
        self._swapped(self.scene.open(loaded.scene))
        self.loaded = loaded
        self.settings = opened_settings(self.settings, self.options.settings, loaded)
        # A new scene keeps the user's navigation choices.
        choices = self.options.navigation if self.view is None else self.view.choices()
        _, _, width, height = self.view_area()
        self.view = ViewControl(loaded, start_camera, choices, width / height)
        self._scene_shown(grown=False)
        self.window.set_title(f"raygs-viewer — {scene_title(loaded.path)}")

    def _scene_shown(self, grown: bool) -> None:
        for part in self.parts:
            self.panel.say(*part.scene_shown(self.loaded, grown).messages)

    def _swapped(self, swapped: Swapped | None) -> None:
        """Another copy of the scene is on the GPU: what was drawn of the one before is stale."""
        if swapped is None:
            return
        self.stats.new_sorter(swapped.kept, self.frame_index)
        self.drawer.forget()
        self.photos.forget()
        self.photo.forget_scene()
        self.frustums.forget()

    def _take_loaded(self) -> None:
        """Shows a scene the background load finished (its words in the panel), and opens
        files dropped on the window."""
        result = self.scenes.poll()
        if isinstance(result, LoadedScene):
            try:
                self._install(result)
            except (UserError, MemoryError, moderngl.Error) as exc:  # e.g. too large for this GPU
                self.panel.say(load_failed(f"{result.path}: {one_line(exc)}"))
            else:
                self.panel.say(shown_message(result))
        else:
            self.panel.say(result)
        if dropped := self.window.dropped():
            self.drop(dropped)

    def open_scene(self, path: str, cameras: str | None = None) -> None:
        """Starts opening ``path`` (the panel's Open; with ``cameras``, a cameras.json)."""
        self.panel.say(self.scenes.open(path, cameras, self.edit_tool.unsaved()))

    def drop(self, paths: list[str]) -> None:
        """Files dropped on the window: the first is opened."""
        self.panel.say(self.scenes.drop(paths, self.edit_tool.unsaved()))

    def _lod_request(self) -> LodRequest | None:
        """A frame's level-of-detail request of the scene shown, after starting to read the
        levels the settings want that are not read (``WindowLod.for_frame``)."""
        lod = self.scene.lod.for_frame(self.loaded, self.settings, self.scenes.loader)
        if lod.read is not None:
            self.panel.say(self.scenes.read_levels(lod.read))
        return lod.request

    # -- requests ---------------------------------------------------------------------------
    def answer(self, reply: Reply) -> None:
        """Says ``reply``'s messages in the panel and carries out its requests, in order."""
        self.panel.say(*reply.messages)
        for request in reply.requests:
            self.carry_out(request)

    def carry_out(self, request: Request) -> None:
        """Does what a part, the panel or the input asks of the window."""
        said: Message | tuple | None = None
        match request:
            case Press(shortcut):
                said = self._press(shortcut)
            case Click(x, y, double):
                shown = Shown(self.shown, self.scene_view())
                pointing = self.pointing()
                self.answer(self.picker.double_click(x, y, shown, pointing) if double else
                            self.picker.click(x, y, shown, pointing, self.frustums.camera_at(x, y)))
            case FlyTo(index):
                said = self.view.select_training_camera(index)
            case AimAt(point):
                self.view.navigator.aim_at(point)
            case Converge(metres):
                self.stereo.rig = replace(self.stereo.rig, convergence=metres)
            case MeasurePoint(picked):
                said = self.measure.add_point(picked)
            case OpenScene(path, cameras):
                self.open_scene(path, cameras)
            case ReadAxes(axes):
                said = self.scenes.switch_axes(self.loaded, axes, self.edit_tool.unsaved())
            case ColourByLevel(on):
                tinted = self.scene.set_tint(on, self.loaded.lod)
                said = failed(tinted, "colour by level") if isinstance(tinted, str) else self._swapped(tinted)
        self.panel.say(said)

    def _press(self, shortcut: Shortcut) -> Message | None:
        """What a shortcut's key does (and says)."""
        actions: dict[Shortcut, Callable[[], Message | None]] = {
            "quit": self.window.request_close,
            "screenshot": self.captures.request,
            "add_keyframe": lambda: self.camera_path.add_view(self.view),
            "switch_navigation": self.view.switch_mode,
            "next_camera": lambda: self.view.step_training_camera(+1),
            "previous_camera": lambda: self.view.step_training_camera(-1),
            "reset_view": self.reset_view,
            "toggle_panel": self.panel.toggle,
        }
        return actions[shortcut]()

    def reset_view(self) -> None:
        self.view.reset(self.view_area()[2:], self.shown_stereo)

    # -- frame -------------------------------------------------------------------------
    def frame(self) -> None:
        """One iteration of the loop. Its steps, in this order, and why:

        1. The clock, the window's events, and what finished in the background: a loaded
           scene is shown before anything reads the scene shown.
        2. The parts act (``Part.act``, in the order of :attr:`parts`), on the last
           frame's view (what the pointer is over): the edit tool's handles and shapes
           take the left button before the camera can.
        3. The camera: the keys and the mouse move it and come back as shortcuts and
           clicks (a pick reads the last frame's view); the view flies on; the path plays
           last, so that it yields to what the user did.
        4. The panel draws, from the last frame, and returns what it changed: the render
           settings (a draft), messages and requests, carried out before the frame is made.
        5. The frame is made, once, from the camera and everything the panel set; its sort
           is asked for (never waited on but on a scripted run's last frame).
        6. The parts draw over the view (``Part.overlay``, the same order: back to front),
           then the notes.
        7. The draw returns a report: the statistics record it, the photo view follows it.
        8. Present, keep the window's image, swap; a screenshot asked for (it re-renders
           offscreen); one step of a probe under way.
        """
        dt = self.stats.tick(self.clock())
        self.frame_index += 1
        self.window.poll_events()
        self._take_loaded()
        width, height = self.window.framebuffer_size()
        if width <= 0 or height <= 0:  # minimised: nothing to draw, do not spin
            if self.options.frames is None:
                self.window.wait_events(0.1)
            return
        self.window.begin_frame()
        imgui.new_frame()
        self.feedback.watch(self.panel)  # what the last frame's actions said
        if imgui.is_mouse_clicked(0):
            self.feedback.clicked()
        self._act(dt)
        draft = Draft(self.settings)
        reply = self.side_panel.draw(panel_sections(self, draft))
        self.settings = draft.settings
        self.answer(reply)
        frame, result, asked = self._make_frame()
        scene, pointing = self.scene_view(), self.pointing()
        self.overlay_rects = {} if not frame.split else draw_split_overlay(
            frame.viewport, self.split, self.settings, self.input.dragging_divider)
        for part in self.parts:
            self.answer(part.overlay(frame, scene, pointing))
        width_shown = imgui.get_io().display_size.x
        left = self.side_panel.notes_left(width_shown)
        self.feedback.draw(left, 10.0, width_shown - left - 10.0)
        imgui.render()
        self._draw(frame, result, asked)
        self.drawer.mono.present(self.ctx.screen, (width, height), frame.viewport,
                                 self.split.column(frame.viewport[2]))
        if self.captures.window_due():
            self.captures.window = self.capture_window()
        self.window.end_frame()
        if self.captures.due():
            self.panel.say(screenshot_said(self._save_shots))
        if self.auto.step():  # this GL's profile is measured: its sort for the scene shown, its blend
            resorted = self.scene.resort()
            self.panel.say(failed(resorted, "sort") if isinstance(resorted, str) else self._swapped(resorted))
            self.settings = self.auto.settings(self.settings, self.options.settings)

    def _act(self, dt: float) -> None:
        """Steps 2 and 3 of :meth:`frame`: the parts act, then the camera moves."""
        shown, mouse_free = Shown(self.shown, self.scene_view()), True
        for part in self.parts:
            reply = part.act(shown, mouse_free)
            mouse_free = mouse_free and not reply.took_mouse
            self.answer(reply)
        for request in self.input.handle(dt, self.view.navigator, camera=self.camera, viewport=self.viewport,
                                         split=self.split if self.right_settings() is not None else None,
                                         mouse_taken=not mouse_free):
            self.carry_out(request)
        self.view.advance(dt, self.options.navigation.turntable)
        self.camera_path.follow(self.view, self.stats.last_frame_time)

    def _make_frame(self) -> tuple[Frame, SortResult | None, SortAsked]:
        """Step 5 of :meth:`frame`: the frame, and its sort asked for (the newest result
        to draw, after a streamed SOG's level arrived the last order until its first)."""
        stereo, said = self.stereo.frame_view(self.shown_stereo)
        self.panel.say(said)
        right = self.right_settings()
        views = self.view_mode.side_views(split=right is not None)
        self.panel.say(views[2])
        framing = self.view.camera(self.view_area(), stereo, self.stereo.headset_size)
        frame = self.shown = Frame.make(self.frame_index, framing, stereo=stereo, settings=self.settings, right=right,
                                        lod=self._lod_request(), deleted=self.edit_tool.deleted, views=views[:2])
        # wait_for_sort: only the last frame of a scripted run, whose capture must show the finished view.
        result, asked = request_sort(self.scene.sorter, frame, self.wait_for_sort)
        return frame, self.scene.shown(result), asked

    def _draw(self, frame: Frame, result: SortResult | None, asked: SortAsked) -> None:
        """Step 7 of :meth:`frame`."""
        report = self.drawer.draw(self.scene.renderer, frame, result, asked, self.scene.sort_timer)
        self.stats.record(report)
        # Settings this GPU cannot render (the panel greys those out) stand until they mend.
        self.panel.say(mended("draw") if report.problem is None else failed(report.problem, source="draw"))
        view, mono = self.view, self.drawer.mono
        index = standing_at(view.cameras, view.training_index, view.lens, view.navigator.pose)
        self.panel.say(self.photo.frame(Drawn(
            self.loaded, None if mono.left is None else index, frame.camera,
            blocked_reason(frame.stereo is not None, frame.split, self.view_mode.channel), report.drew, mono,
            # At a training camera's own size the Photo view renders as ``evaluate`` does, with the
            # panel's settings over the dataset's background, so the two measure one PSNR.
            lambda photo_view, dataset: render_view(self.scene.renderer, self.scene.direct_sorter, photo_view,
                                                    evaluation_settings(self.settings, dataset)))))

    def capture_window(self, overlay: bool = True) -> np.ndarray:
        """(H, W, 3) uint8, top row first: the window as shown, panel included;
        ``overlay=False``: without anything imgui draws (panel, divider, labels)."""
        return self.drawer.mono.capture(self.window.framebuffer_size(), self.viewport,
                                        self.split.column(self.viewport[2]),
                                        self.window.draw_imgui if overlay else None)

    def save_screenshot(self, path: str | Path | None = None) -> Saved:
        """Re-renders the last frame's view offscreen (:mod:`.screenshots`) and saves it;
        returns the (png, json) pair, the left side's or the stereo pair's."""
        frame = self.shown
        if frame is None:
            raise UserError("nothing has been drawn yet")
        self.photo.check_screenshot()
        self.scene.lod.check_screenshot()
        # The settings now: what the frame drew, or what a script set since.
        shown = ShownView(frame.full_camera, self.settings, frame.stereo, self.drawer.shown_view,
                          self.split if self.right_settings() is not None else None, self.drawer.shown_right_view)
        extra = sidecar_extra(self.view.navigator, self.loaded, self.view.training_index,
                              context_description(self.ctx))
        shot = Shot(shown, self.loaded, lod_request(self.loaded, self.settings), self.stereo.save_eyes, extra,
                    self.edit_tool.deleted, self.edit_tool.sidecar_entry(self.loaded))
        self.scene.renderer.set_selection(None)  # a screenshot shows the scene, not the selection's tint
        return self.captures.take(self.scene.renderer, self.scene.direct_sorter, shot, path)

    def _save_shots(self) -> list[Saved]:
        """Every (png, json) pair a screenshot of the last frame writes."""
        self.save_screenshot()
        return self.captures.saved

    # -- loop ------------------------------------------------------------------------
    def run(self) -> None:
        """Frames until the window closes or ``options.frames`` are drawn; the last keeps
        the window's image for ``--window-screenshot``."""
        options = self.options
        while not (self.window.should_close and self.may_close()):
            last = options.frames is not None and self.frame_index + 1 >= options.frames
            self.captures.keep_next |= last and options.window_screenshot is not None
            self.wait_for_sort = last
            if last:  # a scripted run ends on every level of a streamed SOG its settings want
                self._lod_request()
                if reading(self.loaded, self.scenes.loader):
                    self.scenes.loader.wait_done()
            self.frame()
            if last:
                break

    def may_close(self) -> bool:
        """Whether the window, asked to close, may: not at the first ask while deletions
        are not exported (the panel says so, and the same ask again closes)."""
        problem = self.edit_tool.exporter.may_close(self.edit_tool.edits)
        if problem is None:
            return True
        self.window.keep_open()
        self.panel.say(problem)
        return False

    def summary(self) -> str:
        """One line of the frame statistics, printed after a scripted run."""
        gpu_times, post_times = self.drawer.gpu_times()
        return summary(self.stats, self.frame_index, camera=self.camera, stereo=self.shown_stereo, gpu_times=gpu_times,
                       post_times=post_times, scene_count=self.loaded.scene.count,
                       general=self.scene.renderer.general)

    def close(self) -> None:
        """Ends what runs (a load, a video, a probe) and releases what the window made, the
        window last; a second call does nothing."""
        self._made.close()


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
