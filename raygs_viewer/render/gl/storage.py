"""A scene's storage buffers on the GPU, and how they are cut into bindable ranges.

GPUs cap one bound storage range (``GL_MAX_SHADER_STORAGE_BLOCK_SIZE``, 128 MiB on
real drivers), so large scenes are split: :class:`StorageLayout` plans the cut and
:class:`SceneBuffers` holds the buffers and binds them range by range for the
preprocessing pass (chunks) and the draw (one binding per splat block).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sh import C0 as SH_C0
from raygs_viewer.sort.request import DeviceIndices

# The largest GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT drivers report (moderngl's
# ctx.info omits it); every range offset we bind is a multiple of it.
RANGE_ALIGNMENT = 256

GAUSSIAN_BYTES = 48  # struct Gaussian in preprocess.comp
SPLAT_BYTES = 64     # struct Splat in splat.glsl
COLOR_BYTES = 16     # RGB computed at load, for SH degree 0, padded so chunk ranges stay aligned
EXACT_MIP_SPLAT_BYTES = 112  # ... with EXACT_MIP's three extra vec4
GEOMETRY_BYTES = 16  # ... and GEOMETRY's normal, in any mode
MAX_SPLAT_BLOCKS = 8  # bindings splat_blocks.glsl declares
# GL guarantees 65535 workgroups per dispatch; drivers that report a 2 GiB block
# limit would otherwise ask for more in one chunk.
MAX_CHUNK = 1 << 22


def _power_of_two_at_most(value: int) -> int:
    return 1 << (max(int(value), 1).bit_length() - 1)


@dataclass(frozen=True)
class StorageLayout:
    """How N gaussians are cut so that no bound storage range exceeds ``block_limit`` bytes.

    Splat records live in ``splat_blocks`` bindings of ``splats_per_block``; the
    preprocessing pass runs in chunks of ``chunk`` gaussians (a power of two that
    divides ``splats_per_block``, so a chunk never straddles two splat blocks).
    """

    count: int
    block_limit: int
    splats_per_block: int
    chunk: int
    splat_bytes: int = SPLAT_BYTES

    @classmethod
    def plan(cls, count: int, harmonics_bytes: int, block_limit: int, alignment: int = RANGE_ALIGNMENT,
             splat_bytes: int = SPLAT_BYTES) -> "StorageLayout":
        record_bytes = (GAUSSIAN_BYTES, harmonics_bytes, COLOR_BYTES, splat_bytes)
        splats_per_block = _power_of_two_at_most(block_limit // splat_bytes)
        chunk = min(_power_of_two_at_most(block_limit // max(record_bytes)), splats_per_block, MAX_CHUNK)
        # Every bound offset is a multiple of chunk * record size: keep those aligned.
        if chunk * max(record_bytes) > block_limit or any(chunk * b % alignment for b in record_bytes):
            raise UserError(f"a storage block limit of {block_limit} bytes is too small for "
                            f"{max(record_bytes)}-byte gaussian records")
        return cls(count, block_limit, splats_per_block, chunk, splat_bytes)

    @property
    def splat_blocks(self) -> int:
        return max(1, -(-self.count // self.splats_per_block))


@dataclass(frozen=True)
class PlaceRun:
    """One dispatch of the preprocessing pass that writes records in draw order: ``count``
    places from ``first`` (of the order, or of the ranks where the places are ranked),
    whose gaussians lie in the chunk from scene row ``chunk_start`` and whose records
    lie in the splat block from place ``block_start``."""

    chunk_start: int
    block_start: int
    first: int
    count: int


def place_runs(indices: np.ndarray, layout: StorageLayout) -> tuple[np.ndarray | None, list[PlaceRun]]:
    """(ranks, runs) that preprocess the order ``indices`` (M,) into records at its
    places. A preprocessing dispatch binds one chunk of the scene and one splat block, so
    the places are grouped by (chunk, block): ``ranks`` (M,) uint32 lists them group by
    group, ascending within each (a stable partition), and each run is one group; None
    where one chunk and one block hold them all (the places are then 0 .. M - 1)."""
    count = len(indices)
    if count == 0:
        return None, []
    blocks = -(-count // layout.splats_per_block)
    if layout.count <= layout.chunk and blocks == 1:
        return None, [PlaceRun(0, 0, 0, count)]
    group = (np.asarray(indices, np.int64) // layout.chunk) * blocks + np.arange(count) // layout.splats_per_block
    ranks = np.argsort(group.astype(np.uint16 if group.max() < 1 << 16 else np.int64), kind="stable")
    sizes = np.bincount(group)
    runs, first = [], 0
    for key in np.flatnonzero(sizes):
        chunk, block = divmod(int(key), blocks)
        runs.append(PlaceRun(chunk * layout.chunk, block * layout.splats_per_block, first, int(sizes[key])))
        first += int(sizes[key])
    return ranks.astype(np.uint32), runs


def spread_runs(count: int, layout: StorageLayout) -> list[PlaceRun]:
    """The runs that preprocess an order of ``count`` places whose indices stay on the
    GPU (a GPU sort's) into records at its places, without reading it: each splat
    block's places once per chunk of the scene, the shader skipping a place whose
    gaussian lies in another chunk (glsl/preprocess.comp); one run where one chunk and
    one block hold them all, as :func:`place_runs` gives."""
    if count == 0:
        return []
    return [PlaceRun(chunk_start, block_start, block_start, min(layout.splats_per_block, count - block_start))
            for block_start in range(0, count, layout.splats_per_block)
            for chunk_start in range(0, max(layout.count, 1), layout.chunk)]


@dataclass(frozen=True)
class Chunk:
    """One preprocessing chunk, its ranges bound: ``count`` gaussians from ``start``,
    whose records go to ``offset`` within the bound splat block."""

    start: int
    count: int
    offset: int


def gpu_bytes(count: int, sh_degree: int) -> int:
    """The storage buffers a scene takes on the GPU: gaussians, SH, colours computed
    at load (SH degree 0), one splat record each (the exact MIP record, the largest)
    and the order."""
    return count * (GAUSSIAN_BYTES + sh_coefficient_count(sh_degree) * 12 + COLOR_BYTES + EXACT_MIP_SPLAT_BYTES + 4)


def gpu_limit(ctx: moderngl.Context, name: str, default: int) -> int:
    """The GL limit ``name`` from ``ctx.info``, or ``default`` where the driver reports none."""
    value = ctx.info.get(name)
    return int(value) if isinstance(value, int) and value > 0 else default


def _mib(size: int) -> str:
    return f"{size / (1 << 20):,.1f} MiB"


def _float_buffer(ctx: moderngl.Context, array: np.ndarray) -> moderngl.Buffer:
    data = np.ascontiguousarray(array, dtype=np.float32)
    # The array itself, not .tobytes(): no second copy of a GB of SH, and faster on llvmpipe.
    return ctx.buffer(data if data.size else bytes(16))


class SceneBuffers:
    """The storage buffers of one scene, made at once and kept until :meth:`release`:
    ``gaussians`` (N, 12) float32 (position, opacity, scale, pad, rotation),
    ``harmonics`` (N, 3 * coefficients) float32, ``splats`` (the per-view records),
    ``order`` (N,) uint32, and ``colors`` (N, 4) float32, made on first use of SH
    degree 0 (None before).

    ``block_limit`` overrides the GPU's per-block storage limit; ``memory_limit``
    refuses, with a UserError, a scene whose buffers would exceed it.
    """

    def __init__(self, ctx: moderngl.Context, scene: Scene, *, block_limit: int | None = None,
                 memory_limit: int | None = None):
        self.ctx = ctx
        self.scene = scene
        count = scene.count
        coeffs = sh_coefficient_count(scene.sh_degree)
        limit = gpu_limit(ctx, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27)
        self.block_limit = min(block_limit or limit, limit)
        self._layouts: dict[int, StorageLayout] = {}
        self.layout = self.layout_for(SPLAT_BYTES)
        self.gpu_bytes = gpu_bytes(count, scene.sh_degree)
        if memory_limit is not None and self.gpu_bytes > memory_limit:
            raise UserError(f"scene of {count:,} gaussians needs {_mib(self.gpu_bytes)} of GPU buffers, more than "
                            f"the {_mib(memory_limit)} allowed")

        try:
            packed = np.zeros((count, 12), np.float32)
            packed[:, 0:3] = scene.positions
            packed[:, 3] = scene.opacities
            packed[:, 4:7] = scene.scales
            packed[:, 8:12] = scene.rotations
        except MemoryError:
            raise UserError(f"scene of {count:,} gaussians: not enough memory to pack it for the GPU") from None
        buffers = []
        try:
            ctx.error  # noqa: B018 - clears an earlier error, so the check below sees only these
            for make in (lambda: _float_buffer(ctx, packed),
                         lambda: _float_buffer(ctx, scene.sh.reshape(count, coeffs * 3)),
                         lambda: ctx.buffer(reserve=max(count, 1) * SPLAT_BYTES),
                         lambda: ctx.buffer(reserve=max(count, 1) * 4)):
                buffers.append(make())
            if ctx.error == "GL_OUT_OF_MEMORY":  # drivers report it here, not by failing the call
                raise moderngl.Error("GL_OUT_OF_MEMORY")
        except (moderngl.Error, MemoryError) as exc:
            for buffer in buffers:
                buffer.release()
            raise UserError(f"scene of {count:,} gaussians does not fit in this GPU's memory "
                            f"({_mib(self.gpu_bytes)} of buffers: {' '.join(str(exc).split()) or 'out of memory'})"
                            ) from None
        self.gaussians, self.harmonics, self.splats, self.order = buffers
        self.colors: moderngl.Buffer | None = None
        self._uploaded_order: np.ndarray | None = None  # the array whose indices `order` holds
        self._quad_indices: moderngl.Buffer | None = None  # the indexed draw's (made on first use)
        self._ranks: moderngl.Buffer | None = None  # places of a draw-order preprocessing, by group
        self._selection: moderngl.Buffer | None = None  # the selected rows' bits (set_selection)
        #: The digest of the selection shown tinted (None: none), part of the records' key.
        self.selection_key: bytes | None = None

    def layout_for(self, splat_bytes: int) -> StorageLayout:
        """The layout of records of ``splat_bytes``, planned once; UserError when it
        needs more splat blocks than this GPU and the vertex stage can bind."""
        if splat_bytes not in self._layouts:
            count = self.scene.count
            harmonics_bytes = sh_coefficient_count(self.scene.sh_degree) * 12
            layout = StorageLayout.plan(count, harmonics_bytes, self.block_limit, splat_bytes=splat_bytes)
            vertex_blocks = gpu_limit(self.ctx, "GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS", 16) - 1  # one holds the order
            if layout.splat_blocks > min(MAX_SPLAT_BLOCKS, vertex_blocks):
                raise UserError(f"scene of {count} gaussians needs {layout.splat_blocks} storage blocks "
                                f"of {layout.block_limit} bytes; this GPU and renderer allow "
                                f"{min(MAX_SPLAT_BLOCKS, vertex_blocks)}")
            self._layouts[splat_bytes] = layout
        return self._layouts[splat_bytes]

    def hold_records(self, layout: StorageLayout, what: str) -> None:
        """Grows ``splats`` to records of ``layout.splat_bytes`` (the exact MIP record,
        on first use); ``what`` names them in the out-of-memory UserError."""
        count = self.scene.count
        if self.splats.size < max(count, 1) * layout.splat_bytes:
            self.ctx.error  # noqa: B018 - clears an earlier error, so the check below sees only this one
            self.splats.orphan(max(count, 1) * layout.splat_bytes)
            if self.ctx.error == "GL_OUT_OF_MEMORY":
                raise UserError(f"not enough GPU memory for the {what} records of {count:,} gaussians")

    def color_buffer(self) -> moderngl.Buffer:
        """(N, 4) float32: RGB of SH degree 0 (view-independent) and a zero pad;
        computed once, on first use."""
        if self.colors is None:
            colors = np.zeros((self.scene.count, 4))
            colors[:, :3] = np.maximum(SH_C0 * self.scene.sh[:, 0, :].astype(np.float64) + 0.5, 0.0)
            self.colors = _float_buffer(self.ctx, colors)
        return self.colors

    def preprocess_chunks(self, layout: StorageLayout, colors_at_load: bool) -> Iterator[Chunk]:
        """Binds each chunk's ranges in turn (gaussians at 0, the colours at load or the
        SH at 1, the chunk's splat block at 2) and yields it, for one dispatch each."""
        count = self.scene.count
        for start in range(0, count, layout.chunk):
            self.bind_chunk(layout, colors_at_load, start)
            block_start = start - start % layout.splats_per_block
            self.bind_records(layout, block_start)
            yield Chunk(start, min(layout.chunk, count - start), start - block_start)

    def bind_chunk(self, layout: StorageLayout, colors_at_load: bool, start: int) -> None:
        """Binds the chunk of gaussians from scene row ``start`` at 0, and their colours
        at load or SH at 1."""
        if colors_at_load:
            colors, harmonics_bytes = self.color_buffer(), COLOR_BYTES
        else:
            colors, harmonics_bytes = self.harmonics, sh_coefficient_count(self.scene.sh_degree) * 12
        n = min(layout.chunk, self.scene.count - start)
        self.gaussians.bind_to_storage_buffer(0, offset=start * GAUSSIAN_BYTES, size=n * GAUSSIAN_BYTES)
        colors.bind_to_storage_buffer(1, offset=start * harmonics_bytes, size=n * harmonics_bytes)

    def bind_records(self, layout: StorageLayout, block_start: int) -> None:
        """Binds the splat block of records from ``block_start`` at 2 (writable)."""
        block_count = min(layout.splats_per_block, self.scene.count - block_start)
        self.splats.bind_to_storage_buffer(2, offset=block_start * layout.splat_bytes,
                                           size=block_count * layout.splat_bytes)

    def bind_places(self, order_count: int, ranks: np.ndarray | None) -> None:
        """Binds the order (its first ``order_count``) at 3 and, where the places are
        ranked (:func:`place_runs`), ``ranks`` at 4, for a draw-order preprocessing."""
        self.order.bind_to_storage_buffer(3, size=max(order_count, 1) * 4)
        if ranks is None:
            self.order.bind_to_storage_buffer(4, size=4)  # declared by the shader, not read
            return
        if self._ranks is None:
            self._ranks = self.ctx.buffer(reserve=max(self.scene.count, 1) * 4)
        self._ranks.write(ranks)
        self._ranks.bind_to_storage_buffer(4, size=max(len(ranks), 1) * 4)

    def quad_indices(self) -> moderngl.Buffer:
        """The indexed draw's index buffer: 6 uint32 per gaussian, (0, 1, 2, 2, 1, 3) + 4q
        for quad q (the triangle strip's two triangles); made on first use."""
        if self._quad_indices is None:
            quads = np.arange(max(self.scene.count, 1), dtype=np.uint32)[:, None] * np.uint32(4)
            indices = quads + np.array([0, 1, 2, 2, 1, 3], np.uint32)
            self.ctx.error  # noqa: B018 - clears an earlier error, so the check below sees only this one
            self._quad_indices = self.ctx.buffer(indices)
            if self.ctx.error == "GL_OUT_OF_MEMORY":
                self._quad_indices.release()
                self._quad_indices = None
                raise UserError(f"not enough GPU memory for the index buffer of {self.scene.count:,} quads")
        return self._quad_indices

    def bind_for_draw(self, layout: StorageLayout, order_count: int) -> None:
        """Binds the first ``order_count`` indices of ``order`` at 0 and every splat
        block at 1, 2, ... for the vertex stage."""
        count = self.scene.count
        self.order.bind_to_storage_buffer(0, size=order_count * 4)
        for block in range(layout.splat_blocks):
            start = block * layout.splats_per_block
            n = max(1, min(layout.splats_per_block, count - start))
            self.splats.bind_to_storage_buffer(1 + block, offset=start * layout.splat_bytes,
                                               size=n * layout.splat_bytes)

    def upload_order(self, order: np.ndarray | DeviceIndices, count: int) -> bool:
        """Puts ``order`` ((count,) uint32, or indices a GPU sort keeps in a buffer, copied
        GPU to GPU) in ``order`` unless these very indices are already there; True when
        it was written."""
        if order is self._uploaded_order:
            return False
        if count > self.scene.count:
            raise ValueError("order longer than the scene")
        if isinstance(order, DeviceIndices):
            if count:
                self.ctx.copy_buffer(self.order, order.buffer, size=count * 4)
        else:
            self.order.write(np.ascontiguousarray(order, dtype=np.uint32))
        self._uploaded_order = order
        return True

    def set_selection(self, mask: np.ndarray | None, key: bytes | None = None) -> None:
        """Shows the gaussians of ``mask`` ((N,) bool; None or none set: no selection)
        tinted: one bit a gaussian in 32-bit words, bit ``row % 32`` of word ``row // 32``
        (glsl/preprocess.comp, SELECTION), uploaded when ``key`` (the mask's digest)
        changes; the scene's own buffers stay as they are."""
        if key is not None and key == self.selection_key:
            return
        if mask is None or not mask.any():
            self.selection_key = None
            return
        bits = np.zeros(-(-self.scene.count // 32) * 32, bool)
        bits[: self.scene.count] = mask
        data = np.packbits(bits, bitorder="little").view("<u4")  # bit j of word w: row 32 w + j
        if self._selection is None or self._selection.size < data.nbytes:
            if self._selection is not None:
                self._selection.release()
            self._selection = self.ctx.buffer(reserve=max(data.nbytes, 4))
        self._selection.write(data)
        self.selection_key = key if key is not None else data.tobytes()

    def bind_selection(self) -> None:
        """Binds the selection's bits at 5 (set_selection)."""
        self._selection.bind_to_storage_buffer(5)

    def read_records(self, layout: StorageLayout) -> np.ndarray:
        """(N, splat_bytes / 4) float32 copy of the records as ``layout`` writes them."""
        count, floats = self.scene.count, layout.splat_bytes // 4
        return np.frombuffer(self.splats.read(size=count * floats * 4), np.float32).reshape(count, floats)

    def release(self) -> None:
        for obj in (self.gaussians, self.harmonics, self.splats, self.order, self.colors, self._quad_indices,
                    self._ranks, self._selection):
            if obj is not None:
                obj.release()
        self.colors = self._quad_indices = self._ranks = self._selection = None
