"""``raygs-viewer bench sort``: how fast the CPU cull and sort are at real scene sizes, and
how fresh that keeps the drawn order in motion (maths page, section 9; issue 16).

For generated scenes of 100k to 6M gaussians (made in memory, SH degree 0), seen whole
from outside (:func:`view_camera`):

- times: the cull alone, the keys (what the cull with keys adds), the sort, their sum
  (cull+sort, one ``DepthSorter.orders``), the distance key's cull+sort from a new centre
  and on a turn in place (reused, no sort), and the upload of the order into a GL buffer;
  for 1 worker (the single-threaded path), 2 and every core, medians over ``repeat``
  runs with the variants interleaved;
- freshness: the window sorts in the background and draws the newest finished order
  (:func:`drawn_views`, BackgroundSorter's timeline), so while the camera turns
  (90 deg/s) or flies (0.5 scene radius/s) at 60 fps each frame is drawn with the order
  of an older view. A few frames of each motion are rendered with that stale order and
  with the frame's own, at 160x120, for the depth, distance and exact per-pixel orders,
  with the latency measured for 1 worker, for every core, and projected to
  PROJECTED_CORES cores (Amdahl's law fitted to the measured scaling). Reported: the
  PSNR of the stale image against the fresh one, and the PSNR it loses against the
  per-ray truth (the fresh exact per-pixel image) compared with the fresh image of the
  same order; and the age of the drawn order at which that loss crosses 1 dB
  (interpolated; a ladder of latencies in frames fills in ages the measured ones miss).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, replace
from typing import Callable, TextIO

import numpy as np

from raygs_viewer.bench import common
from raygs_viewer.bench.common import count_label
from raygs_viewer.bench.loading import (
    LoadFigures,
    format_load_lines,
    measure_generated_loads,
)
from raygs_viewer.bench.views import flown, turned
from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.depth import DepthSorter

COUNTS = (100_000, 1_000_000, 3_000_000, 6_000_000)
QUICK_COUNTS = COUNTS[:3]
DEFAULT_REPEAT, QUICK_REPEAT = 9, 5
TIMING_SIZE = (1280, 720)
RENDER_SIZE = (160, 120)
FOV_Y = 60.0
FPS = 60.0
TURN_DEGREES_PER_S = 90.0
FLY_RADII_PER_S = 0.5
#: Seconds into each motion whose frames are rendered (the scene still fills most of the view).
SAMPLE_TIMES = (0.2, 0.35, 0.5)
QUICK_SAMPLE_TIMES = (0.25, 0.5)
#: Latencies in frames (at FPS) also simulated, to find where the loss crosses WITHIN_DB.
LADDER_FRAMES = (1, 2, 4, 8, 16)
QUICK_LADDER_FRAMES = (1, 2, 8)
PROJECTED_CORES = 16
WITHIN_DB = 1.0
#: Loads are measured for the scene sizes from this one up (1M, 3M, 6M by default).
LOAD_MIN = 1_000_000
P_MIN = RenderSettings().p_min
SWEEPS = ("turn", "fly")
#: The orders whose freshness is measured: settings, and the sort key whose latency applies.
MODES: dict[str, RenderSettings] = {
    "depth": RenderSettings(order="depth"),
    "distance": RenderSettings(order="distance"),
    "per-pixel": RenderSettings(order="per-pixel", order_k=0),
}
#: The freshness view's distance from the cube's centre (its front face is at 1): about
#: 80 % of the gaussians in view and the cube filling it, so that a turn brings unseen
#: gaussians in, as it does inside a real scene.
FRESHNESS_DISTANCE = 1.5
#: Half the side of the generated cube; its bounding sphere is the scene's radius.
HALF_SIDE = 1.0
SCENE_RADIUS = HALF_SIDE * math.sqrt(3.0)


@dataclass(frozen=True)
class SortOptions:
    counts: tuple[int, ...] = QUICK_COUNTS
    repeat: int = QUICK_REPEAT
    sample_times: tuple[float, ...] = QUICK_SAMPLE_TIMES
    ladder_frames: tuple[int, ...] = QUICK_LADDER_FRAMES
    freshness: bool = True
    loads: bool = True                   # load time and peak memory of SH-3 PLYs of the counts >= LOAD_MIN
    command_line: str = "raygs-viewer bench sort"
    gl_backend: str | None = None


# --- scenes and views ----------------------------------------------------------------------------

def generated_scene(count: int, seed: int = 0) -> Scene:
    """``count`` gaussians uniform in the cube [-1, 1]^3: random rotations, log-scales
    spread +-0.5 about half the mean spacing (neighbours overlap on screen), opacities
    0.1..0.9, random colours (SH degree 0: no view dependence, and a quarter of SH 3's memory)."""
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-HALF_SIDE, HALF_SIDE, (count, 3)).astype(np.float32)
    rotations = rng.normal(size=(count, 4)).astype(np.float32)
    rotations /= np.linalg.norm(rotations, axis=1, keepdims=True)
    spacing = 2.0 * HALF_SIDE / max(count, 1) ** (1.0 / 3.0)
    scales = np.exp(rng.uniform(-0.5, 0.5, (count, 3))).astype(np.float32)
    scales *= np.float32(0.5 * spacing)
    opacities = rng.uniform(0.1, 0.9, count).astype(np.float32)
    sh = rng.uniform(-1.5, 1.5, (count, 1, 3)).astype(np.float32)
    return Scene(positions, rotations, scales, opacities, sh, 0, source="generated")


