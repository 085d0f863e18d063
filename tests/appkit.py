"""Driving the real viewer loop in tests: synthetic imgui input, what the panel drew
and where, and the images the window holds and shows. The ``open_viewer`` fixture
(conftest.py) opens viewers with it."""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)

from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.request import SortRequest, SortResult
from raygs_viewer.sort.worker import BackgroundSorter
from raygs_viewer.viewer.app import Viewer, load_start_scene, start_camera
from raygs_viewer.viewer.state import ScreenshotOptions, ViewerOptions

WIDTH, HEIGHT = 192, 144
PANEL_WIDTH, PANEL_HEIGHT = 640, 800  # room for the whole panel down to the Path section
PANEL_NAME = "raygs-viewer"  # the panel's imgui window


# -- what the panel drew, recorded from the test side ----------------------------------------
#: The imgui functions whose widget a test can name, with the argument that names it: the
#: label (an id for arrow_button). PanelRecorder wraps them on the imgui module, so the
#: panel's code carries no hook of its own. A widget kind the panel starts using is added
#: here when a test needs it; until then naming it fails with the list of what was drawn.
LABELLED = {name: "label" for name in (
    "button", "small_button", "checkbox", "radio_button", "slider_float", "slider_int", "input_text",
    "input_text_with_hint", "input_float", "input_int2", "input_float2", "color_edit3", "combo",
    "selectable", "collapsing_header", "input_float3")} | {"arrow_button": "str_id", "invisible_button": "str_id"}
#: Plain text: named by the text itself (imgui gives it no id, so "##" means nothing there).
TEXTS = ("text", "text_disabled", "text_wrapped")


@dataclass(frozen=True)
class Widget:
    """One widget a frame drew: the imgui function that drew it (``kind``), its ``label``
    as the panel passed it (a text's text, a progress bar's overlay), its screen
    rectangle (x0, y0, x1, y1), and ``within``: the label of the combo whose open popup
    holds it (None: the panel's window)."""

    kind: str
    label: str
    rect: tuple[float, float, float, float]
    within: str | None = None

    @property
    def names(self) -> set[str]:
        return label_names(self.kind, self.label)


def label_names(kind: str, label: str) -> set[str]:
    """What a test may call a widget: its whole label and, for a widget with an imgui id,
    its visible text (before "##") and its id suffix ("##..." / "###..."). So
    "Save##path" answers to "Save##path", "Save" and "##path"; "Play###play" to "Play"
    and "###play"; "##scrub" to "##scrub". Never the empty string."""
    if kind in TEXTS or kind == "progress_bar":
        return {label} - {""}
    visible, hashes, rest = label.partition("##")
    return {label, visible, hashes + rest} - {""}


class Panel:
    """The widgets one frame drew, in drawing order. A name must fit exactly one of them:
    a name never drawn is a KeyError, and so is one that fits several widgets (two with
    the same visible text), so that a test never clicks the wrong one unawares."""

    def __init__(self) -> None:
        self.widgets: list[Widget] = []

    def matching(self, name: str, within: str | None = None) -> list[Widget]:
        """The widgets ``name`` fits: in the window, or with ``within`` (a combo's name)
        among the entries of that combo's open popup."""
        scope = self._scope(within)
        return [w for w in self.widgets if w.within == scope and name in w.names]

    def rect(self, name: str, within: str | None = None) -> tuple[float, float, float, float]:
        """The screen rectangle of the one widget ``name`` fits (see :meth:`matching`)."""
        found = self.matching(name, within)
        if len(found) != 1:
            where = f" in the popup of {within!r}" if within else ""
            drawn = [w.label for w in self.widgets if w.within == self._scope(within)]
            raise KeyError(f"{name!r} fits {len(found)} widgets drawn{where} in the last frame "
                           f"{[w.label for w in found]}; drawn there: {drawn}")
        return found[0].rect

    def __contains__(self, name: str) -> bool:
        """Whether the last frame drew a widget ``name`` fits, in the window."""
        return bool(self.matching(name))

    def labels(self, kind: str | None = None) -> list[str]:
        """The labels the last frame drew (of ``kind`` only: "progress_bar", ...), in order."""
        return [w.label for w in self.widgets if kind is None or w.kind == kind]

    def _scope(self, within: str | None) -> str | None:
        if within is None:
            return None
        opened = {w.within for w in self.widgets if w.within is not None}
        combos = [label for label in opened if within in label_names("begin_combo", label)]
        if len(combos) != 1:
            raise KeyError(f"{within!r} fits {len(combos)} combos open in the last frame; open: {sorted(opened)}")
        return combos[0]


