"""The panel's Measure section: the measure tool's switch, the measurements (select,
delete, clear), the scale from one known length, and the measurements' file.

It draws the :class:`~raygs_viewer.viewer.measure.MeasureWidget` and edits it only
through the widget's methods and its form fields; it returns what the widget said.
"""

from __future__ import annotations

import math

from imgui_bundle import imgui

from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.measure import MeasureWidget
from raygs_viewer.viewer.part import Reply
from raygs_viewer.viewer.state import Message
from raygs_viewer.viewer.panel.widgets import button, checkbox, file_row, header, line, note, tooltip

LIST_ROWS = 5


def draw_measure_section(widget: MeasureWidget, loaded: LoadedScene) -> Reply:
    """The section, for the scene ``loaded`` (the measurements' file names it)."""
    if not header("Measure", open_first=False):
        return Reply()
    widget.on = checkbox("measure", widget.on,
                         help_text="click two points on the view for their distance (each point is its pixel's "
                                   "median depth); a double-click does not move the view while this is on")
    if widget.on:
        imgui.same_line()
        note("second point next" if widget.pending is not None else "click a point")
    _list(widget)
    return Reply.of(_scale(widget), *_files(widget, loaded))


def _list(widget: MeasureWidget) -> None:
    count = len(widget.measurements)
    rows = min(max(count, 1), LIST_ROWS)
    if imgui.begin_list_box("##measurements", (-1, rows * imgui.get_text_line_height_with_spacing() + 6)):
        for i in range(count):
            if imgui.selectable(f"{i}: {widget.describe(i)}##measurement{i}", widget.selected == i)[0]:
                widget.selected = i
        if not count:
            note("no measurements: tick measure and click two points")
        imgui.end_list_box()
    if button("Delete##measurement", widget.selected is not None):
        widget.delete(widget.selected)
    imgui.same_line()
    if imgui.button("Clear##measurements"):
        widget.clear()


def _scale(widget: MeasureWidget) -> Message | None:
    imgui.set_next_item_width(90)
    changed, length = imgui.input_float("##known length", widget.known_length, 0.0, 0.0, "%.4g")
    if changed and math.isfinite(length):
        widget.known_length = length
    tooltip("the true length of the selected measurement")
    imgui.same_line()
    imgui.set_next_item_width(60)
    changed, unit = imgui.input_text("unit##measure", widget.unit)
    if changed:
        widget.set_unit(unit)
    imgui.same_line()
    said = None
    if button("Set scale", widget.selected is not None):
        said = widget.set_scale(widget.selected)
    tooltip("the selected measurement is this long: every distance is shown converted")
    scale = widget.scale
    if scale is None:
        note("distances in scene units")
        return said
    source = "" if scale.reference is None else f" (from {scale.reference})"
    line(f"1 scene unit = {scale.factor:.6g} {scale.unit}{source}")
    imgui.same_line()
    if imgui.small_button("no scale"):
        widget.clear_scale()
    return said


def _files(widget: MeasureWidget, loaded: LoadedScene) -> tuple[Message, ...]:
    widget.file, save, load = file_row("measure", widget.file, "measurements.json", bool(widget.measurements))
    said = (widget.save(loaded) if save else None, widget.load(loaded) if load else None)
    widget.overwrite = checkbox("replace file##measure", widget.overwrite,
                                help_text="let Save replace an existing file")
    return tuple(message for message in said if message is not None)
