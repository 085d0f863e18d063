"""Cleaning the scene in the window: the selection tools the left mouse button draws with
(a rectangle, a lasso, a brush), the box and the sphere, ranges of the histograms, and
the edits they make (``scene.edits``): delete, undelete, crop, undo and redo, export.

The scene on the GPU never changes. A deletion hides rows from every sort the window
makes (the frame's, screenshots', picks': ``sort.deleted``), and the selection is drawn
tinted by the preprocessing pass from one bit a gaussian (``GLRenderer.set_selection``).
Screen shapes are recorded in the drawn camera's pixels, with the camera, so the edit
document replays them (``capture.edit_file``).

While a tool is on, a left drag on the view draws with it (Shift adds to the selection,
Ctrl subtracts, both intersect; the panel's choice otherwise) instead of turning the
camera; the right and middle buttons and the wheel still move it. A shape selects the
centres it covers ("through"), or the gaussians that give at least ``min_weight`` of
some pixel's colour under it ("visible", :mod:`.view_selection`); the click tool selects
the gaussian its pixel shows most. Delete deletes the selection, Ctrl+Z undoes, Ctrl+Y
or Ctrl+Shift+Z redoes.

What the view shows is weighed beside the frames, a slice each (the panel shows how far
it is): Escape or the panel's Cancel drops it with nothing changed; a new shape replaces
it; another scene, or a streamed SOG's next level, drops it with a message. In the split
view each side weighs with its own settings, in the stereo preview the eye the shape
begins on.
"""

from __future__ import annotations

import math
from typing import Callable, Literal, get_args

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.capture.edit_file import edit_document_json
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.scene.edits import Edits, How, Operation
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.selection import ATTRIBUTES, Box, Range, ScreenShape, Sphere, attribute_values
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.viewer.edit_export import EditExport, edit_document
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.part import NO_REPLY, Part, Pointing, Reply, SceneView, Shown
from raygs_viewer.viewer.state import Message, failed, note
from raygs_viewer.render.gl.weighing import WeighOn
from raygs_viewer.viewer.picking import stereo_image
from raygs_viewer.viewer.view_selection import ShownWeighing, advance, start_shown_weighing
from raygs_viewer.viewer.volume_handles import VolumeHandles

#: The tools the left button draws with ("off": it turns the camera; "click": the gaussian
#: the clicked pixel shows most).
Tool = Literal["off", "click", "rectangle", "lasso", "brush"]
TOOLS: tuple[Tool, ...] = get_args(Tool)
#: What a shape selects: the centres it covers, or the gaussians its pixels show.
Selects = Literal["through", "visible"]
#: Histogram bins.
BINS = 64
#: Attributes shown on a log10 axis (they span decades).
LOG_ATTRIBUTES = ("largest scale", "volume")
#: The least time a slice of a weighing aims at (seconds; else about a frame's, so the
#: view's rate halves at worst while it runs): a fast view still weighs in few slices,
#: each paying its sort and draw once.
MIN_SLICE_SECONDS = 0.05
#: A dragged point is kept when it is this far (screen units) from the last one.
TRACE_STEP = 2.0


