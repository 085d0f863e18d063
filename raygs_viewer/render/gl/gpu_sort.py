"""The per-frame cull and sort on the GPU: :class:`GpuSorter` answers a
:class:`~raygs_viewer.sort.request.SortRequest` with the very indices the CPU sort
(:class:`~raygs_viewer.sort.depth.DepthSorter`) gives, bit for bit, and leaves them in
a GPU buffer (:class:`GpuIndices`, a ``DeviceIndices``) that the renderer copies GPU to
GPU: no order crosses the bus.

Per sort, in OpenGL 4.3 compute shaders:

1. glsl/sort_cull.comp: over the request's rows (the whole scene, or a level-of-detail
   choice's spans, as one list in scene order), the cull of ``Cull._may_be_seen`` for
   every cull camera (their union), the depth and distance keys, each workgroup's kept
   count, and the ranges the keys are quantised over (depth: the kept depths;
   distance: every candidate's, kept or not), as exact min and max.
2. glsl/sort_scan.comp: where each workgroup's kept entries start (a prefix sum), and
   their total.
3. The host reads back 20 bytes, the kept count and the ranges: **one sync per sort**.
   It decides how each key sorts exactly as ``keys.stable_order`` does
   (:func:`key_plan`) and computes the quantisation scale in float64, rounded to
   float32 (``keys.quantise_scale``; a GPU's division is not correctly rounded).
4. glsl/sort_compact.comp, per key: the kept entries in scene order (their places from
   the prefix sum, not from atomics), each with its key: 16-bit quantised, or the
   float32 order as a 32-bit uint, or none (scene order).
5. :class:`~raygs_viewer.render.gl.radix_sort.GpuRadixSort`, stable: ties keep scene order.

Why the indices are the same (see glsl/sort_common.glsl): the shaders repeat the CPU's
float32 operations one by one in ``precise`` variables (no fused multiply-add, no
reordering), square roots are corrected to the correctly rounded float32 with exact
double arithmetic, and every constant the CPU derives in float64 (support radii and
root kappa per p_min from ``Cull.support``, the slack, the side planes, the
widening, float32 R and t, the snapped centre, the quantisation scale) is computed by
the CPU sort's own functions and handed over as float32 bits.

Limits: the scene's positions must fit one storage block (12 bytes a gaussian: 11M
gaussians in 128 MiB); GPUs may flush subnormal float32 results to zero where numpy
keeps them (a camera-space coordinate or squared distance under 1.2e-38), the one case
where the keys could differ. Not thread-safe: call it on the thread whose GL context it
uses (the window's GL thread).
"""

from __future__ import annotations

import math
import time
from contextlib import ExitStack, nullcontext
from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.radix_sort import GpuRadixSort
from raygs_viewer.render.gl.shaders import Programs, set_uniform
from raygs_viewer.render.gl.storage import gpu_limit
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.cull import RADIUS_WIDENING, Cull, cull_slack, side_planes
from raygs_viewer.sort.deleted import DeletedRows, deleted_key
from raygs_viewer.sort.keys import SortMethod, check_method, quantisable, quantise_scale, snapped_centre
from raygs_viewer.sort.lod_choice import LodChoice
from raygs_viewer.sort.pool import Closable
from raygs_viewer.sort.request import Order, SortRequest, SortResult

