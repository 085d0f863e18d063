"""The panel's Order section: how each pixel orders its gaussians (depth, distance or
per pixel, and per pixel's window K), then what the per-pixel order did in the last
redraw: fragments per covered pixel, the pool's use, the parts drawn, the path.

Per-pixel order needs a RayGS mode (EWA splats have no ray parameter to sort by). In
GS mode its entry is greyed out; choosing GS in the Render section while the order is
per pixel keeps GS and switches the order to the global one per-pixel order is fed
in (``RenderSettings.sort_key``: depth), and the panel says so (:func:`with_mode`):
the user asked for GS, and gets it with the nearest order it can draw.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.render.setting_info import setting_field
from raygs_viewer.render.settings import (
    MAX_ORDER_K,
    ORDER_LABELS,
    ORDERS,
    RenderSettings,
)
from raygs_viewer.viewer.panel.widgets import choice, header, line, note, tooltip
from raygs_viewer.viewer.stats import FrameStats, order_stats_lines

PER_PIXEL_NEEDS_RAYGS = "per pixel needs a RayGS mode: EWA splats have no ray parameter to sort by"
ORDER_K = setting_field(RenderSettings, "order_k").info


def gs_fallback_note(order: str) -> str:
    return f"GS (EWA) has no per-pixel order: the order is now {ORDER_LABELS[order]}"


ORDER_HELP = ("depth: one global back-to-front sort by the centres' view depth (the paper's).\n"
              "distance: one global sort by the centres' distance from the camera; turning in place\n"
              "  needs no new sort.\n"
              "per pixel: each pixel composites its own gaussians front to back by where its ray\n"
              "  meets them (t*): no popping where gaussians overlap, at a cost in time and memory.\n"
              "  RayGS modes only.")
K_HELP = ("0: every fragment of a pixel is kept and sorted (exact).\n"
          f"1..{MAX_ORDER_K}: fragments arrive in the global depth order and a window of K per pixel\n"
          "re-orders them (a k-buffer): bounded memory, exact where at most K overlap out of order;\n"
          "whether it is faster depends on the GPU (docs/ordering.md).")


def with_mode(settings: RenderSettings, mode: str) -> tuple[RenderSettings, str]:
    """``settings`` in render ``mode``, and what the panel should say about it ("" for
    nothing): GS has no per-pixel order, so per pixel becomes the global order it is
    fed in (``sort_key``)."""
    if mode == "gs" and settings.per_pixel:
        order = settings.sort_key
        return replace(settings, mode=mode, order=order), gs_fallback_note(order)
    return replace(settings, mode=mode), ""


def draw_order_section(settings: RenderSettings, set_settings: Callable[[RenderSettings], None],
                       stats: FrameStats, split_shown: bool) -> None:
    """``set_settings`` receives the edited settings (when an edit changed them);
    ``stats``: the per-pixel order's statistics of the last redraw; ``split_shown``:
    whether the split view is shown (its sides' statistics are labelled)."""
    if not header("Order"):
        return
    gs = settings.mode == "gs"
    order = choice("order", settings.order, {name: ORDER_LABELS[name] for name in ORDERS},
                   {"per-pixel": PER_PIXEL_NEEDS_RAYGS} if gs else None)
    tooltip(ORDER_HELP)
    edited = replace(settings, order=order)
    if edited.per_pixel:
        k = edited.order_k
        changed, k = imgui.slider_int("K (window)", k, *ORDER_K.limits, ORDER_K.words.get(k, "%d per pixel"))
        tooltip(K_HELP)
        if changed:
            edited = replace(edited, order_k=ORDER_K.clamp(int(k)))
    elif gs:
        note("(per pixel needs a RayGS mode)")
    if edited != settings:
        set_settings(edited)
    _statistics(stats, split_shown)


def _statistics(stats: FrameStats, split_shown: bool) -> None:
    """Each per-pixel side's statistics, labelled by side in the split view."""
    left, right = stats.order_stats
    sides = [(name, side) for name, side in (("left", left), ("right", right)) if side is not None]
    for name, side in sides:
        if split_shown:
            line(f"{name} side:")
        for text in order_stats_lines(side):
            note(text)
