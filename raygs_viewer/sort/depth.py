"""Per-frame CPU work before drawing: conservative culling and the global sort (sections 9, 11).

The order is back to front by one key per gaussian: the camera-space depth z of the
centre ("depth") or its distance |p - C| from the camera centre C ("distance"),
descending, ties kept in scene order (both sorts are stable), so the GL renderer and
the float64 reference composite the same sequence.

:class:`DepthSorter` is the one interface; how :meth:`DepthSorter.orders` works (one
pass over the scene, in chunks), each step in a module of its own:

1. Cull and keys (``sort.cull``), per chunk of ``chunk_rows`` gaussians, the chunks
   taken in turn by ``workers`` threads (``sort.pool``).
2. Sort (``sort.ordering``): keys quantised to 16 bits over a range known after step 1
   (depth: the visible depths; distance: the distances of every candidate, opacity >
   p_min, which does not depend on the rotation); one stable argsort, or with several
   workers a bucket merge equal to it bit for bit.
3. A turn in place with the distance key (``sort.turns``: same centre C, snapped, in
   float32; same p_min and method) reuses the sorted candidates of the last sort at
   that centre, filtered by this frame's cull: equal to a fresh sort.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Sequence

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.closing import Closable
from raygs_viewer.sort.cull import CHUNK_ROWS, Cull
from raygs_viewer.sort.keys import (
    SORT_KEYS,
    SortKey,
    SortMethod,
    check_method,
    checked_keys,
    key_values,
    snapped_centre,
    sort_back_to_front,
)
from raygs_viewer.sort.ordering import sorted_rows
from raygs_viewer.sort.pool import ChunkPool
from raygs_viewer.sort.turns import TurnCache, filtered, turn_of

__all__ = ["CHUNK_ROWS", "SORT_KEYS", "DepthSorter", "SortKey", "SortMethod", "sort_back_to_front"]


class _Forwarded:
    """A whole-number attribute of one of the sorter's parts, read and set through the sorter."""

    def __init__(self, part: str):
        self.part = part

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, sorter: object, owner: type | None = None):
        if sorter is None:  # looked up on the class (help(), inspect)
            return self
        return getattr(getattr(sorter, self.part), self.name)

    def __set__(self, sorter: object, value: int) -> None:
        setattr(getattr(sorter, self.part), self.name, int(value))


