"""Per-frame CPU work before drawing: conservative culling and the global sort (sections 9, 11).

The order is back to front by one key per gaussian: the camera-space depth z of the
centre ("depth") or its distance |p - C| from the camera centre C ("distance"),
descending, ties kept in scene order (both sorts are stable), so the GL renderer and
the float64 reference composite the same sequence.

How :meth:`DepthSorter.orders` works (one pass over the scene, in chunks):

1. Cull and keys, per chunk of ``chunk_rows`` gaussians: the chunk's camera-space
   centres mu (float32, one matmul) decide what may be visible, and the same mu gives
   the depth key (its z) of the visible ones; the distance key is |p - C| in float32,
   which a turn about C leaves bit for bit unchanged. Chunks are small enough that
   their working arrays stay in a core's cache, and independent, so ``workers``
   threads take them in turn (numpy releases the GIL in its loops).
2. Sort: keys are quantised to 16 bits over a range known after step 1 (depth: the
   visible depths; distance: the distances of every candidate, opacity > p_min, which
   does not depend on the rotation). With one worker (or fewer than PARALLEL_SORT_MIN
   keys): one stable argsort of all keys, the reference. With more: each chunk sorts
   its keys packed with their scene index, ``key << 32 | index`` (distinct values, so
   any sort is the stable one), the packed range is cut into buckets of about equal
   counts (coarse bins of the key), and each bucket merges its runs
   from every chunk and writes its slice of the output. Bucket b holds exactly the
   keys between its bounds, in (key, index) order, and buckets follow each other in
   key order, so the output is the stable order by key: the one-worker result, bit
   for bit (the chunks, hence the keys, are the same for every worker count).
3. A turn in place with the distance key (same centre C, snapped, in float32; same
   p_min and method) reuses the sorted candidates of the last sort at that centre: the stable
   order restricted to this frame's visible set is that order filtered by the cull,
   equal to a fresh sort because the keys and their range do not change.
"""

from __future__ import annotations

import itertools
import math
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable, Literal, Sequence

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.model import Scene

SortMethod = Literal["auto", "radix", "float"]
#: The global sort keys: camera-space depth of the centre, or its distance from the camera.
SortKey = Literal["depth", "distance"]
SORT_KEYS = ("depth", "distance")

#: Gaussians per chunk of the cull: its working arrays (about 50 bytes a gaussian) stay
#: in one core's cache. Fixed, not derived from the worker count, so that every worker
#: count computes bit-identical keys.
CHUNK_ROWS = 1 << 16
#: Rows per matrix product (see ``DepthSorter._camera_space``).
_MATMUL_ROWS = 1 << 14
#: Keys below which even several workers sort with one argsort: the bucket sort's extra
#: pass and hand-offs cost more than they save.
PARALLEL_SORT_MIN = 1 << 19
#: Packed keys per bucket of the parallel sort (1 MiB of uint64: one core's cache).
BUCKET_KEYS = 1 << 17
#: Coarse bins of the 16-bit key that bucket bounds are chosen from.
_SORTER_SERIALS = itertools.count(1)
_COARSE_SHIFT = 6
_COARSE_EDGES = (np.arange(0, 65536 + 1, 1 << _COARSE_SHIFT, dtype=np.uint64) << np.uint64(32))


@dataclass
class _Piece:
    """What step 1 leaves for one chunk.

    visible: (m,) uint32 scene indices that may be visible, ascending.
    values:  {key: (k,) float32 key values} of ``rows[key]`` (the visible ones, or every
             candidate for a distance order that is being cached).
    rows:    {key: (k,) uint32 scene indices the values belong to}.
    ranges:  {key: (lo, hi)} the values' range over what the key quantises over (inf, -inf: none).
    """

    visible: np.ndarray
    values: dict[str, np.ndarray] = field(default_factory=dict)
    rows: dict[str, np.ndarray] = field(default_factory=dict)
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class _Pass:
    """One request of step 1: the cull cameras (the one whose mu gives the depth key last)."""

    camera: Camera
    p_min: float
    dilation: float | None
    cull_cameras: tuple[Camera, ...]
    depth_from_cull: bool   # the last cull camera has the sort camera's R and t
    keys: tuple[str, ...]   # keys whose values step 1 computes
    candidates: bool        # distance over every candidate (to be cached), not the visible ones
    centre: np.ndarray      # (3,) float32 camera centre: the distance key's C