def view_distance() -> float:
    """From this far in front of the cube's centre its bounding sphere just fills the
    vertical field of view: every gaussian is in view, none wasted."""
    return SCENE_RADIUS / math.sin(math.radians(FOV_Y) / 2)


def view_camera(width: int, height: int, distance: float | None = None) -> Camera:
    """Looking at the cube's centre from ``distance`` (default :func:`view_distance`) in front of it."""
    distance = view_distance() if distance is None else distance
    return look_at((0.0, 0.0, -distance), (0.0, 0.0, 0.0), width=width, height=height, fov_y_degrees=FOV_Y)


def moved(start: Camera, sweep: str, seconds: float) -> Camera:
    """``start`` after ``seconds`` of the motion: "turn" about its own vertical axis at
    TURN_DEGREES_PER_S (its centre fixed), "fly" forward at FLY_RADII_PER_S scene radii a second."""
    if sweep == "turn":
        return turned(start, TURN_DEGREES_PER_S * seconds)
    if sweep == "fly":
        return flown(start, FLY_RADII_PER_S * SCENE_RADIUS * seconds)
    raise ValueError(f"unknown sweep {sweep!r}")


# --- timing ----------------------------------------------------------------------------------------

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


def worker_counts() -> tuple[int, ...]:
    """1 (the single-threaded path), 2 and every core, each once."""
    return tuple(sorted({1, 2, os.cpu_count() or 1}))


#: The key of the parallel path run on the calling thread alone (a closed DepthSorter of
#: 2 workers): the parallel algorithm's own one-thread time, which the projection scales.
ONE_THREAD = 0


