"""The timing half of ``bench sort``: how fast the CPU cull and sort are at real scene
sizes, for 1 worker (the single-threaded path), 2 and every core, and projected to
PROJECTED_CORES cores (maths page, section 9); beside them, in the same runs, the naive
numpy one-liner (:func:`naive_order`) they are measured against, and the GPU sort
(``render.gl.gpu_sort.GpuSorter``, the same order, timed with the GL drained).

Times, medians over ``repeat`` runs with the worker counts interleaved (one untimed run
first): the cull alone (``DepthSorter.cull``), the keys (what the cull with keys adds:
``SortResult.times["cull"]`` less the cull alone), the sort (``times["sort"]``), their
sum (cull+sort: one ``DepthSorter.sort``, timed around the call), the distance key's
cull+sort from a new centre and on a turn in place (reused, no sort), and the upload of
the order into a GL buffer.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from raygs_viewer.bench.common import count_label
from raygs_viewer.bench.cube import moved
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import SortRequest

TIMING_SIZE = (1280, 720)
PROJECTED_CORES = 16
P_MIN = RenderSettings().p_min
#: The key of the parallel path run on the calling thread alone (a closed DepthSorter of
#: 2 workers): the parallel algorithm's own one-thread time, which the projection scales.
ONE_THREAD = 0
#: The times a scene's projection is made for (Timing's fields).
PROJECTED = ("total", "distance", "distance_turn")


@dataclass
class Timing:
    """Medians in ms for one scene and one worker count."""
    workers: int
    cull: float
    cull_keys: float
    sort: float
    total: float             # cull+sort, depth key
    distance: float          # cull+sort, distance key, from a new centre
    distance_turn: float     # cull + the reused order, distance key, turned in place
    visible: int

    @property
    def keys(self) -> float:
        return max(0.0, self.cull_keys - self.cull)


@dataclass
class SceneTimes:
    """Every time of one scene."""
    count: int
    timings: dict[int, Timing]
    upload_ms: float
    projected: dict[str, float]          # a PROJECTED field -> ms on PROJECTED_CORES cores
    one_thread: Timing                   # the parallel path (2 workers) on one thread
    naive_ms: float = math.nan           # the naive one-liner, median, interleaved with the runs above
    gpu_ms: float = math.nan             # the GPU sort's cull+sort, GL drained (nan: not run)
    gpu_timer_ms: float = math.nan       # ... and under a GPU timer query (meaningless on llvmpipe)
    gpu_note: str = ""                   # why the GPU sort did not run ("" when it did)

    @property
    def best(self) -> Timing:
        """The timing of every core (the most workers measured)."""
        return self.timings[max(self.timings)]

    @property
    def naive_ratio(self) -> float:
        """cull+sort on every core over the naive one-liner's time."""
        return self.best.total / self.naive_ms


def naive_order(positions: np.ndarray, camera: Camera) -> np.ndarray:
    """The naive numpy one-liner the sort is measured against: keep what is in front of
    the camera (z > 0), then a stable argsort of those depths, farthest first."""
    depth = positions @ camera.R[2].astype(np.float32) + np.float32(camera.t[2])
    visible = np.flatnonzero(depth > 0)
    return visible[np.argsort(-depth[visible], kind="stable")]


def worker_counts() -> tuple[int, ...]:
    """1 (the single-threaded path), 2 and every core, each once."""
    return tuple(sorted({1, 2, os.cpu_count() or 1}))


def time_scene(ctx, scene: Scene, camera: Camera, repeat: int, workers: tuple[int, ...]) -> SceneTimes:
    """Every time of ``scene`` seen from ``camera``, and the projection to PROJECTED_CORES."""
    timings, order, naive = measure_sorting(scene, camera, repeat, workers)
    upload = upload_ms(ctx, order, repeat)
    one_thread = timings.pop(ONE_THREAD)
    parallel = {1: one_thread, **{w: t for w, t in timings.items() if w > 1}}
    projected = {key: amdahl({w: getattr(t, key) for w, t in parallel.items()}, PROJECTED_CORES)
                 for key in PROJECTED}
    gpu, timer, note = gpu_sort_ms(ctx, scene, camera, repeat, order)
    return SceneTimes(scene.count, timings, upload, projected, one_thread, naive, gpu, timer, note)


