"""What imgui draws over the scene outside the panel: the A/B split view's divider line
and a label on each side, on imgui's background draw list (over the scene, under the
panel)."""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.render.setting_info import setting_parts
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.viewer.state import SplitView

#: (x0, y0, x1, y1) in screen coordinates (imgui's).
Rect = tuple[float, float, float, float]


def describe_settings(settings: RenderSettings) -> str:
    """A short label of the settings that differ from the defaults, e.g. "RayGS + MIP
    0.1 px², 2×2": each field's ``label`` (render.setting_info), so a new setting shows
    up here by itself."""
    parts = setting_parts(settings, "label", changes_only=True)
    return " + ".join(parts[:2]) + "".join(f", {part}" for part in parts[2:])


def draw_split_overlay(viewport: tuple[int, int, int, int], split: SplitView, settings: RenderSettings,
                       grabbed: bool) -> dict[str, Rect]:
    """Draws the divider (bolder while ``grabbed``) and the labels "A: <settings>" and
    "B: <preset>"; returns where each was drawn ("divider", "left label", "right label")."""
    io = imgui.get_io()
    scale = io.display_framebuffer_scale
    sx, sy = (scale.x or 1.0), (scale.y or 1.0)
    vx, vy, vw, vh = viewport
    draw = imgui.get_background_draw_list()
    divider = (vx + split.column(vw)) / sx
    top, bottom = vy / sy, (vy + vh) / sy
    draw.add_line((divider, top), (divider, bottom), imgui.IM_COL32(255, 255, 255, 255 if grabbed else 200),
                  2.0 if grabbed else 1.0)
    rects = {"divider": (divider - 2.0, top, divider + 2.0, bottom)}
    labels = {"left label": f"A: {describe_settings(settings)}", "right label": f"B: {split.preset}"}
    pad = 4.0
    for name, text in labels.items():
        size = imgui.calc_text_size(text)
        width = size.x + 2 * pad
        if name == "left label":  # beside the divider, kept inside the image
            x0 = max(divider - 8.0 - width, vx / sx + 4.0)
        else:
            x0 = min(divider + 8.0, (vx + vw) / sx - 4.0 - width)
        y0 = top + 8.0
        rect = (x0, y0, x0 + width, y0 + size.y + 2 * pad)
        draw.add_rect_filled(rect[:2], rect[2:], imgui.IM_COL32(0, 0, 0, 160), 3.0)
        draw.add_text((x0 + pad, y0 + pad), imgui.IM_COL32(255, 255, 255, 255), text)
        rects[name] = rect
    return rects