def measure_sorting(scene: Scene, camera: Camera, repeat: int,
                    workers: tuple[int, ...]) -> tuple[dict[int, Timing], np.ndarray]:
    """Times every worker count and ONE_THREAD, runs interleaved (one untimed first);
    returns the timings and the depth order (for the upload)."""
    workers = (ONE_THREAD, *workers)
    sorters = {w: DepthSorter(scene, w or 2) for w in workers}
    sorters[ONE_THREAD].close()  # same algorithm as 2 workers, on the calling thread
    samples: dict[int, dict[str, list[float]]] = {w: {k: [] for k in ("cull", "cull_keys", "sort", "total",
                                                                     "distance", "distance_turn")}
                                                  for w in workers}
    # Centres a hair apart: each distance order is a fresh sort; turns about one centre reuse.
    nudges = [replace(camera, t=camera.t + [0.0, 0.0, 1e-3 * (run + 1)]) for run in range(repeat + 1)]
    turns = [moved(camera, "turn", 0.01 * (run % 2 + 1)) for run in range(repeat + 3)]
    order = np.zeros(0, np.uint32)
    try:
        for sorter in sorters.values():  # the cache of two turns, before any timing
            for turn in turns[:2]:
                sorter.order(turn, P_MIN, key="distance")
        for run in range(repeat + 1):
            for w, sorter in sorters.items():
                took = samples[w]
                began = time.perf_counter()
                order = sorter.order(camera, P_MIN)
                total = time.perf_counter() - began
                split = dict(sorter.last_seconds)
                cull = _seconds(lambda: sorter.cull(camera, P_MIN))
                distance = _seconds(lambda: sorter.order(nudges[run], P_MIN, key="distance"))
                reused = sorter.reused
                turn = _seconds(lambda: sorter.order(turns[run + 2], P_MIN, key="distance"))
                if sorter.reused != reused + 1:
                    raise RuntimeError("bench sort: a turn in place was sorted again instead of reused")
                if run:
                    for key, value in (("cull", cull), ("cull_keys", split["cull"]), ("sort", split["sort"]),
                                       ("total", total), ("distance", distance), ("distance_turn", turn)):
                        took[key].append(1e3 * value)
    finally:
        for sorter in sorters.values():
            sorter.close()
    timings = {w: Timing(w, **{k: float(np.median(v)) for k, v in samples[w].items()}, visible=order.size)
               for w in workers}
    return timings, order


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


# --- freshness -------------------------------------------------------------------------------------

def drawn_views(latency: float, fps: float, frames: int) -> list[float]:
    """For frames 0..frames-1 (at k / fps seconds) of a motion that starts at 0, the time
    of the view whose order each frame draws.

    As BackgroundSorter and the window do it: the order of the view at 0 is ready when
    the motion starts; from frame 1 on, every frame requests its own view; a request
    waits in one slot while a sort runs (a newer one replaces it) and starts when the
    worker is free; a sort takes ``latency`` seconds; each frame draws the newest order
    finished by its time (the request of the frame itself comes first, so a sort faster
    than a frame is drawn one frame later)."""
    period, tolerance = 1.0 / fps, 1e-9
    finished = 0.0           # the view time of the newest finished order
    running: tuple[float, float] | None = None  # (view time, finish time)
    waiting: float | None = None
    drawn = []
    for frame in range(frames):
        now = frame * period
        while running is not None and running[1] <= now + tolerance:
            finished, done = running[0], running[1]
            running = None
            if waiting is not None:
                running, waiting = (waiting, done + latency), None
        if frame:
            if running is None:
                running = (now, now + latency)
                if latency <= tolerance:
                    finished, running = now, None
            else:
                waiting = now
        drawn.append(finished)
    return drawn


@dataclass
class Freshness:
    """One (scene, motion, order mode, latency)."""
    count: int
    sweep: str
    mode: str
    cores: str               # "1", "2", "16 (projected)", or "ladder" (a latency chosen, not measured)
    latency_ms: float
    age_ms: float            # mean over the rendered frames of the drawn order's age
    psnr_vs_fresh: float     # stale against fresh, from the mean squared error over frames
    loss_db: float           # PSNR against the per-ray truth: fresh minus stale (nan for per-pixel)


