"""Progress of a long render (``render-path``): a bar on a terminal, or JSON lines for
a program that runs it (the window's *Render video* runs it as a subprocess and reads them).

Modes:

- ``"bar"``: one line on stderr, redrawn in place:
  ``fly.mp4: 37/120 frames [#######-------------] 31%  2.3 fps  1:02 left``;
- ``"auto"``: the bar when stderr is a terminal, else nothing;
- ``"json"``: one JSON object per line on stdout, flushed at once:
  ``{"frame": 37, "frames": 120, "fps": 2.3, "eta_s": 36.1}`` after each frame
  (``fps``, ``eta_s``: null until there is a rate), ``{"done": true, "out": "fly.mp4",
  "frames": 120}`` at the end, ``{"interrupted": true, "frames": 37, "out": "fly.mp4"}``
  (``out`` null when nothing was kept) when stopped;
- ``"none"``: nothing but the line of an interruption.

The rate is taken over the last :data:`RATE_WINDOW` frames, so it follows a render
whose frames get slower or faster (a flight into a dense part of the scene).
"""

from __future__ import annotations

import json
import sys
import time
from collections import deque
from pathlib import Path
from typing import Callable, TextIO

MODES = ("auto", "bar", "json", "none")
#: Frames the rate is measured over.
RATE_WINDOW = 10
BAR_WIDTH = 20
#: Seconds between redraws of the bar (a small render makes hundreds of frames a second).
REDRAW_INTERVAL = 0.1


class Progress:
    """total: frames to render. stream: where the mode writes (default: stderr for the
    bar and messages, stdout for JSON). clock: seconds, monotonic (for tests). label:
    the bar's prefix, usually the output's name."""

    def __init__(self, total: int, mode: str = "auto", stream: TextIO | None = None,
                 clock: Callable[[], float] = time.monotonic, label: str = "") -> None:
        if mode not in MODES:
            raise ValueError(f"progress mode must be one of {', '.join(MODES)}, got {mode!r}")
        self.total = int(total)
        self.clock = clock
        self.label = label
        self._stream = stream
        if mode == "auto":
            mode = "bar" if _is_terminal(sys.stderr if stream is None else stream) else "none"
        self.mode = mode
        self.done = 0
        self._samples: deque[tuple[float, int]] = deque([(clock(), 0)], maxlen=RATE_WINDOW + 1)
        self._width = 0   # of the bar line last drawn
        self._drawn_at: float | None = None

    # -- what the render calls ---------------------------------------------------------
    def update(self, done: int) -> None:
        """``done`` frames are finished."""
        self.done = int(done)
        now = self.clock()
        self._samples.append((now, self.done))
        if self.mode == "bar":
            if self._drawn_at is None or now - self._drawn_at >= REDRAW_INTERVAL or self.done >= self.total:
                self._draw(self.bar_text())
                self._drawn_at = now
        elif self.mode == "json":
            fps, eta = self.rate(), self.eta_seconds()
            self._json({"frame": self.done, "frames": self.total,
                        "fps": None if fps is None else round(fps, 3),
                        "eta_s": None if eta is None else round(eta, 1)})

    def finish(self, out: Path | str) -> None:
        """The render is complete and written to ``out``."""
        if self.mode == "bar":
            self._draw(self.bar_text())
            self._text_stream().write("\n")
            self._text_stream().flush()
        elif self.mode == "json":
            self._json({"done": True, "out": str(out), "frames": self.done})

    def interrupted(self, done: int, out: Path | str | None = None) -> None:
        """The render stopped after ``done`` frames; ``out`` holds them (None: nothing
        was kept). Prints one line in every mode."""
        self.done = int(done)
        if self.mode == "json":
            self._json({"interrupted": True, "frames": self.done, "out": None if out is None else str(out)})
            return
        kept = f"kept {out} ({self.done} frames)" if out is not None else "nothing written"
        line = f"interrupted after {self.done}/{self.total} frames: {kept}"
        stream = self._text_stream()
        stream.write(("\n" if self._width else "") + line + "\n")
        stream.flush()
        self._width = 0

    # -- numbers and text --------------------------------------------------------------
    def rate(self) -> float | None:
        """Frames per second over the last :data:`RATE_WINDOW` frames; None before any."""
        (t0, n0), (t1, n1) = self._samples[0], self._samples[-1]
        if n1 <= n0 or t1 <= t0:
            return None
        return (n1 - n0) / (t1 - t0)

    def eta_seconds(self) -> float | None:
        rate = self.rate()
        return None if rate is None else max(self.total - self.done, 0) / rate

    def bar_text(self) -> str:
        fraction = min(max(self.done / self.total, 0.0), 1.0) if self.total > 0 else 1.0
        filled = int(fraction * BAR_WIDTH)
        rate, eta = self.rate(), self.eta_seconds()
        prefix = f"{self.label}: " if self.label else ""
        return (f"{prefix}{self.done}/{self.total} frames [{'#' * filled}{'-' * (BAR_WIDTH - filled)}] "
                f"{int(fraction * 100):d}%  {'--' if rate is None else format_rate(rate)} fps  "
                f"{'--:--' if eta is None else format_duration(eta)} left")

    # -- output --------------------------------------------------------------------------
    def _text_stream(self) -> TextIO:
        return sys.stderr if self._stream is None else self._stream

    def _draw(self, line: str) -> None:
        stream = self._text_stream()
        stream.write("\r" + line.ljust(self._width))
        stream.flush()
        self._width = max(self._width, len(line))

    def _json(self, record: dict) -> None:
        stream = sys.stdout if self._stream is None else self._stream
        stream.write(json.dumps(record) + "\n")
        stream.flush()


def format_rate(fps: float) -> str:
    """Whole numbers from 10 fps on (``48``), one decimal from 1 on (``2.3``), two
    significant figures below (``0.042``: a large render still shows its pace)."""
    if fps >= 10:
        return f"{fps:.0f}"
    return f"{fps:.1f}" if fps >= 1 else f"{fps:.2g}"


def format_duration(seconds: float) -> str:
    """``m:ss``, or ``h:mm:ss`` from an hour on; rounded up, so "0:00 left" means done."""
    whole = int(-(-seconds // 1))
    hours, rest = divmod(whole, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False
