"""The panel's View section: fly or orbit, the world's up axis and where it came from,
the field of view, the fly speed, and resetting the view."""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.camera.navigation import UP_AXES
from raygs_viewer.viewer.panel.widgets import choice, header, note, slider, tooltip
from raygs_viewer.viewer.part import Press, Reply
from raygs_viewer.viewer.view_control import ViewControl

FOV_RANGE = (10.0, 120.0)


def draw_view_section(view: ViewControl) -> Reply:
    """Edits ``view``'s navigation mode, up axis and field of view; Reset view does what R
    does (frames the scene again)."""
    if not header("View"):
        return Reply()
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
    return Reply.of(Press("reset_view")) if imgui.button("Reset view (R)") else Reply()