class EditTool(Part):
    """The edits of the scene the window shows (None before the first), the tool and
    its settings, the box and the sphere, the export. Each action is handed the scene it
    acts on and returns what the panel says of it."""

    def __init__(self) -> None:
        self.tool: Tool = "off"
        self.how: How = "set"
        self.brush_radius = 20.0   # screen units
        self.selects: Selects = "through"
        self.min_weight = 0.05     # the least share of a pixel's colour "visible" selects
        self.attribute = ATTRIBUTES[0]
        self.exporter = EditExport()
        self.handles = VolumeHandles()
        self.edits: Edits | None = None
        self.box: Box | None = None
        self.sphere: Sphere | None = None
        self.drag: list[tuple[float, float]] | None = None   # screen points of the shape being drawn
        self.histogram_drag: float | None = None   # where a drag across the histogram began (screen x)
        self._drag_how: How = "set"
        self.weighing: ShownWeighing | None = None   # what the view shows, being weighed
        self.weigh_on: WeighOn = "auto"
        self.slice_seconds: float | None = None     # a slice's time (None: the last frame's)
        # Made from the edits' masks, each keyed on the edits' generation (unique to a state).
        self._deleted: tuple[int, DeletedRows | None] = (0, None)
        self._histogram: tuple[int, str, np.ndarray, np.ndarray] | None = None
        self._counted: tuple[int, np.ndarray, int, int] | None = None

    # -- the scene --------------------------------------------------------------------
    def scene_shown(self, loaded: LoadedScene, grown: bool) -> Reply:
        """A new scene: no edits, the box and the sphere around its centres. A streamed
        SOG's finer level (``grown``): the rows added after those read start unedited."""
        dropped = self.drop_weighing("dropped: the scene changed while what the view shows was weighed")
        if grown and self.edits is not None:
            self.edits = self.edits.grow(loaded.scene.count)
            return Reply.of(dropped)
        scene = loaded.scene
        self.edits = Edits(scene.count)
        self.drag, self.exporter.confirm_replace, self.handles.drag, self.exporter.exported = None, None, None, None
        positions = scene.positions.astype(np.float64)
        if scene.count:
            low, high = positions.min(axis=0), positions.max(axis=0)
            centre = np.median(positions, axis=0)
            radius = float(np.linalg.norm(positions - centre, axis=1).max())
        else:
            low, high, centre, radius = np.zeros(3), np.zeros(3), np.zeros(3), 0.0
        self.box = Box(tuple(low.tolist()), tuple(high.tolist()))
        self.sphere = Sphere(tuple(centre.tolist()), radius)
        return Reply.of(dropped)

    @property
    def deleted(self) -> DeletedRows | None:
        """The deleted rows, as every sort of the window leaves them out (made once an edit)."""
        if self.edits is None:
            return None
        generation, deleted = self._deleted
        if generation != self.edits.generation:
            deleted = DeletedRows.of(self.edits.deleted)
            self._deleted = (self.edits.generation, deleted)
        return deleted

    def _state(self) -> tuple[np.ndarray, int, int]:
        """(the selection shown, its count, the count deleted), made once an edit: the
        panel and the draw read them every frame."""
        if self._counted is None or self._counted[0] != self.edits.generation:
            selection = self.edits.selection
            self._counted = (self.edits.generation, selection, int(selection.sum()), int(self.edits.deleted.sum()))
        return self._counted[1:]

    def selection_count(self) -> int:
        return 0 if self.edits is None else self._state()[1]

    def deleted_count(self) -> int:
        return 0 if self.edits is None else self._state()[2]

    def unsaved(self) -> str | None:
        """What another scene opened now, or the window closed, would lose (the deletions
        not exported), or None."""
        return self.exporter.unsaved(self.edits)

    # -- edits ------------------------------------------------------------------------
    def apply(self, operation: Operation, scene: Scene) -> Message | None:
        """Applies ``operation`` to ``scene``; says what it did."""
        if self.edits is None:
            return None
        try:
            changed = self.edits.apply(scene, operation)
        except ValueError as exc:
            return failed(exc, operation.op)
        return note(f"{operation.op}: {self._counts()}" if changed else f"{operation.op}: nothing changed")

    def select(self, shape, scene: Scene, how: How | None = None) -> Message | None:
        return self.apply(Operation("select", shape, how or self.how), scene)

    def undo(self) -> Message | None:
        if self.edits is not None and self.edits.undo():
            return note(f"undone: {self._counts()}")
        return None

    def redo(self) -> Message | None:
        if self.edits is not None and self.edits.redo():
            return note(f"redone: {self._counts()}")
        return None

    # -- what the view shows, weighed beside the frames ------------------------------------
    def drop_weighing(self, why: str) -> Message | None:
        """Drops the selection being weighed, nothing changed; says ``why`` (None: none ran)."""
        if self.weighing is None:
            return None
        self.weighing.release()
        self.weighing = None
        return note(f"selection {why}; nothing changed")

    def _weigh(self, scene: Scene) -> Message | None:
        """The next slice of the selection being weighed; selects what it found once done."""
        done, said = advance(self.weighing, lambda rows, how: self.select(rows, scene, how))
        if done:
            self.weighing.release()
            self.weighing = None
        return said

    def _counts(self) -> str:
        return f"{self.selection_count():,} selected, {self.deleted_count():,} deleted"

    def histogram(self, scene: Scene, attribute: str) -> tuple[np.ndarray, np.ndarray]:
        """(BINS,) float32 counts of the gaussians of ``scene`` not deleted, and the BINS + 1
        edges (in log10 for :data:`LOG_ATTRIBUTES`), made once an edit and attribute."""
        key = (self.edits.generation, attribute)
        if self._histogram is None or self._histogram[:2] != key:
            values = axis_values(scene, attribute)[~self.edits.deleted]
            values = values[np.isfinite(values)]
            low, high = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
            counts, edges = np.histogram(values, BINS, (low, high if high > low else low + 1.0))
            self._histogram = (*key, counts.astype(np.float32), edges)
        return self._histogram[2], self._histogram[3]

    def select_range(self, scene: Scene, attribute: str, low: float, high: float, how: How | None = None
                     ) -> Message | None:
        """Selects ``attribute`` in ``low``..``high`` on the histogram's axis (log10 for
        :data:`LOG_ATTRIBUTES`)."""
        low, high = min(low, high), max(low, high)
        if attribute in LOG_ATTRIBUTES:
            low, high = 10.0 ** low, 10.0 ** high
        return self.select(Range(attribute, low, high), scene, how)

    def sidecar_entry(self, loaded: LoadedScene) -> dict | None:
        """What a screenshot's sidecar records of the edits of ``loaded``: the edit
        document, where a gaussian is deleted (a selection alone changes no screenshot);
        None otherwise."""
        if self.edits is None or not self.edits.edited:
            return None
        return edit_document_json(edit_document(loaded, self.edits))

    # -- each frame -------------------------------------------------------------------
    def act(self, shown: Shown, mouse_free: bool) -> Reply:
        """A finished export said; the keys Delete, Ctrl+Z, Ctrl+Y and Ctrl+Shift+Z (while
        the panel does not type); the left button's drag on the view, where the mouse is
        free: a handle's, else the tool's shape."""
        said = [self.exporter.poll()]
        io = imgui.get_io()
        if self.edits is None:
            return Reply.of(*said)
        scene = shown.scene.loaded.scene
        keys = ()
        if self.weighing is not None:
            if not io.want_capture_keyboard and imgui.is_key_pressed(imgui.Key.escape, False):
                said.append(self.drop_weighing("cancelled"))
                keys = (imgui.Key.escape,)  # Escape cancels here: it does not quit
            else:
                said.append(self._weigh(scene))
        if not io.want_capture_keyboard:
            if imgui.is_key_pressed(imgui.Key.delete, False):
                said.append(self.apply(Operation("delete"), scene))
            if io.key_ctrl and imgui.is_key_pressed(imgui.Key.z, False):
                said.append(self.redo() if io.key_shift else self.undo())
            if io.key_ctrl and imgui.is_key_pressed(imgui.Key.y, False):
                said.append(self.redo())
        took = mouse_free and self.take_mouse(shown, said)
        return Reply.of(*said, took_mouse=took, took_keys=keys)

    def take_mouse(self, shown: Shown, said: list) -> bool:
        """Draws the tool's shape with the left button on the last frame's view; True while
        the mouse is the tool's (the camera leaves the left button alone then). What a
        finished shape selected is said into ``said``."""
        io = imgui.get_io()
        frame = shown.frame
        if self.drag is None:
            took, moved = self.handles.take_mouse(frame, self.box, self.sphere)
            if isinstance(moved, Box):
                self.box = moved
            elif moved is not None:
                self.sphere = moved
            if took:
                return True
        if self.tool == "off" or frame is None:
            self.drag = None
            return False
        x, y = io.mouse_pos.x, io.mouse_pos.y
        finite = math.isfinite(x) and math.isfinite(y) and abs(x) < 1e30 and abs(y) < 1e30
        if self.drag is None:
            if io.want_capture_mouse or not finite or not imgui.is_mouse_clicked(0):
                return False
            self.drag, self._drag_how = [(x, y)], modifier_how(io, self.how)
            return True
        if imgui.is_mouse_down(0):
            last = self.drag[-1]
            if finite and math.hypot(x - last[0], y - last[1]) >= TRACE_STEP:
                self.drag.append((x, y))
            return True
        if finite and (x, y) != self.drag[-1]:
            self.drag.append((x, y))
        points, self.drag = self.drag, None
        said.append(self._select_drawn(points, frame, shown))
        return True

    def _select_drawn(self, points: list[tuple[float, float]], frame: Frame, shown: Shown) -> Message | None:
        """Selects what the shape drawn through screen ``points`` holds: the centres it
        covers; or starts weighing what the view shows under it (the click: its pixel's
        top gaussian), replacing a weighing under way."""
        shape = screen_shape(self.tool, points, frame, self.brush_radius)
        scene = shown.scene
        if shape is None:
            return None
        if self.tool != "click" and self.selects != "visible":
            return self.select(shape, scene.loaded.scene, self._drag_how)
        replaced = self.drop_weighing("replaced by the next shape")
        try:
            self.weighing = start_shown_weighing(
                scene, frame, shape, divider=None if frame.stereo is not None else shown.divider,
                min_weight=None if self.tool == "click" else self.min_weight, how=self._drag_how,
                weigh_on=self.weigh_on,
                slice_seconds=self.slice_seconds or max(MIN_SLICE_SECONDS, shown.frame_seconds))
        except UserError as exc:
            return failed(exc, "nothing selected")
        return replaced

    def overlay(self, frame: Frame, scene: SceneView, pointing: Pointing) -> Reply:
        """The box and the sphere where shown, and the shape being drawn, over the view;
        the selection tinted in the draw to come."""
        if self.edits is not None:
            self.show_selection(scene.renderer)
            self.handles.draw(frame, scene.radius, self.box, self.sphere)
        if self.drag:
            OUTLINES[self.tool](imgui.get_foreground_draw_list(), [imgui.ImVec2(x, y) for x, y in self.drag],
                                imgui.get_color_u32((1.0, 0.85, 0.0, 1.0)), self.brush_radius)
        return NO_REPLY

    def show_selection(self, renderer: GLRenderer) -> None:
        """The selection tinted in ``renderer``'s next draw (uploaded when it changed)."""
        renderer.set_selection(self._state()[0], self.edits.generation.to_bytes(8, "little"))


