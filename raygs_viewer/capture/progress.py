"""The command line's progress: one line on a terminal, redrawn in place
(:class:`TerminalLine`), for a scene's load (:class:`TerminalProgress`) and for a long
render's bar (:class:`Progress`); and render-path's versioned JSON lines for a program
that runs it, and the reader of those lines (the window's *Render video* runs
render-path as a subprocess and reads them with :func:`read_progress_line`).

Modes of a render's progress:

- ``"bar"``: one line on stderr, redrawn in place:
  ``fly.mp4: 37/120 frames [#######-------------] 31%  2.3 fps  1:02 left``;
- ``"auto"``: the bar when stderr is a terminal, else nothing;
- ``"json"``: one JSON object per line on stdout, flushed at once (below);
- ``"none"``: nothing but the line of an interruption.

The JSON lines (protocol version 1, :data:`PROTOCOL`); every line carries
``"progress": 1``, so a reader can tell a line of its own version from anything else
on the stream:

- ``{"progress": 1, "frame": 37, "frames": 120, "fps": 2.3, "eta_s": 36.1}`` after
  each frame (``fps``, ``eta_s``: null until there is a rate): :class:`FrameProgress`;
- ``{"progress": 1, "done": true, "out": "fly.mp4", "frames": 120}`` at the end:
  :class:`RenderDone`;
- ``{"progress": 1, "interrupted": true, "frames": 37, "out": "fly.mp4"}`` when stopped
  (``out`` null when nothing was kept): :class:`RenderInterrupted`.

A change to a line's fields is a new version; a reader returns None for a line of
another version, as for any line that is not one of these.

The rate is taken over the last :data:`RATE_WINDOW` frames, so it follows a render
whose frames get slower or faster (a flight into a dense part of the scene).
"""

from __future__ import annotations

import sys
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, TextIO

from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import JsonFields, json_line, parse_json

#: The version of the JSON lines, written into every line as "progress".
PROTOCOL = 1
MODES = ("auto", "bar", "json", "none")
#: Frames the rate is measured over.
RATE_WINDOW = 10
BAR_WIDTH = 20
#: Seconds between redraws of the bar (a small render makes hundreds of frames a second).
REDRAW_INTERVAL = 0.1


# --------------------------------------------------------------------------- the JSON lines


@dataclass(frozen=True)
class FrameProgress:
    """``frame`` frames of ``frames`` are done; the rate (frames per second) and the time
    left (seconds) are None until there is a rate."""

    frame: int
    frames: int
    fps: float | None = None
    eta_s: float | None = None

    @property
    def fraction(self) -> float:
        return min(max(self.frame / self.frames, 0.0), 1.0) if self.frames > 0 else 0.0


@dataclass(frozen=True)
class RenderDone:
    """The render is complete: ``frames`` frames written to ``out``."""

    out: str
    frames: int


@dataclass(frozen=True)
class RenderInterrupted:
    """The render stopped after ``frames`` frames; ``out`` holds them (None: nothing kept)."""

    frames: int
    out: str | None


#: What one line says.
ProgressRecord = FrameProgress | RenderDone | RenderInterrupted


def progress_line(record: ProgressRecord) -> str:
    """``record`` as one JSON line of this protocol's version, with its newline."""
    if isinstance(record, FrameProgress):
        fields = {"frame": record.frame, "frames": record.frames, "fps": record.fps, "eta_s": record.eta_s}
    elif isinstance(record, RenderDone):
        fields = {"done": True, "out": record.out, "frames": record.frames}
    else:
        fields = {"interrupted": True, "frames": record.frames, "out": record.out}
    return json_line({"progress": PROTOCOL, **fields})


def read_progress_line(line: str) -> ProgressRecord | None:
    """The record of one line written by :func:`progress_line`; None for anything else
    (not JSON, another version, a field missing, unknown or of the wrong type): a stream
    may hold other lines, and a reader must not fail on them."""
    try:
        data = parse_json(line, "progress line")
        if not isinstance(data, dict) or data.get("progress") != PROTOCOL:
            return None
        return _record(JsonFields("progress line", data))
    except UserError:
        return None


def _record(fields: JsonFields) -> ProgressRecord:
    """The record of a line of this version; UserError when its fields are not one."""
    data = fields.data
    fields.get("progress", int)  # 1.0 and true equal 1 in Python, but are not this version
    if "done" in data:
        fields.keys("", data, ("progress", "done", "out", "frames"))
        _true(fields, "done")
        return RenderDone(fields.get("out", str), _count(fields, "frames"))
    if "interrupted" in data:
        fields.keys("", data, ("progress", "interrupted", "frames", "out"))
        _true(fields, "interrupted")
        return RenderInterrupted(_count(fields, "frames"), fields.optional("out", str))
    fields.keys("", data, ("progress", "frame", "frames", "fps", "eta_s"))
    return FrameProgress(_count(fields, "frame"), _count(fields, "frames"),
                         fields.optional("fps", float), fields.optional("eta_s", float))