class _Frames:
    """Orders and images of one scene at RENDER_SIZE, cached by (mode, view time, draw time)."""

    def __init__(self, ctx, renderer: GLRenderer, start: Camera, sweep: str):
        self.ctx, self.renderer, self.start, self.sweep = ctx, renderer, start, sweep
        self.target = FloatTarget(ctx, start.width, start.height)
        self._orders: dict[tuple[str, float], np.ndarray] = {}
        self._images: dict[tuple[str, float, float], np.ndarray] = {}

    def order(self, mode: str, view_time: float) -> np.ndarray:
        key = (MODES[mode].sort_key, view_time)
        if key not in self._orders:
            self._orders[key] = self.renderer.sort(moved(self.start, self.sweep, view_time), MODES[mode])
        return self._orders[key]

    def image(self, mode: str, view_time: float, draw_time: float) -> np.ndarray:
        key = (mode, view_time, draw_time)
        if key not in self._images:
            camera = moved(self.start, self.sweep, draw_time)
            self.renderer.render_into(self.target, camera, MODES[mode], self.order(mode, view_time))
            self._images[key] = self.target.read()[..., :3].astype(np.float64)
        return self._images[key]

    def release(self) -> None:
        self.target.release()


def _mse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean((a - b) ** 2))


def measure_freshness(frames: _Frames, count: int, mode: str, cores: str, latency_ms: float,
                      sample_times: tuple[float, ...]) -> Freshness:
    """The stale images of the sampled frames against the fresh ones and the truth."""
    indices = [round(t * FPS) for t in sample_times]
    views = drawn_views(latency_ms / 1e3, FPS, max(indices) + 1)
    stale_fresh, stale_truth, fresh_truth, ages = [], [], [], []
    for index in indices:
        now, then = index / FPS, views[index]
        truth = frames.image("per-pixel", now, now)
        fresh = frames.image(mode, now, now)
        stale = frames.image(mode, then, now)
        stale_fresh.append(_mse(stale, fresh))
        stale_truth.append(_mse(stale, truth))
        fresh_truth.append(_mse(fresh, truth))
        ages.append(1e3 * (now - then))
    loss = math.nan if mode == "per-pixel" else \
        common.psnr(float(np.mean(fresh_truth))) - common.psnr(float(np.mean(stale_truth)))
    return Freshness(count, frames.sweep, mode, cores, latency_ms, float(np.mean(ages)),
                     common.psnr(float(np.mean(stale_fresh))), loss)


def crossing(points: list[tuple[float, float]], threshold: float = WITHIN_DB) -> str:
    """The age (ms) of the drawn order at which a loss in dB first crosses ``threshold``,
    from (age, loss) points, interpolated linearly; ">A" when it stays below up to the
    oldest, "<A" when it is over already at the youngest (no anchor at 0: the window
    draws an order one frame late however fast the sort); "n/a" without points."""
    points = sorted((lat, loss) for lat, loss in points if math.isfinite(loss))
    if not points:
        return "n/a"
    if points[0][1] > threshold:
        return f"<{points[0][0]:.0f}"
    for (l0, d0), (l1, d1) in zip(points, points[1:]):
        if d0 <= threshold < d1:
            return f"{l0 + (threshold - d0) * (l1 - l0) / (d1 - d0):.0f}"
    return f">{points[-1][0]:.0f}"


# --- the run ---------------------------------------------------------------------------------------

@dataclass
class SceneResult:
    count: int
    timings: dict[int, Timing]
    upload_ms: float
    projected: dict[str, float]          # latency key -> ms on PROJECTED_CORES cores
    one_thread: Timing                   # the parallel path (2 workers) on one thread
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


