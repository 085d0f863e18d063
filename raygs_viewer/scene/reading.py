"""What the PLY and ``.splat`` readers share: progress and cancel points, one-line
errors naming the file, and the last step that drops invalid gaussians and builds the
:class:`~raygs_viewer.scene.model.Scene` (see :mod:`raygs_viewer.scene.io` for the rules).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import Scene, sh_coefficient_count

#: Every reason a gaussian can be dropped for, in the order they are tested.
DROP_REASONS = (
    "nan",
    "infinite position",
    "infinite scale",
    "zero scale",
    "negative scale",
    "infinite rotation",
    "zero quaternion",
    "infinite colour",
)

#: Gaussian data is read (and PLY rows activated) this many bytes at a time,
#: with a progress report and a cancel check after each chunk. A few MiB keeps a
#: progress bar moving on multi-GB files at a negligible per-chunk overhead; tests
#: pass a small ``chunk_bytes`` to get many chunks from a tiny file.
READ_CHUNK_BYTES = 4 << 20

#: ``progress(fraction, stage)``: fraction in [0, 1], never decreasing; stage is a
#: short word ("reading", "activating", "validating", "done").
ProgressCallback = Callable[[float, str], None]

# Where each stage starts, as a fraction of the whole load. Reading dominates on a
# cold file; the rest are vectorised passes over arrays already in memory.
_READ_END = 0.7
_ACTIVATE_AT = 0.72
_VALIDATE_AT = 0.85
_BUILD_AT = 0.93


def shown_token(text: str, limit: int = 60) -> str:
    """A header token made safe for a one-line message (quoted, ASCII, clipped)."""
    if len(text) > limit:
        text = text[:limit] + "..."
    return ascii(text)


def file_error(path, message: str) -> UserError:
    """``UserError("<path>: <message>")`` on one line."""
    line = f"{path}: {message}"
    return UserError(" ".join(line.splitlines()))


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


class DropTally:
    """Which of N gaussians are invalid, and why: filled chunk by chunk (``add``), each
    gaussian counted under the first failing reason of :data:`DROP_REASONS`."""

    def __init__(self, n: int) -> None:
        self.bad = np.zeros(n, dtype=bool)
        self.counts = dict.fromkeys(DROP_REASONS, 0)

    def add(self, start: int, tests: dict[str, np.ndarray]) -> None:
        """``tests``: reason -> (rows,) bool mask of gaussians ``start..start + rows``."""
        bad = None
        for reason in DROP_REASONS:
            mask = tests.get(reason)
            if mask is None:
                continue
            if bad is None:
                bad = self.bad[start: start + mask.shape[0]]
            new = mask & ~bad
            count = int(np.count_nonzero(new))
            if count:
                self.counts[reason] += count
                bad |= new

    @property
    def dropped(self) -> dict[str, int]:
        """reason -> count, for the reasons that dropped any, in :data:`DROP_REASONS` order."""
        return {reason: count for reason, count in self.counts.items() if count}


def _compact(arrays: list[np.ndarray], keep: np.ndarray) -> list[np.ndarray]:
    """The rows ``keep`` (increasing indices) of each array, moved to its front in place,
    a few MiB of rows at a time: no second copy of a multi-GB scene. Safe because
    ``keep[j] >= j``: a chunk reads only rows that no earlier chunk has written."""
    kept = keep.shape[0]
    for array in arrays:
        step = max(1, READ_CHUNK_BYTES // max(1, array[:1].nbytes))
        for start in range(0, kept, step):
            rows = keep[start: start + step]
            array[start: start + rows.shape[0]] = array[rows]
    return [array[:kept] for array in arrays]


def scene_arrays(n: int, degree: int) -> tuple[np.ndarray, ...]:
    """A reader's output for ``n`` gaussians of SH ``degree``, to fill a chunk at a time
    and hand to :func:`build_scene`: positions (n, 3), rotations (n, 4), scales (n, 3),
    opacities (n,), sh (n, (degree+1)^2, 3), all float32 and uninitialised."""
    return (np.empty((n, 3), np.float32), np.empty((n, 4), np.float32), np.empty((n, 3), np.float32),
            np.empty(n, np.float32), np.empty((n, sh_coefficient_count(degree), 3), np.float32))


def build_scene(shown: str, positions, rotations, scales, opacities, sh, degree: int, fused: bool,
                drops: DropTally, report: Reporter, format: str) -> Scene:
    """Drop the invalid gaussians ``drops`` found (moving the valid ones to the front of
    the arrays, which this takes over) and build the Scene; ``format``: Scene.format."""
    report(_BUILD_AT, "validating")
    dropped = drops.dropped
    arrays = [positions, rotations, scales, opacities, sh]
    if dropped:
        arrays = _compact(arrays, np.flatnonzero(~drops.bad))
    positions, rotations, scales, opacities, sh = arrays
    return Scene(
        positions=np.ascontiguousarray(positions, dtype=np.float32),
        rotations=np.ascontiguousarray(rotations, dtype=np.float32),
        scales=np.ascontiguousarray(scales, dtype=np.float32),
        opacities=np.ascontiguousarray(opacities, dtype=np.float32),
        sh=np.ascontiguousarray(sh, dtype=np.float32),
        sh_degree=degree,
        filter_fused=fused,
        source=shown,
        dropped=dropped,
        format=format,
    )