def _true(fields: JsonFields, key: str) -> None:
    if fields.get(key, bool) is not True:
        raise UserError(f"{fields.path}: '{key}' must be true")


def _count(fields: JsonFields, key: str) -> int:
    value = fields.get(key, int)
    if value < 0:
        raise UserError(f"{fields.path}: '{key}' must not be negative")
    return value


# --------------------------------------------------------------------------- the terminal


def is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal (False for one without isatty, or closed): a
    progress line is drawn only there, so piped and scripted output stays as it was."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


class TerminalLine:
    """The one line every progress display of the command line redraws in place on
    ``stream``: each text written over the last after a carriage return (padded to the
    longest drawn, so nothing of a longer one is left), then erased or ended."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        #: The longest text drawn since the line was last erased or ended; 0: none is shown.
        self.width = 0

    def draw(self, text: str) -> None:
        self.stream.write("\r" + text.ljust(self.width))
        self.stream.flush()
        self.width = max(self.width, len(text))

    def erase(self) -> None:
        """Blanks the line, when one is shown (a failed load's error then prints on a clean line)."""
        if self.width:
            self.stream.write("\r" + " " * self.width + "\r")
            self.stream.flush()
            self.width = 0

    def end(self) -> None:
        """Keeps the line as drawn and moves on to the next."""
        self.stream.write("\n")
        self.stream.flush()
        self.width = 0


class TerminalProgress:
    """A :data:`~raygs_viewer.scene.progress.ProgressCallback` that shows a synchronous
    load on a terminal (the scene named on the command line loads before the window
    opens, or before render-path and evaluate render): ``loading NAME: reading 42%``
    redrawn in place at most every ``interval`` seconds, starting once the load has
    taken ``delay`` seconds (small scenes print nothing), erased at "done" and on
    leaving a ``with`` block (so a failed load's error starts on a clean line).

    Writes only when ``stream`` (default: stderr) is a terminal, so piped and scripted
    output stays as it was. ``clock`` is for tests.
    """

    def __init__(self, name: str, stream: TextIO | None = None, *, delay: float = 0.5, interval: float = 0.2,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.name = name
        self.line = TerminalLine(sys.stderr if stream is None else stream)
        self.delay, self.interval, self.clock = delay, interval, clock
        self.enabled = is_terminal(self.line.stream)
        self.started = clock()
        self.shown_at: float | None = None

    def __call__(self, fraction: float, stage: str) -> None:
        if not self.enabled:
            return
        now = self.clock()
        if stage == "done":
            self.close()
            return
        if now - self.started < self.delay or (self.shown_at is not None and now - self.shown_at < self.interval):
            return
        self.line.draw(f"loading {self.name}: {stage} {fraction * 100:3.0f}%")
        self.shown_at = now

    def close(self) -> None:
        """Erases the line, if one is shown."""
        self.line.erase()
        self.shown_at = None

    def __enter__(self) -> "TerminalProgress":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


# --------------------------------------------------------------------------- a render's progress


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
        self._line = TerminalLine(sys.stderr if stream is None else stream)
        if mode == "auto":
            mode = "bar" if is_terminal(self._line.stream) else "none"
        self.mode = mode
        self.done = 0
        self._samples: deque[tuple[float, int]] = deque([(clock(), 0)], maxlen=RATE_WINDOW + 1)
        self._drawn_at: float | None = None

    # -- what the render calls ---------------------------------------------------------
    def update(self, done: int) -> None:
        """``done`` frames are finished."""
        self.done = int(done)
        now = self.clock()
        self._samples.append((now, self.done))
        if self.mode == "bar":
            if self._drawn_at is None or now - self._drawn_at >= REDRAW_INTERVAL or self.done >= self.total:
                self._line.draw(self.bar_text())
                self._drawn_at = now
        elif self.mode == "json":
            fps, eta = self.rate(), self.eta_seconds()
            self._json(FrameProgress(self.done, self.total, None if fps is None else round(fps, 3),
                                     None if eta is None else round(eta, 1)))

    def finish(self, out: Path | str) -> None:
        """The render is complete and written to ``out``."""
        if self.mode == "bar":
            self._line.draw(self.bar_text())
            self._line.end()
        elif self.mode == "json":
            self._json(RenderDone(str(out), self.done))

    def interrupted(self, done: int, out: Path | str | None = None) -> None:
        """The render stopped after ``done`` frames; ``out`` holds them (None: nothing
        was kept). Prints one line in every mode."""
        self.done = int(done)
        if self.mode == "json":
            self._json(RenderInterrupted(self.done, None if out is None else str(out)))
            return
        kept = f"kept {out} ({self.done} frames)" if out is not None else "nothing written"
        if self._line.width:  # the bar stays, the line goes below it
            self._line.end()
        self._line.stream.write(f"interrupted after {self.done}/{self.total} frames: {kept}\n")
        self._line.stream.flush()

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
    def _json(self, record: ProgressRecord) -> None:
        stream = sys.stdout if self._stream is None else self._stream
        stream.write(progress_line(record))
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