def screen_shape(tool: Tool, points: list[tuple[float, float]], frame: Frame, brush_radius: float
                 ) -> ScreenShape | None:
    """The shape ``tool`` drew through screen ``points`` on ``frame``'s view, in its
    camera's pixels (in the stereo preview the camera of the eye the shape begins on);
    None where the drag drew nothing (a lasso of fewer than three points) or began off
    the image. ``brush_radius``: in screen units."""
    camera, (vx, vy, vw, vh) = frame.camera, frame.viewport
    scale = imgui.get_io().display_framebuffer_scale
    sx, sy = (scale.x or 1.0), (scale.y or 1.0)
    offset, halves = 0.0, 1
    if frame.stereo is not None:
        found = stereo_image(points[0][0], points[0][1], frame.viewport, (sx, sy), camera, eyes=frame.eyes,
                             layout=frame.stereo.layout)
        if found is None:
            return None
        camera, offset, halves = found
    pixels = tuple(((px * sx - vx) / vw * halves * camera.width - offset, (py * sy - vy) / vh * camera.height)
                   for px, py in points)
    return SHAPES[tool](pixels, camera, brush_radius * sx * halves * camera.width / vw)


def clicked_pixel(pixels: tuple[tuple[float, float], ...], camera: Camera) -> ScreenShape | None:
    """The pixel under a click's release, as the rectangle of its centre (None: off the image)."""
    u, v = math.floor(pixels[-1][0]), math.floor(pixels[-1][1])
    inside = 0 <= u < camera.width and 0 <= v < camera.height
    return ScreenShape("rectangle", camera, ((u, v), (u + 1, v + 1))) if inside else None


