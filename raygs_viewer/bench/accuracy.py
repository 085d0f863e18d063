"""Benchmarks: ``raygs-viewer bench accuracy`` (what accuracy costs in time).

For every accuracy configuration (``settings.ACCURACY_PRESETS``, applied to base
settings with p_min 1/255 on black) and every view class of every scene, it
measures

- the GPU time of one frame (``GLRenderer.render_into``: preprocessing pass and
  draw, timed with an OpenGL timer query; the median of ``--repeat`` runs, the
  configurations interleaved round-robin so that drift hits them all alike), also
  as a ratio to plain RayGS measured in the same run;
- the error of the GL image against the ground truth
  (``reference.ground_truth``: exact RayGS, every ray composited in its own order
  (``order="per-pixel"``), integrated over each pixel's area), on
  RGB over black: PSNR = 10 log10(1 / MSE) and the 99th percentile and maximum of
  the absolute error, in linear float, unclipped.

The view classes (training-like, far, very close) are built by :mod:`bench.views`.

``--photos MODEL`` adds the photos as a second truth: the model's trained scene at the
first ``--photos-views`` test views of its dataset (``photos.dataset``: every 8th view;
each camera scaled to ``--width`` where it is wider, its photo resized to it as the
INRIA loader does), every configuration over the dataset's background, timed and
compared with the float64 truth as above and with the photo: PSNR and the 3DGS SSIM
(``photos.metrics``) of the render clipped to 0..1, as the training code measures it.

Output: a table per (scene, view class) and machine-readable lines
``KEY SCENE VIEW CONFIG VALUE`` (KEY: ratio, ms, psnr, p99, max; for a photo view VIEW
is ``photo-NAME`` and photo_psnr, photo_ssim follow) on stdout, a
markdown report and a PNG plot of PSNR against time ratio, one panel per view class
(:mod:`bench.accuracy_report`).
"""

from __future__ import annotations

import math
import os
import re
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, TextIO

import numpy as np

from raygs_viewer.bench.common import (
    DEMO,
    RunOptions,
    error_metrics,
    fmt_error,
    gl_context,
    load_scenes,
    median,
    printer,
    run_date,
    scene_renderer,
    shared_scene_paths,
)
from raygs_viewer.bench.views import VIEW_CLASSES, VIEW_TITLES, view_cameras
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.photos.dataset import PhotoView, load_photo, open_dataset, select_split
from raygs_viewer.photos.metrics import psnr, ssim_3dgs
from raygs_viewer.render import reference
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import (
    ACCURACY_PRESETS,
    DEFAULT_P_MIN,
    RenderSettings,
    apply_preset,
)
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

#: Every configuration, in the order of the presets; ratios are taken against BASELINE.
CONFIGS = tuple(ACCURACY_PRESETS)
BASELINE = "RayGS"

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

#: The ground truth's opacity cut-off: far below every configuration's, so the p_min
#: rows are judged against an image whose faint tails are (nearly) all there.
GT_P_MIN = 1e-4

#: --photos-views: the test views measured against their photos (the first in name order).
DEFAULT_PHOTO_VIEWS = 4
#: The ``view`` of a case measured at a photo's camera (its name in ``CaseResult.photo``).
PHOTO_VIEW = "photo"


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
    photo_psnr: float = math.nan   # against the photo (photo cases only)
    photo_ssim: float = math.nan


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
    photo: str = ""   # the photo's view name, for view PHOTO_VIEW


@dataclass
class AccuracyResults:
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
    photos: str = ""   # the photo dataset measured, described ("" without --photos)


@dataclass(frozen=True)
class AccuracyOptions(RunOptions):
    scenes: tuple[str, ...]         # "demo" or scene files
    width: int
    repeat: int
    gt_samples: int                 # training-like and close; far: FAR_GT_FACTOR times as many
    report: Path | None
    plot: Path | None
    overwrite: bool = False
    command_line: str = "raygs-viewer bench accuracy"
    configs: tuple[str, ...] = CONFIGS
    gt_p_min: float = GT_P_MIN   # the ground truth's cut-off
    photos: str | None = None    # a dataset (INRIA model folder) whose test photos are a second truth
    photos_views: int = DEFAULT_PHOTO_VIEWS


def default_scenes(quick: bool) -> tuple[tuple[str, ...], list[str]]:
    """The demo plus the real scenes found in the shared folder; notes for those absent."""
    found, notes = shared_scene_paths(QUICK_REAL_SCENES if quick else REAL_SCENES)
    return (DEMO, *found), notes