#: Invocations per workgroup and list entries per invocation (glsl/sort_common.glsl).
WORKGROUP = 256
TILE_ITEMS = 8
SCAN_ITEMS = 8
TILE = WORKGROUP * TILE_ITEMS
DEFINES = {"WORKGROUP": WORKGROUP, "TILE_ITEMS": TILE_ITEMS, "SCAN_ITEMS": SCAN_ITEMS}
#: GL guarantees 65535 workgroups in x: the cull handles 134M entries in one dispatch.
MAX_GROUPS = 65535
#: Storage bindings (glsl/sort_*.comp).
KEYS_OUT, ROWS_OUT, SPANS, SLOTS, VALUES, GROUP_COUNTS, SUMMARY, CAMERAS = range(8)
POSITIONS, SUPPORTS = 0, 1  # the cull's; the compaction binds its outputs there
#: GL 4.3's guaranteed storage blocks per compute shader; the cull uses all eight.
STORAGE_BLOCKS = 8
#: Summary words (glsl/sort_common.glsl): kept count, depth low/high, distance low/high.
SUMMARY_WORDS = 5
_NONE_LOW, _NONE_HIGH = 0xFFFFFFFF, 0  # the ranges before any value: ordered bits never reach them
CAMERA_BYTES = 96  # struct CullCamera
#: How glsl/sort_compact.comp makes a key.
QUANTISED, FLOAT, SCENE = 0, 1, 2
_KEY_COLUMN = {"depth": 0, "distance": 1}


@dataclass(frozen=True)
class KeyPlan:
    """How one key's kept entries are sorted: ``mode`` QUANTISED (over [near, far]:
    ``far`` and ``scale`` the float32 values ``keys.quantise`` uses), FLOAT (the exact
    float32 order) or SCENE (none: scene order)."""

    mode: int
    far: float = 0.0
    scale: float = 0.0

    @property
    def key_bits(self) -> int:
        return 16 if self.mode == QUANTISED else 32


def key_plan(method: SortMethod, near: float, far: float) -> KeyPlan:
    """How ``keys.stable_order`` sorts keys whose range is [near, far] by ``method``:
    quantised where the range allows it ("auto", "radix"), else scene order for
    "radix" (all keys equal) and the float order for "auto" and "float"."""
    check_method(method)
    if method in ("auto", "radix"):
        if quantisable(near, far):
            return KeyPlan(QUANTISED, float(np.float32(far)), float(quantise_scale(near, far)))
        if method == "radix":
            return KeyPlan(SCENE)
    return KeyPlan(FLOAT)


def float_of_ordered(word: int) -> float:
    """The float32 whose ordered bits (glsl/sort_common.glsl ``ordered``) are ``word``."""
    bits = word & 0x7FFFFFFF if word & 0x80000000 else ~word & 0xFFFFFFFF
    return float(np.uint32(bits).view(np.float32))


def summary_range(low: int, high: int) -> tuple[float, float]:
    """(min, max) of a range in ordered bits; (inf, -inf) where it holds no value, as
    ``cull._range`` of nothing."""
    if low == _NONE_LOW:
        return math.inf, -math.inf
    return float_of_ordered(low), float_of_ordered(high)


