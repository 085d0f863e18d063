"""``doctor``'s speed rows, measured with ``bench gpu``'s and ``bench sort``'s own code:

- a frame and a stereo pair of ``bench gpu``'s generated outdoor scene (SH degree 3;
  the full run: 1M gaussians at 1920 x 1080 and a Quest 3 pair at the headset's size;
  ``--quick``: ``bench gpu --quick``'s sizes) in today's defaults and in each option of
  ``bench.gpu.OPTIONS`` whose correctness rows passed here, as ratios measured in the
  same frames (``bench.gpu.measure_case``); the pair measures today's and the options
  faster than today's in the frame; the fill rate (rasterized fragments a second of
  today's draw) of both;
- the CPU sort (``DepthSorter``, every core) against the GPU sort of ``bench sort``'s
  generated cube (``bench.sort_timing.gpu_sort_ms``: the same order, checked, the GL
  drained) at 1M and 3M gaussians (``--quick``: 100k and 300k), medians;
- the VR budget: the pair's GPU time against a headset's frame time at each refresh rate.

On a software renderer each piece of work is timed on the CPU with the GL drained
(``bench gpu``'s clock), and the full run times one frame (its passes take seconds).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from raygs_viewer.bench import gpu as bench_gpu
from raygs_viewer.bench.common import count_label, fmt_ms, fmt_ratio
from raygs_viewer.bench.cube import generated_scene, view_camera
from raygs_viewer.bench.sort_timing import P_MIN, TIMING_SIZE, gpu_sort_ms
from raygs_viewer.camera.stereo import frame_budget
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import SortRequest


@dataclass(frozen=True)
class SpeedSizes:
    """What the speed rows measure: the generated scene's size, the frame's size, the
    pair's eye (the headset's shrunk ``eye_shrink`` times), timed frames on a GPU and on
    a software renderer, the sort sizes and timed sorts."""

    count: int
    mono: tuple[int, int]
    eye_shrink: int
    frames: int
    software_frames: int
    sort_counts: tuple[int, ...]
    sort_repeat: int


FULL_SPEED = SpeedSizes(1_000_000, bench_gpu.MONO, 1, bench_gpu.DEFAULT_FRAMES, 1, (1_000_000, 3_000_000), 3)
QUICK_SPEED = SpeedSizes(bench_gpu.QUICK_COUNTS[0], bench_gpu.QUICK_MONO, bench_gpu.QUICK_EYE_SHRINK,
                         bench_gpu.QUICK_FRAMES, bench_gpu.QUICK_FRAMES, (100_000, 300_000), 3)


@dataclass(frozen=True)
class SortSpeed:
    """Median ms of the CPU and the GPU sort of ``count`` gaussians; ``note``: why the
    GPU sort has no time ("" when it has)."""

    count: int
    cpu_ms: float
    gpu_ms: float
    note: str = ""


@dataclass
class SpeedResult:
    frames: int
    drained: bool
    cases: list[bench_gpu.GpuResult] = field(default_factory=list)   # the frame, then the pair
    left_out: dict[str, str] = field(default_factory=dict)           # option -> why not measured
    sorts: list[SortSpeed] = field(default_factory=list)


def measure_speed(ctx, sizes: SpeedSizes, drained: bool, correct: Callable[[str], str | None],
                  say: Callable[[str], None]) -> SpeedResult:
    """Every speed row; ``correct(option name)``: None where the option's correctness
    rows passed here, else why it is not measured."""
    frames = sizes.software_frames if drained else sizes.frames
    result = SpeedResult(frames, drained)
    options = []
    for option in bench_gpu.OPTIONS:
        why = correct(option[0])
        if why is None:
            options.append(option)
        else:
            result.left_out[option[0]] = why
    gpu_options = bench_gpu.GpuOptions(counts=(sizes.count,), scenes=(), mono=sizes.mono,
                                       eye_shrink=sizes.eye_shrink, frames=frames, command_line="doctor")
    for case in bench_gpu.build_cases(gpu_options):
        measured = bench_gpu.measure_case(ctx, case, frames, drained, tuple(options))
        result.cases.append(measured)
        say(f"fast: {bench_gpu.case_line(measured)}")
        options = [option for option in options if measured.ratio(option[0]) < 1.0]  # the pair: the faster ones
    for count in sizes.sort_counts:
        result.sorts.append(sort_speed(ctx, count, sizes.sort_repeat))
        say(f"fast: {sort_line(result.sorts[-1])}")
    return result


def sort_speed(ctx, count: int, repeat: int) -> SortSpeed:
    """The CPU and the GPU sort of ``bench sort``'s cube of ``count`` (its timing view)."""
    scene = generated_scene(count)
    camera = view_camera(*TIMING_SIZE)
    request = SortRequest(camera, P_MIN)
    with DepthSorter(scene) as cpu:
        expected = cpu.sort(request).order.indices  # untimed: the caches, the pool
        times = []
        for _ in range(repeat):
            began = time.perf_counter()
            cpu.sort(request)
            times.append(1e3 * (time.perf_counter() - began))
    try:
        gpu, _, note = gpu_sort_ms(ctx, scene, camera, repeat, expected)
    except RuntimeError as exc:  # its order differs from the CPU's: the correctness rows say where
        gpu, note = math.nan, str(exc)
    return SortSpeed(count, float(np.median(times)), gpu, note)


