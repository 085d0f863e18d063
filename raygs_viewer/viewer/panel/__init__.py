"""The imgui panel: one module per section (statistics, scene, level of detail (a
streamed SOG), render, order, stereo, headset, view, training cameras, screenshot,
geometry, camera path, measure), each drawing from
and editing only the state it is given (the path and measure sections: the viewer's
PathWidget and MeasureWidget), and the panel's two message lines under them.

Each section returns what it said and asked for (a ``part.Reply``: messages, and
requests such as opening a scene), which the panel hands back to the window whole; the
state a section edits (the stereo preview, the split view, a part's fields) and the
render settings it edits (through the draft it is handed) are read when the frame is
made, after the panel. Tests find the widgets by their imgui labels (tests/appkit.py
records them): the panel carries no hook for them.
"""

from __future__ import annotations

from typing import Callable, Sequence

from imgui_bundle import imgui

from raygs_viewer.viewer.layout import panel_width_limits
from raygs_viewer.viewer.part import Reply
from raygs_viewer.viewer.state import PanelState


#: The panel's imgui window (the feedback is placed beside it).
PANEL_WINDOW = "raygs-viewer"


def draw_panel(panel: PanelState, sections: Sequence[Callable[[], Reply]]) -> Reply:
    """The panel's window with ``sections`` drawn in order, then ``panel``'s message
    and error lines; returns what the sections said and asked for, in order."""
    # Tab is the fly/orbit key. imgui would also tab into the panel (focused from its
    # first frame): a slider tabbed into turns into a text field that then takes every
    # key, so WASD, R and Tab itself stop reaching the camera.
    imgui.push_item_flag(imgui.ItemFlags_.no_tab_stop.value, True)
    reply = _window(panel, sections)
    imgui.pop_item_flag()
    return reply


def _window(panel: PanelState, sections: Sequence[Callable[[], Reply]]) -> Reply:
    # Down the window's left edge, its whole height (a short window scrolls the panel
    # instead of cutting it off); the user resizes its width, which the view area
    # (layout.view_area) follows from the next frame on.
    display = imgui.get_io().display_size
    narrowest, widest = panel_width_limits(display.x)
    imgui.set_next_window_pos((0, 0), imgui.Cond_.always.value)
    imgui.set_next_window_size((panel.width, display.y), imgui.Cond_.appearing.value)
    imgui.set_next_window_size_constraints((narrowest, display.y), (widest, display.y))
    flags = imgui.WindowFlags_.no_move.value | imgui.WindowFlags_.no_collapse.value
    visible, _ = imgui.begin(PANEL_WINDOW, None, flags)
    panel.width = imgui.get_window_width()
    reply = Reply()
    if not visible:
        imgui.end()
        return reply
    for section in sections:
        reply += section()
    if panel.message:
        imgui.text_wrapped(panel.message)
    if panel.error:
        imgui.push_style_color(imgui.Col_.text.value, (1.0, 0.45, 0.4, 1.0))
        imgui.text_wrapped(panel.error)
        imgui.pop_style_color()
    imgui.end()
    return reply
