"""``raygs-viewer bench order``: what each order mode costs, how far it is from the order
of every ray, and how much it pops in motion (maths page, section 11; docs/ordering.md).

For every scene, from its training-like and very close views (bench/views.py), two
camera sweeps: a turn in place by TURN_DEGREES a frame and a flight forward by
FLY_FRACTION of the scene's radius a frame. For each order mode and each frame:

- the error image e_t = image - truth against that frame's per-ray truth, the GL
  path's exact per-pixel order (which the tests hold to the float64 reference; the
  run checks it once more on each start view and prints the PSNR);
- the PSNR of the mode over the sweep (from the mean squared error of all frames);
- popping: how much the error flickers between neighbouring frames, the 99th
  percentile over pixels of |e_t - e_{t-1}| (the largest over R, G, B), averaged over
  the frame pairs. A mode that is wrong the same way every frame does not pop;
  gaussians that swap places do.

At each start view it also times every mode (GPU timer queries, the median of
``repeat`` frames, modes interleaved) as a ratio to the depth order (today's RayGS),
and measures every mode against the ground truth that is both per-ray ordered and
integrated over each pixel (``reference.ground_truth(order="per-pixel")``), which is
how "the window K that comes within 1 dB of exact" is found.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field, replace
from typing import TextIO

import numpy as np

from raygs_viewer.bench import common
from raygs_viewer.bench.views import close_view, flown, training_view, turned
from raygs_viewer.camera.navigation import scene_bounds
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render import reference
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.results import RenderResult
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

#: The windows measured for the bounded per-pixel order.
WINDOWS = (1, 2, 4, 8, 16)
BASELINE = "depth"
EXACT = "per-pixel"
#: Every mode measured: name -> the settings' order fields.
MODES: dict[str, dict[str, object]] = {
    "depth": {"order": "depth"},
    "distance": {"order": "distance"},
    **{f"per-pixel K={k}": {"order": "per-pixel", "order_k": k} for k in WINDOWS},
    EXACT: {"order": "per-pixel", "order_k": 0},
}
SWEEPS = ("turn", "fly")
VIEWS = ("training", "close")
TURN_DEGREES = 0.5
FLY_FRACTION = 0.01
#: Within this many dB of the exact order's PSNR against the integrated truth.
WITHIN_DB = 1.0

DEFAULT_WIDTH, QUICK_WIDTH = 160, 96
DEFAULT_FRAMES, QUICK_FRAMES = 16, 8
DEFAULT_REPEAT, QUICK_REPEAT = 9, 5
DEFAULT_GT_SAMPLES, QUICK_GT_SAMPLES = 4, 2
DEFAULT_REPORT = "docs/ordering-figures.md"
#: Noted in the report when the GL renders on the CPU (llvmpipe): its times are no GPU's.
SOFTWARE_NOTE = ("This is a software OpenGL renderer (on the CPU): time ratios rank the modes on this machine; a "
                 "GPU's differ (atomics and the resolve pass cost differently there).")


@dataclass(frozen=True)
class OrderOptions(common.ReportedRunOptions):
    scenes: tuple[str, ...]
    width: int = DEFAULT_WIDTH
    frames: int = DEFAULT_FRAMES
    repeat: int = DEFAULT_REPEAT
    gt_samples: int = DEFAULT_GT_SAMPLES
    command_line: str = "raygs-viewer bench order"


@dataclass
class ModeRow:
    """One mode in one (scene, view): time, error against both truths, popping per sweep."""
    mode: str
    gpu_ms: float
    ratio: float
    psnr_integrated: float               # against the per-ray, pixel-integrated ground truth
    psnr: dict[str, float]               # sweep -> against each frame's per-ray truth
    popping: dict[str, float]            # sweep -> mean p99 |e_t - e_(t-1)|


@dataclass
class ViewResult(common.MeasuredView):
    exact_vs_reference_psnr: float       # the GL exact order against the float64 reference
    rows: dict[str, ModeRow]
    fragments_per_pixel: float = math.nan
    within_db: str | None = None         # the smallest window within WITHIN_DB of exact


@dataclass
class OrderResults:
    views: list[ViewResult]
    machine: str
    cpu_count: int
    options: OrderOptions
    date: str
    scenes: list[tuple[str, str]]
    seconds: float
    notes: list[str] = field(default_factory=list)


# --- sweeps and measures -----------------------------------------------------------------------

def sweep_cameras(start: Camera, sweep: str, frames: int, radius: float) -> list[Camera]:
    """``frames`` cameras from ``start``: "turn" rotates about the camera's own vertical
    axis by TURN_DEGREES a frame, its centre fixed; "fly" moves the centre forward along
    the optical axis by FLY_FRACTION * ``radius`` a frame."""
    if sweep == "turn":
        return [turned(start, TURN_DEGREES * frame) for frame in range(frames)]
    if sweep == "fly":
        return [flown(start, FLY_FRACTION * radius * frame) for frame in range(frames)]
    raise ValueError(f"unknown sweep {sweep!r}")


def popping(errors: list[np.ndarray]) -> float:
    """Mean over neighbouring frames of the 99th percentile over pixels of
    |e_t - e_(t-1)| (the largest channel), for (H, W, 3) error images e_t."""
    if len(errors) < 2:
        return math.nan
    flicker = [np.percentile(np.abs(b - a).max(axis=-1), 99) for a, b in zip(errors, errors[1:])]
    return float(np.mean(flicker))


def mode_settings(base: RenderSettings) -> dict[str, RenderSettings]:
    return {name: replace(base, **fields) for name, fields in MODES.items()}


class _Renders:
    """Renders every mode of one scene into one target, each with its exact order."""

    def __init__(self, ctx, renderer: GLRenderer, sorter: DepthSorter):
        self.ctx, self.renderer, self.sorter = ctx, renderer, sorter
        self.target: FloatTarget | None = None

    def image(self, camera: Camera, settings: RenderSettings) -> np.ndarray:
        return self.rendered(camera, settings)[0]

    def rendered(self, camera: Camera, settings: RenderSettings) -> tuple[np.ndarray, RenderResult]:
        """The image, and what the render did."""
        self._sized(camera)
        result = self.renderer.render_into(self.target, camera, settings, exact_order(self.sorter, camera, settings))
        return self.target.read().astype(np.float64), result

    def times(self, camera: Camera, modes: dict[str, RenderSettings], repeat: int) -> dict[str, list[float]]:
        """GPU ms per mode, ``repeat`` each, interleaved round-robin (one untimed first)."""
        self._sized(camera)
        timer = GpuTimer(self.ctx)
        orders = {name: exact_order(self.sorter, camera, s) for name, s in modes.items()}
        times: dict[str, list[float]] = {name: [] for name in modes}
        for run in range(repeat + 1):
            for name, s in modes.items():
                ms = timer.time_ms(lambda: self.renderer.render_into(self.target, camera, s, orders[name]))
                if run:
                    times[name].append(ms)
        return times

    def _sized(self, camera: Camera) -> None:
        if self.target is None or self.target.size != (camera.width, camera.height):
            if self.target is not None:
                self.target.release()
            self.target = FloatTarget(self.ctx, camera.width, camera.height)

    def close(self) -> None:
        if self.target is not None:
            self.target.release()


def measure_view(renders: _Renders, item: common.BenchScene, view: str, start: Camera,
                 options: OrderOptions) -> ViewResult:
    """Every mode of one start view: time, integrated error, and both sweeps."""
    modes = mode_settings(RenderSettings())
    _, radius = scene_bounds(item.scene.positions)
    exact, rendered = renders.rendered(start, modes[EXACT])
    stats = rendered.order_stats
    check = common.error_metrics(exact, reference.render_reference(item.scene, start, modes[EXACT]))["psnr"]
    truth = reference.ground_truth(item.scene, start, RenderSettings(), options.gt_samples, order="per-pixel")
    times = renders.times(start, modes, options.repeat)
    baseline_ms = common.median(times[BASELINE])
    rows = {name: ModeRow(name, common.median(times[name]), common.median(times[name]) / baseline_ms,
                          common.error_metrics(renders.image(start, s), truth)["psnr"], {}, {})
            for name, s in modes.items()}
    for sweep in SWEEPS:
        cameras = sweep_cameras(start, sweep, options.frames, radius)
        truths = [renders.image(camera, modes[EXACT]) for camera in cameras]
        for name, s in modes.items():
            errors = [renders.image(camera, s)[..., :3] - t[..., :3] for camera, t in zip(cameras, truths)]
            mse = float(np.mean([np.mean(e * e) for e in errors]))
            rows[name].psnr[sweep] = common.psnr(mse)
            rows[name].popping[sweep] = popping(errors)
    result = ViewResult(item.name, view, start.width, start.height, check, rows,
                        stats.mean_per_covered_pixel if stats is not None else math.nan)
    result.within_db = within_exact(rows)
    return result


def within_exact(rows: dict[str, ModeRow]) -> str | None:
    """The smallest window whose integrated PSNR is within WITHIN_DB of the exact order's."""
    goal = rows[EXACT].psnr_integrated - WITHIN_DB
    for k in WINDOWS:
        if rows[f"per-pixel K={k}"].psnr_integrated >= goal:
            return f"per-pixel K={k}"
    return None


