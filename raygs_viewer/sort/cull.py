"""The conservative cull of a scene's gaussians for a camera and p_min, and the sort keys
of what it keeps, chunk by chunk (section 9).

A chunk's camera-space centres mu (float32, an exactly defined sequence of operations:
``keys.camera_space``) decide what may be visible, and
the same mu gives the depth key (its z) of the visible ones; the distance key is
|p - C| in float32, which a turn about C leaves bit for bit unchanged. Chunks are
small enough that their working arrays stay in a core's cache, and independent, so
the threads of a :class:`~raygs_viewer.sort.pool.ChunkPool` take them in turn.
"""

from __future__ import annotations

import math
import threading
from dataclasses import KW_ONLY, dataclass, field
from typing import NamedTuple, Sequence

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.deleted import DeletedRows, deleted_key
from raygs_viewer.sort.keys import camera_space, distances
from raygs_viewer.sort.pool import Runner

#: Gaussians per chunk of the cull: its working arrays (about 50 bytes a gaussian) stay
#: in one core's cache. Fixed, not derived from the worker count, so that every worker
#: count computes bit-identical keys.
CHUNK_ROWS = 1 << 16
#: What the cull multiplies every support radius by before adding :func:`cull_slack`.
RADIUS_WIDENING = np.float32(1.0 + 1e-5)
#: A chunk's rows: a slice of the scene, or (k,) int64 indices, ascending.
Rows = slice | np.ndarray


