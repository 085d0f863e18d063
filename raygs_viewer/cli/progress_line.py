"""The progress of a scene load shown on a terminal, for the commands that load a scene
before they can start (``view``, ``render-path``): one line, redrawn in place."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO


class TerminalProgress:
    """A :data:`~raygs_viewer.scene.progress.ProgressCallback` that shows a synchronous
    load on a terminal (the scene named on the command line loads before the window
    opens): ``loading NAME: reading 42%`` redrawn in place at most every ``interval``
    seconds, starting once the load has taken ``delay`` seconds (small scenes print
    nothing), erased at "done" and on leaving a ``with`` block (so a failed load's error
    starts on a clean line).

    Writes only when ``stream`` (default: stderr) is a terminal, so piped and scripted
    output stays as it was. ``clock`` is for tests.
    """

    def __init__(self, name: str, stream: TextIO | None = None, *, delay: float = 0.5, interval: float = 0.2,
                 clock: Callable[[], float] = time.monotonic, force: bool = False) -> None:
        self.name = name
        self.stream = sys.stderr if stream is None else stream
        self.delay, self.interval, self.clock = delay, interval, clock
        self.enabled = force or _is_terminal(self.stream)
        self.started = clock()
        self.shown_at: float | None = None
        self.width = 0

    def __call__(self, fraction: float, stage: str) -> None:
        if not self.enabled:
            return
        now = self.clock()
        if stage == "done":
            self.close()
            return
        if now - self.started < self.delay or (self.shown_at is not None and now - self.shown_at < self.interval):
            return
        line = f"loading {self.name}: {stage} {fraction * 100:3.0f}%"
        self.stream.write("\r" + line.ljust(self.width))
        self.stream.flush()
        self.shown_at, self.width = now, max(self.width, len(line))

    def close(self) -> None:
        """Erases the line, if one is shown (a failed load's error then prints on a clean line)."""
        if self.shown_at is not None:
            self.stream.write("\r" + " " * self.width + "\r")
            self.stream.flush()
            self.shown_at = None

    def __enter__(self) -> "TerminalProgress":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False
