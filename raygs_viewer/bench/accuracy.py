"""Benchmarks: ``raygs-viewer bench accuracy`` (what accuracy costs in time).

For every accuracy configuration (``settings.ACCURACY_PRESETS``, applied to base
settings with p_min 1/255 on black) and every view class of every scene, it
measures

- the GPU time of one frame (``GLRenderer.render_into``: preprocessing pass and
  draw, timed with an OpenGL timer query; the median of ``--repeat`` runs, the
  configurations interleaved round-robin so that drift hits them all alike), also
  as a ratio to plain RayGS measured in the same run;
- the error of the GL image against the ground truth
  (``reference.ground_truth``: exact RayGS integrated over each pixel's area), on
  RGB over black: PSNR = 10 log10(1 / MSE) and the 99th percentile and maximum of
  the absolute error, in linear float, unclipped.

View classes, all built from a scene's "training-like" camera by the functions
below: ``training`` (that camera at the benchmark resolution), ``far`` (pulled back
to twice its distance from the scene's centre, at a quarter of the resolution:
details shrink about 8 times in pixels, where aliasing shows) and ``close`` (moved
forward along its optical axis to about 5 % of its distance to the gaussians at
the image centre, where EWA splatting shows spikes).

Output: a table per (scene, view class) and machine-readable lines
``KEY SCENE VIEW CONFIG VALUE`` (KEY: ratio, ms, psnr, p99, max) on stdout, a
markdown report and a PNG plot of PSNR against time ratio, one panel per view class.
"""

from __future__ import annotations

import argparse
import datetime
import io
import math
import os
import re
import shlex
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import Camera, frame_points
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import (
    ACCURACY_PRESETS,
    DEFAULT_P_MIN,
    RenderSettings,
    apply_preset,
)
from raygs_viewer.scene.model import Scene

#: Every configuration, in the order of the presets; ratios are taken against BASELINE.
CONFIGS = tuple(ACCURACY_PRESETS)
BASELINE = "RayGS"

VIEW_CLASSES = ("training", "far", "close")
VIEW_TITLES = {"training": "training-like", "far": "far away, 1/4 resolution", "close": "very close"}

DEMO = "demo"
#: Real scenes benchmarked by default when the shared scene folder exists (``--quick``: the first).
REAL_SCENES = ("ss-fruit_drops_minimal.ply", "donut-mip-fused.ply", "gs3d-pr477-lod3_tile_0.ply")
QUICK_REAL_SCENES = REAL_SCENES[:1]

DEFAULT_WIDTH, QUICK_WIDTH = 320, 160
DEFAULT_REPEAT, QUICK_REPEAT = 15, 10
#: Ground-truth samples per pixel axis for the training-like and close views; the far
#: view's image is 16 times smaller and gets twice as many per axis.
DEFAULT_GT_SAMPLES, QUICK_GT_SAMPLES = 8, 4
FAR_GT_FACTOR = 2

DEFAULT_REPORT = "docs/accuracy-vs-time.md"
DEFAULT_PLOT = "docs/images/accuracy-vs-time.png"

#: The far view: this many times the training camera's distance from the scene's centre...
FAR_DISTANCE_FACTOR = 2.0
#: ... at 1/this of its resolution (per axis).
FAR_RESOLUTION_DIVISOR = 4

#: The close view ends this fraction of the way short of the central gaussians ...
CLOSE_FRACTION = 0.05
#: ... "central" meaning projected within this fraction of the image size of its centre
#: (per axis, either side) ...
CLOSE_CENTRAL_WINDOW = 0.1
#: ... and their depth being this percentile of the central gaussians' depths (robust to
#: a few stray specks in front of the cluster).
CLOSE_DEPTH_PERCENTILE = 10.0
#: The camera must stay outside every gaussian's support with a margin: c^2 > margin * kappa
#: (a camera just outside a support sees an unboundedly large quad, a robustness case
#: rather than a view). Where it would not, it backs off by this factor at a time.
CLOSE_SUPPORT_MARGIN = 2.0
CLOSE_BACKOFF = 1.25

#: PSNR plotted where the error is exactly zero.
PSNR_CAP = 100.0
#: The verdict's comparisons count any PSNR above this as this: an RMS error of 1e-3 is a
#: quarter of an 8-bit step, and differences between invisible errors should not decide.
VERDICT_PSNR_CAP = 60.0
#: "Within this many dB of the best" in the verdict's summary.
VERDICT_TOLERANCE_DB = 0.5
#: PSNR gains closer than this count as equal for the Pareto front.
PARETO_TOLERANCE_DB = 0.1
#: A time ratio above this counts as slower than RayGS in the verdict (timings are noisy).
SLOWER = 1.1

#: The ground truth's opacity cut-off: far below every configuration's, so the p_min
#: rows are judged against an image whose faint tails are (nearly) all there.
GT_P_MIN = 1e-4
HUMAN_VERDICT_BEGIN = "<!-- BEGIN HUMAN VERDICT (kept when the report is regenerated with --overwrite) -->"
HUMAN_VERDICT_END = "<!-- END HUMAN VERDICT -->"
HUMAN_VERDICT_PLACEHOLDER = "_Verdict to be written from the numbers below: which settings are worth their cost, " \
                            "for which views._"

