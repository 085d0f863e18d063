"""``raygs-viewer bench sort``: how fast the CPU cull and sort are at real scene sizes, and
how fresh that keeps the drawn order in motion (maths page, section 9; issue 16).

For generated scenes of 100k to 6M gaussians (made in memory, SH degree 0: ``bench.cube``),
seen whole from outside, each in turn: the times of ``bench.sort_timing``, then the
freshness of ``bench.freshness`` with those latencies; at the end the loads of
generated PLYs (``bench.loading``). This module runs them and writes the report.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from typing import TextIO

from raygs_viewer.bench import common
from raygs_viewer.bench.common import count_label
from raygs_viewer.bench.cube import (
    FLY_RADII_PER_S,
    FOV_Y,
    TURN_DEGREES_PER_S,
    generated_scene,
    view_camera,
    view_distance,
)
from raygs_viewer.bench.freshness import (
    AGE_RATES,
    FPS,
    QUICK_LADDER_FRAMES,
    QUICK_SAMPLE_TIMES,
    RENDER_SIZE,
    WITHIN_DB,
    Freshness,
    crossing_lines,
    db,
    frames_old,
    measure_scene,
)
from raygs_viewer.bench.loading import LoadFigures, format_load_lines, measure_generated_loads
from raygs_viewer.bench.sort_timing import (
    PROJECTED_CORES,
    TIMING_SIZE,
    SceneTimes,
    summary_lines,
    table_rows,
    time_scene,
    timing_lines,
    worker_counts,
)
from raygs_viewer.render.gl.context import context_description

COUNTS = (100_000, 1_000_000, 3_000_000, 6_000_000)
QUICK_COUNTS = COUNTS[:3]
DEFAULT_REPEAT, QUICK_REPEAT = 9, 5
#: Loads are measured for the scene sizes from this one up (1M, 3M, 6M by default).
LOAD_MIN = 1_000_000
#: --quick measures the freshness up to this size only: on two cores the freshness of 3M
#: takes 20 minutes (mostly its exact per-pixel frames) and of 1M three, that of 100k half
#: a minute, while the times and loads, which --quick keeps for every size, take seconds.
QUICK_FRESHNESS_MAX = 100_000


@dataclass(frozen=True)
class SortOptions(common.RunOptions):
    counts: tuple[int, ...] = QUICK_COUNTS
    repeat: int = QUICK_REPEAT
    sample_times: tuple[float, ...] = QUICK_SAMPLE_TIMES
    ladder_frames: tuple[int, ...] = QUICK_LADDER_FRAMES
    freshness: bool = True
    loads: bool = True                   # load time and peak memory of SH-3 PLYs of the counts >= LOAD_MIN
    command_line: str = "raygs-viewer bench sort"
    freshness_max: int | None = None     # the freshness only for counts up to this (None: every count)


@dataclass
class SceneResult(SceneTimes):
    freshness: list[Freshness] = field(default_factory=list)


@dataclass
class SortResults:
    scenes: list[SceneResult]
    machine: str
    cpu_count: int
    options: SortOptions
    date: str
    seconds: float
    view: str
    loads: list[tuple[int, LoadFigures]] = field(default_factory=list)  # (count, figures)


def run_sort(options: SortOptions, ctx=None, out: TextIO | None = None) -> SortResults:
    say = common.printer(out)
    started = time.perf_counter()
    workers = worker_counts()
    timing_camera = view_camera(*TIMING_SIZE)
    view = (f"{view_distance():.2f} units in front of the cube's centre, {FOV_Y:g} deg vertical field, "
            f"{TIMING_SIZE[0]}x{TIMING_SIZE[1]}: the cube's bounding sphere fills the height, so every gaussian "
            f"is in view")
    results: list[SceneResult] = []
    with common.gl_context(ctx, options.gl_backend) as ctx, ctx:
        machine = context_description(ctx)
        say(f"bench sort: scenes of {', '.join(count_label(n) for n in options.counts)} gaussians, workers "
            f"{', '.join(map(str, workers))} of {os.cpu_count()} cores, {options.repeat} runs each, on {machine}")
        say(f"view: {view}")
        for count in options.counts:
            say(f"[{count_label(count)}] generating ...")
            scene = generated_scene(count)
            result = SceneResult(**vars(time_scene(ctx, scene, timing_camera, options.repeat, workers)))
            for line in timing_lines(result):
                say(line)
            if options.freshness and (options.freshness_max is None or count <= options.freshness_max):
                result.freshness = measure_scene(ctx, scene, result, sample_times=options.sample_times,
                                                 ladder_frames=options.ladder_frames, say=say)
            results.append(result)
            del scene
    loads = []
    if options.loads:
        loads = measure_generated_loads([n for n in options.counts if n >= LOAD_MIN], log=say)
        for line in format_load_lines(loads):
            say(line)
    seconds = time.perf_counter() - started
    say(f"bench sort: done in {seconds:.0f} s")
    return SortResults(results, machine, os.cpu_count() or 1, options, common.run_date(), seconds, view, loads)


# --- the report ------------------------------------------------------------------------------------

def format_report(results: SortResults) -> str:
    lines = [
        "# CPU cull and sort at real sizes: the figures", "",
        "Generated by `raygs-viewer bench sort`.", "",
        f"- Command: `{results.options.command_line}`",
        f"- Date: {results.date}, {results.seconds:.0f} s",
        f"- Machine: {results.machine}, {results.cpu_count} CPU cores",
        f"- View: {results.view}",
        "- Scenes: generated in memory, uniform in a cube of side 2, scales about half the mean spacing, "
        "opacity 0.1..0.9, SH degree 0; p_min 1/255, depth key unless said.",
        f"- Medians of {results.options.repeat} runs, worker counts interleaved. keys: what computing the keys "
        "adds to the cull pass. distance turning: a turn in place reuses the last distance order (no sort). "
        "1 worker is the single-threaded path (one global argsort); from 2 workers on, large sorts take the "
        "parallel bucket sort, whose time on one thread is the '2 on one thread' row; the projection fits "
        "serial + parallel / cores to that row and the multi-worker ones.",
        "", "## Times (ms)", "",
        "| N | workers | cull | keys | sort | cull+sort | speed-up | distance | distance turning | upload |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for scene in results.scenes:
        lines += table_rows(scene)
    fresh = [row for scene in results.scenes for row in scene.freshness]
    if fresh:
        lines += ["", "## Freshness", "",
                  f"At {FPS:g} fps, turning {TURN_DEGREES_PER_S:g} deg/s in place or flying {FLY_RADII_PER_S:g} "
                  f"scene radii/s; frames at {', '.join(f'{t:g}' for t in results.options.sample_times)} s "
                  f"rendered at {RENDER_SIZE[0]}x{RENDER_SIZE[1]}. PSNR vs fresh: the stale image against the "
                  "frame's own order's. Loss: the PSNR against the per-ray truth (fresh exact per-pixel) that "
                  "the stale order loses; per-pixel's stale error is its stale cull's.", "",
                  "| N | motion | order | cores | latency ms | age ms | PSNR vs fresh | loss dB |",
                  "|---:|---|---|---|---:|---:|---:|---:|"]
        lines += [f"| {count_label(r.count)} | {r.sweep} | {r.mode} | {r.cores} | {r.latency_ms:.1f} | "
                  f"{r.age_ms:.0f} | {db(r.psnr_vs_fresh)} | {db(r.loss_db)} |" for r in fresh]
        lines += ["", f"Age (ms) of the drawn order at which the loss crosses {WITHIN_DB:g} dB (interpolated "
                  f"from the rows above; the age is at least the latency plus up to a frame, and up to twice the "
                  f"latency):", ""]
        lines += [f"- {line}" for scene in results.scenes for line in crossing_lines(scene.count, scene.freshness)]
    if results.loads:
        lines += ["", "## Loading", "",
                  "A generated INRIA PLY (SH degree 3, 62 float32 properties per gaussian) loaded by `load_scene` "
                  "in a fresh process; peak: the resident memory the load added at its high-water mark.", "",
                  "| N | file MiB | load s | peak MiB | peak / file |", "|---:|---:|---:|---:|---:|"]
        lines += [f"| {count_label(n)} | {f.file_bytes / (1 << 20):.0f} | {f.seconds:.2f} | "
                  f"{f.peak_bytes / (1 << 20):.0f} | {f.peak_ratio:.2f} |" for n, f in results.loads]
    lines += ["", "## Against the naive one-liner, the GPU sort, and the drawn order's age", "",
              "Naive: the numpy one-liner (cull by z > 0, stable argsort of the depths), timed after each round "
              "of the runs above. GPU sort: `--sort gpu`, the same order (checked), cull and sort in compute "
              "passes, timed with the GL drained (the summary's `gpu-sort` lines add a GPU timer query's time, "
              "meaningless on a software renderer). Age: the mean age, in frames, of the order the window draws "
              "while the view moves (turning or flying alike), with the CPU sort on its thread at every core's "
              "latency and at the projected one; the GPU sort draws the order of the frame itself.", "",
              "| N | naive | cull+sort | / naive | GPU sort | "
              + " | ".join(f"age @ {rate:g} Hz (CPU, {PROJECTED_CORES} cores proj., GPU)" for rate in AGE_RATES)
              + " |", "|---:|---:|---:|---:|---:|" + "---|" * len(AGE_RATES)]
    lines += [age_row(scene) for scene in results.scenes]
    lines += ["", "## Summary", "", *summary_lines(results.scenes), *age_lines(results.scenes),
              *format_load_lines(results.loads)]
    return "\n".join(lines) + "\n"


def _ages(scene: SceneTimes, rate: float) -> tuple[float, float, float]:
    """The drawn order's age in frames at ``rate``: the CPU sort on every core, projected
    to PROJECTED_CORES cores, and the GPU sort (the frame's own: 0; nan when it did not run)."""
    return (frames_old(scene.best.total / 1e3, rate), frames_old(scene.projected["total"] / 1e3, rate),
            math.nan if scene.gpu_note else 0.0)


def age_row(scene: SceneTimes) -> str:
    gpu = f"{scene.gpu_ms:.1f} ms" if not scene.gpu_note else "not run"
    ages = " | ".join(", ".join("n/a" if math.isnan(a) else f"{a:.1f}" for a in _ages(scene, rate))
                      for rate in AGE_RATES)
    return (f"| {count_label(scene.count)} | {scene.naive_ms:.0f} ms | {scene.best.total:.1f} ms | "
            f"{scene.naive_ratio:.2f} | {gpu} | {ages} |")


def age_lines(scenes: list[SceneTimes]) -> list[str]:
    """``order-age@3M/60Hz cpu 2.6 frames, projected 1.0, gpu 0``."""
    lines = []
    for scene in scenes:
        for rate in AGE_RATES:
            cpu, projected, gpu = _ages(scene, rate)
            lines.append(f"order-age@{count_label(scene.count)}/{rate:g}Hz cpu {cpu:.1f} frames, projected "
                         f"{projected:.1f}, gpu " + ("n/a" if math.isnan(gpu) else f"{gpu:.0f}"))
    return lines
