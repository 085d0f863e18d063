"""Driving the real viewer loop in tests: synthetic imgui input, and the images the
window holds and shows. The ``open_viewer`` fixture (conftest.py) opens viewers with it."""

from __future__ import annotations

import threading
import time

import numpy as np
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)

from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import load_now
from raygs_viewer.sort.worker import BackgroundSorter
from raygs_viewer.viewer.app import Viewer, start_camera
from raygs_viewer.viewer.panel.widgets import item_rects
from raygs_viewer.viewer.state import ScreenshotOptions, ViewerOptions

WIDTH, HEIGHT = 192, 144
PANEL_WIDTH, PANEL_HEIGHT = 640, 800  # room for the whole panel down to the Path section
PANEL_NAME = "raygs-viewer"  # the panel's imgui window


class Driver:
    """Queues imgui input for the next frames and runs them."""

    def __init__(self, viewer: Viewer):
        self.viewer = viewer
        self.mouse: tuple[float, float] | None = None
        self._queued: list = []
        viewer.input_script = self._inject
        viewer.fixed_dt = 0.1

    def _inject(self, viewer) -> None:
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
            self.viewer.sorter.wait(self.viewer.sorter.requested, timeout=30)
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
        """A left click at the centre of ``rect`` (x0, y0, x1, y1)."""
        x0, y0, x1, y1 = rect
        self.click_at((x0 + x1) / 2, (y0 + y1) / 2)

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
            x0, y0, x1, y1 = item_rects[label]
            if y0 >= panel.min.y and y1 <= panel.max.y:
                return
            self.move_mouse(panel.min.x + 2, (panel.min.y + panel.max.y) / 2)
            self.frames(1)  # imgui takes the wheel where the mouse was in the frame before
            self.wheel(-1.0 if y1 > panel.max.y else 1.0)
            self.frames(2)  # the scroll shows from the frame after the wheel's
        raise AssertionError(f"{label} never came into the panel's view")

    def click_left_end(self, rect) -> None:
        """A left click 2 px inside the left end of ``rect``: a slider's lowest value."""
        x0, y0, x1, y1 = rect
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


def click_choice(drive: "Driver", tag: str, value: str) -> None:
    """Opens the panel's combo ``tag`` and picks ``value`` from it."""
    drive.click(item_rects[tag])
    drive.frames(1)  # a popup's first frame places it; it is where it stays from the second on
    drive.click(item_rects[f"{tag} {value}"])


def headless(viewer: Viewer, settings: RenderSettings | None = None) -> np.ndarray:
    return viewer.renderer.render(viewer.camera, settings or viewer.settings)


def project(camera, point) -> np.ndarray:
    p = camera.R @ np.asarray(point, float) + camera.t
    return np.array([camera.fx * p[0] / p[2] + camera.cx, camera.fy * p[1] / p[2] + camera.cy, p[2]])




def open_viewer_factory(tmp_path):
    """(open_, close_all): open_(scene, hide_panel, **ViewerOptions fields and the Viewer's
    renderer_factory / sorter_factory) -> (viewer, driver)."""
    viewers = []

    def open_(scene="demo", hide_panel=False, **options):
        options.setdefault("width", WIDTH)
        options.setdefault("height", HEIGHT)
        options.setdefault("screenshots", ScreenshotOptions(folder=str(tmp_path / "shots")))
        factories = {name: options.pop(name) for name in ("renderer_factory", "sorter_factory") if name in options}
        viewer_options = ViewerOptions(scene=scene, platform="null", **options)
        viewer = Viewer(viewer_options, load_now(scene), start_camera(viewer_options), **factories)
        viewers.append(viewer)
        viewer.panel.show_panel = not hide_panel
        return viewer, Driver(viewer)

    def close_all():
        for viewer in viewers:
            viewer.close()

    return open_, close_all


class GatedSorter:
    """Wraps a DepthSorter: the first ``free`` sorts run at once, every later one waits
    until ``release`` is set; ``inside`` is set once a sort has reached the gate."""

    def __init__(self, sorter, free: int = 0):
        self.sorter, self.free = sorter, free
        self.release = threading.Event()
        self.inside = threading.Event()

    def orders(self, *args, **kwargs):
        if self.free > 0:
            self.free -= 1
        else:
            self.inside.set()
            assert self.release.wait(timeout=60)
        return self.sorter.orders(*args, **kwargs)


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

    def request(self, camera, p_min, dilation=0.0, cull_cameras=None, keys=("depth",)):
        self.asked.append((p_min, dilation))
        self.culled_for.append(cull_cameras)
        self.keys.append(tuple(keys))
        return super().request(camera, p_min, dilation, cull_cameras, keys)