#: A timer query that returns this (2^32 - 1 ns) did not measure anything (seen on llvmpipe
#: for the first query of a context).


# --- view classes --------------------------------------------------------------------------

def scene_centre(scene: Scene) -> np.ndarray:
    """The median of the finite gaussian centres, (3,) float64 (the origin for none)."""
    positions = scene.positions[np.all(np.isfinite(scene.positions), axis=1)].astype(np.float64)
    return np.median(positions, axis=0) if positions.shape[0] else np.zeros(3)


def with_width(camera: Camera, width: int) -> Camera:
    """``camera`` resized to ``width`` pixels across, keeping its aspect ratio."""
    height = max(1, round(width * camera.height / camera.width))
    return camera.resized(int(width), int(height))


def moved_to(camera: Camera, eye: np.ndarray) -> Camera:
    """The same orientation and intrinsics with its centre at ``eye``."""
    return replace(camera, t=-camera.R @ np.asarray(eye, dtype=np.float64))


def training_view(camera: Camera, width: int) -> Camera:
    """The training-like view: a training camera at the benchmark width (aspect kept)."""
    return with_width(camera, width)


def far_view(camera: Camera, centre: np.ndarray, factor: float = FAR_DISTANCE_FACTOR,
             divisor: int = FAR_RESOLUTION_DIVISOR) -> Camera:
    """``camera`` pulled back along its optical axis until its distance from ``centre``
    is ``factor`` times what it was, at 1/``divisor`` of its resolution (fx, fy, cx, cy
    scaled with it): the scene's details shrink about factor * divisor times in pixels.

    Moving back by s along the axis f from C, with v = C - centre and d = |v|:
    |v - s f|^2 = factor^2 d^2 gives s = v.f + sqrt((v.f)^2 + (factor^2 - 1) d^2)."""
    forward = camera.R[2]
    offset = camera.center - np.asarray(centre, dtype=np.float64)
    distance, along = float(np.linalg.norm(offset)), float(offset @ forward)
    back = along + math.sqrt(along * along + (factor * factor - 1.0) * distance * distance)
    moved = moved_to(camera, camera.center - back * forward)
    return moved.resized(max(1, camera.width // divisor), max(1, camera.height // divisor))


def inside_support(scene: Scene, point: np.ndarray, p_min: float, margin: float = 1.0) -> np.ndarray:
    """(N,) bool: gaussians whose support (enlarged: c^2 <= margin * kappa, kappa =
    -2 ln(p_min / o)) contains ``point``; computed in float64 in each gaussian's frame."""
    rotations = quaternion_to_matrix(scene.rotations.astype(np.float64))
    offsets = np.asarray(point, dtype=np.float64) - scene.positions.astype(np.float64)
    local = np.einsum("nji,nj->ni", rotations, offsets) / scene.scales.astype(np.float64)
    c2 = np.einsum("ni,ni->n", local, local)
    with np.errstate(divide="ignore"):
        kappa = -2.0 * np.log(p_min / scene.opacities.astype(np.float64))
    return (kappa > 0) & (c2 <= margin * kappa)


def central_depth(camera: Camera, scene: Scene, p_min: float) -> float | None:
    """Depth along the optical axis of the gaussians at the image centre: the
    CLOSE_DEPTH_PERCENTILE-th percentile of the depths of the gaussians (opacity above
    p_min, in front of the camera) whose centres project within CLOSE_CENTRAL_WINDOW of
    the image centre; with none there, of those anywhere in the image, then of all in
    front. None when no gaussian is in front of the camera."""
    mu = scene.positions.astype(np.float64) @ camera.R.T + camera.t
    x, y, z = mu[:, 0], mu[:, 1], mu[:, 2]
    candidates = (z > 0) & (scene.opacities > p_min) & np.all(np.isfinite(mu), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        du = np.abs(camera.fx * x / z + camera.cx - camera.width / 2)
        dv = np.abs(camera.fy * y / z + camera.cy - camera.height / 2)
    for window in (CLOSE_CENTRAL_WINDOW, 0.5):
        chosen = candidates & (du <= window * camera.width) & (dv <= window * camera.height)
        if chosen.any():
            return float(np.percentile(z[chosen], CLOSE_DEPTH_PERCENTILE))
    return float(np.percentile(z[candidates], CLOSE_DEPTH_PERCENTILE)) if candidates.any() else None


def close_view(camera: Camera, scene: Scene, p_min: float = DEFAULT_P_MIN,
               fraction: float = CLOSE_FRACTION) -> Camera:
    """``camera`` moved forward along its optical axis until the gaussians at the image
    centre (:func:`central_depth`, depth D) are ``fraction`` * D in front of it.

    Where that would put the camera inside (or near: c^2 <= CLOSE_SUPPORT_MARGIN * kappa)
    some gaussian's support, it backs off by CLOSE_BACKOFF at a time, at worst to the
    original position. Gaussians whose support already contains the original camera
    are ignored (moving cannot get out of them any better)."""
    depth = central_depth(camera, scene, p_min)
    if depth is None or not depth > 0:
        return camera
    already = inside_support(scene, camera.center, p_min, CLOSE_SUPPORT_MARGIN)
    forward = camera.R[2]
    remaining = fraction * depth
    while remaining < depth:
        eye = camera.center + (depth - remaining) * forward
        if not np.any(inside_support(scene, eye, p_min, CLOSE_SUPPORT_MARGIN) & ~already):
            return moved_to(camera, eye)
        remaining *= CLOSE_BACKOFF
    return camera


def view_cameras(scene: Scene, camera: Camera, width: int, p_min: float = DEFAULT_P_MIN) -> dict[str, Camera]:
    """The three view classes of ``scene`` built from its training camera ``camera``."""
    training = training_view(camera, width)
    return {"training": training,
            "far": far_view(training, scene_centre(scene)),
            "close": close_view(training, scene, p_min)}


# --- error metrics ----------------------------------------------------------------------

def psnr(mse: float) -> float:
    """10 log10(1 / MSE) for a peak of 1; inf for an exact match."""
    return math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse)


def error_metrics(image: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """PSNR (dB), 99th percentile and maximum of |image - truth| over all RGB values
    (alpha ignored), in float64, unclipped."""
    if image.shape[:2] != truth.shape[:2]:
        raise ValueError(f"image {image.shape} and ground truth {truth.shape} differ in size")
    error = np.abs(np.asarray(image, np.float64)[..., :3] - np.asarray(truth, np.float64)[..., :3])
    return {"psnr": psnr(float(np.mean(error * error))),
            "p99": float(np.quantile(error, 0.99)),
            "max": float(error.max())}


# --- running it ---------------------------------------------------------------------------

@dataclass
class ConfigResult:
    config: str
    gpu_ms: float          # median of the timed repeats
    ratio: float           # gpu_ms / gpu_ms of BASELINE in the same case
    psnr: float
    p99: float
    max_error: float
    times_ms: list[float] = field(default_factory=list)


@dataclass
class CaseResult:
    """One (scene, view class)."""
    scene: str
    view: str
    width: int
    height: int
    gt_samples: int
    gt_seconds: float
    rows: dict[str, ConfigResult]


@dataclass
class BenchResults:
    cases: list[CaseResult]
    gl_renderer: str
    cpu_count: int
    command_line: str
    date: str
    repeat: int
    width: int
    scenes: list[tuple[str, str]]   # (name, "N gaussians, from ...")
    notes: list[str] = field(default_factory=list)
    gt_p_min: float = GT_P_MIN


@dataclass(frozen=True)
class BenchOptions:
    scenes: tuple[str, ...]         # "demo" or scene files
    width: int
    repeat: int
    gt_samples: int                 # training-like and close; far: FAR_GT_FACTOR times as many
    report: Path
    plot: Path
    overwrite: bool = False
    command_line: str = "raygs-viewer bench accuracy"
    gl_backend: str | None = None
    configs: tuple[str, ...] = CONFIGS
    notes: tuple[str, ...] = ()
    gt_p_min: float = GT_P_MIN   # the ground truth's cut-off


@dataclass
class _BenchScene:
    name: str
    scene: Scene
    camera: Camera        # the training camera, at its own resolution
    description: str


def shared_scenes_dir() -> Path | None:
    """``../shared/scenes`` next to the current directory, else next to this repository."""
    for base in (Path.cwd(), Path(__file__).resolve().parents[1]):
        candidate = base.parent / "shared" / "scenes"
        if candidate.is_dir():
            return candidate
    return None


def default_scenes(quick: bool) -> tuple[tuple[str, ...], list[str]]:
    """The demo plus the real scenes found in the shared folder; notes for those absent."""
    found, notes = shared_scene_paths(QUICK_REAL_SCENES if quick else REAL_SCENES)
    return (DEMO, *found), notes


def shared_scene_paths(names: tuple[str, ...]) -> tuple[tuple[str, ...], list[str]]:
    """The paths (relative to the current directory) of those of ``names`` found in the
    shared scenes folder, and a note for each one missing."""
    folder = shared_scenes_dir()
    if folder is None:
        return (), ["no ../shared/scenes folder next to the current directory or the repository: "
                    "benchmarking without the real scenes"]
    found, notes = [], []
    for name in names:
        path = folder / name
        if path.is_file():
            found.append(os.path.relpath(path))
        else:
            notes.append(f"{name} not found in {os.path.relpath(folder)}: skipped")
    return tuple(found), notes


def _load_scenes(specs: tuple[str, ...]) -> list[_BenchScene]:
    from raygs_viewer.scene.loader import load_now
    loaded, names = [], set()
    for spec in specs:
        if spec != DEMO and not os.path.isfile(spec):
            raise UserError(f"{spec}: no such file" if not os.path.exists(spec) else f"{spec}: not a scene file")
    for spec in specs:
        result = load_now(spec)
        for warning in result.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        scene = result.scene
        if result.cameras:
            camera, origin = result.cameras[0], ("its first view" if spec == DEMO
                                                 else f"the first camera of {result.cameras_path}")
        else:
            camera, origin = frame_points(scene.positions), "a camera framing its gaussians (no cameras.json)"
        name = DEMO if spec == DEMO else Path(spec).stem
        base, n = name, 2
        while name in names:
            name, n = f"{base}-{n}", n + 1
        names.add(name)
        loaded.append(_BenchScene(name, scene, camera,
                                  f"{scene.count:,} gaussians, SH degree {scene.sh_degree}; training-like view: {origin}"))
    return loaded


def _ground_truth(scene: Scene, camera: Camera, settings: RenderSettings, samples: int) -> np.ndarray:
    from raygs_viewer.render import reference  # looked up per call (tests replace it)
    return reference.ground_truth(scene, camera, settings, samples)


def measure(ctx, renderer, camera: Camera, settings: dict[str, RenderSettings], repeat: int
            ) -> tuple[dict[str, list[float]], dict[str, np.ndarray]]:
    """GPU times (ms, ``repeat`` per configuration) and the image of every configuration.

    Each configuration is sorted once and rendered once untimed (compiling its shaders;
    that image is the one compared against the ground truth); then the timed renders
    go round-robin over the configurations ``repeat`` times."""
    target = FloatTarget(ctx, camera.width, camera.height)
    timer = GpuTimer(ctx)
    try:
        orders = {name: renderer.sort(camera, s) for name, s in settings.items()}
        images = {}
        for name, s in settings.items():
            timer.time_ms(lambda: renderer.render_into(target, camera, s, orders[name]))  # primes the query
            images[name] = target.read()
        times: dict[str, list[float]] = {name: [] for name in settings}
        for _ in range(repeat):
            for name, s in settings.items():
                times[name].append(timer.time_ms(lambda: renderer.render_into(target, camera, s, orders[name])))
        return times, images
    finally:  # (moderngl 5.13 queries have no release(); they go with the context)
        target.release()


def _median(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


def run_accuracy(options: BenchOptions, ctx=None, out=None) -> BenchResults:
    """Runs the benchmark; prints progress, a table per case and the machine-readable
    lines to ``out`` (stdout). ``ctx``: a GL context to use (default: a new headless one,
    released at the end)."""
    from raygs_viewer.render.gl.context import create_headless_context
    from raygs_viewer.render.gl.renderer import GLRenderer

    out = out or sys.stdout

    def say(line: str = "") -> None:
        print(line, file=out, flush=True)

    if BASELINE not in options.configs:
        raise UserError(f"the configurations must include the baseline '{BASELINE}'")
    scenes = _load_scenes(options.scenes)
    base = RenderSettings(p_min=DEFAULT_P_MIN, background=(0.0, 0.0, 0.0))
    settings = {name: apply_preset(base, name) for name in options.configs}
    truth_settings = replace(base, p_min=options.gt_p_min)
    samples = {"training": options.gt_samples, "far": FAR_GT_FACTOR * options.gt_samples,
               "close": options.gt_samples}
    own_ctx = ctx is None
    if own_ctx:
        ctx = create_headless_context(options.gl_backend)
    cases: list[CaseResult] = []
    truths: dict[tuple[str, str], np.ndarray] = {}  # the run's ground-truth cache
    started = time.perf_counter()
    try:
        with ctx:
            renderer_name = str(ctx.info.get("GL_RENDERER", "unknown renderer"))
            say(f"bench accuracy: {len(scenes)} scene(s) x {len(VIEW_CLASSES)} views x {len(settings)} "
                f"configurations, {options.repeat} timed frames each, on {renderer_name}")
            for item in scenes:
                say(f"[{item.name}] {item.description}")
                renderer = GLRenderer(ctx, item.scene)
                try:
                    cameras = view_cameras(item.scene, item.camera, options.width, base.p_min)
                    for view in VIEW_CLASSES:
                        camera = cameras[view]
                        key = (item.name, view)
                        say(f"[{item.name} / {view}] {camera.width}x{camera.height}: ground truth, "
                            f"{samples[view]}x{samples[view]} samples per pixel ...")
                        clock = time.perf_counter()
                        if key not in truths:
                            truths[key] = _ground_truth(item.scene, camera, truth_settings, samples[view])
                        truth = truths[key]
                        gt_seconds = time.perf_counter() - clock
                        say(f"[{item.name} / {view}] ground truth in {gt_seconds:.1f} s; timing "
                            f"{len(settings)} configurations x {options.repeat} ...")
                        times, images = measure(ctx, renderer, camera, settings, options.repeat)
                        baseline_ms = _median(times[BASELINE])
                        rows = {}
                        for name in settings:
                            metrics = error_metrics(images[name], truth)
                            ms = _median(times[name])
                            rows[name] = ConfigResult(name, ms, 1.0 if name == BASELINE else ms / baseline_ms,
                                                      metrics["psnr"], metrics["p99"], metrics["max"], times[name])
                        case = CaseResult(item.name, view, camera.width, camera.height, samples[view], gt_seconds, rows)
                        cases.append(case)
                        say(format_case_text(case))
                        for line in machine_lines(case):
                            say(line)
                finally:
                    renderer.release()
    finally:
        if own_ctx:
            ctx.release()
    say(f"bench accuracy: done in {time.perf_counter() - started:.1f} s")
    return BenchResults(cases, renderer_name, os.cpu_count() or 1, options.command_line,
                        datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
                        options.repeat, options.width, [(s.name, s.description) for s in scenes],
                        list(options.notes), options.gt_p_min)


# --- text output --------------------------------------------------------------------------

def slug(text: str) -> str:
    """A configuration's name as one token for machine-readable lines: "RayGS + MIP" -> "raygs-mip"."""
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def _fmt(value: float, digits: int = 2) -> str:
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf"
    return f"{value:.{digits}f}"


def _fmt_error(value: float) -> str:
    return "nan" if math.isnan(value) else f"{value:.2g}" if value < 0.01 else f"{value:.3f}"


def format_case_text(case: CaseResult) -> str:
    """The plain-text table printed while running."""
    head = f"{'configuration':<28} {'GPU ms':>8} {'ratio':>6} {'PSNR dB':>8} {'p99':>8} {'max':>8}"
    lines = [f"{case.scene} / {VIEW_TITLES[case.view]} ({case.width}x{case.height})", head, "-" * len(head)]
    for row in case.rows.values():
        lines.append(f"{row.config:<28} {_fmt(row.gpu_ms):>8} {_fmt(row.ratio):>6} {_fmt(row.psnr):>8} "
                     f"{_fmt_error(row.p99):>8} {_fmt_error(row.max_error):>8}")
    return "\n".join(lines)


def machine_lines(case: CaseResult) -> list[str]:
    """``KEY SCENE VIEW CONFIG VALUE`` lines (KEY: ratio, ms, psnr, p99, max; CONFIG as a slug)."""
    lines = []
    for row in case.rows.values():
        for key, value in (("ratio", row.ratio), ("ms", row.gpu_ms), ("psnr", row.psnr),
                           ("p99", row.p99), ("max", row.max_error)):
            lines.append(f"{key} {case.scene} {case.view} {slug(row.config)} {value:.6g}")
    return lines


# --- the verdict's data-driven part -----------------------------------------------------------

def _capped(value: float, cap: float = VERDICT_PSNR_CAP) -> float:
    return min(value, cap) if not math.isnan(value) else value


@dataclass
class ViewSummary:
    """One configuration in one view class, over all scenes."""
    config: str
    ratio: float         # geometric mean over scenes of the time ratio
    gain_db: float       # mean over scenes of PSNR - PSNR(BASELINE), PSNRs capped at VERDICT_PSNR_CAP
    worst_gain_db: float
    best_gain_db: float  # the best scene's
    raw_gain_db: float   # the same without the cap (breaks ties between capped gains)
    pareto: bool = False


def summarize(results: BenchResults, view: str) -> list[ViewSummary]:
    cases = [c for c in results.cases if c.view == view]
    if not cases:
        return []
    summaries = []
    for config in cases[0].rows:
        ratios = [c.rows[config].ratio for c in cases]
        gains = [_capped(c.rows[config].psnr) - _capped(c.rows[BASELINE].psnr) for c in cases]
        raw = [_capped(c.rows[config].psnr, PSNR_CAP) - _capped(c.rows[BASELINE].psnr, PSNR_CAP) for c in cases]
        good = [r for r in ratios if r > 0 and math.isfinite(r)]
        ratio = math.exp(sum(math.log(r) for r in good) / len(good)) if good else math.nan
        summaries.append(ViewSummary(config, ratio, float(np.mean(gains)), float(np.min(gains)), float(np.max(gains)),
                                     float(np.mean(raw))))
    for s in summaries:  # gains within PARETO_TOLERANCE_DB of each other count as equal
        s.pareto = not any(o is not s and ((o.ratio < s.ratio and o.gain_db >= s.gain_db - PARETO_TOLERANCE_DB)
                                           or (o.ratio <= s.ratio and o.gain_db > s.gain_db + PARETO_TOLERANCE_DB))
                           for o in summaries)
    return summaries


def verdict_lines(summaries: list[ViewSummary]) -> list[str]:
    """Facts for one view class: the best, the cheapest near it, the Pareto front, and
    what is slower than the baseline without being more accurate."""
    valid = [s for s in summaries if math.isfinite(s.gain_db) and math.isfinite(s.ratio)]
    if not valid:
        return ["no finite results"]
    best = max(valid, key=lambda s: (s.gain_db, s.raw_gain_db))
    near = [s for s in valid if s.gain_db >= best.gain_db - VERDICT_TOLERANCE_DB]
    cheapest = min(near, key=lambda s: s.ratio)

    def named(s: ViewSummary) -> str:
        return f"{s.config} ({s.gain_db:+.2f} dB, x{s.ratio:.2f} time)"

    lines = [f"most accurate: {named(best)}",
             f"cheapest within {VERDICT_TOLERANCE_DB:g} dB of it: {named(cheapest)}",
             f"Pareto front (no other configuration is faster and as accurate, within {PARETO_TOLERANCE_DB:g} dB): "
             + ", ".join(named(s) for s in sorted((s for s in valid if s.pareto), key=lambda s: s.ratio))]
    useless = [s.config for s in valid if s.config != BASELINE and s.ratio > SLOWER and s.best_gain_db <= 0.0]
    if useless:
        lines.append(f"over {SLOWER - 1:.0%} slower than RayGS and no more accurate in any scene: " + ", ".join(useless))
    return lines


def case_notes(case: CaseResult) -> dict[str, str]:
    """Per row of one case: "best" (highest PSNR), "cheapest near best" (within
    VERDICT_TOLERANCE_DB of it, fastest), "baseline"."""
    rows = [r for r in case.rows.values() if not math.isnan(r.psnr)]
    notes = {BASELINE: "baseline"}
    if rows:
        best = max(rows, key=lambda r: (_capped(r.psnr), _capped(r.psnr, PSNR_CAP)))
        near = [r for r in rows if _capped(r.psnr) >= _capped(best.psnr) - VERDICT_TOLERANCE_DB]
        cheapest = min(near, key=lambda r: r.ratio if math.isfinite(r.ratio) else math.inf)
        for row, note in ((cheapest, "cheapest near best"), (best, "best")):
            notes[row.config] = ", ".join(n for n in (notes.get(row.config), note) if n)
    return notes


# --- the report and the plot ---------------------------------------------------------------------

def _existing_human_verdict(path: Path) -> str | None:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    start, end = text.find(HUMAN_VERDICT_BEGIN), text.find(HUMAN_VERDICT_END)
    if start < 0 or end < start:
        return None
    kept = text[start + len(HUMAN_VERDICT_BEGIN):end].strip()
    return kept if kept and kept != HUMAN_VERDICT_PLACEHOLDER else None


def _p_min_text(p_min: float) -> str:
    return "1/255" if p_min == DEFAULT_P_MIN else f"{p_min:g}"


def format_report(results: BenchResults, plot_link: str | None, human_verdict: str | None = None) -> str:
    """The markdown report."""
    configs = list(results.cases[0].rows) if results.cases else list(CONFIGS)
    lines = [
        "# Accuracy against time",
        "",
        "What each accuracy option of the renderer costs in GPU time and what it buys in error against "
        "ground truth, per kind of view. Generated by `raygs-viewer bench accuracy`; the tables, the plot and "
        "the data-driven verdict are rewritten on every run, the human verdict is kept.",
        "",
        f"- Command: `{results.command_line}`",
        f"- Date: {results.date}",
        f"- Machine: {results.gl_renderer}, {results.cpu_count} CPU cores",
        f"- Timing: GPU time of one frame (preprocessing pass and draw, `GLRenderer.render_into`) from an "
        f"OpenGL timer query, median of {results.repeat} frames, configurations interleaved round-robin; "
        f"the ratio is to plain RayGS in the same scene and view, in the same run.",
        f"- Error: RGB over black against `reference.ground_truth` (exact RayGS, p_min {_p_min_text(results.gt_p_min)}, "
        "integrated over each pixel's area with n x n samples), linear float, unclipped; PSNR = 10 log10(1/MSE); "
        "p99 and max of the absolute error over all RGB values.",
        f"- Views, from each scene's training-like camera at {results.width} px wide: *training-like*; "
        f"*far*: pulled back along the optical axis to {FAR_DISTANCE_FACTOR:g}x its distance from the scene's "
        f"centre (median of the centres), at 1/{FAR_RESOLUTION_DIVISOR} of the resolution; *close*: moved "
        f"forward to {CLOSE_FRACTION:.0%} of its distance to the gaussians at the image centre, backing off "
        f"while that would be inside a gaussian's support (c^2 <= {CLOSE_SUPPORT_MARGIN:g} kappa).",
        "- Configurations (`settings.ACCURACY_PRESETS` over p_min 1/255, black background): "
        + ", ".join(configs) + ".",
        "",
        "Scenes:",
        "",
    ]
    lines += [f"- **{name}**: {description}" for name, description in results.scenes]
    notes = list(results.notes)
    if results.gt_p_min == DEFAULT_P_MIN:
        notes.append("The ground truth has the baseline's cut-off p_min 1/255, so the rows that change p_min show "
                     "their difference from that cut-off, not from the image without one (see --gt-p-min).")
    if notes:
        lines += ["", "Notes:", ""] + [f"- {note}" for note in notes]
    lines += ["", "## Verdict", "", HUMAN_VERDICT_BEGIN, human_verdict or HUMAN_VERDICT_PLACEHOLDER,
              HUMAN_VERDICT_END, ""]
    lines += ["### From the numbers (generated)", "",
              f"Per view class, over all scenes: time ratio as a geometric mean, PSNR gain over RayGS as a mean "
              f"(and the worst scene's). A PSNR above {VERDICT_PSNR_CAP:g} dB counts as {VERDICT_PSNR_CAP:g} dB here "
              f"and in the notes of the tables below (an RMS error of 1e-3 is a quarter of an 8-bit step: "
              f"differences between invisible errors do not decide).", ""]
    if plot_link:
        lines += [f"![PSNR against GPU time ratio to RayGS, per view class]({plot_link})", ""]
    for view in VIEW_CLASSES:
        summaries = summarize(results, view)
        if not summaries:
            continue
        lines += [f"#### {VIEW_TITLES[view]}", ""]
        lines += [f"- {line}" for line in verdict_lines(summaries)]
        lines += ["", "| configuration | time ratio | PSNR gain (dB) | worst scene (dB) | Pareto |",
                  "|---|---:|---:|---:|:---:|"]
        for s in summaries:
            lines.append(f"| {s.config} | {_fmt(s.ratio)} | {s.gain_db:+.2f} | {s.worst_gain_db:+.2f} | "
                         f"{'yes' if s.pareto else ''} |")
        lines.append("")
    lines += ["## Results per scene and view", ""]
    for case in results.cases:
        notes = case_notes(case)
        lines += [f"### {case.scene}: {VIEW_TITLES[case.view]}", "",
                  f"{case.width}x{case.height} px; ground truth {case.gt_samples}x{case.gt_samples} samples "
                  f"per pixel ({case.gt_seconds:.1f} s).", "",
                  "| configuration | GPU ms | ratio to RayGS | PSNR (dB) | p99 error | max error | note |",
                  "|---|---:|---:|---:|---:|---:|---|"]
        for row in case.rows.values():
            lines.append(f"| {row.config} | {_fmt(row.gpu_ms)} | {_fmt(row.ratio)} | {_fmt(row.psnr)} | "
                         f"{_fmt_error(row.p99)} | {_fmt_error(row.max_error)} | {notes.get(row.config, '')} |")
        lines.append("")
    return "\n".join(lines)


def draw_plot(results: BenchResults):
    """A Pillow image: one panel per view class, PSNR against time ratio to RayGS (log x),
    a colour per configuration and a marker shape per scene; below, the same per view
    class averaged over the scenes (PSNR gain over RayGS, as in the verdict's tables)."""
    from raygs_viewer.bench.plot import PALETTE, SHAPES, Panel, Point, scatter_panels
    configs = list(results.cases[0].rows) if results.cases else list(CONFIGS)
    colors = {c: PALETTE[i % len(PALETTE)] for i, c in enumerate(configs)}
    scene_names = list(dict.fromkeys(case.scene for case in results.cases))
    shapes = {s: SHAPES[i % len(SHAPES)] for i, s in enumerate(scene_names)}
    panels = []
    for view in VIEW_CLASSES:
        points = [Point(row.ratio, _capped(row.psnr, PSNR_CAP), colors[row.config], shapes[case.scene])
                  for case in results.cases if case.view == view for row in case.rows.values()]
        panels.append(Panel(VIEW_TITLES[view], points, guides_x=(1.0,)))
    per_scene = scatter_panels(panels, title="Error against GPU time, per view class and scene",
                               x_label="GPU time / RayGS time (log scale)", y_label="PSNR against ground truth (dB)",
                               series=[(c, colors[c]) for c in configs],
                               groups=[(f"scene: {s}", shapes[s]) for s in scene_names])
    # The verdict's view: one marker per configuration, averaged over the scenes.
    panels = [Panel(VIEW_TITLES[view], [Point(s.ratio, s.gain_db, colors[s.config]) for s in summarize(results, view)],
                    guides_x=(1.0,)) for view in VIEW_CLASSES]
    mean = scatter_panels(panels, title=f"Mean over scenes (time: geometric mean; PSNR capped at "
                                        f"{VERDICT_PSNR_CAP:g} dB before averaging)",
                          x_label="GPU time / RayGS time (log scale)", y_label="PSNR gain over RayGS (dB)",
                          series=[(c, colors[c]) for c in configs])
    from PIL import Image
    image = Image.new("RGB", (per_scene.width, per_scene.height + mean.height), (255, 255, 255))
    image.paste(per_scene, (0, 0))
    image.paste(mean, (0, per_scene.height))
    return image


def png_bytes(image) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


def write_outputs(results: BenchResults, report: Path, plot: Path, overwrite: bool) -> None:
    """Writes the plot and the report, each atomically (a temporary file moved into place)."""
    from raygs_viewer.capture.image_io import write_atomically
    human = _existing_human_verdict(report) if overwrite else None
    link = os.path.relpath(os.path.abspath(plot), os.path.dirname(os.path.abspath(report))).replace(os.sep, "/")
    write_atomically(plot, png_bytes(draw_plot(results)), overwrite)
    write_atomically(report, format_report(results, link, human).encode("utf-8"), overwrite)
    if human:
        print(f"note: kept the human verdict of the existing {report}; check it against the new numbers",
              file=sys.stderr)


# --- command line ------------------------------------------------------------------------------

def add_parser(commands) -> None:
    """Adds ``bench`` and its subcommands to the CLI's subparsers."""
    from raygs_viewer.cli.main import (  # the CLI's own number types (cli imports bench)
        _real_number,
        _whole_number,
    )

    def count(low: int, high: int):
        return _whole_number(low, high, f"outside {low}..{high}")

    bench = commands.add_parser("bench", help="benchmarks (accuracy against time; stereo sharing error and "
                                              "frame budget; per-stage frame times and cost ratios)")
    kinds = bench.add_subparsers(dest="bench", required=True, parser_class=type(bench))
    accuracy = kinds.add_parser(
        "accuracy", help="GPU time and error against ground truth of every accuracy option",
        description="For every accuracy configuration and every view class (training-like, far at 1/4 "
                    "resolution, very close) of the demo and the shared real scenes: GPU time per frame "
                    "(timer queries, as a ratio to plain RayGS) and the error against the ground truth "
                    "(PSNR, p99, max). Writes a markdown report and a PNG plot.")
    accuracy.add_argument("--quick", action="store_true",
                          help=f"the demo and one small real scene, {QUICK_WIDTH} px wide, {QUICK_REPEAT} timed "
                               f"frames, ground truth {QUICK_GT_SAMPLES}x{QUICK_GT_SAMPLES} samples (about two minutes)")
    accuracy.add_argument("--scenes", nargs="+", metavar="SCENE",
                          help=f"scene files (or '{DEMO}') instead of the demo and the real scenes in "
                               f"../shared/scenes")
    accuracy.add_argument("--width", type=count(4, 16384), metavar="PX",
                          help=f"width of the training-like view (default {DEFAULT_WIDTH}, --quick {QUICK_WIDTH}); "
                               f"the far view has a quarter of it")
    accuracy.add_argument("--repeat", type=count(1, 100000), metavar="N",
                          help=f"timed frames per configuration (default {DEFAULT_REPEAT}, --quick {QUICK_REPEAT}); "
                               f"use at least 10")
    accuracy.add_argument("--gt-samples", type=count(1, 64), metavar="N",
                          help=f"ground-truth samples per pixel axis for the training-like and close views "
                               f"(default {DEFAULT_GT_SAMPLES}, --quick {QUICK_GT_SAMPLES}); the far view uses "
                               f"{FAR_GT_FACTOR} times as many")
    accuracy.add_argument("--gt-p-min", type=_real_number(lambda p: 0.0 < p < 1.0, "not in (0, 1)"), metavar="P",
                          help=f"opacity cut-off of the ground truth (default {GT_P_MIN:g}, below every "
                               f"configuration's, so that the p_min rows are judged against the faint tails too)")
    accuracy.add_argument("--report", default=DEFAULT_REPORT, metavar="PATH.md",
                          help=f"markdown report (default {DEFAULT_REPORT})")
    accuracy.add_argument("--plot", default=DEFAULT_PLOT, metavar="PATH.png",
                          help=f"plot of PSNR against time (default {DEFAULT_PLOT})")
    accuracy.add_argument("--overwrite", action="store_true",
                          help="replace an existing report and plot (the report's human verdict is kept)")
    accuracy.add_argument("--gl-backend", choices=("auto", "egl", "osmesa"),
                          help="headless OpenGL (default: $RAYGS_GL_BACKEND or auto: EGL, else OSMesa)")
    from raygs_viewer.bench import (
        stereo as bench_stereo,  # imports this module: only once both exist
    )
    bench_stereo.add_parser(kinds, count)
    from raygs_viewer.bench import perf as bench_perf
    bench_perf.add_parser(kinds, count)


def command_line(args: argparse.Namespace) -> str:
    """The command that reproduces this run (options in a fixed order)."""
    parts = ["raygs-viewer", "bench", "accuracy"]
    if args.quick:
        parts.append("--quick")
    if args.scenes:
        parts += ["--scenes", *args.scenes]
    for flag, dest in (("--width", "width"), ("--repeat", "repeat"), ("--gt-samples", "gt_samples"),
                       ("--gt-p-min", "gt_p_min"), ("--gl-backend", "gl_backend")):
        if getattr(args, dest) is not None:
            parts += [flag, str(getattr(args, dest))]
    parts += ["--report", str(args.report), "--plot", str(args.plot)]
    if args.overwrite:
        parts.append("--overwrite")
    return shlex.join(parts)


def options_from_args(args: argparse.Namespace) -> BenchOptions:
    notes: list[str] = []
    if args.scenes:
        scenes = tuple(args.scenes)
    else:
        scenes, notes = default_scenes(args.quick)
    report, plot = Path(args.report), Path(args.plot)
    if os.path.abspath(report) == os.path.abspath(plot):
        raise UserError(f"{report}: the report and the plot must be different files")
    return BenchOptions(
        scenes=scenes,
        width=args.width or (QUICK_WIDTH if args.quick else DEFAULT_WIDTH),
        repeat=args.repeat or (QUICK_REPEAT if args.quick else DEFAULT_REPEAT),
        gt_samples=args.gt_samples or (QUICK_GT_SAMPLES if args.quick else DEFAULT_GT_SAMPLES),
        report=check_output_path(report, args.overwrite, (".md",)),
        plot=check_output_path(plot, args.overwrite, (".png",)),
        overwrite=args.overwrite,
        command_line=command_line(args),
        gl_backend=args.gl_backend,
        notes=tuple(notes),
        gt_p_min=GT_P_MIN if args.gt_p_min is None else args.gt_p_min,
    )


def command(args: argparse.Namespace, ctx=None) -> int:
    """Runs ``bench <kind>``. ``ctx``: a GL context to use instead of a new one (tests)."""
    if args.bench == "stereo":
        from raygs_viewer.bench import stereo as bench_stereo
        return bench_stereo.command(args, ctx)
    if args.bench == "perf":
        from raygs_viewer.bench import perf as bench_perf
        return bench_perf.command(args, ctx)
    if args.bench != "accuracy":
        raise UserError(f"unknown benchmark '{args.bench}'")
    options = options_from_args(args)
    for note in options.notes:
        print(f"note: {note}", flush=True)
    results = run_accuracy(options, ctx)
    write_outputs(results, options.report, options.plot, options.overwrite)
    print(f"wrote {options.report} and {options.plot}", flush=True)
    return 0