def camera_records(cameras: tuple[Camera, ...], coordinate_scale: float) -> bytes:
    """The CullCamera records (glsl/sort_cull.comp) of ``cameras``: float32 R and t as
    ``keys.camera_space`` rounds them, ``cull.side_planes`` and ``cull.cull_slack``."""
    records = np.zeros((len(cameras), CAMERA_BYTES // 4), np.float32)
    for record, camera in zip(records, cameras):
        rows = np.empty((3, 4), np.float32)
        rows[:, :3] = camera.R.astype(np.float32)
        rows[:, 3] = camera.t.astype(np.float32)
        record[:12] = rows.reshape(-1)
        record[12:20] = [value for _, across, along in side_planes(camera) for value in (across, along)]
        record[20] = cull_slack(coordinate_scale, camera)
    return records.tobytes()


def row_list(spans: np.ndarray | None, count: int) -> tuple[np.ndarray, int]:
    """The rows a sort culls, as the shaders find them: ((S, 2) uint32 (first row, first
    list entry) of each non-empty span, the list's length). ``spans``: (S, 2) ascending
    [start, stop) rows; None: the whole scene of ``count`` rows."""
    spans = np.array([[0, count]], np.int64) if spans is None else np.asarray(spans, np.int64).reshape(-1, 2)
    spans = spans[spans[:, 1] > spans[:, 0]]
    lengths = spans[:, 1] - spans[:, 0]
    ends = np.cumsum(lengths)
    return np.column_stack([spans[:, 0], ends - lengths]).astype(np.uint32), int(ends[-1]) if ends.size else 0


def _bind_storage(*bindings: tuple[moderngl.Buffer, int]) -> None:
    """Binds each (buffer, binding point) pair as a shader storage block, in order."""
    for buffer, binding in bindings:
        buffer.bind_to_storage_buffer(binding)


#: An order's indirect draw commands (glsl/sort_commands.comp), five words each, by the
#: draw layout's vertices: the instanced strip's and the 6-vertex draw's
#: DrawArraysIndirect, the indexed draw's DrawElementsIndirect; written where the cull's
#: cameras were bound.
COMMAND_INDEX = {"instanced": 0, "triangles": 1, "indexed": 2}
COMMAND_WORDS = 5 * len(COMMAND_INDEX)
COMMANDS = CAMERAS


class _OrderBuffer:
    """One buffer an order's indices are written to, its indirect draw commands, and
    which order holds them now."""

    def __init__(self, ctx: moderngl.Context, capacity: int):
        self.buffer = ctx.buffer(reserve=max(capacity, 1) * 4)
        self.commands = ctx.buffer(reserve=COMMAND_WORDS * 4)
        self.holder = 0  # the serial of the sort whose order it holds


class GpuIndices:
    """A sorted order's indices in a buffer of the :class:`GpuSorter` (a
    ``DeviceIndices``): ``count`` uint32 scene rows, back to front. Valid until the
    sorter writes that buffer again (each key alternates between two: at the earliest
    the second sort after the one that made it) or is closed; :attr:`valid` says which."""

    def __init__(self, store: _OrderBuffer | None, count: int, serial: int, empty: moderngl.Buffer):
        self._store = store
        self._count = count
        self._serial = serial
        self._empty = empty

    @property
    def count(self) -> int:
        return self._count

    @property
    def buffer(self) -> moderngl.Buffer:
        return self._empty if self._store is None else self._store.buffer

    @property
    def commands(self) -> moderngl.Buffer | None:
        """The order's indirect draw commands, their count the GPU's (COMMAND_WORDS;
        None for an empty order, which draws nothing)."""
        return None if self._store is None else self._store.commands

    @property
    def valid(self) -> bool:
        """Whether the buffer still holds these indices."""
        return self._store is None or self._store.holder == self._serial

    def read(self) -> np.ndarray:
        """(count,) uint32 copy of the indices; RuntimeError once the buffer was reused."""
        if not self.valid:
            raise RuntimeError("these GPU sort indices were overwritten by a later sort or released by close() "
                               "(an order is valid at least until the second sort after the one that made it)")
        if self._count == 0:
            return np.zeros(0, np.uint32)
        return np.frombuffer(self.buffer.read(size=self._count * 4), np.uint32).copy()


class GpuSorter(Closable):
    """Culls and sorts a scene on the GPU for any :class:`SortRequest`, with the orders
    of :class:`~raygs_viewer.sort.depth.DepthSorter` (the module's docstring says how).

    ``sort`` returns new :class:`GpuIndices` each time; each key's orders alternate
    between two buffers, so **an order stays valid until the second sort after the one
    that made it** (the renderer copies an order into its own buffer when it is handed
    a new one, so drawing never depends on that). Each sort reads 20 bytes back after
    the cull (one sync); ``finish``: wait for the GPU at the end of a sort too, so that
    ``times["sort"]`` is the GPU's time (what a benchmark's wall clock needs). False
    (the window's): the commands stay queued, the time is their issue, whatever draws
    the order next waits for them on the GPU, and a sort's GPU time comes from
    ``timer``, a :class:`GpuTimer` each sort is measured under, read frames later.

    The positions go to the GPU once; the support arrays (``Cull.support``, computed by
    numpy as the CPU sort computes them) once per p_min. ``programs``: a
    :class:`Programs` to build in (the renderer's); by default its own. Counters:
    ``sorted`` orders made, ``support_uploads`` p_min or deleted rows changes uploaded.
    What it makes on the GPU is released once, by :meth:`close`; a buffer that cannot be
    made while the sorter is being made releases those made before it."""

    def __init__(self, ctx: moderngl.Context, scene: Scene, *, programs: Programs | None = None,
                 finish: bool = True, timer: GpuTimer | None = None):
        problem = self.problem(ctx)
        if problem:
            raise UserError(f"the GPU sort cannot run here: {problem}")
        self.ctx = ctx
        self.finish = finish
        self.timer = timer
        self._cull = Cull(scene)
        count = self._cull.count
        if count > self.capacity(ctx):
            raise UserError(f"the GPU sort holds a scene's positions in one storage block: {count:,} gaussians "
                            f"need {count * 12:,} bytes; one holds {self.capacity(ctx):,} gaussians on this GPU")
        self._spans = self._cameras = None  # buffers made as sorts come (moderngl.Buffer)
        self._spans_key: bytes | None = None
        self._orders: dict[str, list[_OrderBuffer]] = {}  # per key, the two buffers it alternates between
        capacity = max(count, 1)
        with ExitStack() as made:
            self.programs = programs or Programs(ctx)
            if programs is None:  # its own, not the renderer's
                made.callback(self.programs.release)
            self._radix = GpuRadixSort(ctx, 0, programs=self.programs)
            made.callback(self._radix.release)

            def buffer(data=None, reserve: int = 0) -> moderngl.Buffer:
                made_buffer = ctx.buffer(data, reserve=reserve)
                made.callback(made_buffer.release)
                return made_buffer

            self._positions = buffer(np.ascontiguousarray(scene.positions, np.float32) if count else bytes(12))
            self._supports = buffer(reserve=capacity * 8)
            self._slots = buffer(reserve=capacity * 4)
            self._values = buffer(reserve=capacity * 8)
            self._keys = buffer(reserve=capacity * 4)
            self._group_counts = buffer(reserve=max(-(-count // TILE), 1) * 4)
            self._summary = buffer(reserve=SUMMARY_WORDS * 4)
            self._empty = buffer(reserve=4)  # what an empty order binds
            made.callback(self._release_per_sort)  # made as sorts come, released first
            self._owned = made.pop_all()
        self._support_key: tuple[float, bytes] | None = None
        self._serial = 0
        self.sorted = self.support_uploads = 0

    @staticmethod
    def problem(ctx: moderngl.Context) -> str | None:
        """One line saying why ``ctx`` cannot run the GPU sort; None where it can. It
        needs compute shaders (GL 4.3) with eight storage blocks; double precision
        (for the exact square roots) is core from GL 4.0."""
        if ctx.version_code < 430:
            major, minor = divmod(ctx.version_code, 100)
            return f"OpenGL {major}.{minor // 10} has no compute shaders (the GPU sort needs 4.3)"
        blocks = gpu_limit(ctx, "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS", STORAGE_BLOCKS)
        if blocks < STORAGE_BLOCKS:
            return f"compute shaders here have {blocks} storage blocks; the GPU sort needs {STORAGE_BLOCKS}"
        return None

    @staticmethod
    def capacity(ctx: moderngl.Context) -> int:
        """The most gaussians it sorts on ``ctx``: their positions fill one storage block."""
        return gpu_limit(ctx, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27) // 12

    @property
    def count(self) -> int:
        return self._cull.count

    def sort(self, request: SortRequest) -> SortResult:
        """One order per key of ``request``, one cull for all: the indices
        ``DepthSorter(scene).sort(request)`` gives, as :class:`GpuIndices`. ``times``:
        {"choice", "wait", "cull", "sort"} (wait: always 0, nothing is shared between
        threads); "cull" ends with the read-back that drains the GPU."""
        if self._closed:
            raise RuntimeError("GpuSorter.sort after close()")
        begin = time.perf_counter()
        choice = None if request.levels is None else request.levels.choose(request.camera)
        chosen = time.perf_counter()
        self._serial += 1
        starts, total = row_list(None if choice is None else choice.spans, self.count)
        if total == 0:  # an empty scene or an empty choice: nothing to cull
            orders = {key: self._order(key, request, choice, None, 0) for key in request.keys}
            return SortResult(request, orders, choice, {"choice": chosen - begin, "wait": 0.0, "cull": 0.0,
                                                        "sort": 0.0})
        groups = -(-total // TILE)
        if groups > MAX_GROUPS:
            raise UserError(f"the GPU sort culls at most {MAX_GROUPS * TILE:,} rows, asked for {total:,}")
        with nullcontext() if self.timer is None else self.timer.measure():
            self._cull_pass(request, starts, total, groups)
            summary = np.frombuffer(self._summary.read(), np.uint32)  # waits for the cull: the one sync
            culled = time.perf_counter()
            kept = int(summary[0])
            ranges = {"depth": summary_range(int(summary[1]), int(summary[2])),
                      "distance": summary_range(int(summary[3]), int(summary[4]))}
            orders = {}
            for key in request.keys:
                store = self._order_buffer(key) if kept else None
                if store is not None:
                    self._sort_key(key, key_plan(request.method, *ranges[key]), store, total=total, groups=groups,
                                   kept=kept)
                orders[key] = self._order(key, request, choice, store, kept)
                self.sorted += 1
            self.ctx.memory_barrier()  # a copy or a read of the orders sees the last writes
        if self.finish:
            self.ctx.finish()
        return SortResult(request, orders, choice, {"choice": chosen - begin, "wait": 0.0, "cull": culled - chosen,
                                                    "sort": time.perf_counter() - culled})

    def _order(self, key: str, request: SortRequest, choice: LodChoice | None, store: _OrderBuffer | None,
               count: int) -> Order:
        return Order(GpuIndices(store, count, self._serial, self._empty), key, request, choice)

    def _order_buffer(self, key: str) -> _OrderBuffer:
        """The buffer of ``key``'s order this sort writes: the one its last order did not hold."""
        if key not in self._orders:
            self._orders[key] = [_OrderBuffer(self.ctx, self.count) for _ in range(2)]
        pair = self._orders[key]
        store = pair[0] if pair[0].holder < pair[1].holder else pair[1]
        store.holder = self._serial
        return store

    # ------------------------------------------------------------------ passes

    def _upload_support(self, p_min: float, deleted: DeletedRows | None) -> None:
        """(radius, root_kappa) per gaussian for ``p_min``, root_kappa's sign bit set
        where the gaussian is no candidate (transparent, or deleted), uploaded when p_min
        or the deleted rows change: 8 bytes a gaussian, the scene itself stays."""
        if self._support_key == (p_min, deleted_key(deleted)):
            return
        support = self._cull.support(p_min, deleted)
        packed = np.empty((self.count, 2), np.float32)
        packed[:, 0] = support.radius
        kappa_bits = support.root_kappa.view(np.uint32) & np.uint32(0x7FFFFFFF)
        kappa_bits |= (~support.candidate).astype(np.uint32) << np.uint32(31)
        packed[:, 1] = kappa_bits.view(np.float32)
        self._supports.write(packed)
        self._support_key = (p_min, deleted_key(deleted))
        self.support_uploads += 1

    def _upload_spans(self, starts: np.ndarray) -> None:
        data = starts.tobytes()
        if data == self._spans_key:
            return
        if self._spans is None or self._spans.size < len(data):
            if self._spans is not None:
                self._spans.release()
            self._spans = self.ctx.buffer(reserve=max(len(data), 8))
        self._spans.write(data)
        self._spans_key = data

    def _upload_cameras(self, cameras: tuple[Camera, ...]) -> None:
        data = camera_records(cameras, self._cull.coordinate_scale)
        if self._cameras is None or self._cameras.size < len(data):
            if self._cameras is not None:
                self._cameras.release()
            self._cameras = self.ctx.buffer(reserve=len(data))
        self._cameras.write(data)

    def _cull_pass(self, request: SortRequest, starts: np.ndarray, total: int, groups: int) -> None:
        """Passes 1 and 2 (the module's docstring): the cull, the keys, the ranges and
        the kept entries' starts."""
        cameras = tuple(request.cull_cameras or (request.camera,))
        self._upload_support(request.p_min, request.deleted)
        self._upload_spans(starts)
        self._upload_cameras(cameras)
        self._summary.write(np.array([0, _NONE_LOW, _NONE_HIGH, _NONE_LOW, _NONE_HIGH], np.uint32))
        camera = request.camera
        depth_row = np.append(camera.R[2].astype(np.float32), np.float32(camera.t[2]))
        centre = snapped_centre(camera, self._cull.coordinate_scale)
        dilation = request.dilation
        cull = self.programs.compute("sort_cull.comp", DEFINES)
        for name, value in (("u_total", total), ("u_spans", len(starts)), ("u_cameras", len(cameras)),
                            ("u_frustum", dilation is not None), ("u_dilate", bool(dilation)),
                            ("u_dilation", float(np.float32(dilation or 0.0))),
                            ("u_widening", float(RADIUS_WIDENING)),
                            ("u_depth", "depth" in request.keys), ("u_distance", "distance" in request.keys),
                            ("u_depth_row", depth_row.astype(np.float32).tobytes()),
                            ("u_centre", centre.astype(np.float32).tobytes())):
            set_uniform(cull, name, value)
        _bind_storage((self._positions, POSITIONS), (self._supports, SUPPORTS), (self._spans, SPANS),
                      (self._slots, SLOTS), (self._values, VALUES), (self._group_counts, GROUP_COUNTS),
                      (self._summary, SUMMARY), (self._cameras, CAMERAS))
        cull.run(groups)
        self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)
        scan = self.programs.compute("sort_scan.comp", DEFINES)
        set_uniform(scan, "u_groups", groups)
        scan.run(1)
        # The summary is read with glGetBufferSubData, the starts by the compaction.
        self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT | moderngl.BUFFER_UPDATE_BARRIER_BIT)

    def _sort_key(self, key: str, plan: KeyPlan, store: _OrderBuffer, *, total: int, groups: int, kept: int) -> None:
        """Passes 4 and 5 for ``key``: its kept entries and keys in scene order, sorted
        stably into ``store`` (SCENE: the compaction is the order); ``total`` rows culled
        in ``groups`` workgroups, ``kept`` of them kept."""
        compact = self.programs.compute("sort_compact.comp", DEFINES)
        for name, value in (("u_total", total), ("u_key", _KEY_COLUMN[key]), ("u_mode", plan.mode),
                            ("u_far", plan.far), ("u_scale", plan.scale)):
            set_uniform(compact, name, value)
        _bind_storage((self._keys, KEYS_OUT), (store.buffer, ROWS_OUT), (self._slots, SLOTS), (self._values, VALUES),
                      (self._group_counts, GROUP_COUNTS))
        compact.run(groups)
        self.ctx.memory_barrier(moderngl.SHADER_STORAGE_BARRIER_BIT)
        if plan.mode != SCENE:
            self._radix.sort(self._keys, store.buffer, kept, plan.key_bits)
        commands = self.programs.compute("sort_commands.comp", DEFINES)
        _bind_storage((self._summary, SUMMARY), (store.commands, COMMANDS))
        commands.run(1)

    # ------------------------------------------------------------------ lifetime

    def _release_per_sort(self) -> None:
        """The buffers made as sorts came: the spans, the cameras and the orders (which
        become invalid)."""
        for buffer in (self._spans, self._cameras):
            if buffer is not None:
                buffer.release()
        self._spans = self._cameras = None
        for pair in self._orders.values():
            for store in pair:
                store.holder = -1
                store.buffer.release()
                store.commands.release()
        self._orders.clear()

    def close(self) -> None:
        """Releases the buffers and programs (the orders it made become invalid). Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._owned.close()

    release = close