def gpu_sort_ms(ctx, scene: Scene, camera: Camera, repeat: int, expected: np.ndarray) -> tuple[float, float, str]:
    """(median ms of the GPU sort's cull+sort of the depth order with the GL drained, and
    under a GPU timer query; why it did not run, or ""). Its order is checked against the
    CPU's ``expected``: a benchmark of a sort that differs would measure something else.
    The timer spans the sort's one read-back (the range), as the frame waits for it too."""
    problem = GpuSorter.problem(ctx)
    if problem:
        return math.nan, math.nan, problem
    try:
        sorter = GpuSorter(ctx, scene)
    except UserError as error:
        return math.nan, math.nan, str(error)
    request = SortRequest(camera, P_MIN)
    timer = GpuTimer(ctx)
    try:
        drained, timed = [], []
        for run in range(repeat + 1):
            ctx.finish()
            began = time.perf_counter()
            result = sorter.sort(request)  # ends with the GPU drained (finish=True)
            if run:
                drained.append(1e3 * (time.perf_counter() - began))
                timed.append(timer.time_ms(lambda: sorter.sort(request)))
            elif not np.array_equal(result.order.host_indices(), expected):
                raise RuntimeError("bench sort: the GPU sort's order differs from the CPU sort's")
        return float(np.median(drained)), float(np.median(timed)), ""
    finally:
        sorter.close()


def measure_sorting(scene: Scene, camera: Camera, repeat: int,
                    workers: tuple[int, ...]) -> tuple[dict[int, Timing], np.ndarray, float]:
    """Times every worker count and ONE_THREAD, runs interleaved (one untimed first), and
    the naive one-liner after each round; returns the timings, the depth order (for the
    upload) and the naive one-liner's median ms."""
    workers = (ONE_THREAD, *workers)
    sorters = {w: DepthSorter(scene, w or 2) for w in workers}
    sorters[ONE_THREAD].close()  # same algorithm as 2 workers, on the calling thread
    samples: dict[int, dict[str, list[float]]] = {w: {k: [] for k in ("cull", "cull_keys", "sort", "total",
                                                                     "distance", "distance_turn")}
                                                  for w in workers}
    # Centres a hair apart: each distance order is a fresh sort; turns about one centre reuse.
    # The requests are made before the clocks start (a request copies its camera).
    nudges = [_distance(replace(camera, t=camera.t + [0.0, 0.0, 1e-3 * (run + 1)])) for run in range(repeat + 1)]
    turns = [_distance(moved(camera, "turn", 0.01 * (run % 2 + 1))) for run in range(repeat + 3)]
    depth = SortRequest(camera, P_MIN)
    order = np.zeros(0, np.uint32)
    naive = []
    try:
        for sorter in sorters.values():  # the cache of two turns, before any timing
            for turn in turns[:2]:
                sorter.sort(turn)
        for run in range(repeat + 1):
            for w, sorter in sorters.items():
                took = samples[w]
                began = time.perf_counter()
                result = sorter.sort(depth)
                total = time.perf_counter() - began
                order, split = result.order.indices, result.times
                cull = _seconds(lambda: sorter.cull(depth))
                distance = _seconds(lambda: sorter.sort(nudges[run]))
                reused = sorter.reused
                turn = _seconds(lambda: sorter.sort(turns[run + 2]))
                if sorter.reused != reused + 1:
                    raise RuntimeError("bench sort: a turn in place was sorted again instead of reused")
                if run:
                    for key, value in (("cull", cull), ("cull_keys", split["cull"]), ("sort", split["sort"]),
                                       ("total", total), ("distance", distance), ("distance_turn", turn)):
                        took[key].append(1e3 * value)
            one_liner = _seconds(lambda: naive_order(scene.positions, camera))
            if run:
                naive.append(1e3 * one_liner)
    finally:
        for sorter in sorters.values():
            sorter.close()
    timings = {w: Timing(w, **{k: float(np.median(v)) for k, v in samples[w].items()}, visible=order.size)
               for w in workers}
    return timings, order, float(np.median(naive))


def _distance(camera: Camera) -> SortRequest:
    return SortRequest(camera, P_MIN, keys=("distance",))


def _seconds(work: Callable[[], object]) -> float:
    began = time.perf_counter()
    work()
    return time.perf_counter() - began


def upload_ms(ctx, order: np.ndarray, repeat: int) -> float:
    """Median ms to write ``order`` into a GL buffer of its size, the GPU drained on both sides."""
    buffer = ctx.buffer(reserve=max(4, order.nbytes))
    try:
        times = []
        for run in range(repeat + 1):
            ctx.finish()
            began = time.perf_counter()
            buffer.write(order)
            ctx.finish()
            if run:
                times.append(1e3 * (time.perf_counter() - began))
        return float(np.median(times))
    finally:
        buffer.release()