class DepthSorter(Closable):
    """Caches what culling needs per scene, then culls and sorts for any camera and p_min.

    ``workers``: threads for the cull and the sort (None: ``os.cpu_count()``), the
    calling thread one of them; 1 runs everything on the calling thread with one global
    argsort, the reference every other worker count equals exactly (see the module's
    steps). The pool is made on the first order that has more than one chunk and shut
    down by :meth:`close` (after which orders run on the calling thread, with the same
    results). ``chunk_rows``: gaussians per chunk (tests make it small to get many
    chunks from a small scene).

    Counters: ``sorted`` orders made by a sort, ``reused`` distance orders filtered from
    the cached candidate order of a turn in place. ``last_seconds``: {"cull", "sort"}
    wall times of the last :meth:`orders` (cull includes the keys).

    A lock serialises callers that share one sorter (the window's sort thread and screenshots).
    """

    #: Both may be changed before the first order (they live in the pool and the cull).
    workers = _Forwarded("_pool")
    chunk_rows = _Forwarded("_cull")

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
        self.last_seconds: dict[str, float] = {}
        self._lock = threading.RLock()

    @property
    def thread_prefix(self) -> str:
        """The pool's threads are named ``thread_prefix`` + "_0", "_1", ..."""
        return self._pool.thread_prefix

    def close(self) -> None:
        """Shuts the thread pool down (waiting for a running order first). Idempotent;
        later orders run on the calling thread."""
        with self._lock:
            self._closed = True
            self._turns.clear()
            self._pool.close()

    def support_radius(self, p_min: float) -> np.ndarray:
        """(N,) float32 world-space radius of a sphere that holds every peak point with
        opacity >= p_min: the kappa-ellipsoid fits in a sphere of sqrt(kappa)*max(s);
        NaN-free, 0 where kappa <= 0 (those are culled separately)."""
        return self._cull.support(p_min).radius

    def order(self, camera: Camera, p_min: float, method: SortMethod = "auto", *,
              dilation: float | None = 0.0, cull_cameras: Sequence[Camera] | None = None,
              key: SortKey = "depth", spans: np.ndarray | None = None) -> np.ndarray:
        """(M,) uint32 indices of the gaussians that may be visible, back to front by
        ``key``: what :meth:`orders` returns for it (see there and :meth:`cull`)."""
        return self.orders(camera, p_min, method, dilation=dilation, cull_cameras=cull_cameras, keys=(key,),
                           spans=spans)[key]

    def orders(self, camera: Camera, p_min: float, method: SortMethod = "auto", *,
               dilation: float | None = 0.0, cull_cameras: Sequence[Camera] | None = None,
               keys: Sequence[SortKey] = ("depth",), spans: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """{key: (M,) uint32 order} for each distinct key of ``keys``, one cull for all
        (the A/B split view may show two keys of one view). The cull is :meth:`cull`'s;
        each order holds its gaussians back to front by that key, ties in scene order.
        ``spans``: (S, 2) ascending [start, stop) rows: only these are culled and sorted
        (a level-of-detail choice, ``sort.lod_choice``); None: the whole scene.

        ``method``: "radix" quantises the key to 16 bits (depth over the visible depths,
        distance over the distances of every gaussian with opacity > p_min), so keys
        closer than range/65535 keep scene order; "float" sorts the float32 keys
        exactly; "auto" is radix, or float when the range cannot be quantised (fewer
        than two distinct finite keys)."""
        keys = checked_keys(keys)
        check_method(method)
        if self._cull.count == 0:
            return {key: np.zeros(0, np.uint32) for key in keys}
        with self._lock:
            begin = time.perf_counter()
            centre = snapped_centre(camera, self._cull.coordinate_scale)
            turn = turn_of(centre, p_min, method, spans)
            kept = self._turns.kept(turn) if "distance" in keys else None
            keep = "distance" in keys and kept is None and self._turns.worth_keeping(turn)
            computed = tuple(key for key in keys if not (key == "distance" and kept is not None))
            request = self._cull.request(camera, p_min, dilation, cull_cameras, computed, keep, centre, spans)
            pieces = self._cull.pieces(request, self._pool.run)
            culled = time.perf_counter()
            result = {}
            for key in keys:
                if key == "distance" and kept is not None:
                    result[key] = self._visible(kept)
                    self.reused += 1
                    continue
                order = sorted_rows(pieces, key, method, self.workers, self._pool.run)
                self.sorted += 1
                if key == "distance":
                    self._turns.sorted(turn, order if keep else None)
                    if keep:
                        order = self._visible(order)
                result[key] = order
            self.last_seconds = {"cull": culled - begin, "sort": time.perf_counter() - culled}
            return result

    def cull(self, camera: Camera, p_min: float, *, dilation: float | None = 0.0,
             cull_cameras: Sequence[Camera] | None = None, spans: np.ndarray | None = None) -> np.ndarray:
        """(M,) int64 indices, ascending, of the gaussians that may be visible.

        A gaussian is dropped only when it cannot reach any pixel: opacity <= p_min
        (kappa <= 0), its support sphere entirely behind the camera plane, or entirely
        outside one side plane of the view frustum. ``dilation`` (from
        :meth:`RenderSettings.cull_dilation`) widens each support sphere by
        sqrt(kappa) * dilation * |mu|, the most a pixel filter of that standard deviation
        per unit distance adds; None keeps every gaussian in front of the camera plane
        (for footprints no sphere bounds, such as EWA's).

        ``cull_cameras``: keep what any of these cameras may see, instead of what
        ``camera`` may see (stereo: one sort from the midpoint between the eyes serves both).
        """
        if self._cull.count == 0:
            return np.zeros(0, np.int64)
        with self._lock:
            request = self._cull.request(camera, p_min, dilation, cull_cameras, (), False, None, spans)
            pieces = self._cull.pieces(request, self._pool.run)
            return np.concatenate([piece.visible for piece in pieces]).astype(np.int64)

    def sort(self, camera: Camera, visible: np.ndarray, method: SortMethod = "auto",
             key: SortKey = "depth") -> np.ndarray:
        """(M,) uint32: ``visible`` (indices) back to front by ``key`` seen from ``camera``,
        its keys in the float32 forms :meth:`orders` uses, quantised over their own range
        (so a distance order can differ from :meth:`orders`', which quantises over every
        candidate). The two-step form of the benchmarks and tests."""
        visible = np.asarray(visible)
        values = key_values(self._cull.positions[visible], camera, key, self._cull.coordinate_scale)
        return visible[sort_back_to_front(values, method)].astype(np.uint32)

    def _visible(self, order: np.ndarray) -> np.ndarray:
        """``order`` without what the last cull dropped, relative order kept."""
        parts = max(1, min(2 * self.workers, -(-order.size // self.chunk_rows)))
        return filtered(order, self._cull.union, self._pool.run, parts)