def latencies(result: SceneResult, mode: str, sweep: str, ladder_frames: tuple[int, ...]) -> list[tuple[str, float]]:
    """(cores label, latency ms) for this order and motion: the window's sort measured
    on each worker count (a turn in place reuses the distance order: cull only), projected
    to PROJECTED_CORES, and the ladder of latencies in frames."""
    field_name = "total" if MODES[mode].sort_key == "depth" else \
        ("distance_turn" if sweep == "turn" else "distance")
    measured = [(str(w), getattr(t, field_name)) for w, t in result.timings.items()]
    measured.append((f"{PROJECTED_CORES} (projected)", result.projected[field_name]))
    return measured + [("ladder", 1e3 * frames / FPS) for frames in ladder_frames]


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
            label = count_label(count)
            say(f"[{label}] generating ...")
            scene = generated_scene(count)
            timings, order = measure_sorting(scene, timing_camera, options.repeat, workers)
            upload = upload_ms(ctx, order, options.repeat)
            one_thread = timings.pop(ONE_THREAD)
            parallel = {1: one_thread, **{w: t for w, t in timings.items() if w > 1}}
            projected = {key: amdahl({w: getattr(t, key) for w, t in parallel.items()}, PROJECTED_CORES)
                         for key in ("total", "distance", "distance_turn")}
            result = SceneResult(count, timings, upload, projected, one_thread)
            for line in timing_lines(result):
                say(line)
            if options.freshness:
                _freshness(ctx, scene, result, options, say)
            results.append(result)
            del scene, order
    loads = []
    if options.loads:
        loads = measure_generated_loads([n for n in options.counts if n >= LOAD_MIN], log=say)
        for line in format_load_lines(loads):
            say(line)
    seconds = time.perf_counter() - started
    say(f"bench sort: done in {seconds:.0f} s")
    return SortResults(results, machine, os.cpu_count() or 1, options, common.run_date(), seconds, view, loads)


def _freshness(ctx, scene: Scene, result: SceneResult, options: SortOptions, say) -> None:
    renderer = GLRenderer(ctx, scene)
    start = view_camera(*RENDER_SIZE, FRESHNESS_DISTANCE)
    try:
        seen = renderer.sort(start, MODES["depth"]).size / max(scene.count, 1)
        say(f"  freshness view: {FRESHNESS_DISTANCE:g} units from the cube's centre (0.5 in front of its face), "
            f"{RENDER_SIZE[0]}x{RENDER_SIZE[1]}: {seen:.0%} of the gaussians in view, the cube filling it")
        for sweep in SWEEPS:
            frames = _Frames(ctx, renderer, start, sweep)
            try:
                for mode in MODES:
                    for cores, latency in latencies(result, mode, sweep, options.ladder_frames):
                        row = measure_freshness(frames, result.count, mode, cores, latency, options.sample_times)
                        result.freshness.append(row)
                        say(freshness_line(row))
            finally:
                frames.release()
    finally:
        renderer.sorter.close()
        renderer.release()


# --- output ----------------------------------------------------------------------------------------

def summary_line(count: int, ms: float) -> str:
    """``cull+sort@1M 18.3 ms``."""
    return f"cull+sort@{count_label(count)} {ms:.1f} ms"


def _db(value: float) -> str:
    if math.isnan(value):
        return "n/a"
    return "inf" if math.isinf(value) else f"{value:.1f}"


def timing_lines(result: SceneResult) -> list[str]:
    label = count_label(result.count)
    single = result.timings[1].total
    lines = []
    for w, t in result.timings.items():
        lines.append(f"  {label} workers={w}: cull {t.cull:.1f} ms, keys {t.keys:.1f} ms, sort {t.sort:.1f} ms, "
                     f"cull+sort {t.total:.1f} ms (x{single / t.total:.2f} of 1 worker), distance "
                     f"{t.distance:.1f} ms, distance turning in place {t.distance_turn:.1f} ms; "
                     f"{t.visible:,} visible")
    t = result.one_thread
    lines.append(f"  {label} workers=2 on one thread (the parallel path's own scaling base): cull+sort "
                 f"{t.total:.1f} ms (sort {t.sort:.1f} ms)")
    lines.append(f"  {label} upload of the order: {result.upload_ms:.2f} ms; projected to {PROJECTED_CORES} cores "
                 f"(Amdahl's law on the parallel path's 1-thread and multi-worker times): cull+sort "
                 f"{result.projected['total']:.1f} ms")
    return lines


