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
"""

from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.capture.edit_file import EditDocument, edit_document_json
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.scene.edits import Edits, Operation
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.selection import ATTRIBUTES, Box, Range, ScreenShape, Sphere, attribute_values
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.viewer.edit_export import EditExport
from raygs_viewer.viewer.view_selection import shown_rows
from raygs_viewer.viewer.volume_handles import VolumeHandles

#: The tools the left button draws with ("off": it turns the camera; "click": the gaussian
#: the clicked pixel shows most).
TOOLS = ("off", "click", "rectangle", "lasso", "brush")
#: Histogram bins.
BINS = 64
#: Attributes shown on a log10 axis (they span decades).
LOG_ATTRIBUTES = ("largest scale", "volume")
#: A dragged point is kept when it is this far (screen units) from the last one.
TRACE_STEP = 2.0


class EditTool:
    """The edits of the scene the window shows (``host``: the viewer, ``app.Viewer``)."""

    def __init__(self, host) -> None:
        self.host = host
        self.tool = "off"
        self.how = "set"
        self.brush_radius = 20.0   # screen units
        self.selects = "through"   # or "visible": the gaussians a shape's pixels show, not the centres it covers
        self.min_weight = 0.05     # the least share of a pixel's colour "visible" selects
        self.attribute = ATTRIBUTES[0]
        self.exporter = EditExport(self)
        self.handles = VolumeHandles(self)
        self.edits: Edits | None = None
        self.box: Box | None = None
        self.sphere: Sphere | None = None
        self.drag: list[tuple[float, float]] | None = None   # screen points of the shape being drawn
        self.histogram_drag: float | None = None   # where a drag across the histogram began (screen x)
        self._drag_how = "set"
        self._deleted_rows: tuple[int, DeletedRows | None] = (-1, None)
        self._histogram: tuple[int, str, np.ndarray, np.ndarray] | None = None
        self._counted: tuple | None = None

    # -- the scene --------------------------------------------------------------------
    def opened(self, scene: Scene) -> None:
        """A new scene: no edits, the box and the sphere around its centres."""
        self.edits = Edits(scene.count)
        self.drag, self._histogram, self._counted, self.exporter.confirm_replace = None, None, None, None
        self.handles.drag, self.exporter.exported = None, None
        positions = scene.positions.astype(np.float64)
        if scene.count:
            low, high = positions.min(axis=0), positions.max(axis=0)
            centre = np.median(positions, axis=0)
            radius = float(np.linalg.norm(positions - centre, axis=1).max())
        else:
            low, high, centre, radius = np.zeros(3), np.zeros(3), np.zeros(3), 0.0
        self.box = Box(tuple(low.tolist()), tuple(high.tolist()))
        self.sphere = Sphere(tuple(centre.tolist()), radius)

    def grown(self, scene: Scene) -> None:
        """A streamed SOG's next level added rows after those read: they start unedited."""
        if self.edits is not None and scene.count != self.edits.count:
            old = self.edits
            self.edits = Edits(scene.count)
            self.edits.selected[: old.count], self.edits.deleted[: old.count] = old.selected, old.deleted
            self.edits.operations = list(old.operations)
            self._histogram = self._counted = None

    @property
    def scene(self) -> Scene:
        return self.host.loaded.scene

    @property
    def deleted(self) -> DeletedRows | None:
        """The deleted rows, as every sort of the window leaves them out (made once an edit)."""
        if self.edits is None:
            return None
        generation, deleted = self._deleted_rows
        if generation != self.edits.generation:
            deleted = DeletedRows.of(self.edits.deleted)
            self._deleted_rows = (self.edits.generation, deleted)
        return deleted

    def _state(self) -> tuple[np.ndarray, int, int]:
        """(the selection shown, its count, the count deleted), made once an edit: the
        panel and the draw read them every frame."""
        key = (id(self.edits), self.edits.generation)
        if self._counted is None or self._counted[0] != key:
            selection = self.edits.selection
            self._counted = (key, selection, int(selection.sum()), int(self.edits.deleted.sum()))
        return self._counted[1:]

    def selection_count(self) -> int:
        return 0 if self.edits is None else self._state()[1]

    def deleted_count(self) -> int:
        return 0 if self.edits is None else self._state()[2]

    def show_selection(self, renderer) -> None:
        """The selection tinted in the next draw (uploaded when it changed)."""
        if self.edits is not None:
            renderer.set_selection(self._state()[0], self.edits.generation.to_bytes(8, "little") +
                                   id(self.edits).to_bytes(8, "little"))

    # -- edits ------------------------------------------------------------------------
    def apply(self, operation: Operation) -> bool:
        """Applies ``operation``; says what it did on the message line."""
        if self.edits is None:
            return False
        try:
            changed = self.edits.apply(self.scene, operation)
        except ValueError as exc:
            self.host.panel.error = f"error: {operation.op}: {one_line(exc)}"
            return False
        self.host.panel.note(f"{operation.op}: {self.selection_count():,} selected, {self.deleted_count():,} deleted"
                             if changed else f"{operation.op}: nothing changed")
        return changed

    def select(self, shape, how: str | None = None) -> bool:
        return self.apply(Operation("select", shape, how or self.how))

    def undo(self) -> None:
        if self.edits is not None and self.edits.undo():
            self.host.panel.note(f"undone: {self.selection_count():,} selected, {self.deleted_count():,} deleted")

    def redo(self) -> None:
        if self.edits is not None and self.edits.redo():
            self.host.panel.note(f"redone: {self.selection_count():,} selected, {self.deleted_count():,} deleted")

    def histogram(self, attribute: str) -> tuple[np.ndarray, np.ndarray]:
        """(BINS,) float32 counts of the gaussians not deleted, and the BINS + 1 edges (in
        log10 for :data:`LOG_ATTRIBUTES`), made once an edit and attribute."""
        key = (self.edits.generation, attribute)
        if self._histogram is None or self._histogram[:2] != key:
            values = self.axis_values(attribute)[self.edits.kept]
            values = values[np.isfinite(values)]
            low, high = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
            counts, edges = np.histogram(values, BINS, (low, high if high > low else low + 1.0))
            self._histogram = (*key, counts.astype(np.float32), edges)
        return self._histogram[2], self._histogram[3]

    def axis_values(self, attribute: str) -> np.ndarray:
        values = attribute_values(self.scene, attribute)
        if attribute in LOG_ATTRIBUTES:
            with np.errstate(divide="ignore"):
                return np.log10(values)
        return values

    def select_range(self, attribute: str, low: float, high: float, how: str | None = None) -> bool:
        """Selects ``attribute`` in ``low``..``high`` on the histogram's axis (log10 for
        :data:`LOG_ATTRIBUTES`)."""
        low, high = min(low, high), max(low, high)
        if attribute in LOG_ATTRIBUTES:
            low, high = 10.0 ** low, 10.0 ** high
        return self.select(Range(attribute, low, high), how)

    def sidecar_entry(self) -> dict | None:
        """What a screenshot's sidecar records of the edits: the edit document, where a
        gaussian is deleted (a selection alone changes no screenshot); None otherwise."""
        if self.edits is None or not self.edits.edited:
            return None
        return edit_document_json(self.document())

    def document(self) -> EditDocument:
        loaded = self.host.loaded
        return EditDocument(SceneSource(loaded.path).recorded_path, loaded.content_sha256, self.edits.count,
                            tuple(self.edits.operations))

    # -- input ------------------------------------------------------------------------
    def take_mouse(self, frame) -> bool:
        """Draws the tool's shape with the left button on ``frame``'s view; True while the
        mouse is the tool's (the camera leaves the left button alone then)."""
        io = imgui.get_io()
        if self.edits is not None and self.drag is None and self.handles.take_mouse(frame):
            return True
        if self.tool == "off" or frame is None or frame.stereo is not None or self.edits is None:
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
        shape = self.screen_shape(points, frame)
        if shape is not None and (self.tool == "click" or self.selects == "visible"):
            try:
                shape = shown_rows(self.scene, self.host.scene.direct_sorter, frame, shape, self.deleted,
                                   None if self.tool == "click" else self.min_weight)
            except UserError as exc:
                self.host.panel.error, shape = f"error: nothing selected: {one_line(exc)}", None
            else:
                if shape is None:
                    self.host.panel.note("nothing selected: no gaussian shows at that pixel")
        if shape is not None:
            self.select(shape, self._drag_how)
        return True

    def screen_shape(self, points: list[tuple[float, float]], frame) -> ScreenShape | None:
        """The shape drawn through screen ``points`` on ``frame``'s view, in its camera's
        pixels; None where the drag drew nothing (a lasso of fewer than three points)."""
        camera, (vx, vy, vw, vh) = frame.camera, frame.viewport
        scale = imgui.get_io().display_framebuffer_scale
        sx, sy = (scale.x or 1.0), (scale.y or 1.0)
        pixels = tuple(((px * sx - vx) / vw * camera.width, (py * sy - vy) / vh * camera.height)
                       for px, py in points)
        if self.tool == "click":  # the pixel under the release, as the rectangle of its centre
            u, v = math.floor(pixels[-1][0]), math.floor(pixels[-1][1])
            inside = 0 <= u < camera.width and 0 <= v < camera.height
            return ScreenShape("rectangle", camera, ((u, v), (u + 1, v + 1))) if inside else None
        if self.tool == "rectangle":
            return ScreenShape("rectangle", camera, (pixels[0], pixels[-1]))
        if self.tool == "lasso":
            return ScreenShape("polygon", camera, pixels) if len(pixels) >= 3 else None
        return ScreenShape("brush", camera, pixels, self.brush_radius * sx * camera.width / vw)

    def frame(self) -> None:
        """Each frame: a finished export said, and the keys Delete, Ctrl+Z, Ctrl+Y and
        Ctrl+Shift+Z (while the panel does not type)."""
        self.exporter.poll()
        io = imgui.get_io()
        if io.want_capture_keyboard or self.edits is None:
            return
        if imgui.is_key_pressed(imgui.Key.delete, False):
            self.apply(Operation("delete"))
        if io.key_ctrl and imgui.is_key_pressed(imgui.Key.z, False):
            self.redo() if io.key_shift else self.undo()
        if io.key_ctrl and imgui.is_key_pressed(imgui.Key.y, False):
            self.redo()

    def draw_overlay(self, frame, radius: float) -> None:
        """The box and the sphere where shown, and the shape being drawn, over the view."""
        self.handles.draw(frame, radius)
        if not self.drag:
            return
        draw = imgui.get_foreground_draw_list()
        colour = imgui.get_color_u32((1.0, 0.85, 0.0, 1.0))
        points = [imgui.ImVec2(x, y) for x, y in self.drag]
        if self.tool == "rectangle":
            draw.add_rect(points[0], points[-1], colour, 0.0, 1.5)
        elif self.tool == "lasso":
            draw.add_polyline(points, colour, 1.5, imgui.ImDrawFlags_.closed.value)
        else:
            for point in points:
                draw.add_circle(point, self.brush_radius, colour, 0, 1.0)


def modifier_how(io, default: str) -> str:
    """How a drag combines with the selection: Shift adds, Ctrl subtracts, both intersect."""
    if io.key_shift and io.key_ctrl:
        return "intersect"
    if io.key_shift:
        return "add"
    if io.key_ctrl:
        return "subtract"
    return default
