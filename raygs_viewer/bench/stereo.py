"""``raygs-viewer bench stereo``: what the shared sort and colour cost, and whether both
eyes fit a headset's frame budget.

Two measurements, per scene (the demo and the shared real scenes, found as ``bench
accuracy`` finds them):

- **Sharing error.** The stereo images the viewer draws (one sort from the eyes'
  midpoint, SH colour seen from it: ``render_stereo(..., shared=True)``) against
  per-eye ones (each eye sorted from its own position, its colour seen from there),
  for the training-like and very close views of ``bench`` at two scene scales: 1 m per
  unit, and the scale that makes the scene 1 m across. The two sources are also taken
  apart: the shared images against eyes that differ from them only in the sort
  (*sort only*) or only in the colour (*colour only*).
- **Frame budget.** Both eyes at each headset preset's per-eye resolution and field of
  view, from the scene's training-like pose, drawn with the shared order: the GPU time
  of the two ``render_into`` calls under one timer query, against the budget of each
  refresh rate of ``stereo.REFRESH_RATES``; the CPU time of the stereo sort beside it.

Output: progress and machine-readable lines (``stereo-error SCENE VIEW SCALE KEY VALUE``,
``stereo-budget SCENE PRESET KEY VALUE``) on stdout while it runs, then a markdown
report, also written to ``--out`` when given.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import TextIO

import numpy as np

from raygs_viewer.bench import common
from raygs_viewer.bench.views import (
    CLOSE_FRACTION,
    CLOSE_SUPPORT_MARGIN,
    VIEW_TITLES,
    close_view,
    training_view,
)
from raygs_viewer.camera import stereo
from raygs_viewer.camera.navigation import scene_bounds
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.gl.stereo_frame import StereoFrame, render_stereo, stereo_order
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

#: The views of ``bench`` measured here: where sharing costs least and where it costs most.
VIEWS = ("training", "close")
#: Scene scales, by the token of the machine-readable lines.
UNIT_SCALE, ACROSS_SCALE = "1m-per-unit", "1m-across"
SCALES = (UNIT_SCALE, ACROSS_SCALE)
#: The three comparisons of the sharing error, by the prefix of their keys.
PARTS = {"whole": "", "sort-only": "sort-only-", "colour-only": "colour-only-"}

DEFAULT_WIDTH = 320
DEFAULT_REPEAT, QUICK_REPEAT = 10, 3
#: Noted in the report when the GL renders on the CPU (llvmpipe): its times are no headset GPU's.
SOFTWARE_NOTE = ("This is a software OpenGL renderer (on the CPU): its times rank the presets and scenes on this "
                 "machine; they say nothing about what a headset's GPU would take.")


# --- the measurements ------------------------------------------------------------------------

def one_metre_scale(scene) -> tuple[float, float]:
    """(scene_scale, extent): the metres per unit that make the scene 1 m across, its
    extent in units being twice ``camera.navigation.scene_bounds``' robust radius (the diagonal of
    the 1st..99th percentile box of the centres)."""
    _, radius = scene_bounds(scene.positions)
    extent = 2.0 * radius
    return 1.0 / extent, extent


def _pair(images) -> np.ndarray:
    return np.concatenate(list(images), axis=1)


def sharing_errors(renderer, sorter: DepthSorter, camera: Camera, settings: RenderSettings,
                   rig: stereo.StereoRig) -> dict[str, dict[str, float]]:
    """{part: error_metrics} over both eyes (side by side) of the shared images against:
    "whole": per-eye ones (own sort, own colour); "sort-only": each eye's own sort with the
    midpoint's colour; "colour-only": the shared order with each eye's own colour.
    ``sorter`` sorts every order."""
    eyes = stereo.eye_cameras(camera, rig)
    shared = _pair(render_stereo(renderer, sorter, camera, settings, rig, shared=True))
    own = _pair(render_stereo(renderer, sorter, camera, settings, rig, shared=False))
    sort_only = _pair(renderer.render(eye, settings, exact_order(sorter, eye, settings), color_origin=camera.center)
                      for eye in eyes)
    order = stereo_order(sorter, camera, settings, rig)
    colour_only = _pair(renderer.render(eye, settings, order) for eye in eyes)
    return {"whole": common.error_metrics(shared, own), "sort-only": common.error_metrics(shared, sort_only),
            "colour-only": common.error_metrics(shared, colour_only)}


def time_both_eyes(ctx, renderer, sorter: DepthSorter, camera: Camera, settings: RenderSettings, *,
                   rig: stereo.StereoRig, repeat: int) -> tuple[list[float], list[float]]:
    """(GPU ms, sort CPU ms), ``repeat`` of each: per frame the stereo sort by ``sorter``
    (timed on the CPU), then both eyes drawn with it as the window draws them
    (``StereoFrame.draw_eyes``), under one timer query: what the window's frame-budget
    meter reads. One untimed frame first compiles the shaders and primes the query. An
    elapsed time the driver marks invalid is NaN."""
    frame = StereoFrame(ctx)
    timer = GpuTimer(ctx)
    eyes = stereo.eye_cameras(camera, rig)
    gpu_ms, sort_ms = [], []
    try:
        for index in range(repeat + 1):
            clock = time.perf_counter()
            order = stereo_order(sorter, camera, settings, rig)
            sorted_in = time.perf_counter() - clock
            elapsed = timer.time_ms(lambda: frame.draw_eyes(renderer, camera, settings, eyes, order))
            if index:
                gpu_ms.append(elapsed)
                sort_ms.append(sorted_in * 1e3)
        return gpu_ms, sort_ms
    finally:  # (moderngl 5.13 queries have no release(); they go with the context)
        frame.release()


def budget_text(fraction: float) -> str:
    """A fraction of a frame budget (``stereo.frame_budget``) as "×4.2 over" or "fits, 63 %"."""
    if not math.isfinite(fraction):
        return "nan"
    return f"×{fraction:.1f} over" if fraction > 1.0 else f"fits, {fraction * 100:.0f} %"


# --- running it -----------------------------------------------------------------------------

@dataclass
class ErrorRow:
    scene: str
    view: str                 # one of VIEWS
    scale: str                # one of SCALES
    scene_scale: float        # metres per unit
    width: int
    height: int
    parts: dict[str, dict[str, float]]   # sharing_errors


@dataclass
class BudgetRow:
    scene: str
    preset: str               # the key in stereo.PRESETS
    label: str
    width: int                # per eye, as rendered
    height: int
    gpu_ms: float             # median, both eyes
    sort_ms: float            # median, CPU
    gpu_times: list[float] = field(default_factory=list)
    sort_times: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class StereoOptions(common.ReportedRunOptions):
    scenes: tuple[str, ...]
    presets: tuple[str, ...]
    width: int
    repeat: int
    command_line: str = "raygs-viewer bench stereo"
    rig: stereo.StereoRig = stereo.StereoRig()


@dataclass
class StereoResults:
    errors: list[ErrorRow]
    budgets: list[BudgetRow]
    machine: str
    cpu_count: int
    options: StereoOptions
    date: str
    scenes: list[tuple[str, str]]
    notes: list[str]
    seconds: float = math.nan


def error_lines(row: ErrorRow) -> list[str]:
    """``stereo-error SCENE VIEW SCALE KEY VALUE``: KEY psnr, p99, max for the whole error,
    with a sort-only- or colour-only- prefix for the parts; scene-scale for the 1 m across row."""
    head = f"stereo-error {row.scene} {row.view} {row.scale}"
    lines = [f"{head} scene-scale {row.scene_scale:.6g}"] if row.scale == ACROSS_SCALE else []
    for part, prefix in PARTS.items():
        lines += [f"{head} {prefix}{key} {row.parts[part][key]:.6g}" for key in ("psnr", "p99", "max")]
    return lines


def budget_lines(row: BudgetRow) -> list[str]:
    """``stereo-budget SCENE PRESET KEY VALUE``: ms (both eyes, GPU), sort-ms (CPU) and
    fraction-of-RATEHz for every refresh rate."""
    head = f"stereo-budget {row.scene} {row.preset}"
    lines = [f"{head} ms {row.gpu_ms:.6g}", f"{head} sort-ms {row.sort_ms:.6g}"]
    budget = stereo.frame_budget(row.gpu_ms / 1e3)
    lines += [f"{head} fraction-of-{rate}Hz {fraction:.6g}" for rate, _, fraction in budget]
    return lines


def _describe(item: common.BenchScene) -> str:
    sh = item.scene.sh
    if item.scene.sh_degree > 0 and not np.any(sh[:, 1:]):
        return f"{item.description} (its higher SH bands are all zero: colour does not depend on the view)"
    return item.description


def _error_rows(renderer, sorter: DepthSorter, item: common.BenchScene, options: StereoOptions,
                settings: RenderSettings):
    """Yields the sharing error of ``item`` in every view at every scene scale, one row at
    a time (each is printed as it comes)."""
    training = training_view(item.camera, options.width)
    views = {"training": training, "close": close_view(training, item.scene, settings.p_min)}
    across, _ = one_metre_scale(item.scene)
    for view in VIEWS:
        camera = views[view]
        for scale, scene_scale in ((UNIT_SCALE, 1.0), (ACROSS_SCALE, across)):
            rig = replace(options.rig, scene_scale=scene_scale)
            yield ErrorRow(item.name, view, scale, scene_scale, camera.width, camera.height,
                           sharing_errors(renderer, sorter, camera, settings, rig))


def run_stereo(options: StereoOptions, ctx=None, out: TextIO | None = None) -> StereoResults:
    """Runs both measurements; prints progress and the machine-readable lines to ``out``
    (stdout). ``ctx``: a GL context to use (default: a new headless one, released at the
    end)."""
    say = common.printer(out)
    scenes = common.load_scenes(options.scenes)
    presets = [stereo.PRESETS[name] for name in options.presets]
    settings = RenderSettings()
    errors: list[ErrorRow] = []
    budgets: list[BudgetRow] = []
    started = time.perf_counter()
    with common.current_context(ctx, options.gl_backend) as (ctx, machine):
        say(f"bench stereo: {len(scenes)} scene(s); sharing error in {len(VIEWS)} views x {len(SCALES)} "
            f"scales; frame budget for {', '.join(options.presets)}, {options.repeat} timed frames each; "
            f"on {machine}")
        for item in scenes:
            say(f"[{item.name}] {_describe(item)}")
            with common.scene_renderer(ctx, item.scene) as (renderer, sorter):
                for row in _error_rows(renderer, sorter, item, options, settings):
                    errors.append(row)
                    for line in error_lines(row):
                        say(line)
                for preset in presets:
                    camera = preset.camera(item.camera)
                    say(f"[{item.name} / {preset.name}] {camera.width}x{camera.height} per eye: "
                        f"timing {options.repeat} frames ...")
                    gpu, sort = time_both_eyes(ctx, renderer, sorter, camera, settings, rig=options.rig,
                                               repeat=options.repeat)
                    row = BudgetRow(item.name, preset.name, preset.label, camera.width, camera.height,
                                    common.median(gpu), common.median(sort), gpu, sort)
                    budgets.append(row)
                    for line in budget_lines(row):
                        say(line)
    finished = common.finished_run_fields("stereo", started, machine=machine, notes=options.notes,
                                          software_note=SOFTWARE_NOTE, say=say)
    return StereoResults(errors=errors, budgets=budgets, options=options,
                         scenes=[(s.name, _describe(s)) for s in scenes], **finished)


# --- the report -------------------------------------------------------------------------------

def _psnr_text(value: float) -> str:
    if math.isnan(value):
        return "nan"
    return "inf" if math.isinf(value) else f"{value:.1f}"


def _scale_text(row: ErrorRow) -> str:
    return "1 m/unit" if row.scale == UNIT_SCALE else f"{row.scene_scale:.3g} m/unit (1 m across)"


def format_report(results: StereoResults) -> str:
    """The markdown report: header, the sharing-error table and the frame-budget table."""
    options = results.options
    rig = options.rig
    rates = stereo.REFRESH_RATES
    lines = [
        "# Stereo: what sharing costs, and the frame budget",
        "",
        "Generated by `raygs-viewer bench stereo`.",
        "",
        f"- Command: `{options.command_line}`",
        f"- Date: {results.date}",
        f"- Machine: {results.machine}, {results.cpu_count} CPU cores",
        "- Settings: `RenderSettings()`: RayGS, p_min 1/255, black background, each scene's full SH degree.",
        f"- Rig: IPD {rig.ipd:g} m, convergence {rig.convergence:g} m.",
        "",
        "Scenes:",
        "",
    ]
    lines += [f"- **{name}**: {description}" for name, description in results.scenes]
    if results.notes:
        lines += ["", "Notes:", ""] + [f"- {note}" for note in results.notes]
    lines += [
        "",
        "## What sharing costs",
        "",
        "The shared images (one sort from the eyes' midpoint, SH colour seen from it: what the viewer draws) "
        "against per-eye ones (each eye sorted from its own position, its colour seen from there): RGB over both "
        "eyes, linear float, unclipped; PSNR = 10 log10(1/MSE) (inf: identical), p99 and max of the absolute "
        "error. *Sort only*: against eyes with their own sort and the midpoint's colour, so only the sort "
        "differs; *colour only*: against the shared order with each eye's own colour.",
        "",
        f"Views, from each scene's training-like camera at {options.width} px wide: *training-like*, and *very "
        f"close*: moved forward to {CLOSE_FRACTION:.0%} of its distance to the gaussians at the image centre, "
        f"backing off while that would be inside a gaussian's support (c^2 <= {CLOSE_SUPPORT_MARGIN:g} kappa; "
        "`docs/accuracy-vs-time.md`). Scene scales: 1 m per unit, and the scale that makes the scene 1 m across, "
        "its extent being twice the robust radius of `camera.navigation.scene_bounds` (the diagonal of the 1st..99th "
        "percentile box of the gaussian centres).",
        "",
        "| scene | view | size | scene scale | PSNR (dB) | p99 | max | sort only: PSNR | sort only: max "
        "| colour only: PSNR | colour only: max |",
        "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in results.errors:
        whole, sort, colour = (row.parts[part] for part in PARTS)
        lines.append(f"| {row.scene} | {VIEW_TITLES[row.view]} | {row.width}×{row.height} | {_scale_text(row)} | "
                     f"{_psnr_text(whole['psnr'])} | {common.fmt_error(whole['p99'])} | "
                     f"{common.fmt_error(whole['max'])} | "
                     f"{_psnr_text(sort['psnr'])} | {common.fmt_error(sort['max'])} | "
                     f"{_psnr_text(colour['psnr'])} | {common.fmt_error(colour['max'])} |")
    lines += [
        "",
        "## Frame budget",
        "",
        "Both eyes at each headset preset's per-eye resolution and field of view (`stereo.PRESETS`), from each "
        "scene's training-like pose as the midpoint, drawn with the shared order into two eye-sized float "
        "targets: the GPU time of the two `GLRenderer.render_into` calls (preprocessing pass and draw, per eye) "
        f"under one OpenGL timer query, median of {options.repeat} frames after one untimed warm-up. The stereo "
        "sort (`stereo_frame.stereo_order`, on the CPU) is timed apart, median over the same frames, and is not in the "
        "GPU time. Each rate's budget is 1000 / rate ms: *×N over* takes N times the budget, *fits, P %* takes "
        "P % of it.",
        "",
        "| scene | headset | per eye | both eyes GPU ms | sort CPU ms | "
        + " | ".join(f"{rate} Hz ({budget * 1e3:.1f} ms)" for rate, budget, _ in stereo.frame_budget(0.0)) + " |",
        "|---|---|---|---:|---:|" + "---:|" * len(rates),
    ]
    for row in results.budgets:
        lines.append(f"| {row.scene} | {row.label} | {row.width}×{row.height} | {row.gpu_ms:.1f} | "
                     f"{row.sort_ms:.2f} | "
                     + " | ".join(budget_text(fraction) for _, _, fraction in stereo.frame_budget(row.gpu_ms / 1e3))
                     + " |")
    lines.append("")
    return "\n".join(lines)