class PanelRecorder:
    """Wraps imgui's widget functions (``install``): after each, the widget's rectangle
    (imgui's last item) goes into ``target``, the Panel of the frame being drawn. The
    Driver of the viewer whose frame starts sets ``target``, so each viewer's widgets
    land in its own driver's Panel."""

    def __init__(self) -> None:
        self.target: Panel | None = None
        self._combos: list[str] = []  # the labels of the combos whose popup is open, innermost last

    def start_frame(self) -> Panel:
        self.target, self._combos = Panel(), []
        return self.target

    def install(self, monkeypatch) -> None:
        """Wraps the functions on the ``imgui`` module object, undone with ``monkeypatch``:
        the panel looks them up as ``imgui.name`` each time it draws, so it calls the wrappers."""
        for kind, argument in LABELLED.items():
            monkeypatch.setattr(imgui, kind, self._labelled(kind, getattr(imgui, kind), argument))
        for kind in TEXTS:
            monkeypatch.setattr(imgui, kind, self._labelled(kind, getattr(imgui, kind), "fmt"))
        progress_bar, begin_combo, end_combo = imgui.progress_bar, imgui.begin_combo, imgui.end_combo

        def progress(fraction, size_arg=None, overlay=None):
            progress_bar(fraction, size_arg, overlay)
            self._record("progress_bar", overlay or "")

        def begin(label, *args, **kwargs):
            opened = begin_combo(label, *args, **kwargs)
            if opened:  # recorded at end_combo, after the entries of its popup
                self._combos.append(label)
            else:
                self._record("begin_combo", label)
            return opened

        def end():
            end_combo()
            # Ending the popup's window gives imgui's last item back to the combo.
            self._record("begin_combo", self._combos.pop())

        monkeypatch.setattr(imgui, "progress_bar", progress)
        monkeypatch.setattr(imgui, "begin_combo", begin)
        monkeypatch.setattr(imgui, "end_combo", end)

    def _labelled(self, kind: str, draw, argument: str):
        def wrapper(*args, **kwargs):
            result = draw(*args, **kwargs)
            self._record(kind, args[0] if args else kwargs[argument])
            return result
        return wrapper

    def _record(self, kind: str, label: str) -> None:
        if self.target is None:  # drawn before any driven frame
            return
        low, high = imgui.get_item_rect_min(), imgui.get_item_rect_max()
        within = self._combos[-1] if self._combos else None
        self.target.widgets.append(Widget(kind, label, (low.x, low.y, high.x, high.y), within))


class FrameClock:
    """The viewer's clock in tests: each reading is ``step`` seconds after the last (one
    frame of that time). A step that is no finite number gives that reading once and the
    clock goes on from the last finite one; a step too small to move a clock grown huge
    starts it again from 0 (that one frame's time is negative: the viewer moves nothing)."""

    def __init__(self, step: float = 0.1):
        self.step, self.now = step, 0.0

    def __call__(self) -> float:
        reading = self.now + self.step
        if not math.isfinite(reading):
            return reading
        if reading == self.now and self.step > 0:
            reading = self.step
        self.now = reading
        return reading