class DepthSorter:
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

    def __init__(self, scene: Scene, workers: int | None = None, *, chunk_rows: int = CHUNK_ROWS):
        self.positions = scene.positions
        self.max_scale = scene.scales.max(axis=1) if scene.count else np.zeros(0, np.float32)
        with np.errstate(divide="ignore"):
            self.log_opacity = np.log(scene.opacities)  # -inf for opacity 0: always culled
        # float32 camera transforms lose ~1e-7 of the coordinates' magnitude: widen the
        # culling bounds by that much so rounding never drops a visible gaussian.
        self.coordinate_scale = float(np.abs(self.positions).max()) if scene.count else 0.0
        if workers is None:
            workers = os.cpu_count() or 1
        if int(workers) < 1 or int(chunk_rows) < 1:
            raise ValueError(f"DepthSorter needs workers >= 1 and chunk_rows >= 1, got {workers}, {chunk_rows}")
        self.workers, self.chunk_rows = int(workers), int(chunk_rows)
        #: The pool's threads are named ``thread_prefix`` + "_0", "_1", ...
        self.thread_prefix = f"raygs-cull-{next(_SORTER_SERIALS)}."
        self.sorted = 0
        self.reused = 0
        self.last_seconds: dict[str, float] = {}
        self._lock = threading.RLock()
        self._pool: ThreadPoolExecutor | None = None
        self._closed = False
        self._local = threading.local()  # per-thread scratch arrays of one chunk
        self._support: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._union: np.ndarray | None = None  # (N,) bool: the last cull, for the turn reuse
        self._last_distance: tuple | None = None  # (centre, p_min, method) of the last distance order
        self._cached: tuple[tuple, np.ndarray] | None = None  # (same, (K,) uint32 sorted candidates)

    # -- pool ---------------------------------------------------------------------
    def close(self) -> None:
        """Shuts the thread pool down (waiting for a running order first). Idempotent;
        later orders run on the calling thread."""
        with self._lock:
            self._closed = True
            pool, self._pool = self._pool, None
            self._cached = None
        if pool is not None:
            pool.shutdown(wait=True)

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> "DepthSorter":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def _run(self, task: Callable[[int], object], count: int) -> list:
        """[task(0), ..., task(count - 1)]: spread over the pool and the calling thread,
        each thread taking the next index as it finishes one."""
        threads = min(self.workers, count)
        if threads <= 1 or self._closed:
            return [task(index) for index in range(count)]
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.workers - 1, thread_name_prefix=self.thread_prefix)
        results: list = [None] * count
        indices = iter(range(count))  # next() on it is atomic under the GIL

        def drain() -> None:
            for index in indices:
                results[index] = task(index)

        helpers = [self._pool.submit(drain) for _ in range(threads - 1)]
        try:
            drain()
        finally:
            for helper in helpers:
                helper.result()  # re-raises a helper's exception here
        return results

    # -- culling ------------------------------------------------------------------
    def support_radius(self, p_min: float) -> np.ndarray:
        """(N,) float32 world-space radius of a sphere that holds every peak point with
        opacity >= p_min: the kappa-ellipsoid fits in a sphere of sqrt(kappa)*max(s);
        NaN-free, 0 where kappa <= 0 (those are culled separately)."""
        return self._support_for(p_min)[1]

    def _support_for(self, p_min: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """(p_min, support radius, sqrt(max(kappa, 0)), opacity > p_min), cached for the
        last p_min: they change only with it."""
        if self._support is None or self._support[0] != p_min:
            kappa = 2.0 * (self.log_opacity - np.float32(math.log(p_min)))
            root_kappa = np.sqrt(np.maximum(kappa, 0.0))
            with np.errstate(over="ignore"):  # absurd scales give inf: a sphere that culls nothing
                radius = root_kappa * self.max_scale
            self._support = (p_min, radius, root_kappa, self.log_opacity > np.float32(math.log(p_min)))
        return self._support

    def order(self, camera: Camera, p_min: float, method: SortMethod = "auto", *,
              dilation: float | None = 0.0, cull_cameras: Sequence[Camera] | None = None,
              key: SortKey = "depth") -> np.ndarray:
        """(M,) uint32 indices of the gaussians that may be visible, back to front by
        ``key``: what :meth:`orders` returns for it (see there and :meth:`cull`)."""
        return self.orders(camera, p_min, method, dilation=dilation, cull_cameras=cull_cameras, keys=(key,))[key]

    def orders(self, camera: Camera, p_min: float, method: SortMethod = "auto", *,
               dilation: float | None = 0.0, cull_cameras: Sequence[Camera] | None = None,
               keys: Sequence[SortKey] = ("depth",)) -> dict[str, np.ndarray]:
        """{key: (M,) uint32 order} for each distinct key of ``keys``, one cull for all
        (the A/B split view may show two keys of one view). The cull is :meth:`cull`'s;
        each order holds its gaussians back to front by that key, ties in scene order.

        ``method``: "radix" quantises the key to 16 bits (depth over the visible depths,
        distance over the distances of every gaussian with opacity > p_min), so keys
        closer than range/65535 keep scene order; "float" sorts the float32 keys
        exactly; "auto" is radix, or float when the range cannot be quantised (fewer
        than two distinct finite keys)."""
        for key in keys:
            if key not in SORT_KEYS:
                raise ValueError(f"unknown sort key {key!r}; expected one of {', '.join(SORT_KEYS)}")
        if method not in ("auto", "radix", "float"):
            raise ValueError(f"unknown sort method {method!r}")
        keys = tuple(dict.fromkeys(keys))
        if self.positions.shape[0] == 0:
            return {key: np.zeros(0, np.uint32) for key in keys}
        with self._lock:
            begin = time.perf_counter()
            centre = self._centre(camera)
            turn = (centre.tobytes(), float(p_min), method)
            reuse = "distance" in keys and self._cached is not None and self._cached[0] == turn
            cache = "distance" in keys and not reuse and self._last_distance == turn
            computed = tuple(key for key in keys if not (key == "distance" and reuse))
            pieces = self._cull_pass(camera, p_min, dilation, cull_cameras, computed, cache, centre)
            culled = time.perf_counter()
            result = {}
            for key in keys:
                if key == "distance" and reuse:
                    result[key] = self._filter(self._cached[1])
                    self.reused += 1
                    continue
                order = self._sort(pieces, key, method)
                self.sorted += 1
                if key == "distance":
                    self._last_distance = turn
                    if cache:
                        self._cached = (turn, order)
                        order = self._filter(order)
                result[key] = order
            self.last_seconds = {"cull": culled - begin, "sort": time.perf_counter() - culled}
            return result

    def cull(self, camera: Camera, p_min: float, *, dilation: float | None = 0.0,
             cull_cameras: Sequence[Camera] | None = None) -> np.ndarray:
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
        if self.positions.shape[0] == 0:
            return np.zeros(0, np.int64)
        with self._lock:
            pieces = self._cull_pass(camera, p_min, dilation, cull_cameras, (), False, None)
            return np.concatenate([piece.visible for piece in pieces]).astype(np.int64)

    def _cull_pass(self, camera: Camera, p_min: float, dilation: float | None,
                   cull_cameras: Sequence[Camera] | None, keys: tuple[str, ...], candidates: bool,
                   centre: np.ndarray | None) -> list[_Piece]:
        """Step 1 over every chunk: one :class:`_Piece` per chunk, in scene order."""
        cameras = list(cull_cameras or (camera,))
        same = [c for c in cameras if np.array_equal(c.R, camera.R) and np.array_equal(c.t, camera.t)]
        if same:  # its mu is the last one computed: the depth key reads it
            cameras.remove(same[0])
            cameras.append(same[0])
        self._support_for(p_min)  # once, before the threads read it
        if self._union is None:
            self._union = np.empty(self.positions.shape[0], bool)
        view = _Pass(camera, p_min, dilation, tuple(cameras), bool(same), keys, candidates, centre)
        count = -(-self.positions.shape[0] // self.chunk_rows)
        return self._run(lambda index: self._cull_chunk(index, view), count)

    def _scratch(self) -> "_Scratch":
        scratch = getattr(self._local, "scratch", None)
        if scratch is None:
            scratch = self._local.scratch = _Scratch(min(self.chunk_rows, self.positions.shape[0]))
        return scratch

    def _cull_chunk(self, index: int, view: _Pass) -> _Piece:
        start = index * self.chunk_rows
        stop = min(start + self.chunk_rows, self.positions.shape[0])
        rows, n = slice(start, stop), stop - start
        scratch = self._scratch()
        union = scratch.union[:n]
        for number, culling in enumerate(view.cull_cameras):
            self._may_be_seen(culling, view.p_min, view.dilation, rows, scratch)
            if number == 0:
                union[:] = scratch.keep[:n]
            else:
                union |= scratch.keep[:n]
        self._union[rows] = union
        local = np.flatnonzero(union)
        piece = _Piece((local + start).astype(np.uint32))
        if "depth" in view.keys:
            if not view.depth_from_cull:
                self._camera_space(view.camera, rows, scratch.mu[:, :n])
            depth = scratch.mu[2, :n][local]
            piece.values["depth"], piece.rows["depth"] = depth, piece.visible
            piece.ranges["depth"] = (float(depth.min()), float(depth.max())) if depth.size else (math.inf, -math.inf)
        if "distance" in view.keys:
            distance = scratch.radius[:n]  # free once the cull is done
            _distance(self.positions[rows], view.centre, scratch.mu[:, :n], distance)
            candidate = self._support_for(view.p_min)[3][rows]
            among = distance[candidate]
            piece.ranges["distance"] = (float(among.min()), float(among.max())) if among.size else (math.inf, -math.inf)
            if view.candidates:
                piece.values["distance"] = among
                piece.rows["distance"] = (np.flatnonzero(candidate) + start).astype(np.uint32)
            else:
                piece.values["distance"], piece.rows["distance"] = distance[local], piece.visible
        return piece

    def _centre(self, camera: Camera) -> np.ndarray:
        """(3,) float32: the camera centre C of the distance key, snapped to a grid 2^-32
        of the scene's extent. A turn in place recomputes t from R and C, and C = -R^T t
        comes back off by rounding (1e-17 where it was 0, which float32 keeps): the
        snapped centre is the same, so the keys of the turn are bit for bit the same.
        Adding 0.0 turns the -0.0 that rounds from a tiny negative into 0.0: the cache
        compares the bytes, and those of -0.0 and 0.0 differ."""
        step = 2.0 ** (math.frexp(max(self.coordinate_scale, 1e-30))[1] - 32)
        return (np.round(np.asarray(camera.center, np.float64) / step) * step + 0.0).astype(np.float32)

    def _camera_space(self, camera: Camera, rows: slice, out: np.ndarray) -> None:
        """out[:] = (3, n) mu = R p + t of the rows, in float32 (the form the GPU uses),
        one row per axis so that every later pass reads contiguous memory."""
        rotation, positions = camera.R.astype(np.float32), self.positions[rows]
        # OpenBLAS spreads a gemm over its own threads above m*n*k = 4 * 65536, and those
        # threads then fight the pool's: keep each product below that.
        for start in range(0, out.shape[1], _MATMUL_ROWS):
            block = slice(start, start + _MATMUL_ROWS)
            np.matmul(rotation, positions[block].T, out=out[:, block])
        out += camera.t.astype(np.float32)[:, None]

    def _may_be_seen(self, camera: Camera, p_min: float, dilation: float | None, rows: slice,
                     scratch: "_Scratch") -> None:
        """Sets ``scratch.keep[:n]`` to whether each support sphere of ``rows`` (n of
        them) may reach a pixel of ``camera``; leaves their mu in ``scratch.mu[:n]``."""
        n = rows.stop - rows.start
        mu, radius, product, term, keep, test = (scratch.mu[:, :n], scratch.radius[:n], scratch.product[:n],
                                                 scratch.term[:n], scratch.keep[:n], scratch.test[:n])
        self._camera_space(camera, rows, mu)
        slack = np.float32(1e-5 * (self.coordinate_scale + float(np.abs(camera.t).max())) + 1e-6)
        _, support, root_kappa, opaque_enough = self._support_for(p_min)
        radius[:] = support[rows]
        if dilation:
            np.multiply(mu[0], mu[0], out=term)
            term += np.square(mu[1], out=product)
            term += np.square(mu[2], out=product)
            np.sqrt(term, out=term)
            term *= root_kappa[rows]
            term *= np.float32(dilation)
            radius += term
        radius *= np.float32(1.0 + 1e-5)
        radius += slack
        np.negative(radius, out=radius)  # from here on: -radius, the bound every test compares with
        x, y, z = mu
        np.greater(z, radius, out=keep)
        keep &= opaque_enough[rows]
        if dilation is None:
            return
        # Side planes through the camera centre, at the image border (pixel centres lie
        # half a pixel inside it), with unit normals pointing into the frustum.
        for coordinate, a, b, extent in ((x, camera.fx, camera.cx, camera.width),
                                         (y, camera.fy, camera.cy, camera.height)):
            for normal in ((a, b), (-a, extent - b)):
                norm = np.float32(1.0 / math.hypot(*normal))
                np.multiply(coordinate, np.float32(normal[0]) * norm, out=product)
                np.multiply(z, np.float32(normal[1]) * norm, out=term)
                product += term
                np.greater(product, radius, out=test)
                keep &= test

    # -- sorting ------------------------------------------------------------------
    def _sort(self, pieces: list[_Piece], key: str, method: SortMethod) -> np.ndarray:
        """(K,) uint32: the rows of ``key`` from every piece, back to front by its values."""
        near = min(piece.ranges[key][0] for piece in pieces)
        far = max(piece.ranges[key][1] for piece in pieces)
        quantisable = method != "float" and math.isfinite(far - near) and far > near
        total = sum(piece.values[key].size for piece in pieces)
        if self.workers == 1 or total < PARALLEL_SORT_MIN or not quantisable:
            rows = np.concatenate([piece.rows[key] for piece in pieces])
            values = np.concatenate([piece.values[key] for piece in pieces])
            return rows[_stable_order(values, near, far, method)]
        return self._bucket_sort(pieces, key, near, far)

    def _bucket_sort(self, pieces: list[_Piece], key: str, near: float, far: float) -> np.ndarray:
        """The parallel form of ``_sort`` (see the module's step 2)."""
        def runs(index: int) -> tuple[np.ndarray, np.ndarray]:
            piece = pieces[index]
            packed = _quantise(piece.values[key], near, far).astype(np.uint64) << np.uint64(32)
            packed |= piece.rows[key]
            packed.sort()
            return packed, np.searchsorted(packed, _COARSE_EDGES)

        sorted_runs = self._run(runs, len(pieces))
        bounds = np.stack([edges for _, edges in sorted_runs])   # (chunks, bins + 1)
        per_bin = (bounds[:, 1:] - bounds[:, :-1]).sum(axis=0)  # (bins,)
        total = int(per_bin.sum())
        buckets = max(2 * self.workers, -(-total // BUCKET_KEYS))
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

        self._run(merge, len(cuts) - 1)
        return out

    def _filter(self, order: np.ndarray) -> np.ndarray:
        """``order`` without what the last cull dropped, relative order kept."""
        union = self._union
        parts = max(1, min(2 * self.workers, -(-order.size // self.chunk_rows)))
        bounds = np.linspace(0, order.size, parts + 1).astype(np.int64)

        def kept(index: int) -> np.ndarray:
            part = order[bounds[index]:bounds[index + 1]]
            return part[union[part]]

        return np.concatenate(self._run(kept, parts))

    def sort(self, camera: Camera, visible: np.ndarray, method: SortMethod = "auto",
             key: SortKey = "depth") -> np.ndarray:
        """(M,) uint32: ``visible`` (indices) back to front by ``key`` seen from ``camera``,
        its keys in the float32 forms :meth:`orders` uses, quantised over their own range
        (so a distance order can differ from :meth:`orders`', which quantises over every
        candidate). The two-step form of the benchmarks and tests."""
        visible = np.asarray(visible)
        if key == "depth":
            values = (self.positions[visible] @ camera.R.astype(np.float32).T)[:, 2]
            values += np.float32(camera.t[2])
        elif key == "distance":
            values = np.empty(visible.size, np.float32)
            centre = self._centre(camera)
            _distance(self.positions[visible], centre, np.empty((3, visible.size), np.float32), values)
        else:
            raise ValueError(f"unknown sort key {key!r}; expected one of {', '.join(SORT_KEYS)}")
        return visible[sort_back_to_front(values, method)].astype(np.uint32)


class _Scratch:
    """The chunk-sized working arrays of one thread."""

    def __init__(self, count: int):
        self.mu = np.empty((3, count), np.float32)  # one row per axis
        self.radius, self.product, self.term = (np.empty(count, np.float32) for _ in range(3))
        self.keep, self.test, self.union = (np.empty(count, bool) for _ in range(3))


def _distance(positions: np.ndarray, centre: np.ndarray, work: np.ndarray, out: np.ndarray) -> None:
    """out[:] = |p - C| of (n, 3) ``positions`` in float32, summed x, y, z in that order:
    element by element, so the same for any chunking, and independent of the camera's
    rotation. ``work``: (3, n) float32 scratch."""
    np.subtract(positions.T, centre[:, None], out=work)
    np.square(work, out=work)
    np.add(work[0], work[1], out=out)
    out += work[2]
    np.sqrt(out, out=out)


def _quantise(values: np.ndarray, near: float, far: float) -> np.ndarray:
    """(M,) uint16: 0 at ``far`` up to 65535 at ``near`` (far > near, both finite)."""
    scaled = (far - values) * np.float32(65535.0 / (far - near))
    return np.minimum(scaled, np.float32(65535.0)).astype(np.uint16)  # rounding may pass 65535


def _stable_order(values: np.ndarray, near: float, far: float, method: SortMethod) -> np.ndarray:
    """Stable argsort of ``values``, farthest first, quantised over [near, far] (see
    :func:`sort_back_to_front`)."""
    if values.size == 0:
        return np.zeros(0, np.int64)
    if method in ("auto", "radix"):
        if math.isfinite(far - near) and far > near:
            return np.argsort(_quantise(values, near, far), kind="stable")
        if method == "radix":
            return np.arange(values.size)  # all keys equal: scene order is the stable order
    elif method != "float":
        raise ValueError(f"unknown sort method {method!r}")
    return np.argsort(-values, kind="stable")


def sort_back_to_front(depth: np.ndarray, method: SortMethod = "auto") -> np.ndarray:
    """Stable argsort of (M,) keys (depths or distances), farthest first.

    "radix" quantises depth to 16 bits over its range so numpy picks its radix sort
    (about 2x faster than float argsort at 1M); depths closer than range/65535 keep
    scene order. "float" sorts the float32 depths exactly. "auto" is radix, falling
    back to float when the range cannot be quantised (fewer than two distinct finite
    depths)."""
    if depth.size == 0:
        return np.zeros(0, np.int64)
    return _stable_order(depth, float(depth.min()), float(depth.max()), method)