def run_order(options: OrderOptions, ctx=None, out: TextIO | None = None) -> OrderResults:
    say = common.printer(out)
    scenes = common.load_scenes(options.scenes)
    views: list[ViewResult] = []
    started = time.perf_counter()
    with common.current_context(ctx, options.gl_backend) as (ctx, machine):
        say(f"bench order: {len(scenes)} scene(s) x {len(VIEWS)} views x {len(MODES)} modes, sweeps of "
            f"{options.frames} frames, {options.repeat} timed frames each, on {machine}")
        for item in scenes:
            say(f"[{item.name}] {item.description}")
            with common.scene_renderer(ctx, item.scene) as (renderer, sorter), \
                    contextlib.closing(_Renders(ctx, renderer, sorter)) as renders:
                training = training_view(item.camera, options.width)
                starts = {"training": training, "close": close_view(training, item.scene)}
                for view in VIEWS:
                    say(f"[{item.name} / {view}] {starts[view].width}x{starts[view].height} ...")
                    result = measure_view(renders, item, view, starts[view], options)
                    views.append(result)
                    for line in view_lines(result):
                        say(line)
    finished = common.finished_run_fields("order", started, machine=machine, notes=options.notes,
                                          software_note=SOFTWARE_NOTE, say=say)
    return OrderResults(views=views, options=options, scenes=[(s.name, s.description) for s in scenes], **finished)


