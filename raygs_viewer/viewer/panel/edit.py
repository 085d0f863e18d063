"""The panel's Edit section: the selection tool, the box and the sphere, the histograms,
the selection's and the deletions' counts, delete / undelete / crop / undo / redo, and
the export. It edits the :class:`~raygs_viewer.viewer.edit_tool.EditTool` only through
its methods and fields, and returns what the tool said."""

from __future__ import annotations

import math

from imgui_bundle import imgui

from raygs_viewer.scene.edits import Operation
from raygs_viewer.scene.filters import CropBox, CropSphere
from raygs_viewer.scene.selection import ATTRIBUTES, Box, Sphere
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.scene.model import Scene
from raygs_viewer.viewer.edit_tool import LOG_ATTRIBUTES, TOOLS, EditTool
from raygs_viewer.viewer.panel.widgets import button, choice, header, line, note, tooltip
from raygs_viewer.viewer.part import Reply
from raygs_viewer.viewer.state import Message

TOOL_LABELS = {tool: tool for tool in TOOLS}
SELECTS_LABELS = {"through": "centres inside (through)", "visible": "what the view shows"}
HOW_LABELS = {"set": "set", "add": "add", "subtract": "subtract", "intersect": "intersect"}
HISTOGRAM_HEIGHT = 60.0


def draw_edit_section(tool: EditTool, loaded: LoadedScene) -> Reply:
    """The section, for the scene ``loaded`` the tool edits."""
    if not header("Edit", open_first=False) or tool.edits is None:
        return Reply()
    edits, scene, said = tool.edits, loaded.scene, []
    line(f"{tool.selection_count():,} selected, {tool.deleted_count():,} deleted of {edits.count:,}")
    said.append(_weighing(tool))
    tool.tool = choice("tool##edit", tool.tool, TOOL_LABELS)
    tooltip("a left drag on the view selects with the shape it draws, a click the gaussian its pixel shows "
            "most (Shift adds, Ctrl subtracts, both intersect); the camera turns again with the tool off")
    tool.how = choice("combine##edit", tool.how, HOW_LABELS)
    if tool.tool in ("rectangle", "lasso", "brush"):
        tool.selects = choice("selects##edit", tool.selects, SELECTS_LABELS)
        tooltip("through: every centre inside, hidden ones too; what the view shows: the gaussians giving at "
                "least the weight below of some pixel's colour under the shape, in the order the view composites")
        if tool.selects == "visible":
            changed, weight = imgui.slider_float("least weight##edit", tool.min_weight, 0.001, 1.0, "%.3f",
                                                 imgui.SliderFlags_.logarithmic.value)
            if changed and math.isfinite(weight):
                tool.min_weight = min(1.0, max(0.001, weight))
    if tool.tool == "brush":
        changed, radius = imgui.slider_float("brush radius##edit", tool.brush_radius, 2.0, 200.0, "%.0f px")
        if changed and math.isfinite(radius):
            tool.brush_radius = radius
    for label, op in (("All", "select all"), ("None", "select none"), ("Invert", "invert")):
        if imgui.button(f"{label}##select"):
            said.append(tool.apply(Operation(op), scene))
        imgui.same_line()
    note("")
    if button("Delete##edit", tool.selection_count() > 0):
        said.append(tool.apply(Operation("delete"), scene))
    imgui.same_line()
    if button("Undelete all##edit", tool.deleted_count() > 0):
        said.append(tool.apply(Operation("undelete all"), scene))
    imgui.same_line()
    if button("Undo##edit", edits.can_undo()):
        said.append(tool.undo())
    imgui.same_line()
    if button("Redo##edit", edits.can_redo()):
        said.append(tool.redo())
    said += [_volume(tool, scene), _histogram(tool, scene), _export(tool, loaded)]
    return Reply.of(*said)


def _weighing(tool: EditTool) -> Message | None:
    """What the view shows being weighed: how far, on what, and Cancel (Escape does the same)."""
    weighing = tool.weighing
    if weighing is None:
        return None
    imgui.progress_bar(weighing.progress, imgui.ImVec2(-80.0, 0.0),
                       f"weighing what the view shows: {weighing.progress:.0%}")
    imgui.same_line()
    cancelled = imgui.button("Cancel##weighing")
    tooltip(f"weighed on the {weighing.where}, a slice a frame; Escape or Cancel drops it, nothing changed")
    return tool.drop_weighing("cancelled") if cancelled else None


def _corner(label: str, values: tuple[float, float, float]) -> tuple[float, float, float] | None:
    changed, new = imgui.input_float3(label, list(values), "%.4g")
    return tuple(float(v) for v in new) if changed and all(math.isfinite(v) for v in new) else None