class Driver:
    """Queues imgui input for the next frames and runs them; ``panel``: the widgets the
    last frame drew (recorded by ``recorder``); ``clock``: the viewer's (its frame time:
    ``clock.step``)."""

    def __init__(self, viewer: Viewer, recorder: PanelRecorder, clock: FrameClock):
        self.viewer = viewer
        self.recorder = recorder
        self.clock = clock
        self.panel = Panel()
        self.mouse: tuple[float, float] | None = None
        self._queued: list = []
        begin_frame = viewer.window.begin_frame

        def begin_then_inject() -> None:
            begin_frame()
            self._inject()
        # After the GLFW backend has read the devices, before imgui starts the frame: where
        # synthetic imgui events must go, whoever runs the frame (frames(), viewer.run()).
        viewer.window.begin_frame = begin_then_inject

    def _inject(self) -> None:
        # This frame's widgets replace the last frame's.
        self.panel = self.recorder.start_frame()
        io = imgui.get_io()
        if self.mouse is not None:  # the GLFW backend overwrites the position every frame
            io.add_mouse_pos_event(*self.mouse)
        for event in self._queued:
            event(io)
        self._queued = []

    def key(self, key, down: bool = True) -> None:
        self._queued.append(lambda io: io.add_key_event(key, down))

    def tap(self, key) -> None:
        self.key(key, True)
        self.frames(1)
        self.key(key, False)
        self.frames(1)

    def button(self, button: int, down: bool) -> None:
        self._queued.append(lambda io: io.add_mouse_button_event(button, down))

    def wheel(self, ticks: float) -> None:
        self._queued.append(lambda io: io.add_mouse_wheel_event(0.0, ticks))

    def move_mouse(self, x: float, y: float) -> None:
        self.mouse = (x, y)

    def frames(self, count: int = 1) -> None:
        for _ in range(count):
            self.viewer.frame()

    def settle(self) -> None:
        """Frames until the drawn order is the one for the current view."""
        for _ in range(50):
            self.frames(1)
            self.viewer.scene.sorter.wait(self.viewer.scene.sorter.requested, timeout=30)
            self.frames(1)
            if self.viewer.stats.order_age == 0:
                return
        raise AssertionError("the order never caught up with the view")

    def wait_for_load(self) -> None:
        """Frames until the background load has finished and the window has taken its result."""
        for _ in range(3000):
            if not self.viewer.scenes.loader.busy:
                break
            time.sleep(0.01)
        assert not self.viewer.scenes.loader.busy
        self.frames(1)

    def click(self, rect) -> None:
        """A left click at the centre of ``rect`` (x0, y0, x1, y1), or of the widget it
        names in the last frame (Panel.rect); a combo's near its left end, on its box (a
        narrow box's centre is its label's, which does not open it)."""
        x0, y0, x1, y1 = self.panel.rect(rect) if isinstance(rect, str) else rect
        combo = isinstance(rect, str) and [w.kind for w in self.panel.matching(rect)] == ["begin_combo"]
        self.click_at(x0 + 8 if combo else (x0 + x1) / 2, (y0 + y1) / 2)

    def click_at(self, x: float, y: float) -> None:
        self.move_mouse(x, y)
        self.frames(1)
        self.button(0, True)
        self.frames(1)
        self.button(0, False)
        self.frames(1)

    def reveal(self, label: str) -> None:
        """Scrolls the panel with the mouse wheel (over its left margin, where no widget
        takes the wheel) until the widget ``label`` lies inside its visible part."""
        for _ in range(60):
            panel = imgui.internal.find_window_by_name(PANEL_NAME).inner_clip_rect
            x0, y0, x1, y1 = self.panel.rect(label)
            if y0 >= panel.min.y and y1 <= panel.max.y:
                return
            self.move_mouse(panel.min.x + 2, (panel.min.y + panel.max.y) / 2)
            self.frames(1)  # imgui takes the wheel where the mouse was in the frame before
            self.wheel(-1.0 if y1 > panel.max.y else 1.0)
            self.frames(2)  # the scroll shows from the frame after the wheel's
        raise AssertionError(f"{label} never came into the panel's view")

    def click_left_end(self, rect) -> None:
        """A left click 2 px inside the left end of ``rect`` (or of the widget it names):
        a slider's lowest value."""
        x0, y0, x1, y1 = self.panel.rect(rect) if isinstance(rect, str) else rect
        self.click_at(x0 + 2, (y0 + y1) / 2)


def window_image(viewer: Viewer) -> np.ndarray:
    """The scene image the window shows (its float target), top row first."""
    return viewer.drawer.mono.left.read()


def right_image(viewer: Viewer) -> np.ndarray:
    """The split view's right side as drawn (its float target), top row first."""
    return viewer.drawer.mono.right.read()


def presented(viewer: Viewer) -> np.ndarray:
    """(h, w, 3) int: the viewport as the present pass shows it, without what imgui
    draws over it (panel, divider, labels)."""
    x, y, w, h = viewer.viewport
    return viewer.capture_window(overlay=False)[y:y + h, x:x + w].astype(int)


def split_expected(a: np.ndarray, b: np.ndarray, column: int) -> np.ndarray:
    """(h, w, 3) int: 8-bit ``a`` left of ``column``, ``b`` from it on."""
    return np.concatenate([to_rgb8(a)[:, :column], to_rgb8(b)[:, column:]], axis=1).astype(int)


