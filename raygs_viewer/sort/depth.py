"""Per-frame CPU work before drawing: conservative culling and the global sort (sections 9, 11).

The order is back to front by one key per gaussian: the camera-space depth z of the
centre ("depth") or its distance |p - C| from the camera centre C ("distance"),
descending, ties kept in scene order (both sorts are stable), so the GL renderer and
the float64 reference composite the same sequence.

:class:`DepthSorter` is the one interface: :meth:`DepthSorter.sort` answers a
:class:`~raygs_viewer.sort.request.SortRequest` with one order per key, in one pass
over the scene, in chunks:

1. Cull and keys (``sort.cull``), per chunk of ``chunk_rows`` gaussians, the chunks
   taken in turn by ``workers`` threads (``sort.pool``).
2. Sort (``sort.ordering``): keys quantised to 16 bits over a range known after step 1
   (depth: the visible depths; distance: the distances of every candidate, opacity >
   p_min, which does not depend on the rotation); one stable argsort, or with several
   workers a bucket merge equal to it bit for bit.
3. A turn in place with the distance key (:class:`TurnCache`) reuses the sorted
   candidates of the last sort at that centre, filtered by this frame's cull: equal
   to a fresh sort. The distance key |p - C| does not change when the camera turns
   about its centre C (in float32, with C snapped: ``keys.snapped_centre``), and its
   range is taken over every candidate, which does not depend on the rotation either.
   The second distance order at a centre sorts every candidate and keeps them; every
   later one at that centre (same p_min, method and rows) filters them.
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np

from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.cull import CHUNK_ROWS, Cull
from raygs_viewer.sort.deleted import DeletedRows, deleted_key
from raygs_viewer.sort.keys import SortMethod, snapped_centre
from raygs_viewer.sort.ordering import sorted_rows
from raygs_viewer.sort.pool import ChunkPool, Closable, Runner
from raygs_viewer.sort.request import Order, SortRequest, SortResult

#: What a distance order is reused for: (bytes of the snapped centre, p_min, method,
#: bytes of the spans culled and of the deleted rows' key: both change the candidates).
Turn = tuple[bytes, float, str, bytes]


class DepthSorter(Closable):
    """Caches what culling needs per scene, then culls and sorts for any request.

    ``workers``: threads for the cull and the sort (None: ``os.cpu_count()``), the
    calling thread one of them; 1 runs everything on the calling thread with one global
    argsort, the reference every other worker count equals exactly (see the module's
    steps). The pool is made on the first sort that has more than one chunk and shut
    down by :meth:`close` (after which sorts run on the calling thread, with the same
    results). ``chunk_rows``: gaussians per chunk (tests make it small to get many
    chunks from a small scene).

    Counters: ``sorted`` orders made by a sort, ``reused`` distance orders filtered from
    the cached candidate order of a turn in place.

    A lock serialises callers that share one sorter (the window's sort thread and screenshots).
    """

    def __init__(self, scene: Scene, workers: int | None = None, *, chunk_rows: int = CHUNK_ROWS):
        if workers is None:
            workers = os.cpu_count() or 1
        if int(workers) < 1 or int(chunk_rows) < 1:
            raise ValueError(f"DepthSorter needs workers >= 1 and chunk_rows >= 1, got {workers}, {chunk_rows}")
        self._cull = Cull(scene, int(chunk_rows))
        self._pool = ChunkPool(int(workers))
        self._turns = TurnCache()
        self.sorted = 0
        self.reused = 0
        self._lock = threading.RLock()

    @property
    def workers(self) -> int:
        return self._pool.workers

    @property
    def chunk_rows(self) -> int:
        return self._cull.chunk_rows

    @property
    def thread_prefix(self) -> str:
        """The pool's threads are named ``thread_prefix`` + "_0", "_1", ..."""
        return self._pool.thread_prefix

    def close(self) -> None:
        """Shuts the thread pool down (waiting for a running sort first). Idempotent;
        later sorts run on the calling thread."""
        with self._lock:
            self._closed = True
            self._turns.clear()
            self._pool.close()

    def sort(self, request: SortRequest) -> SortResult:
        """One :class:`Order` per key of ``request``, one cull for all (the A/B split
        view may show two keys of one view). The cull is :meth:`cull`'s; each order holds
        its gaussians back to front by its key, ties in scene order. A request's
        ``levels`` are chosen for its camera first; then only their rows are culled and
        sorted.

        ``request.method``: "radix" quantises the key to 16 bits (depth over the visible
        depths, distance over the distances of every gaussian with opacity > p_min), so
        keys closer than range/65535 keep scene order; "float" sorts the float32 keys
        exactly; "auto" is radix, or float when the range cannot be quantised (fewer
        than two distinct finite keys)."""
        begin = time.perf_counter()
        choice = None if request.levels is None else request.levels.choose(request.camera)
        spans = None if choice is None else choice.spans
        chosen = time.perf_counter()
        if self._cull.count == 0:
            orders = {key: Order(np.zeros(0, np.uint32), key, request, choice) for key in request.keys}
            times = {"choice": chosen - begin, "wait": 0.0, "cull": 0.0, "sort": 0.0}
            return SortResult(request, orders, choice, times)
        with self._lock:
            locked = time.perf_counter()  # after another thread's sort on this sorter, if one ran
            keys, method = request.keys, request.method
            centre = snapped_centre(request.camera, self._cull.coordinate_scale)
            turn = _turn_of(centre, request.p_min, method, spans, request.deleted)
            kept = self._turns.kept(turn) if "distance" in keys else None
            keep = "distance" in keys and kept is None and self._turns.worth_keeping(turn)
            computed = tuple(key for key in keys if not (key == "distance" and kept is not None))
            cull = self._cull.request(request.camera, request.p_min, request.dilation, request.cull_cameras,
                                      keys=computed, candidates=keep, centre=centre, spans=spans,
                                      deleted=request.deleted)
            pieces, union = self._cull.pieces(cull, self._pool.run)
            culled = time.perf_counter()
            orders = {}
            for key in keys:
                if key == "distance" and kept is not None:
                    indices = self._visible(kept, union)
                    self.reused += 1
                else:
                    indices = sorted_rows(pieces, key, method, self.workers, self._pool.run)
                    self.sorted += 1
                    if key == "distance":
                        self._turns.sorted(turn, indices if keep else None)
                        if keep:
                            indices = self._visible(indices, union)
                orders[key] = Order(indices, key, request, choice)
            times = {"choice": chosen - begin, "wait": locked - chosen, "cull": culled - locked,
                     "sort": time.perf_counter() - culled}
            return SortResult(request, orders, choice, times)

    def cull(self, request: SortRequest) -> np.ndarray:
        """(M,) int64 indices, ascending, of the gaussians that may be visible for
        ``request`` (its keys are not computed).

        A gaussian is dropped only when it cannot reach any pixel: opacity <= p_min
        (kappa <= 0), its support sphere entirely behind the camera plane, or entirely
        outside one side plane of the view frustum. ``request.dilation`` (from
        ``RenderSettings.cull_dilation``) widens each support sphere by
        sqrt(kappa) * dilation * |mu|, the most a pixel filter of that standard deviation
        per unit distance adds; None keeps every gaussian in front of the camera plane
        (for footprints no sphere bounds, such as EWA's). ``request.cull_cameras``: keep
        what any of these cameras may see (stereo: one sort from the midpoint between
        the eyes serves both).
        """
        if self._cull.count == 0:
            return np.zeros(0, np.int64)
        choice = None if request.levels is None else request.levels.choose(request.camera)
        with self._lock:
            cull = self._cull.request(request.camera, request.p_min, request.dilation, request.cull_cameras,
                                      spans=None if choice is None else choice.spans, deleted=request.deleted)
            pieces = self._cull.pieces(cull, self._pool.run).pieces
            return np.concatenate([np.zeros(0, np.int64), *(piece.visible for piece in pieces)]).astype(np.int64)

    def _visible(self, order: np.ndarray, union: np.ndarray) -> np.ndarray:
        """``order`` without what a cull dropped (``union``: (N,) bool, what it kept),
        relative order kept."""
        parts = max(1, min(2 * self.workers, -(-order.size // self.chunk_rows)))
        return _filtered(order, union, self._pool.run, parts)


def _turn_of(centre: np.ndarray, p_min: float, method: SortMethod, spans: np.ndarray | None,
             deleted: DeletedRows | None) -> Turn:
    spans_key = b"" if spans is None else np.asarray(spans, np.int64).tobytes()
    return (centre.tobytes(), float(p_min), method, spans_key + deleted_key(deleted))


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


def _filtered(order: np.ndarray, keep: np.ndarray, run: Runner, parts: int) -> np.ndarray:
    """``order`` without the indices where ``keep`` ((N,) bool) is False, relative order
    kept; in ``parts`` slices handed out by ``run``."""
    bounds = np.linspace(0, order.size, parts + 1).astype(np.int64)

    def kept(index: int) -> np.ndarray:
        part = order[bounds[index]:bounds[index + 1]]
        return part[keep[part]]

    return np.concatenate(run(kept, parts))