@dataclass
class Piece:
    """What the cull leaves for one chunk.

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
class CullRequest:
    """One pass of the cull: its cameras (the one whose mu gives the depth key last)."""

    camera: Camera
    p_min: float
    dilation: float | None
    _: KW_ONLY
    cull_cameras: tuple[Camera, ...]
    depth_from_cull: bool   # the last cull camera has the sort camera's R and t
    keys: tuple[str, ...]   # keys whose values the pass computes
    candidates: bool        # distance over every candidate (to be cached), not the visible ones
    centre: np.ndarray | None  # (3,) float32 camera centre: the distance key's C
    chunks: list[Rows] | None = None  # each chunk's rows (span_chunks); None: the whole scene in CHUNK_ROWS
    deleted: DeletedRows | None = None  # rows no camera keeps and no key counts (deleted)


class Culled(NamedTuple):
    """What one pass of the cull gives: one :class:`Piece` per chunk, in scene order, and
    ``union``, (N,) bool, what the pass kept (what a cached order is filtered by; rows
    outside the pass's spans are left unset)."""

    pieces: list[Piece]
    union: np.ndarray


class Support(NamedTuple):
    """What the cull needs per p_min and deleted rows, per gaussian: the radius of a sphere
    holding its support, sqrt(max(kappa, 0)), and whether it is a candidate: its opacity
    passes p_min and it is not deleted (a deleted gaussian is culled like a transparent one,
    by the CPU's cull and the GPU's alike)."""

    p_min: float
    deleted: bytes
    radius: np.ndarray
    root_kappa: np.ndarray
    candidate: np.ndarray


class Cull:
    """Holds what culling needs of a scene; culls and computes keys chunk by chunk.

    ``chunk_rows``: gaussians per chunk (may be changed between passes)."""

    def __init__(self, scene: Scene, chunk_rows: int = CHUNK_ROWS):
        self.positions = scene.positions
        self.columns = np.ascontiguousarray(scene.positions.T)  # (3, N): each coordinate contiguous
        self.chunk_rows = chunk_rows
        self.max_scale = scene.scales.max(axis=1) if scene.count else np.zeros(0, np.float32)
        with np.errstate(divide="ignore"):
            self.log_opacity = np.log(scene.opacities)  # -inf for opacity 0: always culled
        # float32 camera transforms lose ~1e-7 of the coordinates' magnitude: widen the
        # culling bounds by that much so rounding never drops a visible gaussian.
        self.coordinate_scale = float(np.abs(self.positions).max()) if scene.count else 0.0
        self._support: Support | None = None
        self._local = threading.local()  # per-thread scratch arrays of one chunk

    @property
    def count(self) -> int:
        return self.positions.shape[0]

    def support(self, p_min: float, deleted: DeletedRows | None = None) -> Support:
        """The :class:`Support` of ``p_min`` and ``deleted``, cached for the last ones: it
        changes only with them. The radius: the kappa-ellipsoid fits in a sphere of
        sqrt(kappa)*max(s); NaN-free, 0 where kappa <= 0 (those are culled separately)."""
        key = deleted_key(deleted)
        if self._support is None or self._support.p_min != p_min or self._support.deleted != key:
            kappa = 2.0 * (self.log_opacity - np.float32(math.log(p_min)))
            root_kappa = np.sqrt(np.maximum(kappa, 0.0))
            with np.errstate(over="ignore"):  # absurd scales give inf: a sphere that culls nothing
                radius = root_kappa * self.max_scale
            candidate = self.log_opacity > np.float32(math.log(p_min))
            if deleted is not None:
                candidate &= ~deleted.mask
            self._support = Support(p_min, key, radius, root_kappa, candidate)
        return self._support

    def request(self, camera: Camera, p_min: float, dilation: float | None,
                cull_cameras: Sequence[Camera] | None, *, keys: tuple[str, ...] = (), candidates: bool = False,
                centre: np.ndarray | None = None, spans: np.ndarray | None = None,
                deleted: DeletedRows | None = None) -> CullRequest:
        """The pass for these arguments (see ``DepthSorter.cull`` for what they mean):
        by default one that only culls, computing no keys."""
        cameras = list(cull_cameras or (camera,))
        same = [c for c in cameras if np.array_equal(c.R, camera.R) and np.array_equal(c.t, camera.t)]
        if same:  # its mu is the last one computed: the depth key reads it
            cameras.remove(same[0])
            cameras.append(same[0])
        chunks = None if spans is None else span_chunks(spans, self.chunk_rows)
        return CullRequest(camera, p_min, dilation, cull_cameras=tuple(cameras), depth_from_cull=bool(same), keys=keys,
                           candidates=candidates, centre=centre, chunks=chunks, deleted=deleted)

    def pieces(self, request: CullRequest, run: Runner) -> Culled:
        """The pass over every chunk, the chunks handed out by ``run``: one
        :class:`Piece` per chunk, in scene order, and what the pass kept as one mask."""
        self.support(request.p_min, request.deleted)  # once, before the threads read it
        # Spans leave the rest of the mask unset: only an order cached for the same spans
        # (the turn cache keys on them) is filtered by it, and it holds none of those rows.
        union = np.empty(self.count, bool)
        count = -(-self.count // self.chunk_rows) if request.chunks is None else len(request.chunks)
        return Culled(run(lambda index: self._chunk(index, request, union), count), union)

    def _scratch(self) -> "_Scratch":
        size = min(self.chunk_rows, self.count)
        scratch = getattr(self._local, "scratch", None)
        if scratch is None or scratch.size < size:
            scratch = self._local.scratch = _Scratch(size)
        return scratch

    def _chunk(self, index: int, request: CullRequest, kept: np.ndarray) -> Piece:
        if request.chunks is None:
            start = index * self.chunk_rows
            rows = slice(start, min(start + self.chunk_rows, self.count))
        else:
            rows = request.chunks[index]
        n = row_count(rows)
        scratch = self._scratch()
        union = scratch.union[:n]
        for number, culling in enumerate(request.cull_cameras):
            self._may_be_seen(culling, request, rows, n, scratch)
            if number == 0:
                union[:] = scratch.keep[:n]
            else:
                union |= scratch.keep[:n]
        kept[rows] = union
        local = np.flatnonzero(union)
        piece = Piece(scene_rows(rows, local))
        if "depth" in request.keys:
            if not request.depth_from_cull:
                self._camera_space(request.camera, rows, scratch.mu[:, :n], scratch.product[:n])
            depth = scratch.mu[2, :n][local]
            piece.values["depth"], piece.rows["depth"] = depth, piece.visible
            piece.ranges["depth"] = _range(depth)
        if "distance" in request.keys:
            distance = scratch.radius[:n]  # free once the cull is done
            distances(self.positions[rows], request.centre, scratch.mu[:, :n], distance)
            candidate = self.support(request.p_min, request.deleted).candidate[rows]
            among = distance[candidate]
            piece.ranges["distance"] = _range(among)
            if request.candidates:
                piece.values["distance"] = among
                piece.rows["distance"] = scene_rows(rows, np.flatnonzero(candidate))
            else:
                piece.values["distance"], piece.rows["distance"] = distance[local], piece.visible
        return piece

    def _camera_space(self, camera: Camera, rows: Rows, out: np.ndarray, work: np.ndarray) -> None:
        """out[:] = (3, n) mu = R p + t of the rows (``keys.camera_space``), one row per
        axis so that every later pass reads contiguous memory; ``work``: (n,) scratch."""
        camera_space(self.columns[:, rows], camera, out, work)

    def _may_be_seen(self, camera: Camera, request: CullRequest, rows: Rows, n: int, scratch: "_Scratch") -> None:
        """Sets ``scratch.keep[:n]`` to whether each support sphere of ``rows`` (n of
        them) may reach a pixel of ``camera``; leaves their mu in ``scratch.mu[:n]``."""
        mu, radius, product, term, keep, test = (scratch.mu[:, :n], scratch.radius[:n], scratch.product[:n],
                                                 scratch.term[:n], scratch.keep[:n], scratch.test[:n])
        self._camera_space(camera, rows, mu, product)
        slack = cull_slack(self.coordinate_scale, camera)
        support, dilation = self.support(request.p_min, request.deleted), request.dilation
        radius[:] = support.radius[rows]
        if dilation:
            np.multiply(mu[0], mu[0], out=term)
            term += np.square(mu[1], out=product)
            term += np.square(mu[2], out=product)
            np.sqrt(term, out=term)
            term *= support.root_kappa[rows]
            term *= np.float32(dilation)
            radius += term
        radius *= RADIUS_WIDENING
        radius += slack
        np.negative(radius, out=radius)  # from here on: -radius, the bound every test compares with
        z = mu[2]
        np.greater(z, radius, out=keep)
        keep &= support.candidate[rows]
        if dilation is None:
            return
        for axis, across, along in side_planes(camera):
            np.multiply(mu[axis], across, out=product)
            np.multiply(z, along, out=term)
            product += term
            np.greater(product, radius, out=test)
            keep &= test


def cull_slack(coordinate_scale: float, camera: Camera) -> np.float32:
    """What the cull adds to every support radius for ``camera`` (after widening it by
    :data:`RADIUS_WIDENING`): float32 camera transforms lose ~1e-7 of the coordinates'
    magnitude (the scene's, ``coordinate_scale``, and the camera's translation)."""
    return np.float32(1e-5 * (coordinate_scale + float(np.abs(camera.t).max())) + 1e-6)


def side_planes(camera: Camera) -> list[tuple[int, np.float32, np.float32]]:
    """The frustum's four side planes as (axis, a, b): a point of camera space mu is
    inside a plane by ``mu[axis] * a + mu.z * b`` (each product rounded to float32 on its
    own). The planes pass through the camera centre at the image border (pixel centres
    lie half a pixel inside it), with unit normals pointing into the frustum: x planes
    first, each axis's low side first. Shared with the GPU sort, which passes these very
    float32 values to its shader."""
    planes = []
    for axis, a, b, extent in ((0, camera.fx, camera.cx, camera.width), (1, camera.fy, camera.cy, camera.height)):
        for normal in ((a, b), (-a, extent - b)):
            norm = np.float32(1.0 / math.hypot(*normal))
            planes.append((axis, np.float32(normal[0]) * norm, np.float32(normal[1]) * norm))
    return planes


def row_count(rows: Rows) -> int:
    return rows.stop - rows.start if isinstance(rows, slice) else rows.shape[0]


def scene_rows(rows: Rows, local: np.ndarray) -> np.ndarray:
    """(k,) uint32 scene indices of the chunk-local indices ``local``."""
    return (local + rows.start if isinstance(rows, slice) else rows[local]).astype(np.uint32)


def span_chunks(spans: np.ndarray, chunk_rows: int) -> list[Rows]:
    """The rows of ``spans`` ((S, 2) ascending [start, stop)), in order, as chunks of at
    most ``chunk_rows``: a span of a quarter chunk or more is cut into slices of its own,
    and shorter ones are packed together, their rows as one int64 array (a
    level-of-detail choice holds many short spans), so the fixed work of a chunk is paid
    per ``chunk_rows`` rows rather than per span, and large spans keep the cheap slices."""
    chunks: list[Rows] = []
    packed: list[tuple[int, int]] = []
    packed_rows = 0

    def flush() -> None:
        nonlocal packed, packed_rows
        if len(packed) == 1:
            chunks.append(slice(*packed[0]))
        elif packed:
            chunks.append(np.concatenate([np.arange(start, stop, dtype=np.int64) for start, stop in packed]))
        packed, packed_rows = [], 0

    for start, stop in np.asarray(spans, np.int64).reshape(-1, 2).tolist():
        if stop - start >= chunk_rows // 4:
            flush()
            chunks.extend(slice(at, min(at + chunk_rows, stop)) for at in range(start, stop, chunk_rows))
        elif stop > start:
            if packed_rows + stop - start > chunk_rows:
                flush()
            packed.append((start, stop))
            packed_rows += stop - start
    flush()
    return chunks


def _range(values: np.ndarray) -> tuple[float, float]:
    """(min, max) of ``values``; (inf, -inf) when there are none."""
    return (float(values.min()), float(values.max())) if values.size else (math.inf, -math.inf)


class _Scratch:
    """The chunk-sized working arrays of one thread."""

    def __init__(self, count: int):
        self.size = count
        self.mu = np.empty((3, count), np.float32)  # one row per axis
        self.radius, self.product, self.term = (np.empty(count, np.float32) for _ in range(3))
        self.keep, self.test, self.union = (np.empty(count, bool) for _ in range(3))
