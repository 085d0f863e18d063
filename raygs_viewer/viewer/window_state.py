"""What the window holds, and what changes it: the scene shown and its loading, the
state the panel edits, the window's parts, and the requests they make.

:class:`WindowState` owns the parts, each of which keeps only its own state (``part``):
the edit tool (``edit_tool``, with its export and handles), the camera path
(``path_widget``), the measure tool (``measure``), picking (``pick_tool``), the training
cameras' frustums (``training_frustums``) and the photo view (``photo_view``); beside
them the state (``state``), input (``input``), the camera (``view_control``), loading
(``loading``), the scene shown with its sorters and level of detail (``shown_scene``,
``lod_window``), drawing (``drawing``), the frame statistics (``stats``), the panel
(``side_panel``) and screenshots (``screenshots``). The parts answer with values
(``part.Reply``: messages, requests); the window says the messages in the panel
(``PanelState.say``) and carries out the requests (:meth:`WindowState.carry_out`). The
loop that drives all this each frame is ``app.Viewer``'s, paced by the runtime while the
window is in a headset (``headset``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import replace

import moderngl
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.render.gl.probe import Probe
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.sort.lod_choice import LodRequest
from raygs_viewer.sort.worker import BackgroundSorter
from raygs_viewer.viewer.auto_defaults import AutoDefaults
from raygs_viewer.viewer.drawing import SceneDrawer
from raygs_viewer.viewer.edit_tool import EditTool
from raygs_viewer.viewer.feedback import Feedback
from raygs_viewer.viewer.file_dialog import FileDialog
from raygs_viewer.viewer.frame import NO_VIEWPORT, Frame
from raygs_viewer.viewer.headset import HeadsetMode
from raygs_viewer.viewer.input import InputHandler
from raygs_viewer.viewer.loading import (
    SceneOpener,
    load_failed,
    scene_title,
    shown_message,
)
from raygs_viewer.viewer.lod_window import (
    refines,
    window_fits,
    window_settings,
)
from raygs_viewer.viewer.measure import MeasureWidget
from raygs_viewer.viewer.part import (
    AimAt,
    Click,
    ColourByLevel,
    Converge,
    FlyTo,
    Headset,
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
from raygs_viewer.viewer.photo_view import PhotoCompare, ScenePhotos
from raygs_viewer.viewer.pick_tool import PickTool
from raygs_viewer.viewer.remembered import Remembered
from raygs_viewer.viewer.screenshots import Captures
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
)
from raygs_viewer.viewer.stats import FrameStats
from raygs_viewer.viewer.thumbnails import Thumbnails
from raygs_viewer.viewer.training_frustums import TrainingFrustums
from raygs_viewer.viewer.view_control import ViewControl
from raygs_viewer.viewer.window import Window


class WindowState:
    """What the window holds and what changes it: the window, the scene shown
    (``scene``: as read, on the GPU, its sorters and its level of detail) and its
    loading, the panel's state, the parts, and the requests they make
    (:meth:`carry_out`). The desktop loop that drives it is ``app.Viewer``.

    ``renderer_factory(ctx, scene, general=)``, ``sorter_factory(direct_sorter)``,
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
        try:
            self.window = Window(f"raygs-viewer — {scene_title(loaded.path)}", options.width, options.height,
                                 options.platform, options.vsync)
            self._made.callback(self.window.close)
            self.ctx = self.window.ctx
            self.auto = AutoDefaults(self.ctx, options.sort, options.auto_precision, options.frames is None,
                                     probe_factory)
            self.settings: RenderSettings = self.auto.settings(options.settings, options.settings)
            # Copies: the panel edits the viewer's state, never the options.
            self.stereo: StereoPreview = replace(options.stereo)
            self.captures = Captures(replace(options.screenshots))
            self.split, self.view_mode, self.panel = SplitView(), ViewMode(), PanelState()
            self.stats = FrameStats()
            self.drawer = self._made_here(SceneDrawer(self.ctx), "release")
            self.scene = self._made_here(ShownScene(self.ctx, general=options.general,
                                                    renderer_factory=renderer_factory, sorter_factory=sorter_factory,
                                                    sort_for=self.auto.sort_for), "close")
            self._made.callback(self.auto.close)  # a probe under way: its GL objects, while the context lives
            self.photos = ScenePhotos(options.images)
            self.photo = PhotoCompare(self.ctx, self.photos)
            self.picker, self.input = PickTool(), InputHandler()
            self.file_dialog, self.feedback = FileDialog(), Feedback()
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
            self.headset = self._made_here(HeadsetMode(self.ctx, options.headset, self.window.make_current), "close")
            self.frame_index = 0
            self.loaded: LoadedScene | None = None
            self.view: ViewControl | None = None
            self.shown: Frame | None = None
            self.wait_for_sort = False          # set for the last frame of a scripted run
            #: The split view's divider and side labels as drawn last frame, (x0, y0, x1, y1)
            #: in screen coordinates (imgui's); empty without the split view.
            self.overlay_rects: dict[str, tuple[float, float, float, float]] = {}
            self.auto.check(self.ctx)  # before any scene, in one line
            self.panel.say(*self._install(loaded, start_camera))
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
        """The split view's right side; None when it is off (it is, in the stereo preview and the headset)."""
        return None if self.stereo.on or self.headset.running else self.split.right(self.settings)

    def view_area(self) -> Viewport:
        """The part of the window the view is laid out in: beside the panel while it is
        shown (``layout.view_area``)."""
        return self.side_panel.view_area(self.window.framebuffer_size(),
                                         imgui.get_io().display_framebuffer_scale.x or 1.0)

    def scene_view(self) -> SceneView:
        """The scene shown, as the parts see it (the orders of the last frame drawn)."""
        return SceneView(self.loaded, self.scene.renderer, self.scene.direct_sorter, self.edit_tool.deleted,
                         self.drawer.orders, float(self.view.radius))

    def path_scene(self, settings: RenderSettings | None = None) -> PathScene:
        """What the path widget is handed for an action (``settings``: as the panel edits
        them; None: the window's)."""
        loaded = self.loaded
        return PathScene(self.view, loaded, settings or self.settings, self.shown,
                         lambda: self.edit_tool.sidecar_entry(loaded))

    def pointing(self) -> Pointing:
        """What the pointer's clicks do this frame."""
        navigator, shown = self.view.navigator, self.shown
        return Pointing(self.measure.on, self.measure.scale, self.stereo.converge_on_pick, self.stereo.rig,
                        flying=navigator.animating, orbiting=navigator.mode == "orbit",
                        divider=None if shown is None else self.split.column(shown.camera.width))

    # -- scenes ----------------------------------------------------------------------------
    def _install(self, loaded: LoadedScene, start_camera: Camera | None = None) -> tuple[Message, ...]:
        """Puts a loaded scene on the GPU; on failure the current scene stays. Returns what
        the parts said of it (said after the scene's own line)."""
        if refines(self.loaded, loaded):  # a streamed SOG's next level: the view stays
            refined, swapped = self.scene.refine(self.loaded, loaded, self.settings, self.options.settings,
                                                 self.scenes.loader)
            self.forget_drawn(swapped)
            if refined is None:
                return ()
            self.settings, self.loaded = refined.settings, refined.loaded
            return self._scene_shown(grown=True)
        self.forget_drawn(self.scene.open(loaded.scene))
        self.loaded = loaded
        self.settings = opened_settings(self.settings, self.options.settings, loaded)
        # A new scene keeps the user's navigation choices.
        choices = self.options.navigation if self.view is None else self.view.choices()
        _, _, width, height = self.view_area()
        self.view = ViewControl(loaded, start_camera, choices, width / height)
        self.window.set_title(f"raygs-viewer — {scene_title(loaded.path)}")
        return self._scene_shown(grown=False)

    def _scene_shown(self, grown: bool) -> tuple[Message, ...]:
        return tuple(message for part in self.parts for message in part.scene_shown(self.loaded, grown).messages)

    def forget_drawn(self, swapped: Swapped | None) -> None:
        """Another copy of the scene is on the GPU: what was drawn of the one before is stale."""
        if swapped is None:
            return
        self.stats.new_sorter(swapped.kept, self.frame_index)
        self.drawer.forget()
        self.photos.forget()
        self.photo.forget_scene()
        self.frustums.forget()

    def take_loaded(self) -> None:
        """Shows a scene the background load finished (its words in the panel), and opens
        files dropped on the window."""
        result = self.scenes.poll()
        if isinstance(result, LoadedScene):
            try:
                news = self._install(result)
            except (UserError, MemoryError, moderngl.Error) as exc:  # e.g. too large for this GPU
                self.panel.say(load_failed(f"{result.path}: {one_line(exc)}"))
            else:
                self.panel.say(shown_message(result), *news)
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

    def frame_lod(self) -> LodRequest | None:
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
                said = self.swap_said(self.scene.set_tint(on, self.loaded.lod), "colour by level")
            case Headset(action):
                said = self.headset.act(action)
        self.panel.say(said)

    def swap_said(self, swap: Swapped | str | None, action: str) -> Message | None:
        """What a swap of the GPU's copy (``ShownScene.set_tint``, ``.resort``) leaves to
        do: forget what was drawn of the copy before, or say in one line why it failed."""
        if isinstance(swap, str):
            return failed(swap, action)
        self.forget_drawn(swap)
        return None

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
