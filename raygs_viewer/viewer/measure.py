"""The window's measure tool as one widget (:class:`MeasureWidget`): while it is on, each
click on the view picks a point (its pixel's median depth, :mod:`.picking`) and every
second point closes a measurement; the measurements are kept, listed and deleted in the
panel's Measure section, drawn over the view, converted by a scale set from one known
length, and saved to and loaded from a measurements file
(:mod:`raygs_viewer.capture.measure_file`).

The lines are drawn like the camera path (:mod:`.path_overlay`): on imgui's background
draw list, so never in a screenshot, cut at a near plane in front of the camera (a
measurement partly behind the camera is drawn up to where it passes the near plane,
not wrapped through infinity) and cut to the view.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.capture.measure_file import (
    MeasureDocument,
    MeasureScale,
    Measurement,
    check_unit,
    convert,
    load_measure_document,
    measure_scene_mismatch,
    save_measure_document,
)
from raygs_viewer.errors import UserError
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.path_overlay import project_points, screen_segments, viewport_rect
from raygs_viewer.viewer.path_widget import OVERLAY_NEAR, scene_argument
from raygs_viewer.viewer.part import NO_REPLY, Part, Pointing, Reply, SceneView
from raygs_viewer.viewer.picking import Picked
from raygs_viewer.viewer.state import Message, done, failed, note, saved

LINE_COLOUR = (255, 120, 40, 240)
POINT_COLOUR = (255, 230, 60, 255)
LABEL_BACKGROUND = (0, 0, 0, 170)


@dataclass(frozen=True)
class DrawnMeasure:
    """What the overlay drew last frame, for tests: the screen segment of each
    measurement with a visible part (measurement index -> ((x0, y0), (x1, y1))), and
    the first point of the measurement under way where it is visible."""

    lines: dict[int, tuple[tuple[float, float], tuple[float, float]]] = field(default_factory=dict)
    pending: tuple[float, float] | None = None


def format_distance(distance: float, scale: MeasureScale | None) -> str:
    """A distance in scene units as the panel shows it: "1.234 m", or "0.5 units"."""
    value, unit = convert(distance, scale)
    return f"{value:.4g} {unit}"


class MeasureWidget(Part):
    """``on``: clicks on the view measure; ``measurements``, the ``selected`` one (None:
    none) and ``pending``: the first point of the next one. ``scale``: None shows scene
    units. The panel's fields: ``known_length`` and ``unit`` (what Set scale makes the
    selected measurement), ``file`` and ``overwrite`` (Save may replace it). ``drawn``:
    the overlay as drawn last frame. Each action returns what the panel says of it."""

    def __init__(self) -> None:
        self.on = False
        self.measurements: list[Measurement] = []
        self.selected: int | None = None
        self.pending: Picked | None = None
        self.scale: MeasureScale | None = None
        self.known_length = 1.0
        self.unit = "m"
        self.file = "measurements.json"
        self.overwrite = False
        self.drawn = DrawnMeasure()

    # -- points and measurements ------------------------------------------------------------
    def add_point(self, picked: Picked) -> Message | None:
        """The first point of a measurement, or its second (which closes it and selects
        it). A second point equal to the first is ignored: the two clicks of a
        double-click are one point, not a measurement of length 0."""
        first = self.pending
        if first is None:
            self.pending = picked
            return note("first point picked: click the second")
        if np.array_equal(first.point, picked.point):
            return None
        self.pending = None
        self.measurements.append(Measurement(first.point, picked.point))
        self.selected = len(self.measurements) - 1
        return note(f"measurement {self.selected}: {self.describe(self.selected)}")

    def describe(self, index: int) -> str:
        return format_distance(self.measurements[index].distance, self.scale)

    def delete(self, index: int) -> None:
        """Removes measurement ``index``; the scale stays (its factor was set from it), no
        longer naming it."""
        del self.measurements[index]
        if self.scale is not None and self.scale.reference is not None:
            reference = self.scale.reference
            moved = None if reference == index else reference - (reference > index)
            self.scale = MeasureScale(self.scale.factor, self.scale.unit, moved)
        if self.selected is not None:
            self.selected = None if not self.measurements else min(self.selected, len(self.measurements) - 1)

    def clear(self) -> None:
        self.measurements, self.selected, self.pending = [], None, None
        if self.scale is not None:
            self.scale = MeasureScale(self.scale.factor, self.scale.unit)

    # -- the scale ---------------------------------------------------------------------
    def set_scale(self, index: int) -> Message:
        """Measurement ``index`` is ``known_length`` ``unit``s long: every distance is
        shown converted from now on."""
        try:
            self.scale = MeasureScale.from_length(self.measurements[index], float(self.known_length), self.unit, index)
        except UserError as exc:
            return failed(exc, "scale not set")
        return done(f"scale: 1 scene unit = {self.scale.factor:.6g} {self.scale.unit}")

    def set_unit(self, unit: str) -> None:
        """The unit text; a scale already set keeps its factor and takes the new name."""
        self.unit = unit
        if self.scale is not None:
            try:
                self.scale = MeasureScale(self.scale.factor, check_unit(unit), self.scale.reference)
            except UserError:
                pass  # an empty field while typing: the scale keeps its last unit

    def clear_scale(self) -> None:
        self.scale = None

    # -- files -------------------------------------------------------------------------
    def document(self, loaded: LoadedScene) -> MeasureDocument:
        """The measurements of the scene ``loaded``, as a file records them."""
        return MeasureDocument(tuple(self.measurements), self.scale, scene_argument(loaded), loaded.content_sha256)

    def save(self, loaded: LoadedScene) -> Message:
        return saved("measurements", lambda: save_measure_document(self.document(loaded), self.file, self.overwrite))

    def load(self, loaded: LoadedScene) -> Message:
        """The file's measurements and scale replace these; a file measured on another
        scene than ``loaded`` loads with a warning."""
        try:
            document = load_measure_document(self.file)
        except UserError as exc:
            return failed(exc, "measurements not loaded")
        self.measurements, self.scale, self.pending = list(document.measurements), document.scale, None
        self.selected = None
        if self.scale is not None:
            self.unit = self.scale.unit
        warning = measure_scene_mismatch(document, scene_argument(loaded), loaded.content_sha256)
        return done("; ".join(filter(None, [f"loaded {self.file}: {len(self.measurements)} measurements", warning])))

    # -- the overlay -------------------------------------------------------------------
    def overlay(self, frame: Frame, scene: SceneView, pointing: Pointing) -> Reply:
        """The measurements over ``frame``'s view, each labelled with its distance; not in
        the stereo preview, whose image shows two eyes rather than the frame's camera's view."""
        if frame.stereo is not None or not (self.measurements or self.pending):
            self.drawn = DrawnMeasure()
        else:
            self.drawn = draw_measure_overlay(self, frame.camera, frame.viewport, OVERLAY_NEAR * scene.radius)
        return NO_REPLY


def draw_measure_overlay(widget: MeasureWidget, camera: Camera, viewport: tuple[int, int, int, int],
                         near: float) -> DrawnMeasure:
    scale = imgui.get_io().display_framebuffer_scale
    rect = viewport_rect(viewport, (scale.x or 1.0, scale.y or 1.0))
    draw = imgui.get_background_draw_list()
    lines = {}
    for index, measurement in enumerate(widget.measurements):
        segments = screen_segments(camera, measurement.a[None], measurement.b[None], rect, near)
        if not len(segments):
            continue
        (x0, y0), (x1, y1) = (tuple(float(c) for c in end) for end in segments[0])
        lines[index] = ((x0, y0), (x1, y1))
        chosen = index == widget.selected
        draw.add_line((x0, y0), (x1, y1), imgui.IM_COL32(*LINE_COLOUR), 3.0 if chosen else 2.0)
        _label(draw, ((x0 + x1) / 2, (y0 + y1) / 2), f"{index}: {widget.describe(index)}")
    pending = None
    if widget.pending is not None:
        depth = (camera.R @ widget.pending.point + camera.t)[2]
        x, y = project_points(camera, widget.pending.point, rect)[0]
        if depth >= near and rect[0] <= x <= rect[2] and rect[1] <= y <= rect[3]:
            pending = (float(x), float(y))
            draw.add_circle_filled(pending, 4.0, imgui.IM_COL32(*POINT_COLOUR))
    return DrawnMeasure(lines, pending)


def _label(draw, at: tuple[float, float], text: str) -> None:
    size = imgui.calc_text_size(text)
    x, y = at[0] + 6.0, at[1] - size.y - 6.0
    draw.add_rect_filled((x - 3, y - 2), (x + size.x + 3, y + size.y + 2), imgui.IM_COL32(*LABEL_BACKGROUND), 3.0)
    draw.add_text((x, y), imgui.IM_COL32(255, 255, 255, 255), text)