# --- output ------------------------------------------------------------------------------------

def _db(value: float) -> str:
    if math.isnan(value):
        return "nan"
    return "inf" if math.isinf(value) else f"{value:.1f}"


def view_lines(result: ViewResult) -> list[str]:
    """Machine-readable lines ``KEY SCENE VIEW MODE VALUE`` (KEY: ratio, ms, psnr-gt,
    psnr-turn, psnr-fly, pop-turn, pop-fly) and the check of the truth."""
    lines = [f"check {result.scene} {result.view} gl-exact-vs-reference-psnr {_db(result.exact_vs_reference_psnr)}"]
    for row in result.rows.values():
        mode = row.mode.replace(" ", "").replace("=", "")
        lines += [f"ms {result.scene} {result.view} {mode} {row.gpu_ms:.3f}",
                  f"ratio {result.scene} {result.view} {mode} {row.ratio:.2f}",
                  f"psnr-gt {result.scene} {result.view} {mode} {_db(row.psnr_integrated)}"]
        lines += [f"psnr-{sweep} {result.scene} {result.view} {mode} {_db(row.psnr[sweep])}" for sweep in SWEEPS]
        lines += [f"pop-{sweep} {result.scene} {result.view} {mode} {row.popping[sweep]:.5f}" for sweep in SWEEPS]
    lines.append(f"within-1db {result.scene} {result.view} {(result.within_db or 'none').replace(' ', '')}")
    return lines