def measure(ctx, renderer, sorter: DepthSorter, camera: Camera, settings: dict[str, RenderSettings], *,
            repeat: int) -> tuple[dict[str, list[float]], dict[str, np.ndarray]]:
    """GPU times (ms, ``repeat`` per configuration) and the image of every configuration.

    Each configuration is sorted once (by ``sorter``) and rendered once untimed (compiling its shaders;
    that image is the one compared against the ground truth); then the timed renders
    go round-robin over the configurations ``repeat`` times."""
    target = FloatTarget(ctx, camera.width, camera.height)
    timer = GpuTimer(ctx)
    try:
        orders = {name: exact_order(sorter, camera, s) for name, s in settings.items()}
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


def run_accuracy(options: AccuracyOptions, ctx=None, out: TextIO | None = None,
                 ground_truth: Callable[..., np.ndarray] = reference.ground_truth) -> AccuracyResults:
    """Runs the benchmark; prints progress, a table per case and the machine-readable
    lines to ``out`` (stdout). ``ctx``: a GL context to use (default: a new headless one,
    released at the end). ``ground_truth(scene, camera, settings, samples)``: the
    image every configuration is compared against."""
    say = printer(out)
    if BASELINE not in options.configs:
        raise UserError(f"the configurations must include the baseline '{BASELINE}'")
    scenes = load_scenes(options.scenes)
    base = RenderSettings(p_min=DEFAULT_P_MIN, background=(0.0, 0.0, 0.0))
    settings = {name: apply_preset(base, name) for name in options.configs}
    # The truth composites every ray in its own order (maths page, section 11), so the
    # global orders' error shows beside aliasing's.
    truth_settings = replace(base, p_min=options.gt_p_min, order="per-pixel")
    samples = {"training": options.gt_samples, "far": FAR_GT_FACTOR * options.gt_samples,
               "close": options.gt_samples}
    cases: list[CaseResult] = []
    started = time.perf_counter()
    with gl_context(ctx, options.gl_backend) as ctx, ctx:  # made current for the run
        renderer_name = str(ctx.info.get("GL_RENDERER", "unknown renderer"))
        say(f"bench accuracy: {len(scenes)} scene(s) x {len(VIEW_CLASSES)} views x {len(settings)} "
            f"configurations, {options.repeat} timed frames each, on {renderer_name}")
        for item in scenes:
            say(f"[{item.name}] {item.description}")
            with scene_renderer(ctx, item.scene) as (renderer, sorter):
                cameras = view_cameras(item.scene, item.camera, options.width, base.p_min)
                for view in VIEW_CLASSES:
                    camera = cameras[view]
                    say(f"[{item.name} / {view}] {camera.width}x{camera.height}: ground truth, "
                        f"{samples[view]}x{samples[view]} samples per pixel ...")
                    clock = time.perf_counter()
                    truth = ground_truth(item.scene, camera, truth_settings, samples[view])
                    gt_seconds = time.perf_counter() - clock
                    say(f"[{item.name} / {view}] ground truth in {gt_seconds:.1f} s; timing "
                        f"{len(settings)} configurations x {options.repeat} ...")
                    times, images = measure(ctx, renderer, sorter, camera, settings, repeat=options.repeat)
                    case = CaseResult(item.name, view, camera.width, camera.height, samples[view], gt_seconds,
                                      compare(times, images, truth))
                    cases.append(case)
                    say_case(case, say)
        photos = ""
        if options.photos is not None:
            photo_results, photos = photo_cases(ctx, options, base, ground_truth, say)
            cases += photo_results
    say(f"bench accuracy: done in {time.perf_counter() - started:.1f} s")
    return AccuracyResults(cases, renderer_name, os.cpu_count() or 1, options.command_line,
                           run_date(),
                           options.repeat, options.width, [(s.name, s.description) for s in scenes],
                           list(options.notes), options.gt_p_min, photos)


def photo_camera(camera: Camera, width: int) -> Camera:
    """``camera`` scaled to ``width`` pixels wide where it is wider (the height rounded)."""
    if camera.width <= width:
        return camera
    return camera.resized(width, max(1, round(camera.height * width / camera.width)))


def say_case(case: CaseResult, say) -> None:
    """Prints a measured case: its text and its machine-readable lines."""
    say(format_case_text(case))
    for line in machine_lines(case):
        say(line)


