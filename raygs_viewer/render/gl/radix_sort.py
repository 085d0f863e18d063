"""A stable GPU radix sort of (uint32 key, uint32 value) pairs held in storage buffers,
in OpenGL 4.3 compute shaders: the sort stage of a depth sort that stays on the GPU
(cull -> keys -> sort -> indirect draw).

After :meth:`GpuRadixSort.sort` the values read ``values[np.argsort(keys & mask,
kind="stable")]`` bit for bit (``mask`` the low ``key_bits``), on any driver: no
subgroup operations, no extensions, no order taken from atomics.

Per pass of ``digit_bits`` (8 by default; 16-bit keys take two passes, 32-bit four):

1. glsl/radix_count.comp: each workgroup counts its tile's digits, stored digit-major.
2. glsl/radix_scan_blocks.comp and glsl/radix_scan_top.comp: one exclusive scan over
   (digit, tile), in two levels, gives each (digit, tile) where its elements start.
3. glsl/radix_scatter.comp: each workgroup sorts its tile stably by the digit in shared
   memory (4 bits at a time, by counting and one scan) and writes every element to its
   (digit, tile) start plus its place in the tile's run of that digit.

Before the passes, glsl/radix_setup.comp reads the count (a Python int written to a small
buffer, or a word an earlier pass left in a GPU buffer: :class:`CountRef`) and writes the
tile and scan sizes and the indirect dispatch arguments (``run_indirect``) of the passes.
Indirect rather than dispatching for the capacity and letting idle groups exit: those
would cost every pass the whole capacity's groups, and the scan the capacity's length,
where a depth sort after culling often sorts a small part of the scene. One path serves
both kinds of count, so the host count tests the GPU one.

8-bit digits rather than 4, for the GPU: there the passes are bound by memory traffic,
and 8-bit digits read and write every pair half as often for the same local ranking work
(4 bits at a time either way). llvmpipe, where memory is a CPU's cache and each shared
memory access a scalar loop over the lanes, runs the 4-bit layout 2 to 21 % faster at 1M
pairs (docs/radix_sort_timing.py, two runs on a busy 2-core machine): not what this sort
is for. :class:`RadixLayout` takes either.

Limits: ``count`` up to what one storage block holds per buffer (``capacity * 4`` bytes,
128 MiB on llvmpipe: 33M pairs); dispatches past 65535 workgroups fold into rows. Each
tile's ranking counts in 16-bit halves (a tile holds far fewer than 65536 elements) and
uses 28 KiB of shared memory by default (GL guarantees 32).

The passes ping-pong between the caller's buffers and one scratch pair; the pass count
is even (2, 4 or 8), so the sorted pairs end where they started: the sort is in place.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import moderngl

from raygs_viewer.render.gl.shaders import Programs, set_uniform
from raygs_viewer.render.gl.storage import RANGE_ALIGNMENT, gpu_limit

#: Invocations per workgroup: a constant every GL 4.3 driver runs (it guarantees 1024), one
#: per digit of an 8-bit pass when a tile's digit offsets are fetched.
WORKGROUP = 256
#: Bits per pass (see the module's docstring for why 8).
DEFAULT_DIGIT_BITS = 8
KEY_BITS = (16, 32)
#: GL guarantees 32 KiB of shared memory to a workgroup; the scatter pass must fit.
SHARED_BYTES = 32768
#: Bytes of RadixParams (glsl/radix.glsl): four words, then the tile and scan dispatches.
PARAMS_BYTES = 48
TILE_DISPATCH, SCAN_DISPATCH = 16, 32  # their offsets
# Storage bindings of the passes (glsl/radix*.comp).
PARAMS, COUNT_SOURCE, KEYS_IN, VALUES_IN, KEYS_OUT, VALUES_OUT, COUNTS, BLOCK_SUMS = range(8)
_BARRIERS = moderngl.SHADER_STORAGE_BARRIER_BIT | moderngl.COMMAND_BARRIER_BIT


@dataclass(frozen=True)
class RadixLayout:
    """How the work is cut. The defaults serve; the tests shrink them to reach the paths
    a large sort takes (several scan steps, folded dispatches) with few elements.

    ``digit_bits``: bits per pass, 4 or 8. ``tile_items`` / ``scan_items``: elements
    per invocation in the tile passes / the scan passes (a tile holds ``256 *
    tile_items``). ``max_groups_x``: workgroups per dispatch row; GL guarantees 65535,
    a larger count folds into rows."""

    digit_bits: int = DEFAULT_DIGIT_BITS
    tile_items: int = 8
    scan_items: int = 8
    max_groups_x: int = 65535

    def __post_init__(self):
        if self.digit_bits not in (4, 8):
            raise ValueError(f"digit_bits must be 4 or 8, got {self.digit_bits}")
        if not 1 <= self.max_groups_x <= 65535:
            raise ValueError(f"max_groups_x must be 1 to 65535, got {self.max_groups_x}")
        for name, items, shared in (("tile_items", self.tile_items, self.scatter_shared_bytes()),
                                    ("scan_items", self.scan_items, 4 * (self.scan_block + 2 * WORKGROUP))):
            if items < 1 or shared > SHARED_BYTES:
                raise ValueError(f"{name} {items}: its pass would need {shared} bytes of shared memory, "
                                 f"GL guarantees {SHARED_BYTES}")

    @property
    def radix(self) -> int:
        return 1 << self.digit_bits

    @property
    def tile(self) -> int:
        return WORKGROUP * self.tile_items

    @property
    def scan_block(self) -> int:
        return WORKGROUP * self.scan_items

    def scatter_shared_bytes(self) -> int:
        """Shared memory of glsl/radix_scatter.comp: the tile's keys and values, 8 counter
        words per invocation, the scan's two rows, two words per digit."""
        return 4 * (2 * self.tile + 8 * WORKGROUP + 2 * WORKGROUP + 2 * self.radix)

    def tiles(self, count: int) -> int:
        return -(-count // self.tile)

    def defines(self) -> dict[str, object]:
        return {"WORKGROUP": WORKGROUP, "DIGIT_BITS": self.digit_bits, "TILE_ITEMS": self.tile_items,
                "SCAN_ITEMS": self.scan_items, "MAX_GROUPS_X": f"{self.max_groups_x}u"}


@dataclass(frozen=True)
class CountRef:
    """An element count left on the GPU: the uint32 at byte ``offset`` of ``buffer``
    (a multiple of 4), written by an earlier pass. The sort reads it there, never on
    the host."""

    buffer: moderngl.Buffer
    offset: int = 0


class SortedPairs(NamedTuple):
    """The buffers holding the sorted keys and values: the first ``count`` uint32 of each."""

    keys: moderngl.Buffer
    values: moderngl.Buffer


class GpuRadixSort:
    """The sort's programs and scratch buffers: a key/value pair the size of the largest
    sort so far (grown on demand from ``capacity`` elements), the (digit, tile) counts,
    their block sums, the parameters and a word for a host count. ``programs``: a
    :class:`Programs` to build in (the renderer's); by default the sort keeps its own."""

    def __init__(self, ctx: moderngl.Context, capacity: int = 0, layout: RadixLayout = RadixLayout(),
                 programs: Programs | None = None):
        self.ctx = ctx
        self.layout = layout
        self.block_limit = gpu_limit(ctx, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27)
        self._own_programs = programs is None
        self.programs = programs or Programs(ctx)
        self._params = ctx.buffer(reserve=PARAMS_BYTES)
        self._host_count = ctx.buffer(reserve=16)
        self._scratch: list[moderngl.Buffer] = []  # keys, values, counts, block sums
        self.capacity = 0
        if capacity:
            self._hold(capacity)

    def _hold(self, capacity: int) -> None:
        if capacity * 4 > self.block_limit:
            raise ValueError(f"{capacity:,} pairs need {capacity * 4:,} bytes per key or value range; "
                             f"one storage block holds {self.block_limit:,}")
        if capacity <= self.capacity:
            return
        for buffer in self._scratch:
            buffer.release()
        counts = self.layout.radix * self.layout.tiles(capacity)
        block_sums = -(-counts // self.layout.scan_block)
        self._scratch = [self.ctx.buffer(reserve=4 * n) for n in (capacity, capacity, counts, block_sums)]
        self.capacity = capacity

    def sort(self, keys: moderngl.Buffer, values: moderngl.Buffer, count: int | CountRef,
             key_bits: int = 32) -> SortedPairs:
        """Sorts the first ``count`` pairs of ``keys`` and ``values`` (uint32 each, numpy
        ``(count,)`` ``np.uint32`` as bytes) stably by the low ``key_bits`` (16 or 32) of
        the keys, ascending; higher bits are ignored. In place: the sorted pairs are in
        ``keys`` and ``values`` (returned), the words past ``count`` untouched.

        ``count``: an int, or a :class:`CountRef` to a count on the GPU, which is then
        never read back; a GPU count larger than the buffers hold sorts what they hold.
        Issues GPU commands only: the caller decides when to wait. Leaves storage
        bindings 0 to 7 on its own buffers: a later pass binds its own (as the renderer's
        passes do before each use)."""
        if key_bits not in KEY_BITS:
            raise ValueError(f"key_bits must be 16 or 32, got {key_bits}")
        if keys is values:
            raise ValueError("keys and values must be two buffers")
        held = min(keys.size, values.size) // 4
        if isinstance(count, CountRef):
            if count.offset % 4 or not 0 <= count.offset <= count.buffer.size - 4:
                raise ValueError(f"a count at byte {count.offset} of a {count.buffer.size}-byte buffer")
            capacity, source = held, count
        else:
            if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= held:
                raise ValueError(f"count must be an int from 0 to the {held:,} pairs the buffers hold, got {count!r}")
            if count == 0:
                return SortedPairs(keys, values)
            self._host_count.write(int(count).to_bytes(4, "little"))
            capacity, source = count, CountRef(self._host_count, 0)
        if capacity == 0:
            return SortedPairs(keys, values)
        self._hold(capacity)
        self._setup(source, capacity)
        self._passes(keys, values, capacity, key_bits)
        return SortedPairs(keys, values)

    def _setup(self, source: CountRef, capacity: int) -> None:
        # A range around the count, not the whole buffer: it may be larger than one
        # storage block may be (a draw's records); range offsets must be aligned.
        start = source.offset - source.offset % RANGE_ALIGNMENT
        source.buffer.bind_to_storage_buffer(COUNT_SOURCE, offset=start,
                                             size=min(RANGE_ALIGNMENT, source.buffer.size - start))
        self._params.bind_to_storage_buffer(PARAMS)
        setup = self.programs.compute("radix_setup.comp", self.layout.defines())
        set_uniform(setup, "u_count_word", (source.offset - start) // 4)
        set_uniform(setup, "u_capacity", capacity)
        setup.run(1)
        self.ctx.memory_barrier(_BARRIERS)

    def _passes(self, keys: moderngl.Buffer, values: moderngl.Buffer, capacity: int, key_bits: int) -> None:
        defines = self.layout.defines()
        count_pass = self.programs.compute("radix_count.comp", defines)
        scan_blocks = self.programs.compute("radix_scan_blocks.comp", defines)
        scan_top = self.programs.compute("radix_scan_top.comp", defines)
        scatter = self.programs.compute("radix_scatter.comp", defines)
        scratch_keys, scratch_values, counts, block_sums = self._scratch
        counts.bind_to_storage_buffer(COUNTS)
        block_sums.bind_to_storage_buffer(BLOCK_SUMS)
        self._params.bind_to_storage_buffer(PARAMS)
        # An even number of passes (2, 4 or 8) ends in the caller's pair: in place.
        pairs = [(keys, values), (scratch_keys, scratch_values)]
        size = capacity * 4
        for number, shift in enumerate(range(0, key_bits, self.layout.digit_bits)):
            (keys_in, values_in), (keys_out, values_out) = pairs[number % 2], pairs[1 - number % 2]
            keys_in.bind_to_storage_buffer(KEYS_IN, size=size)
            values_in.bind_to_storage_buffer(VALUES_IN, size=size)
            keys_out.bind_to_storage_buffer(KEYS_OUT, size=size)
            values_out.bind_to_storage_buffer(VALUES_OUT, size=size)
            set_uniform(count_pass, "u_shift", shift)
            set_uniform(scatter, "u_shift", shift)
            # Sized by radix_setup.comp from the count where it lies (see the module's docstring).
            count_pass.run_indirect(self._params, TILE_DISPATCH)
            self.ctx.memory_barrier(_BARRIERS)
            scan_blocks.run_indirect(self._params, SCAN_DISPATCH)
            self.ctx.memory_barrier(_BARRIERS)
            scan_top.run(1)
            self.ctx.memory_barrier(_BARRIERS)
            scatter.run_indirect(self._params, TILE_DISPATCH)
            self.ctx.memory_barrier(_BARRIERS)
        # Whatever reads the result next (a draw, buffer.read) sees the last writes.
        self.ctx.memory_barrier()

    def release(self) -> None:
        for buffer in (self._params, self._host_count, *self._scratch):
            buffer.release()
        self._scratch = []
        self.capacity = 0
        if self._own_programs:
            self.programs.release()