def sort_line(s: SortSpeed) -> str:
    gpu = f"GPU {fmt_ms(s.gpu_ms)} ({fmt_ratio(s.gpu_ms / s.cpu_ms)}x the CPU's)" if not s.note else \
        f"GPU not timed: {s.note}"
    return f"sort@{count_label(s.count)}: CPU {fmt_ms(s.cpu_ms)}, {gpu}"


def _rate(value: float) -> str:
    return f"{value / 1e6:,.3g} M/s" if math.isfinite(value) else "n/a"


def speed_tables(result: SpeedResult) -> list[str]:
    """The speed section's markdown tables (after its heading)."""
    lines = ["| case | size | visible / N | today: preprocess + draw | fragments rasterized | kept | fill |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in result.cases:
        lines.append(f"| {r.name} {r.view} | {r.size} | {r.visible:,} / {r.count:,} | {fmt_ms(r.frame_ms['today'])} | "
                     f"{r.rasterized / 1e6:.2f} M | {r.kept / 1e6:.2f} M | {_rate(r.fill_rate)} |")
    names = [name for name, _, _ in bench_gpu.OPTIONS]
    lines += ["", "Each option's whole frame over today's, in the same frames (below 1: faster); the largest "
              "difference from today's image:", "",
              "| option | " + " | ".join(f"{r.view}" for r in result.cases) + " | differs from today's by |",
              "|---|" + "---:|" * len(result.cases) + "---:|"]
    for name in names:
        if name in result.left_out:
            lines.append(f"| {name} | " + " | ".join("" for _ in result.cases) + f" | not measured: "
                         f"{result.left_out[name]} |")
            continue
        cells = []
        for r in result.cases:
            ratio = r.ratio(name)
            cells.append("not measured (not faster in the frame)" if name not in r.frame_ms else
                         f"**{fmt_ratio(ratio)}** (faster)" if ratio < 1 else fmt_ratio(ratio))
        error = result.cases[0].max_error.get(name, math.nan) if result.cases else math.nan
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {'identical' if error == 0 else f'{error:.2g}'} |")
    lines += ["", "| sort | CPU (every core) | GPU | GPU / CPU |", "|---|---:|---:|---:|"]
    for s in result.sorts:
        gpu = fmt_ms(s.gpu_ms) if not s.note else f"not timed: {s.note}"
        lines.append(f"| {count_label(s.count)} gaussians | {fmt_ms(s.cpu_ms)} | {gpu} | "
                     f"{fmt_ratio(s.gpu_ms / s.cpu_ms)} |")
    pairs = [r for r in result.cases if r.view == "stereo"]
    if pairs:
        pair = pairs[0]
        faster = [n for n in names if n in pair.frame_ms and n != bench_gpu.TODAY and pair.ratio(n) < 1]
        best = min(faster, key=pair.ratio, default=None)
        rows = [("today", pair.frame_ms[bench_gpu.TODAY])]
        if best is not None:
            rows.append((best, pair.frame_ms[best]))
        budget = frame_budget(0.0)
        lines += ["", f"VR budget: the pair's GPU time (both eyes' preprocess + draw) over the frame time of "
                  f"{bench_gpu.HEADSET.label} at each refresh rate; beside it the CPU cull+sort of its order.", "",
                  "| path | both eyes | " + " | ".join(f"{rate} Hz ({fmt_ms(seconds * 1e3)})"
                                                   for rate, seconds, _ in budget) + " | CPU cull+sort |",
                  "|---|---:|" + "---:|" * len(budget) + "---:|"]
        for name, ms in rows:
            used = " | ".join(f"{fraction:.2f}×" for _, _, fraction in frame_budget(ms * 1e-3))
            lines.append(f"| {name} | {fmt_ms(ms)} | {used} | {fmt_ms(pair.sort_ms)} |")
    return lines
