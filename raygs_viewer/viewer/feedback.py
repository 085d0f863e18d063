"""What the window tells its user, where the eye is: every result of an action (a
screenshot saved, a scene opened) and every error, over the view, and on stderr.

One mechanism for every source: whatever sets the panel's message or error line (the
panel sections, F12, the loader, the photo view) is picked up once a frame by
:meth:`Feedback.watch`. A result shows over the view for RESULT_SECONDS; an error stays
until it is seen: a click lands anywhere after it has been up for SEEN_AFTER seconds.
The notes take no input: a click through them reaches the view (a pick, a drag). Both go into a short history the panel lists, and to stderr, so a
scripted run's terminal has them too.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable, TextIO

from imgui_bundle import imgui

from raygs_viewer.viewer.state import PanelState

#: How long a result stays over the view (seconds).
RESULT_SECONDS = 4.0
#: An error counts as seen after a click that comes this long after it appeared.
SEEN_AFTER = 2.0
#: How many notes the history keeps.
HISTORY = 8
ERROR_COLOUR = (1.0, 0.45, 0.4, 1.0)


@dataclass
class Note:
    text: str
    error: bool
    at: float            # when it appeared (the clock's seconds)
    seen: bool = False   # an error, dismissed


class Feedback:
    """The notes of one window. ``out``: where they are printed (stderr); ``clock``:
    seconds, monotonic (tests pass their own)."""

    def __init__(self, out: TextIO | None = None, clock: Callable[[], float] = time.monotonic):
        self.out = out
        self.clock = clock
        self.history: deque[Note] = deque(maxlen=HISTORY)
        self._last = ("", "")  # the panel's message and error lines as last seen

    def watch(self, panel: PanelState) -> None:
        """Turns a new message or error line of the panel into a note."""
        message, error = panel.message, panel.error
        if message and message != self._last[0]:
            self.post(message, error=False)
        if error and error != self._last[1]:
            self.post(error, error=True)
        self._last = (message, error)

    def post(self, text: str, error: bool) -> None:
        self.history.append(Note(text, error, self.clock()))
        print(text if error or text.startswith("error") else f"raygs-viewer: {text}", file=self.out or sys.stderr,
              flush=True)

    def shown(self) -> list[Note]:
        """The notes over the view now: results younger than RESULT_SECONDS, errors not
        yet seen."""
        now = self.clock()
        return [note for note in self.history
                if (note.error and not note.seen) or (not note.error and now - note.at < RESULT_SECONDS)]

    def clicked(self) -> None:
        """A click anywhere: the errors up for SEEN_AFTER seconds have been seen."""
        now = self.clock()
        for note in self.history:
            if note.error and now - note.at >= SEEN_AFTER:
                note.seen = True

    def draw(self, left: float, top: float, width: float) -> None:
        """The notes shown, in a window at (left, top) screen units, at most ``width``
        wide (the view area the panel leaves visible), which takes no input."""
        notes = self.shown()
        if not notes:
            return
        imgui.set_next_window_pos((left, top))
        imgui.set_next_window_size_constraints((0, 0), (max(width, 120.0), 1e9))
        imgui.set_next_window_bg_alpha(0.8)
        flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                 | imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_focus_on_appearing
                 | imgui.WindowFlags_.no_nav | imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_inputs)
        imgui.begin("##feedback", None, flags)
        imgui.push_text_wrap_pos(max(width, 120.0) - 16)
        for note in notes:
            if note.error:
                imgui.push_style_color(imgui.Col_.text.value, ERROR_COLOUR)
            imgui.text_wrapped(note.text)
            if note.error:
                imgui.pop_style_color()
        imgui.pop_text_wrap_pos()
        imgui.end()


def draw_history(feedback: Feedback) -> None:
    """The panel's short history of notes, newest last (errors in red)."""
    if not feedback.history or not imgui.collapsing_header(f"Messages ({len(feedback.history)})"):
        return
    for note in feedback.history:
        if note.error:
            imgui.push_style_color(imgui.Col_.text.value, ERROR_COLOUR)
        imgui.text_wrapped(note.text)
        if note.error:
            imgui.pop_style_color()