def amdahl(times: dict[int, float], cores: int) -> float:
    """The time on ``cores`` of work measured at several worker counts, fitted as
    serial + parallel / workers (least squares, both parts >= 0)."""
    counts = sorted(times)
    if len(counts) < 2:
        return times[counts[0]]
    a = np.array([[1.0, 1.0 / w] for w in counts])
    b = np.array([times[w] for w in counts])
    serial, parallel = np.linalg.lstsq(a, b, rcond=None)[0]
    if serial < 0:
        serial, parallel = 0.0, float(np.mean(b * np.array(counts)))
    elif parallel < 0:
        serial, parallel = float(np.mean(b)), 0.0
    return float(serial + parallel / cores)


# --- output ----------------------------------------------------------------------------------------

def summary_line(count: int, ms: float, naive_ms: float | None = None) -> str:
    """``cull+sort@1M 18.3 ms``, and with ``naive_ms`` its ratio to the naive one-liner:
    ``cull+sort@3M 31.3 ms (0.13x the naive one-liner's 240 ms)``."""
    line = f"cull+sort@{count_label(count)} {ms:.1f} ms"
    if naive_ms is not None:
        line += f" ({ms / naive_ms:.2f}x the naive one-liner's {naive_ms:.0f} ms)"
    return line


def timing_lines(times: SceneTimes) -> list[str]:
    """What the run prints for a scene once it is timed."""
    label = count_label(times.count)
    single = times.timings[1].total
    lines = []
    for w, t in times.timings.items():
        lines.append(f"  {label} workers={w}: cull {t.cull:.1f} ms, keys {t.keys:.1f} ms, sort {t.sort:.1f} ms, "
                     f"cull+sort {t.total:.1f} ms (x{single / t.total:.2f} of 1 worker), distance "
                     f"{t.distance:.1f} ms, distance turning in place {t.distance_turn:.1f} ms; "
                     f"{t.visible:,} visible")
    t = times.one_thread
    lines.append(f"  {label} workers=2 on one thread (the parallel path's own scaling base): cull+sort "
                 f"{t.total:.1f} ms (sort {t.sort:.1f} ms)")
    lines.append(f"  {label} upload of the order: {times.upload_ms:.2f} ms; projected to {PROJECTED_CORES} cores "
                 f"(Amdahl's law on the parallel path's 1-thread and multi-worker times): cull+sort "
                 f"{times.projected['total']:.1f} ms")
    lines.append(f"  {label} naive one-liner (cull by z, stable argsort of the depths): {times.naive_ms:.1f} ms; "
                 f"cull+sort on every core is {times.naive_ratio:.2f}x of it")
    lines.append(f"  {label} GPU sort (the same order): "
                 + (f"{times.gpu_ms:.1f} ms with the GL drained, {times.gpu_timer_ms:.1f} ms by the GPU timer"
                    if not times.gpu_note else f"not run: {times.gpu_note}"))
    return lines


def table_rows(times: SceneTimes) -> list[str]:
    """The report's rows of the times table for one scene."""
    label, single = count_label(times.count), times.timings[1].total
    lines = [f"| {label} | {w} | {t.cull:.1f} | {t.keys:.1f} | {t.sort:.1f} | {t.total:.1f} | "
             f"{single / t.total:.2f} | {t.distance:.1f} | {t.distance_turn:.1f} | {times.upload_ms:.2f} |"
             for w, t in times.timings.items()]
    t = times.one_thread
    lines.append(f"| {label} | 2 on one thread | {t.cull:.1f} | {t.keys:.1f} | {t.sort:.1f} | {t.total:.1f} | "
                 f"{single / t.total:.2f} | {t.distance:.1f} | {t.distance_turn:.1f} | |")
    lines.append(f"| {label} | {PROJECTED_CORES} (projected) | | | | {times.projected['total']:.1f} | "
                 f"{single / times.projected['total']:.2f} | {times.projected['distance']:.1f} | "
                 f"{times.projected['distance_turn']:.1f} | |")
    return lines


def summary_lines(scenes: list[SceneTimes]) -> list[str]:
    """``cull+sort@N`` on every core, then the same per worker count and the speed-up."""
    lines = [summary_line(s.count, s.best.total, s.naive_ms) for s in scenes]
    lines += [f"gpu-sort@{count_label(s.count)} {s.gpu_ms:.1f} ms (GPU timer {s.gpu_timer_ms:.1f} ms)"
              for s in scenes if not s.gpu_note]
    for scene in scenes:
        label = count_label(scene.count)
        for w, t in scene.timings.items():
            lines.append(f"cull+sort-{w}-workers@{label} {t.total:.1f} ms")
        lines.append(f"cull+sort-{PROJECTED_CORES}-cores-projected@{label} {scene.projected['total']:.1f} ms")
        lines.append(f"speed-up@{label} {scene.timings[1].total / scene.timings[max(scene.timings)].total:.2f}")
    return lines
