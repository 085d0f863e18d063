"""The panel's View section: fly or orbit, the world's up axis, the field of view, the
fly speed, and resetting the view."""

from __future__ import annotations

from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.camera.navigation import UP_AXES, Navigator
from raygs_viewer.viewer.panel.widgets import header, slider, tooltip

FOV_RANGE = (10.0, 120.0)


def draw_view_section(navigator: Navigator, fov_y_degrees: float, set_fov: Callable[[float], None],
                      reset_view: Callable[[], None]) -> None:
    """Edits ``navigator``'s mode and up axis; ``set_fov`` takes a new vertical field of
    view (degrees), ``reset_view`` frames the scene again."""
    if not header("View"):
        return
    for mode in ("fly", "orbit"):
        if imgui.radio_button(mode, navigator.mode == mode):
            navigator.set_mode(mode)
        imgui.same_line()
    imgui.text_disabled("(Tab)")
    axes = list(UP_AXES)
    changed, index = imgui.combo("up axis", axes.index(navigator.up), axes)
    if changed:
        navigator.set_up(axes[index])
    fov = slider("field of view", fov_y_degrees, *FOV_RANGE, "%.1f deg")
    if fov is not None:
        set_fov(min(max(fov, FOV_RANGE[0]), FOV_RANGE[1]))
    imgui.text_disabled(f"speed {navigator.speed:.3g} units/s")
    tooltip("the mouse wheel changes it in fly mode")
    imgui.same_line()
    if imgui.button("Reset view (R)"):
        reset_view()
