"""Progress and cancel points of a scene load: the one callback type every loading step
reports through, and :class:`Reporter`, which keeps a caller's bar from running
backwards and makes every progress point a cancel point."""

from __future__ import annotations

import threading
from collections.abc import Callable

from raygs_viewer.errors import UserError

#: Gaussian data is read (and PLY rows activated) this many bytes at a time,
#: with a progress report and a cancel check after each chunk. A few MiB keeps a
#: progress bar moving on multi-GB files at a negligible per-chunk overhead; tests
#: pass a small ``chunk_bytes`` to get many chunks from a tiny file.
READ_CHUNK_BYTES = 4 << 20

#: ``progress(fraction, stage)``: fraction in [0, 1], never decreasing; stage is a
#: short word ("reading", "activating", "validating", "hashing", "done").
ProgressCallback = Callable[[float, str], None]

# Where each stage of a scene read starts, as a fraction of the whole read. Reading
# dominates on a cold file; the rest are vectorised passes over arrays already in memory.
_READ_END = 0.7
_ACTIVATE_AT = 0.72
_VALIDATE_AT = 0.85
_BUILD_AT = 0.93


class Reporter:
    """Forwards progress to the caller's callback and turns a set cancel event into
    ``UserError("loading cancelled")``: every progress point is also a cancel point."""

    def __init__(self, progress: ProgressCallback | None, cancel: threading.Event | None) -> None:
        self.progress = progress
        self.cancel = cancel
        self.last = 0.0

    def __call__(self, fraction: float, stage: str) -> None:
        if self.cancel is not None and self.cancel.is_set():
            raise UserError("loading cancelled")
        if self.progress is not None:
            # Clamped so a caller's bar never runs backwards, whatever the stage maths says.
            self.last = min(1.0, max(self.last, float(fraction)))
            self.progress(self.last, stage)

    def reading(self, done: int, total: int) -> None:
        """``done`` of ``total`` (rows, bytes) of the gaussian data read."""
        self(_READ_END * done / total, "reading")

    def activating(self) -> None:
        self(_ACTIVATE_AT, "activating")

    def validating(self) -> None:
        self(_VALIDATE_AT, "validating")

    def building(self) -> None:
        """The invalid gaussians are being dropped and the Scene built."""
        self(_BUILD_AT, "validating")