def text_past_the_panel(drive: "Driver") -> list[str]:
    """The text the panel drew last frame that is cut off: lines of text and widgets
    with their labels (checkboxes, buttons...) that run past its right edge, and
    progress bars whose label is wider than the bar. The notes over the view, right of
    the panel, are not its."""
    window = imgui.internal.find_window_by_name(PANEL_NAME)
    left, right = window.pos.x, window.inner_clip_rect.max.x + 0.5
    mine = [w for w in drive.panel.widgets if w.within is None and left <= w.rect[0] < right]
    past = [f"{w.kind}: {w.label}" for w in mine if w.rect[2] > right]
    padding = 2 * imgui.get_style().frame_padding.x
    return past + [f"progress_bar: {w.label}" for w in mine if w.kind == "progress_bar"
                   and imgui.calc_text_size(w.label).x + padding > w.rect[2] - w.rect[0] + 0.5]


def click_choice(drive: "Driver", combo: str, entry: str) -> None:
    """Opens the panel's combo ``combo`` and picks the entry shown as ``entry`` from it."""
    drive.click(combo)
    drive.frames(1)  # a popup's first frame places it; it is where it stays from the second on
    drive.click(drive.panel.rect(entry, within=combo))


def headless(viewer: Viewer, settings: RenderSettings | None = None) -> np.ndarray:
    """The viewer's last view rendered offscreen with an exact sort of the levels it drew."""
    settings = settings or viewer.settings
    drawn = next(iter(viewer.drawer.orders.values()), None)
    order = exact_order(viewer.scene.direct_sorter, viewer.camera, settings, levels=None if drawn is None else drawn.choice)
    return viewer.scene.renderer.render(viewer.camera, settings, order)


def project(camera, point) -> np.ndarray:
    p = camera.R @ np.asarray(point, float) + camera.t
    return np.array([camera.fx * p[0] / p[2] + camera.cx, camera.fy * p[1] / p[2] + camera.cy, p[2]])




def open_viewer_factory(tmp_path):
    """(open_, close_all): open_(scene (a path or a SceneSource), hide_panel, **ViewerOptions fields and the Viewer's
    renderer_factory / sorter_factory) -> (viewer, driver). Each driver records its
    viewer's panel; close_all also takes the recording wrappers off imgui."""
    viewers = []
    recorder, patches = PanelRecorder(), pytest.MonkeyPatch()
    recorder.install(patches)

    def open_(scene: str | SceneSource = "demo", hide_panel=False, **options):
        options.setdefault("width", WIDTH)
        options.setdefault("height", HEIGHT)
        options.setdefault("screenshots", ScreenshotOptions(folder=str(tmp_path / "shots")))
        factories = {name: options.pop(name) for name in ("renderer_factory", "sorter_factory", "probe_factory")
                     if name in options}
        source = scene if isinstance(scene, SceneSource) else SceneSource(scene)
        viewer_options = ViewerOptions(source=source, platform="null", **options)
        clock = FrameClock()
        viewer = Viewer(viewer_options, load_start_scene(viewer_options), start_camera(viewer_options), clock=clock,
                        **factories)
        viewers.append(viewer)
        viewer.panel.show_panel = not hide_panel
        return viewer, Driver(viewer, recorder, clock)

    def close_all():
        try:
            for viewer in viewers:
                viewer.close()
        finally:
            patches.undo()

    return open_, close_all


class GatedSorter:
    """Wraps a DepthSorter: the first ``free`` sorts run at once, every later one waits
    until ``release`` is set; ``inside`` is set once a sort has reached the gate."""

    def __init__(self, sorter, free: int = 0):
        self.sorter, self.free = sorter, free
        self.release = threading.Event()
        self.inside = threading.Event()

    def sort(self, request: SortRequest) -> SortResult:
        if self.free > 0:
            self.free -= 1
        else:
            self.inside.set()
            assert self.release.wait(timeout=60)
        return self.sorter.sort(request)

    def close(self) -> None:
        self.sorter.close()


def gated_viewer(open_viewer, free: int = 0, **options):
    """(viewer, driver, gate): a viewer whose background sorter runs a GatedSorter."""
    gates = []

    def factory(sorter):
        gates.append(GatedSorter(sorter, free))
        return BackgroundSorter(gates[-1])

    viewer, drive = open_viewer(sorter_factory=factory, **options)
    return viewer, drive, gates[-1]


class RecordingSorter(BackgroundSorter):
    """Records the (p_min, dilation) of every request, the cameras it culls for and the
    sort keys it asks for."""

    def __init__(self, sorter):
        super().__init__(sorter)
        self.asked: list[tuple[float, float | None]] = []
        self.culled_for: list[tuple | None] = []
        self.keys: list[tuple[str, ...]] = []

    def request(self, request: SortRequest) -> int:
        self.asked.append((request.p_min, request.dilation))
        self.culled_for.append(request.cull_cameras)
        self.keys.append(request.keys)
        return super().request(request)