#: Each drawing tool's shape from its drag: (the drag's points in the camera's pixels, the
#: camera, the brush's radius in its pixels) -> the shape (None: the drag drew none).
SHAPES: dict[Tool, Callable[[tuple[tuple[float, float], ...], Camera, float], ScreenShape | None]] = {
    "click": lambda pixels, camera, radius: clicked_pixel(pixels, camera),
    "rectangle": lambda pixels, camera, radius: ScreenShape("rectangle", camera, (pixels[0], pixels[-1])),
    "lasso": lambda pixels, camera, radius: ScreenShape("polygon", camera, pixels) if len(pixels) >= 3 else None,
    "brush": lambda pixels, camera, radius: ScreenShape("brush", camera, pixels, radius),
}
#: Each drawing tool's outline of the drag under way: (imgui's draw list, the screen
#: points, the colour, the brush's radius in screen units).
OUTLINES: dict[Tool, Callable[[object, list, int, float], None]] = {
    "rectangle": lambda draw, points, colour, radius: draw.add_rect(points[0], points[-1], colour, 0.0, 1.5),
    "lasso": lambda draw, points, colour, radius: draw.add_polyline(points, colour, 1.5,
                                                                   imgui.ImDrawFlags_.closed.value),
    "brush": lambda draw, points, colour, radius: [draw.add_circle(point, radius, colour, 0, 1.0)
                                                   for point in points],
}
OUTLINES["click"] = OUTLINES["brush"]  # the press under way, ringed as a dab


def axis_values(scene: Scene, attribute: str) -> np.ndarray:
    """(N,) float64: ``attribute`` of ``scene``'s gaussians on the histogram's axis
    (log10 for :data:`LOG_ATTRIBUTES`)."""
    values = attribute_values(scene, attribute)
    if attribute in LOG_ATTRIBUTES:
        with np.errstate(divide="ignore"):
            return np.log10(values)
    return values


def modifier_how(io, default: How) -> How:
    """How a drag combines with the selection: Shift adds, Ctrl subtracts, both intersect."""
    if io.key_shift and io.key_ctrl:
        return "intersect"
    if io.key_shift:
        return "add"
    if io.key_ctrl:
        return "subtract"
    return default