def freshness_line(row: Freshness) -> str:
    return (f"  fresh {count_label(row.count)} {row.sweep} {row.mode} cores={row.cores.split()[0]}: latency "
            f"{row.latency_ms:.1f} ms, age {row.age_ms:.0f} ms, PSNR vs fresh {_db(row.psnr_vs_fresh)} dB, "
            f"loss vs truth {_db(row.loss_db)} dB")


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
        single = scene.timings[1].total
        for w, t in scene.timings.items():
            lines.append(f"| {count_label(scene.count)} | {w} | {t.cull:.1f} | {t.keys:.1f} | {t.sort:.1f} | "
                         f"{t.total:.1f} | {single / t.total:.2f} | {t.distance:.1f} | {t.distance_turn:.1f} | "
                         f"{scene.upload_ms:.2f} |")
        t = scene.one_thread
        lines.append(f"| {count_label(scene.count)} | 2 on one thread | {t.cull:.1f} | {t.keys:.1f} | "
                     f"{t.sort:.1f} | {t.total:.1f} | {single / t.total:.2f} | {t.distance:.1f} | "
                     f"{t.distance_turn:.1f} | |")
        lines.append(f"| {count_label(scene.count)} | {PROJECTED_CORES} (projected) | | | | "
                     f"{scene.projected['total']:.1f} | {single / scene.projected['total']:.2f} | "
                     f"{scene.projected['distance']:.1f} | {scene.projected['distance_turn']:.1f} | |")
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
                  f"{r.age_ms:.0f} | {_db(r.psnr_vs_fresh)} | {_db(r.loss_db)} |" for r in fresh]
        lines += ["", f"Age (ms) of the drawn order at which the loss crosses {WITHIN_DB:g} dB (interpolated "
                  f"from the rows above; the age is at least the latency plus up to a frame, and up to twice the "
                  f"latency):", ""]
        lines += [f"- {line}" for line in crossing_lines(results)]
    if results.loads:
        lines += ["", "## Loading", "",
                  "A generated INRIA PLY (SH degree 3, 62 float32 properties per gaussian) loaded by `load_scene` "
                  "in a fresh process; peak: the resident memory the load added at its high-water mark.", "",
                  "| N | file MiB | load s | peak MiB | peak / file |", "|---:|---:|---:|---:|---:|"]
        lines += [f"| {count_label(n)} | {f.file_bytes / (1 << 20):.0f} | {f.seconds:.2f} | "
                  f"{f.peak_bytes / (1 << 20):.0f} | {f.peak_ratio:.2f} |" for n, f in results.loads]
    lines += ["", "## Summary", "", *summary_lines(results)]
    return "\n".join(lines) + "\n"


def crossing_lines(results: SortResults) -> list[str]:
    lines = []
    for scene in results.scenes:
        for sweep in SWEEPS:
            for mode in ("depth", "distance"):
                rows = [r for r in scene.freshness if r.sweep == sweep and r.mode == mode]
                if rows:
                    lines.append(f"1db-age@{count_label(scene.count)}/{sweep}/{mode} "
                                 f"{crossing([(r.age_ms, r.loss_db) for r in rows])} ms")
    return lines


def summary_lines(results: SortResults) -> list[str]:
    """``cull+sort@N`` on every core, then the same per worker count and the speed-up,
    then ``load@N`` per measured load."""
    lines = [summary_line(s.count, s.timings[max(s.timings)].total) for s in results.scenes]
    for scene in results.scenes:
        label = count_label(scene.count)
        for w, t in scene.timings.items():
            lines.append(f"cull+sort-{w}-workers@{label} {t.total:.1f} ms")
        lines.append(f"cull+sort-{PROJECTED_CORES}-cores-projected@{label} {scene.projected['total']:.1f} ms")
        lines.append(f"speed-up@{label} {scene.timings[1].total / scene.timings[max(scene.timings)].total:.2f}")
    return lines + format_load_lines(results.loads)