def format_report(results: OrderResults) -> str:
    options = results.options
    lines = [
        "# Order per ray: the figures",
        "",
        "Generated by `raygs-viewer bench order`; docs/ordering.md explains the method and reads them.",
        "",
        f"- Command: `{options.command_line}`",
        f"- Date: {results.date}, {results.seconds:.0f} s",
        f"- Machine: {results.machine}, {results.cpu_count} CPU cores",
        f"- Sweeps of {options.frames} frames: turn {TURN_DEGREES:g} deg a frame in place; fly forward "
        f"{FLY_FRACTION:g} of the scene's radius a frame. Settings: RayGS, p_min 1/255, black background.",
        f"- Ground truth (\"vs GT\"): `reference.ground_truth(order=\"per-pixel\")`, "
        f"{options.gt_samples}x{options.gt_samples} samples per pixel. Sweep PSNR and popping are against each "
        f"frame's exact per-pixel GL image.",
        "- Popping: mean over frame pairs of the 99th percentile over pixels of |e_t - e_(t-1)| (largest "
        "channel), e_t = image - truth of frame t.",
        "",
        "Scenes:",
        "",
    ]
    lines += [f"- **{name}**: {description}" for name, description in results.scenes]
    if results.notes:
        lines += ["", *[f"Note: {note}" for note in results.notes]]
    for view in results.views:
        lines += ["", f"## {view.scene}: {view.view} ({view.width}x{view.height})", "",
                  f"GL exact per-pixel against the float64 per-pixel reference: PSNR "
                  f"{_db(view.exact_vs_reference_psnr)} dB. Fragments per covered pixel: "
                  f"{view.fragments_per_pixel:.1f}. Smallest window within {WITHIN_DB:g} dB of exact (vs GT): "
                  f"{view.within_db or 'none'}.", "",
                  "| order | GPU ms | ratio to depth | PSNR vs GT | PSNR turn | PSNR fly | popping turn | popping fly |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for row in view.rows.values():
            lines.append(f"| {row.mode} | {row.gpu_ms:.2f} | {row.ratio:.2f} | {_db(row.psnr_integrated)} | "
                         f"{_db(row.psnr['turn'])} | {_db(row.psnr['fly'])} | {row.popping['turn']:.4f} | "
                         f"{row.popping['fly']:.4f} |")
    lines += ["", *summary_lines(results)]
    return "\n".join(lines) + "\n"


def summary_lines(results: OrderResults) -> list[str]:
    """Per mode, the mean over every (scene, view) of the ratio, PSNR and popping."""
    if not results.views:
        return []
    lines = ["## Mean over every scene and view", "",
             "| order | ratio to depth | PSNR vs GT | PSNR turn | PSNR fly | popping turn | popping fly |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    def mean(values):
        return float(np.mean([min(v, 100.0) for v in values]))  # an exact match counts as 100 dB

    for mode in MODES:
        rows = [view.rows[mode] for view in results.views]
        lines.append(f"| {mode} | {mean([r.ratio for r in rows]):.2f} | {mean([r.psnr_integrated for r in rows]):.1f} | "
                     f"{mean([r.psnr['turn'] for r in rows]):.1f} | {mean([r.psnr['fly'] for r in rows]):.1f} | "
                     f"{mean([r.popping['turn'] for r in rows]):.4f} | {mean([r.popping['fly'] for r in rows]):.4f} |")
    return lines
