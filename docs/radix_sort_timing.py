"""Times the GPU radix sort (raygs_viewer/render/gl/radix_sort.py) against numpy's
stable argsort of the same keys, on whatever GL the headless context finds (llvmpipe
on the development machines: a correctness platform, so read the ratios, not a GPU's
speed).

    python docs/radix_sort_timing.py [--digit-bits 4|8] [--tile-items N] [--repeat N]

Each GPU time is the median of ``--repeat`` sorts of freshly uploaded keys, from the
first command to ``ctx.finish()`` (the upload is finished before the clock starts);
the first sort of each kind, which compiles the programs, is not counted. Every sort is
checked against the argsort. For 16-bit keys the last column times numpy's argsort of
the keys as uint16, which numpy sorts by radix.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from raygs_viewer.render.gl.context import create_headless_context, context_description
from raygs_viewer.render.gl.radix_sort import GpuRadixSort, RadixLayout

SIZES = (100_000, 1_000_000)


def _keys(rng: np.random.Generator, count: int, key_bits: int) -> np.ndarray:
    if key_bits == 16:
        return rng.integers(0, 1 << 16, count, dtype=np.uint32)
    # Depths as float32 bit patterns: positive floats sort as their bits do.
    return rng.uniform(0.1, 100.0, count).astype(np.float32).view(np.uint32)


def _cpu_ms(keys: np.ndarray, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        np.argsort(keys, kind="stable")
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--digit-bits", type=int, default=8)
    parser.add_argument("--tile-items", type=int, default=8)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    ctx = create_headless_context()
    layout = RadixLayout(digit_bits=args.digit_bits, tile_items=args.tile_items)
    sorter = GpuRadixSort(ctx, max(SIZES), layout)
    rng = np.random.default_rng(0)
    print(f"{context_description(ctx)}; {layout}")
    print(f"{'M':>9} {'key bits':>8} {'GPU sort ms':>12} {'np.argsort ms':>14} {'ratio':>6} {'as uint16 ms':>14}")
    for count in SIZES:
        for key_bits in (16, 32):
            keys = _keys(rng, count, key_bits)
            values = np.arange(count, dtype=np.uint32)
            expected = values[np.argsort(keys, kind="stable")]
            key_buffer, value_buffer = ctx.buffer(keys), ctx.buffer(values)
            gpu = []
            for attempt in range(args.repeat + 1):
                key_buffer.write(keys)
                value_buffer.write(values)
                ctx.finish()
                start = time.perf_counter()
                sorter.sort(key_buffer, value_buffer, count, key_bits)
                ctx.finish()
                if attempt:
                    gpu.append(time.perf_counter() - start)
                assert np.array_equal(np.frombuffer(value_buffer.read(), np.uint32), expected)
            key_buffer.release()
            value_buffer.release()
            g, c = statistics.median(gpu) * 1e3, _cpu_ms(keys, args.repeat)
            # numpy sorts 16-bit dtypes by radix: the CPU's best for 16-bit keys.
            narrow = f"{_cpu_ms(keys.astype(np.uint16), args.repeat):>14.1f}" if key_bits == 16 else f"{'':>14}"
            print(f"{count:>9,} {key_bits:>8} {g:>12.1f} {c:>14.1f} {g / c:>6.1f} {narrow}")
    sorter.release()
    ctx.release()


if __name__ == "__main__":
    main()
