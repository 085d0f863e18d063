"""The panel as the window lays it out: down the window's left edge with the sections it
is handed, its width the user's (remembered from one run to the next when a drag of its
edge ends), and from it the view area beside it and where the notes over the view go."""

from __future__ import annotations

from typing import Callable, Sequence

from imgui_bundle import imgui

from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.viewer.layout import view_area
from raygs_viewer.viewer.panel import draw_panel
from raygs_viewer.viewer.part import Reply
from raygs_viewer.viewer.remembered import Remembered
from raygs_viewer.viewer.state import PanelState

#: The narrowest strip beside the panel the notes are placed in (screen units); a window
#: narrower than that shows them over the panel.
MIN_NOTE_WIDTH = 160.0


class SidePanel:
    """``state``: the panel's state (shown or not, its width as last drawn); ``remembered``:
    the width kept between runs, which ``state.width`` starts from."""

    def __init__(self, state: PanelState, remembered: Remembered):
        self.state, self.remembered = state, remembered
        state.width = remembered.panel_width
        self._dragged = False  # the width changed in the drag under way

    def view_area(self, window: tuple[int, int], scale: float) -> Viewport:
        """Where the view goes in a ``window`` (width, height) framebuffer of ``scale``
        pixels per screen unit: beside the panel while it is shown (``layout.view_area``)."""
        return view_area(window, self.state.width if self.state.show_panel else None, scale)

    def draw(self, sections: Sequence[Callable[[], Reply]]) -> Reply:
        """The panel with ``sections``, when shown; returns what they said and asked for.
        Its width is remembered when the user's drag ends; a width the window merely
        clamps (a smaller window) leaves the remembered one alone."""
        if not self.state.show_panel:
            return Reply()
        before = self.state.width
        reply = draw_panel(self.state, sections)
        if imgui.is_mouse_down(0):
            self._dragged |= self.state.width != before
        elif self._dragged:
            self.close()
        return reply

    def notes_left(self, display_width: float) -> float:
        """The left edge of the notes over the view (screen units): right of the panel
        when it is shown, over it where the window leaves no room beside it."""
        left = self.state.width + 10.0 if self.state.show_panel else 10.0
        return 10.0 if display_width - left < MIN_NOTE_WIDTH else left

    def close(self) -> None:
        """Keeps the width of a drag that has ended (or that the window closes in)."""
        if self._dragged:
            self.remembered.keep(self.state.width)
            self._dragged = False
