"""The distance order of a turn in place, reused instead of sorted again.

The distance key |p - C| does not change when the camera turns about its centre C (in
float32, with C snapped: ``keys.snapped_centre``), and its 16-bit range is taken over
every candidate (opacity > p_min), which does not depend on the rotation either. So
the sorted candidates of one frame, filtered by the next frame's cull, are that
frame's stable distance order: equal to a fresh sort. The second distance order at a
centre sorts every candidate and keeps them; every later one at that centre (same
p_min and method) filters them.
"""

from __future__ import annotations

import numpy as np

from raygs_viewer.sort.keys import SortMethod
from raygs_viewer.sort.pool import Runner

#: What a distance order is reused for: (bytes of the snapped centre, p_min, method,
#: bytes of the spans culled: a level-of-detail choice changes the candidates).
Turn = tuple[bytes, float, str, bytes]


def turn_of(centre: np.ndarray, p_min: float, method: SortMethod, spans: np.ndarray | None = None) -> Turn:
    return (centre.tobytes(), float(p_min), method, b"" if spans is None else np.asarray(spans, np.int64).tobytes())


class TurnCache:
    """The last distance order's turn and the sorted candidates kept for one turn."""

    def __init__(self) -> None:
        self._last: Turn | None = None
        self._kept: tuple[Turn, np.ndarray] | None = None

    def kept(self, turn: Turn) -> np.ndarray | None:
        """(K,) uint32 sorted candidates kept for ``turn``; None when there are none."""
        return self._kept[1] if self._kept is not None and self._kept[0] == turn else None

    def worth_keeping(self, turn: Turn) -> bool:
        """Whether the last distance order was sorted for ``turn`` too: a second order at
        one centre is a turn in place, and more are likely to follow."""
        return self._last == turn

    def sorted(self, turn: Turn, order: np.ndarray | None) -> None:
        """Records a distance order sorted for ``turn``; ``order``: its sorted
        candidates, to keep (None: not kept)."""
        self._last = turn
        if order is not None:
            self._kept = (turn, order)

    def clear(self) -> None:
        """Drops the kept candidates (their memory)."""
        self._kept = None


def filtered(order: np.ndarray, keep: np.ndarray, run: Runner, parts: int) -> np.ndarray:
    """``order`` without the indices where ``keep`` ((N,) bool) is False, relative order
    kept; in ``parts`` slices handed out by ``run``."""
    bounds = np.linspace(0, order.size, parts + 1).astype(np.int64)

    def kept(index: int) -> np.ndarray:
        part = order[bounds[index]:bounds[index + 1]]
        return part[keep[part]]

    return np.concatenate(run(kept, parts))
