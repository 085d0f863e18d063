"""The panel's View section: fly or orbit, the world's up axis and where it came from,
the field of view, the fly speed, and resetting the view."""

from __future__ import annotations

from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.camera.navigation import UP_AXES
from raygs_viewer.viewer.panel.widgets import choice, header, note, slider, tooltip

FOV_RANGE = (10.0, 120.0)


def draw_view_section(view, reset_view: Callable[[], None]) -> None:
    """Edits ``view``'s (a view_control.ViewControl) navigation mode, up axis and field
    of view; ``reset_view`` frames the scene again."""
    if not header("View"):
        return
    navigator = view.navigator
    for mode in ("fly", "orbit"):
        if imgui.radio_button(mode, navigator.mode == mode):
            navigator.set_mode(mode)
        imgui.same_line()
    note("(Tab)")
    up = choice("up axis", navigator.up, {axis: axis for axis in UP_AXES})
    if up != navigator.up:
        view.set_up(up)
    note(f"up: {navigator.up} ({view.up_source})")
    fov = slider("field of view", view.lens.fov_y_degrees, *FOV_RANGE, "%.1f deg")
    if fov is not None:
        view.set_fov(min(max(fov, FOV_RANGE[0]), FOV_RANGE[1]))
    note(f"speed {navigator.speed:.3g} units/s")
    tooltip("the mouse wheel changes it in fly mode")
    imgui.same_line()
    if imgui.button("Reset view (R)"):
        reset_view()
