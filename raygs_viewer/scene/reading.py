"""What every scene reader shares: one-line errors naming the file, the tally of
invalid gaussians, and the last step that drops them and builds the
:class:`~raygs_viewer.scene.model.Scene` (see :mod:`raygs_viewer.scene.io` for the rules).

A reader fills the arrays of :func:`scene_arrays` a chunk at a time, records what is
invalid in a :class:`DropTally`, and ends in :func:`build_scene`, whose arguments are
keywords only: the Scene's own field names, so a call reads like the Scene it builds.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.progress import READ_CHUNK_BYTES, Reporter

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


def shown_token(text: str, limit: int = 60) -> str:
    """A header token made safe for a one-line message (quoted, ASCII, clipped)."""
    if len(text) > limit:
        text = text[:limit] + "..."
    return ascii(text)


def file_error(path, message: str) -> UserError:
    """``UserError("<path>: <message>")`` on one line."""
    line = f"{path}: {message}"
    return UserError(" ".join(line.splitlines()))


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


class SceneArrays(NamedTuple):
    """A reader's output arrays for N gaussians, activated, float32: positions (N, 3),
    rotations (N, 4), scales (N, 3), opacities (N,), sh (N, (degree+1)^2, 3)."""

    positions: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    sh: np.ndarray


def scene_arrays(n: int, degree: int) -> SceneArrays:
    """Uninitialised :class:`SceneArrays` for ``n`` gaussians of SH ``degree``, to fill a
    chunk at a time and hand to :func:`build_scene`."""
    return SceneArrays(np.empty((n, 3), np.float32), np.empty((n, 4), np.float32), np.empty((n, 3), np.float32),
                       np.empty(n, np.float32), np.empty((n, sh_coefficient_count(degree), 3), np.float32))


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


def build_scene(*, arrays: SceneArrays, sh_degree: int, drops: DropTally, report: Reporter, source: str,
                format: str, filter_fused: bool = False) -> Scene:
    """The Scene of a reader's ``arrays`` less the invalid gaussians ``drops`` found (the
    valid ones are moved to the front of the arrays, which this takes over). ``source``,
    ``format``, ``sh_degree`` and ``filter_fused`` are the Scene's fields of those names."""
    report.building()
    dropped = drops.dropped
    kept, file_rows = list(arrays), None
    if dropped:
        file_rows = np.flatnonzero(~drops.bad).astype(np.int64)
        kept = _compact(kept, file_rows)
    positions, rotations, scales, opacities, sh = kept
    return Scene(
        positions=np.ascontiguousarray(positions, dtype=np.float32),
        rotations=np.ascontiguousarray(rotations, dtype=np.float32),
        scales=np.ascontiguousarray(scales, dtype=np.float32),
        opacities=np.ascontiguousarray(opacities, dtype=np.float32),
        sh=np.ascontiguousarray(sh, dtype=np.float32),
        sh_degree=sh_degree,
        filter_fused=filter_fused,
        source=source,
        dropped=dropped,
        format=format,
        file_rows=file_rows,
    )
