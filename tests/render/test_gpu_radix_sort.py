"""The GPU radix sort (raygs_viewer/render/gl/radix_sort.py) against numpy's stable
argsort, bit for bit: keys with many ties (where only a stable sort gives one answer),
unique values that show any tie out of order, every size where tiles and scan blocks
begin and end, a count left on the GPU, and small layouts that take the paths only
millions of elements take by default (several scan steps, folded dispatches)."""

import numpy as np
import pytest

from raygs_viewer.render.gl import shaders
from raygs_viewer.render.gl.radix_sort import WORKGROUP, CountRef, GpuRadixSort, RadixLayout, SortedPairs

TILE = RadixLayout().tile
#: An odd multiplier is a bijection of uint32: unique values, every bit in use.
SCRAMBLE = np.uint32(2654435761)


@pytest.fixture(scope="module")
def sorter(gl_session_ctx):
    gl_session_ctx.__enter__()
    sorter = GpuRadixSort(gl_session_ctx)
    yield sorter
    gl_session_ctx.__enter__()
    sorter.release()


def _values(rng: np.random.Generator, count: int) -> np.ndarray:
    return rng.permutation(count).astype(np.uint32) * SCRAMBLE


def _tied_keys(rng: np.random.Generator, count: int, key_bits: int, distinct: int = 37) -> np.ndarray:
    """Keys drawn from ``distinct`` values spread over all ``key_bits`` bits: many ties."""
    pool = rng.integers(0, 1 << key_bits, distinct, dtype=np.uint64).astype(np.uint32)
    pool[0] = (1 << key_bits) - 1  # the largest key, the padding's digits
    pool[1] = 0
    return rng.choice(pool, count)


def _sorted_on_gpu(ctx, sorter, keys, values, key_bits, count=None, pad=0):
    """Sorts ``keys``/``values`` (``count`` of them, all by default; ``pad`` words of
    0xDEADBEEF after) on the GPU; returns the read-back keys and values (with the pad)."""
    fill = np.full(pad, 0xDEADBEEF, np.uint32)
    key_buffer = ctx.buffer(np.concatenate([keys, fill]) if len(keys) + pad else bytes(4))
    value_buffer = ctx.buffer(np.concatenate([values, fill]) if len(values) + pad else bytes(4))
    try:
        result = sorter.sort(key_buffer, value_buffer, len(keys) if count is None else count, key_bits)
        assert result == SortedPairs(key_buffer, value_buffer)  # in place
        return (np.frombuffer(key_buffer.read(), np.uint32)[:len(keys) + pad],
                np.frombuffer(value_buffer.read(), np.uint32)[:len(values) + pad])
    finally:
        key_buffer.release()
        value_buffer.release()


def _check(ctx, sorter, keys, key_bits, rng, pad=0):
    values = _values(rng, len(keys))
    got_keys, got_values = _sorted_on_gpu(ctx, sorter, keys, values, key_bits, pad=pad)
    order = np.argsort(keys & np.uint32((1 << key_bits) - 1), kind="stable")
    np.testing.assert_array_equal(got_values[:len(keys)], values[order])
    np.testing.assert_array_equal(got_keys[:len(keys)], keys[order])
    assert (got_keys[len(keys):] == 0xDEADBEEF).all() and (got_values[len(keys):] == 0xDEADBEEF).all()


@pytest.mark.parametrize("key_bits", [16, 32])
@pytest.mark.parametrize("count", [0, 1, 2, TILE - 1, TILE, TILE + 1, 5 * TILE + 17])
def test_ties_keep_their_input_order(gl_ctx, sorter, count, key_bits):
    rng = np.random.default_rng(count * 100 + key_bits)
    _check(gl_ctx, sorter, _tied_keys(rng, count, key_bits), key_bits, rng, pad=3)


def test_many_tiles_take_the_two_level_scan(gl_ctx, sorter):
    """Float32 depths as keys (positive floats sort as their bits; the top bits vary),
    rounded to make ties: 147 tiles, 37,632 (digit, tile) counts in 19 scan blocks."""
    layout = sorter.layout
    count = 300_000
    assert layout.radix * layout.tiles(count) > layout.scan_block  # more than one block
    rng = np.random.default_rng(7)
    depths = np.round(rng.uniform(0.0, 3.0e4, count), 0).astype(np.float32) * np.float32(1.0e-3)
    _check(gl_ctx, sorter, depths.view(np.uint32), 32, rng)


@pytest.mark.parametrize("key_bits", [16, 32])
def test_sorted_and_reversed_inputs(gl_ctx, sorter, key_bits):
    rng = np.random.default_rng(key_bits)
    keys = np.sort(_tied_keys(rng, 3 * TILE + 5, key_bits, distinct=500))
    _check(gl_ctx, sorter, keys, key_bits, rng)
    _check(gl_ctx, sorter, keys[::-1].copy(), key_bits, rng)


def test_16_bit_keys_sort_by_their_low_16_bits(gl_ctx, sorter):
    rng = np.random.default_rng(3)
    keys = _tied_keys(rng, TILE + 100, 32)  # the high half varies too, and is ignored
    _check(gl_ctx, sorter, keys, 16, rng)