def _volume(tool: EditTool, scene: Scene) -> tuple:
    """The box and the sphere: their numbers, select inside, crop to them."""
    said = []
    imgui.separator_text("box")
    _, tool.handles.show_box = imgui.checkbox("show in the view##box", tool.handles.show_box)
    tooltip("the box's edges over the view; drag its centre dot to move it, a face's dot to move that face")
    low, high = _corner("low##box", tool.box.low), _corner("high##box", tool.box.high)
    if low is not None or high is not None:
        try:
            box = CropBox(low or tool.box.low, high or tool.box.high)
            tool.box = Box(box.low, box.high)
        except ValueError as exc:
            note(str(exc))
    if imgui.button("Select in box"):
        said.append(tool.select(tool.box, scene))
    imgui.same_line()
    if imgui.button("Crop to box"):
        said.append(tool.apply(Operation("crop", tool.box), scene))
    imgui.separator_text("sphere")
    _, tool.handles.show_sphere = imgui.checkbox("show in the view##sphere", tool.handles.show_sphere)
    tooltip("the sphere over the view; drag its centre dot to move it, the dot on its rim to set the radius")
    centre = _corner("centre##sphere", tool.sphere.centre)
    changed, radius = imgui.input_float("radius##sphere", tool.sphere.radius, 0.0, 0.0, "%.4g")
    if centre is not None or (changed and math.isfinite(radius) and radius >= 0):
        sphere = CropSphere(centre or tool.sphere.centre, radius if changed else tool.sphere.radius)
        tool.sphere = Sphere(sphere.centre, sphere.radius)
    if imgui.button("Select in sphere"):
        said.append(tool.select(tool.sphere, scene))
    imgui.same_line()
    if imgui.button("Crop to sphere"):
        said.append(tool.apply(Operation("crop", tool.sphere), scene))
    return tuple(message for message in said if message is not None)


def _histogram(tool: EditTool, scene: Scene) -> Message | None:
    """The attribute's histogram of what is not deleted; a drag across it selects that range."""
    imgui.separator_text("splat data")
    tool.attribute = choice("attribute##edit", tool.attribute, {a: a for a in ATTRIBUTES})
    counts, edges = tool.histogram(scene, tool.attribute)
    # Bars drawn over a button: the button holds the drag (a drag on bare panel moves it).
    imgui.invisible_button("##histogram", (max(imgui.get_content_region_avail().x, 1.0), HISTOGRAM_HEIGHT))
    low, high = imgui.get_item_rect_min(), imgui.get_item_rect_max()
    activated, active = imgui.is_item_activated(), imgui.is_item_active()
    draw = imgui.get_window_draw_list()
    draw.add_rect_filled(low, high, imgui.get_color_u32(imgui.Col_.frame_bg))
    step, tallest = (high.x - low.x) / len(counts), max(float(counts.max()), 1.0)
    for index, count in enumerate(counts):
        top = high.y - (high.y - low.y) * float(count) / tallest
        draw.add_rect_filled(imgui.ImVec2(low.x + index * step, top), imgui.ImVec2(low.x + (index + 1) * step - 1, high.y),
                             imgui.get_color_u32(imgui.Col_.plot_histogram))
    axis = "log10 " if tool.attribute in LOG_ATTRIBUTES else ""
    note(f"{axis}{edges[0]:.4g} .. {edges[-1]:.4g}: drag across to select")

    def value(x: float) -> float:
        fraction = min(max((x - low.x) / max(high.x - low.x, 1.0), 0.0), 1.0)
        return float(edges[0] + fraction * (edges[-1] - edges[0]))

    x = imgui.get_io().mouse_pos.x
    if activated:
        tool.histogram_drag = x
    start = tool.histogram_drag
    if start is None:
        return None
    draw.add_rect_filled(imgui.ImVec2(min(start, x), low.y), imgui.ImVec2(max(start, x), high.y),
                         imgui.get_color_u32((1.0, 0.85, 0.0, 0.35)))
    if active:
        return None
    tool.histogram_drag = None
    return tool.select_range(scene, tool.attribute, value(start), value(x))


def _export(tool: EditTool, loaded: LoadedScene) -> tuple:
    imgui.separator_text("export")
    imgui.set_next_item_width(-70)
    export = tool.exporter
    _, export.file = imgui.input_text_with_hint("##export file", "clean.ply (.splat, .spz, .sog)", export.file)
    imgui.same_line()
    said = ()
    if button("Export", export.writing is None):
        said = export.export(tool.edits, loaded)
    tooltip("the gaussians not deleted, in their order (a PLY's rows as the file has them), and the edits "
            "beside them as NAME.edits.json")
    if export.confirm_replace is not None:
        there = " and ".join(export.existing)
        note(f"{there} {'exist' if len(export.existing) > 1 else 'exists'}: replace {'them' if len(export.existing) > 1 else 'it'}?")
        if imgui.button("Replace##export"):
            said = export.export(tool.edits, loaded, replace=True)
        imgui.same_line()
        if imgui.button("Cancel##export"):
            export.confirm_replace = None
    return said

