"""Where the window's parts go: the panel down its left edge, the view in what the panel
leaves visible.

Everything the view shows (the free view, a training camera's letterbox, the split
view, the stereo eyes, the Photo view) is laid out in the view area, so nothing of it
sits under the panel; hiding the panel gives the view the whole window. In a window
too narrow for both, the view keeps the whole window and the panel covers its left part
(a panel squeezing the view to a sliver would help nobody).
"""

from __future__ import annotations

from raygs_viewer.render.gl.mono_frame import Viewport

#: The panel's width (screen coordinates) until it is resized, and the narrowest it may be.
PANEL_WIDTH = 360.0
MIN_PANEL_WIDTH = 320.0
#: The least share of the window's width the view keeps beside the panel; below it the
#: view takes the whole window. The panel is never resized past it.
MIN_VIEW_SHARE = 0.4


def view_area(window: tuple[int, int], panel_width: float | None, scale: float = 1.0) -> Viewport:
    """(x, y, w, h) in framebuffer pixels from the top-left: the part of a ``window``
    (width, height) framebuffer the view is laid out in, beside a panel ``panel_width``
    screen units wide at its left edge (None: hidden); ``scale``: framebuffer pixels per
    screen unit (a high-DPI display's)."""
    width, height = max(1, int(window[0])), max(1, int(window[1]))
    if panel_width is None:
        return 0, 0, width, height
    panel = int(round(panel_width * scale))
    if width - panel < MIN_VIEW_SHARE * width:
        return 0, 0, width, height
    return panel, 0, width - panel, height


def panel_width_limits(display_width: float) -> tuple[float, float]:
    """(narrowest, widest) width the panel may be resized to in a display of that width."""
    return MIN_PANEL_WIDTH, max(PANEL_WIDTH, (1.0 - MIN_VIEW_SHARE) * display_width)