@pytest.mark.parametrize("count", [0, 1, 2 * TILE + 77])
def test_a_count_written_on_the_gpu_is_read_there(gl_ctx, sorter, count):
    """A compute pass writes the count at byte 260 (past the first bindable range, so
    the range around it is bound); only the first ``count`` pairs move."""
    rng = np.random.default_rng(11)
    total = 4 * TILE
    keys, values = _tied_keys(rng, total, 32), _values(rng, total)
    holder = gl_ctx.buffer(reserve=512)
    holder.bind_to_storage_buffer(0)
    writer = gl_ctx.compute_shader(f"""#version 430
        layout(local_size_x = 1) in;
        layout(std430, binding = 0) buffer Holder {{ uint words[]; }};
        void main() {{ words[65] = {count}u; }}""")
    try:
        writer.run(1)
        gl_ctx.memory_barrier()
        got_keys, got_values = _sorted_on_gpu(gl_ctx, sorter, keys, values, 32, count=CountRef(holder, 260))
    finally:
        writer.release()
        holder.release()
    order = np.argsort(keys[:count], kind="stable")
    np.testing.assert_array_equal(got_values[:count], values[:count][order])
    np.testing.assert_array_equal(got_values[count:], values[count:])
    np.testing.assert_array_equal(got_keys[count:], keys[count:])


def test_a_gpu_count_past_the_buffers_sorts_what_they_hold(gl_ctx, sorter):
    rng = np.random.default_rng(12)
    keys, values = _tied_keys(rng, TILE + 3, 16), _values(rng, TILE + 3)
    holder = gl_ctx.buffer(np.array([10**9], np.uint32))
    try:
        got_keys, got_values = _sorted_on_gpu(gl_ctx, sorter, keys, values, 16, count=CountRef(holder))
    finally:
        holder.release()
    np.testing.assert_array_equal(got_values, values[np.argsort(keys, kind="stable")])


def test_one_sorter_grows_and_sorts_again(gl_ctx):
    sorter = GpuRadixSort(gl_ctx, capacity=10)
    rng = np.random.default_rng(5)
    try:
        for count in (10, 3 * TILE, 7):
            _check(gl_ctx, sorter, _tied_keys(rng, count, 32), 32, rng)
        assert sorter.capacity == 3 * TILE
    finally:
        sorter.release()


# Small layouts reach what only large sorts reach by default: a block-sum scan of more
# than one step (more than scan_block blocks), dispatches folded into rows; 4-bit digits.
LAYOUTS = {
    "several top-scan steps": (RadixLayout(tile_items=1, scan_items=1), 70_000),
    "folded dispatches": (RadixLayout(tile_items=1, scan_items=1, max_groups_x=7), 3_000),
    "4-bit digits": (RadixLayout(digit_bits=4, tile_items=3, scan_items=2, max_groups_x=5), 20_000),
}


@pytest.mark.parametrize("case", LAYOUTS)
def test_small_layouts(gl_ctx, case):
    layout, count = LAYOUTS[case]
    sorter = GpuRadixSort(gl_ctx, layout=layout)
    rng = np.random.default_rng(len(case))
    try:
        for key_bits in (16, 32):
            _check(gl_ctx, sorter, _tied_keys(rng, count, key_bits, distinct=300), key_bits, rng)
    finally:
        sorter.release()
    blocks = layout.radix * layout.tiles(count) / layout.scan_block
    assert case != "several top-scan steps" or blocks > layout.scan_block
    assert case != "folded dispatches" or layout.tiles(count) > layout.max_groups_x


def test_ties_out_of_input_order_are_caught(gl_ctx, monkeypatch):
    """The check is not blind to stability: ranking each invocation's elements in stripes
    instead of runs (a tempting coalesced read) puts equal keys out of order. With keys
    that differ in their top 4 bits only, the last ranking step alone orders them and
    they still come out sorted: only the values show it. (Where earlier steps order too,
    the next scrambles their work and the keys come out wrong as well: least significant
    digit first needs every step stable.)"""
    text = shaders._read("radix_scatter.comp")
    runs = "keys[i] = s_keys[t * uint(TILE_ITEMS) + i];\n            values[i] = s_values[t * uint(TILE_ITEMS) + i];"
    stripes = "keys[i] = s_keys[i * uint(WORKGROUP) + t];\n            values[i] = s_values[i * uint(WORKGROUP) + t];"
    assert text.count(runs) == 1
    read = shaders._read
    monkeypatch.setattr(shaders, "_read", lambda name: read(name).replace(runs, stripes)
                        if name == "radix_scatter.comp" else read(name))
    sorter = GpuRadixSort(gl_ctx)  # its own programs, built from the broken source
    rng = np.random.default_rng(1)
    keys, values = _tied_keys(rng, 2 * TILE, 16) & np.uint32(0xF000), _values(rng, 2 * TILE)
    try:
        got_keys, got_values = _sorted_on_gpu(gl_ctx, sorter, keys, values, 16)
    finally:
        sorter.release()
    order = np.argsort(keys, kind="stable")
    np.testing.assert_array_equal(got_keys, keys[order])
    assert not np.array_equal(got_values, values[order])


def test_bad_arguments(gl_ctx, sorter):
    keys, values = gl_ctx.buffer(reserve=64), gl_ctx.buffer(reserve=32)
    try:
        with pytest.raises(ValueError, match="0 to the 8 pairs"):
            sorter.sort(keys, values, 9)
        with pytest.raises(ValueError, match="0 to the 8 pairs"):
            sorter.sort(keys, values, -1)
        with pytest.raises(ValueError, match="16 or 32"):
            sorter.sort(keys, values, 8, key_bits=24)
        with pytest.raises(ValueError, match="two buffers"):
            sorter.sort(keys, keys, 8)
        with pytest.raises(ValueError, match="a count at byte 30"):
            sorter.sort(keys, values, CountRef(values, 30))
        with pytest.raises(ValueError, match="a count at byte 32"):
            sorter.sort(keys, values, CountRef(values, 32))
    finally:
        keys.release()
        values.release()
    with pytest.raises(ValueError, match="shared memory"):
        RadixLayout(tile_items=16)
    with pytest.raises(ValueError, match="digit_bits"):
        RadixLayout(digit_bits=6)
    assert WORKGROUP * RadixLayout().tile_items == TILE
