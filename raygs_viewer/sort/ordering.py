"""The global order of the cull's pieces by one key: one stable argsort, or the bucket
merge that equals it bit for bit on several threads (section 11).

Keys are quantised to 16 bits over the range of all pieces. With one worker (or fewer
than PARALLEL_SORT_MIN keys, or a range that cannot be quantised): one stable argsort of
all keys, the reference. With more: each chunk sorts its keys packed with their scene
index, ``key << 32 | index`` (distinct values, so any sort is the stable one), the
packed range is cut into buckets of about equal counts (coarse bins of the key), and
each bucket merges its runs from every chunk and writes its slice of the output.
Bucket b holds exactly the keys between its bounds, in (key, index) order, and buckets
follow each other in key order, so the output is the stable order by key: the
one-worker result, bit for bit (the chunks, hence the keys, are the same for every
worker count).
"""

from __future__ import annotations

import sys

import numpy as np

from raygs_viewer.sort.cull import Piece
from raygs_viewer.sort.keys import SortMethod, quantisable, quantise, stable_order
from raygs_viewer.sort.pool import Runner

#: Keys below which even several workers sort with one argsort: the bucket sort's extra
#: pass and hand-offs cost more than they save.
PARALLEL_SORT_MIN = 1 << 19
#: Packed keys per bucket of the parallel sort (1 MiB of uint64: one core's cache).
BUCKET_KEYS = 1 << 17
#: Coarse bins of the 16-bit key that bucket bounds are chosen from.
_COARSE_SHIFT = 6
#: Which uint32 half of a native uint64 holds its high bits.
_HIGH = 1 if sys.byteorder == "little" else 0
_COARSE_EDGES = (np.arange(0, 65536 + 1, 1 << _COARSE_SHIFT, dtype=np.uint64) << np.uint64(32))


def sorted_rows(pieces: list[Piece], key: str, method: SortMethod, workers: int, run: Runner) -> np.ndarray:
    """(K,) uint32: the rows of ``key`` from every piece, back to front by its values
    (none for no pieces: a level-of-detail choice of no rows)."""
    if not pieces:
        return np.zeros(0, np.uint32)
    near = min(piece.ranges[key][0] for piece in pieces)
    far = max(piece.ranges[key][1] for piece in pieces)
    total = sum(piece.values[key].size for piece in pieces)
    if workers == 1 or total < PARALLEL_SORT_MIN or method == "float" or not quantisable(near, far):
        rows = np.concatenate([piece.rows[key] for piece in pieces])
        values = np.concatenate([piece.values[key] for piece in pieces])
        return rows[stable_order(values, near, far, method)]
    return _bucket_sort(pieces, key, near, far, workers=workers, run=run)


def _bucket_sort(pieces: list[Piece], key: str, near: float, far: float, *, workers: int,
                 run: Runner) -> np.ndarray:
    """The parallel form of :func:`sorted_rows` (see the module's description)."""
    def runs(index: int) -> tuple[np.ndarray, np.ndarray]:
        piece = pieces[index]
        packed = np.empty(piece.values[key].size, np.uint64)
        # key << 32 | index, written as the two uint32 halves of each word: one pass
        # each, where shifting and or-ing make three over uint64.
        halves = packed.view(np.uint32).reshape(-1, 2)
        halves[:, 1 - _HIGH] = piece.rows[key]
        halves[:, _HIGH] = quantise(piece.values[key], near, far)
        packed.sort()
        return packed, np.searchsorted(packed, _COARSE_EDGES)

    sorted_runs = run(runs, len(pieces))
    bounds = np.stack([edges for _, edges in sorted_runs])   # (chunks, bins + 1)
    per_bin = (bounds[:, 1:] - bounds[:, :-1]).sum(axis=0)  # (bins,)
    total = int(per_bin.sum())
    buckets = max(2 * workers, -(-total // BUCKET_KEYS))
    # bin e_b starts bucket b: the cumulative count passes b/buckets of the total there
    before = np.concatenate([[0], np.cumsum(per_bin)])
    cuts = np.searchsorted(before, np.arange(1, buckets) * total / buckets, side="left")
    cuts = np.unique(np.concatenate([[0], cuts, [per_bin.size]]))
    out = np.empty(total, np.uint32)

    def merge(b: int) -> None:
        lo, hi = cuts[b], cuts[b + 1]
        start, stop = int(before[lo]), int(before[hi])
        if stop == start:
            return
        parts = [packed[edges[lo]:edges[hi]] for packed, edges in sorted_runs if edges[hi] > edges[lo]]
        merged = parts[0] if len(parts) == 1 else np.sort(np.concatenate(parts))
        out[start:stop] = merged  # the uint32 cast keeps the low 32 bits: the scene index

    run(merge, len(cuts) - 1)
    return out
