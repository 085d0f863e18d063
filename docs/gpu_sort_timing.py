"""Times the GPU sort (raygs_viewer/render/gl/gpu_sort.py) against the CPU sort
(DepthSorter, 2 workers) on the benchmark cube (bench/cube.py: ``generated_scene``,
``view_camera(1280, 720)``), on whatever GL the headless context finds (llvmpipe on the
development machines: a correctness platform, so read the ratios, not a GPU's speed).

    python docs/gpu_sort_timing.py [--sizes 100000 1000000] [--repeat N] [--workers N]

Each time is the median of ``--repeat`` sorts of one request after a first, untimed one
(which compiles the programs and uploads the support arrays): the GPU's from the call to
its return, with the GPU drained (``GpuSorter(finish=True)``: the sort ends in
``ctx.finish()``); the CPU's the same call on a DepthSorter. The orders are checked equal.
The request culls with the default dilation and p_min and sorts by depth ("auto").
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from raygs_viewer.bench.cube import generated_scene, view_camera
from raygs_viewer.render.gl.context import context_description, create_headless_context
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import sort_request
from raygs_viewer.sort.depth import DepthSorter


def _timed(sort, request, repeat: int) -> tuple[float, dict[str, float], object]:
    """(median seconds, median of each part of ``times``, the last result)."""
    result = sort(request)  # compiles, uploads
    seconds, parts = [], {}
    for _ in range(repeat):
        start = time.perf_counter()
        result = sort(request)
        seconds.append(time.perf_counter() - start)
        for name, value in result.times.items():
            parts.setdefault(name, []).append(value)
    return statistics.median(seconds), {name: statistics.median(v) for name, v in parts.items()}, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--key", choices=["depth", "distance"], default="depth")
    args = parser.parse_args()
    ctx = create_headless_context()
    camera = view_camera(1280, 720)
    settings = RenderSettings(order="distance") if args.key == "distance" else RenderSettings()
    print(context_description(ctx))
    print(f"{'N':>9} {'kept':>9} {'GPU ms':>8} {'(cull':>7} {'sort)':>7} {'CPU ms':>8} {'(cull':>7} {'sort)':>7} "
          f"{'GPU/CPU':>8}")
    for count in args.sizes:
        scene = generated_scene(count)
        request = sort_request(camera, settings)
        with GpuSorter(ctx, scene) as gpu, DepthSorter(scene, args.workers) as cpu:
            g, g_parts, g_result = _timed(gpu.sort, request, args.repeat)
            c, c_parts, c_result = _timed(cpu.sort, request, args.repeat)
            assert np.array_equal(g_result.order.host_indices(), c_result.order.indices)
            kept = g_result.order.count
        print(f"{count:>9,} {kept:>9,} {g * 1e3:>8.1f} {g_parts['cull'] * 1e3:>7.1f} {g_parts['sort'] * 1e3:>7.1f} "
              f"{c * 1e3:>8.1f} {c_parts['cull'] * 1e3:>7.1f} {c_parts['sort'] * 1e3:>7.1f} {g / c:>8.2f}")
    ctx.release()


if __name__ == "__main__":
    main()
