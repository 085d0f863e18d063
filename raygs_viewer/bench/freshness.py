"""The freshness half of ``bench sort``: how stale the drawn order is in motion, and what
that costs in the image (issue 16).

The window sorts in the background and draws the newest finished order
(:func:`drawn_views`, BackgroundSorter's timeline), so while the camera turns (90 deg/s)
or flies (0.5 scene radius/s) at 60 fps each frame is drawn with the order of an older
view. A few frames of each motion are rendered with that stale order and with the
frame's own, at 160x120, for the depth, distance and exact per-pixel orders, with the
latency measured for each worker count and projected to PROJECTED_CORES cores (by
``bench.sort_timing``). Reported: the PSNR of the stale image against the fresh one, and
the PSNR it loses against the per-ray truth (the fresh exact per-pixel image) compared
with the fresh image of the same order; and the age of the drawn order at which that
loss crosses 1 dB (interpolated; a ladder of latencies in frames fills in ages the
measured ones miss).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from raygs_viewer.bench import common
from raygs_viewer.bench.common import count_label
from raygs_viewer.bench.cube import SWEEPS, moved, view_camera
from raygs_viewer.bench.sort_timing import PROJECTED_CORES, SceneTimes
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import Order

RENDER_SIZE = (160, 120)
FPS = 60.0
#: Seconds into each motion whose frames are rendered (the scene still fills most of the view).
SAMPLE_TIMES = (0.2, 0.35, 0.5)
QUICK_SAMPLE_TIMES = (0.25, 0.5)
#: Latencies in frames (at FPS) also simulated, to find where the loss crosses WITHIN_DB.
LADDER_FRAMES = (1, 2, 4, 8, 16)
QUICK_LADDER_FRAMES = (1, 2, 8)
WITHIN_DB = 1.0
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


#: The refresh rates the drawn order's age is given at (bench sort's report).
AGE_RATES = (60.0, 90.0)


def frames_old(latency: float, rate: float, frames: int = 240) -> float:
    """The mean age, in frames, of the order the window draws while the view moves at
    ``rate`` frames a second and each sort takes ``latency`` seconds on the sort thread
    (:func:`drawn_views`), over the second half of ``frames`` (the steady state). The GPU
    sort's order is the frame's own (``sort.worker.InlineSorter``): 0."""
    views = drawn_views(latency, rate, frames)
    return max(0.0, round(float(np.mean([(k / rate - view) * rate for k, view in enumerate(views)][frames // 2:])), 9))


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


class Frames:
    """Orders and images of one scene at RENDER_SIZE along one motion, cached by (mode,
    view time, draw time)."""

    def __init__(self, ctx, renderer: GLRenderer, sorter: DepthSorter, start: Camera, sweep: str):
        self.ctx, self.renderer, self.sorter, self.start, self.sweep = ctx, renderer, sorter, start, sweep
        self.target = FloatTarget(ctx, start.width, start.height)
        self._orders: dict[tuple[str, float], Order] = {}
        self._images: dict[tuple[str, float, float], np.ndarray] = {}

    def order(self, mode: str, view_time: float) -> Order:
        key = (MODES[mode].sort_key, view_time)
        if key not in self._orders:
            self._orders[key] = exact_order(self.sorter, moved(self.start, self.sweep, view_time), MODES[mode])
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


def measure_freshness(frames: Frames, mode: str, cores: str, latency_ms: float, *, count: int,
                      sample_times: tuple[float, ...]) -> Freshness:
    """The stale images of the sampled frames against the fresh ones and the truth, for the
    row of a scene of ``count`` gaussians."""
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


def latencies(times: SceneTimes, mode: str, sweep: str, ladder_frames: tuple[int, ...]) -> list[tuple[str, float]]:
    """(cores label, latency ms) for this order and motion: the window's sort measured
    on each worker count (a turn in place reuses the distance order: cull only), projected
    to PROJECTED_CORES, and the ladder of latencies in frames."""
    field_name = "total" if MODES[mode].sort_key == "depth" else \
        ("distance_turn" if sweep == "turn" else "distance")
    measured = [(str(w), getattr(t, field_name)) for w, t in times.timings.items()]
    measured.append((f"{PROJECTED_CORES} (projected)", times.projected[field_name]))
    return measured + [("ladder", 1e3 * frames / FPS) for frames in ladder_frames]


def measure_scene(ctx, scene: Scene, times: SceneTimes, *, sample_times: tuple[float, ...],
                  ladder_frames: tuple[int, ...], say: Callable[..., None]) -> list[Freshness]:
    """Every motion, order and latency of ``scene``, each row printed as it is measured."""
    start = view_camera(*RENDER_SIZE, FRESHNESS_DISTANCE)
    rows = []
    with common.scene_renderer(ctx, scene) as (renderer, sorter):
        seen = exact_order(sorter, start, MODES["depth"]).count / max(scene.count, 1)
        say(f"  freshness view: {FRESHNESS_DISTANCE:g} units from the cube's centre (0.5 in front of its face), "
            f"{RENDER_SIZE[0]}x{RENDER_SIZE[1]}: {seen:.0%} of the gaussians in view, the cube filling it")
        for sweep in SWEEPS:
            frames = Frames(ctx, renderer, sorter, start, sweep)
            try:
                for mode in MODES:
                    for cores, latency in latencies(times, mode, sweep, ladder_frames):
                        rows.append(measure_freshness(frames, mode, cores, latency, count=times.count,
                                                       sample_times=sample_times))
                        say(freshness_line(rows[-1]))
            finally:
                frames.release()
    return rows


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


# --- output ----------------------------------------------------------------------------------------

def db(value: float) -> str:
    if math.isnan(value):
        return "n/a"
    return "inf" if math.isinf(value) else f"{value:.1f}"


def freshness_line(row: Freshness) -> str:
    return (f"  fresh {count_label(row.count)} {row.sweep} {row.mode} cores={row.cores.split()[0]}: latency "
            f"{row.latency_ms:.1f} ms, age {row.age_ms:.0f} ms, PSNR vs fresh {db(row.psnr_vs_fresh)} dB, "
            f"loss vs truth {db(row.loss_db)} dB")


def crossing_lines(count: int, rows: list[Freshness]) -> list[str]:
    """``1db-age@N/motion/order`` for the depth and distance orders of one scene."""
    lines = []
    for sweep in SWEEPS:
        for mode in ("depth", "distance"):
            chosen = [r for r in rows if r.sweep == sweep and r.mode == mode]
            if chosen:
                lines.append(f"1db-age@{count_label(count)}/{sweep}/{mode} "
                             f"{crossing([(r.age_ms, r.loss_db) for r in chosen])} ms")
    return lines