def photo_cases(ctx, options: AccuracyOptions, base: RenderSettings, ground_truth: Callable[..., np.ndarray],
                say: Callable[[str], None]) -> tuple[list[CaseResult], str]:
    """The cases of ``--photos`` (see the module docstring) and the dataset described."""
    dataset = open_dataset(options.photos)
    if dataset.scene_path is None:
        raise UserError(f"--photos {options.photos}: no trained scene in it (an INRIA model folder holds "
                        f"point_cloud/iteration_*/point_cloud.ply)")
    views = select_split(dataset.views, "test")[:options.photos_views]
    if not views:
        raise UserError(f"--photos {options.photos}: the dataset has no test views")
    item = load_scenes((str(dataset.scene_path),))[0]
    over = replace(base, background=dataset.background)
    settings = {name: apply_preset(over, name) for name in options.configs}
    truth_settings = replace(over, p_min=options.gt_p_min, order="per-pixel")
    cases, skipped = [], 0
    say(f"[photos] {item.name}: {len(views)} test view(s) of {dataset.root} against their photos")
    with scene_renderer(ctx, item.scene) as (renderer, sorter):
        for view in views:
            camera = photo_camera(view.camera, options.width)
            try:
                photo = load_photo(PhotoView(view.name, camera, view.image_path, view.index), dataset.background)
            except UserError as exc:
                say(f"[photos] skipped {view.name}: {one_line(exc)}")
                skipped += 1
                continue
            clock = time.perf_counter()
            truth = ground_truth(item.scene, camera, truth_settings, options.gt_samples)
            gt_seconds = time.perf_counter() - clock
            times, images = measure(ctx, renderer, sorter, camera, settings, repeat=options.repeat)
            rows = compare(times, images, truth)
            for name, row in rows.items():
                shown = np.clip(images[name][..., :3], 0.0, 1.0)
                row.photo_psnr, row.photo_ssim = psnr(shown, photo), ssim_3dgs(shown, photo)
            case = CaseResult(item.name, PHOTO_VIEW, camera.width, camera.height, options.gt_samples, gt_seconds,
                              rows, photo=view.name)
            cases.append(case)
            say_case(case, say)
    described = (f"{len(cases)} test view(s) of {dataset.root} ({dataset.layout}), scene {item.name}, "
                 f"background {dataset.background}" + (f"; {skipped} skipped" if skipped else ""))
    return cases, described


def compare(times: dict[str, list[float]], images: dict[str, np.ndarray], truth: np.ndarray
            ) -> dict[str, ConfigResult]:
    """Each configuration's row of one case: its median time, its ratio to BASELINE's
    and its error against ``truth``."""
    baseline_ms = median(times[BASELINE])
    rows = {}
    for name in times:
        metrics = error_metrics(images[name], truth)
        ms = median(times[name])
        rows[name] = ConfigResult(name, ms, 1.0 if name == BASELINE else ms / baseline_ms,
                                  metrics["psnr"], metrics["p99"], metrics["max"], times[name])
    return rows


# --- text output --------------------------------------------------------------------------

def slug(text: str) -> str:
    """A configuration's name as one token for machine-readable lines: "RayGS + MIP" -> "raygs-mip"."""
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def fmt_number(value: float, digits: int = 2) -> str:
    """A number for a table, nan and inf spelled out."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf"
    return f"{value:.{digits}f}"


def case_title(case: CaseResult) -> str:
    """A view class's title, or "test view NAME against its photo"."""
    return f"test view {case.photo} against its photo" if case.photo else VIEW_TITLES[case.view]


def format_case_text(case: CaseResult) -> str:
    """The plain-text table printed while running."""
    head = f"{'configuration':<28} {'GPU ms':>8} {'ratio':>6} {'PSNR dB':>8} {'p99':>8} {'max':>8}"
    if case.photo:
        head += f" {'photo dB':>8} {'SSIM':>6}"
    lines = [f"{case.scene} / {case_title(case)} ({case.width}x{case.height})", head, "-" * len(head)]
    for row in case.rows.values():
        line = (f"{row.config:<28} {fmt_number(row.gpu_ms):>8} {fmt_number(row.ratio):>6} "
                f"{fmt_number(row.psnr):>8} {fmt_error(row.p99):>8} {fmt_error(row.max_error):>8}")
        if case.photo:
            line += f" {fmt_number(row.photo_psnr):>8} {fmt_number(row.photo_ssim, 4):>6}"
        lines.append(line)
    return "\n".join(lines)


def machine_lines(case: CaseResult) -> list[str]:
    """``KEY SCENE VIEW CONFIG VALUE`` lines (KEY: ratio, ms, psnr, p99, max, and for a
    photo case, whose VIEW is ``photo-NAME``, photo_psnr and photo_ssim; CONFIG as a slug)."""
    lines = []
    view = f"{PHOTO_VIEW}-{slug(case.photo)}" if case.photo else case.view
    for row in case.rows.values():
        values = [("ratio", row.ratio), ("ms", row.gpu_ms), ("psnr", row.psnr), ("p99", row.p99),
                  ("max", row.max_error)]
        if case.photo:
            values += [("photo_psnr", row.photo_psnr), ("photo_ssim", row.photo_ssim)]
        for key, value in values:
            lines.append(f"{key} {case.scene} {view} {slug(row.config)} {value:.6g}")
    return lines


