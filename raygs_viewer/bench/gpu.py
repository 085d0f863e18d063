"""``raygs-viewer bench gpu``: what a frame costs where users run it, and what each fill
option saves, measured side by side in the same frames.

Cases: generated scenes shaped like a trained outdoor capture (an object and its
surroundings, log-normal sizes, SH degree 3; made in memory, never read from disk) of
1 M, 3 M and 6 M gaussians, and the shared real scenes; each seen at 1920 x 1080 and as
a Quest 3 class stereo pair (2064 x 2208 per eye, one sort from the eyes' midpoint, each
eye preprocessed and drawn, as the window's stereo preview draws them).

Each case runs ``frames`` frames of a moving view (two views 0.1 degree apart, so the
sort, the upload and the preprocessing run every frame). Per frame, in this order:

- the CPU cull and sort (``DepthSorter.sort``, its own clock);
- today's path (float32 blend, one instanced quad per splat, records at scene index):
  the preprocessing pass and the draw, each under a GPU timer query;
- the floor pass (the same quads, a constant fragment, never discarded) and EWA
  splatting (GS, with its own order), under timer queries;
- each option (:data:`OPTIONS`: a blend precision or a draw layout) as a whole
  preprocess + draw (+ the resolve a narrow blend needs) into a float32 image, and
  today's path the same way, one after the other, so drift affects all alike.

Fragments are counted once per case with samples-passed queries: *rasterized* (the
floor pass: every fragment the quads cover) and *kept* (the RayGS draw: those over the
p_min cut-off). The fill rate is rasterized fragments over the draw's GPU time.

The clock: timer queries on a GPU. On a software renderer (llvmpipe) the passes may run
after a query closes, so there every time is the CPU's with the GL drained around the
work (``ctx.finish``), and the report says so.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Callable, TextIO

import numpy as np

from raygs_viewer.bench import common
from raygs_viewer.bench.perf import NUDGE_DEGREES, at_resolution, nudged
from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.camera.stereo import DEFAULT_HEADSET, PRESETS, StereoRig, eye_cameras, frame_budget
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.plan import DEFAULT_DRAW_LAYOUT, DrawLayout
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.storage import place_runs
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order, sort_request
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import Order

COUNTS = (1_000_000, 3_000_000, 6_000_000)
QUICK_COUNTS = (30_000,)
REAL_SCENES = ("ss-fruit_drops_minimal.ply", "donut-mip-fused.ply", "gs3d-pr477-lod3_tile_0.ply",
               "metalsplatter-train3.ply", "schwa-centered_lastchance.splat")
QUICK_REAL_SCENES: tuple[str, ...] = ()
MONO = (1920, 1080)
QUICK_MONO = (320, 180)
#: The stereo pair's headset (camera/stereo.py), and --quick's eye: the same eye shrunk 8 times.
HEADSET = PRESETS[DEFAULT_HEADSET]
QUICK_EYE_SHRINK = 8
DEFAULT_FRAMES = 5
QUICK_FRAMES = 3
GENERATED_SH_DEGREE = 3
#: The outdoor scene's median standard deviation on its object, at 1M gaussians (units).
SIZE_AT_1M = 0.0027
#: The options measured against today's path: (name, settings changes, draw layout).
OPTIONS: tuple[tuple[str, dict, DrawLayout], ...] = (
    ("float16 blend", {"precision": "float16"}, DEFAULT_DRAW_LAYOUT),
    ("8-bit blend", {"precision": "8bit"}, DEFAULT_DRAW_LAYOUT),
    ("indexed draw", {}, DrawLayout("indexed")),
    ("6-vertex draw", {}, DrawLayout("triangles")),
    ("draw-order records", {}, DrawLayout("instanced", "draw")),
    ("indexed, draw-order records", {}, DrawLayout("indexed", "draw")),
    ("float16, indexed, draw-order records", {"precision": "float16"}, DrawLayout("indexed", "draw")),
)
TODAY = "today"


# --- cases ----------------------------------------------------------------------------------------

def outdoor_scene(count: int, seed: int = 0) -> Scene:
    """``count`` gaussians shaped like a trained outdoor capture: 55 % an object (a ball
    of radius 1 at the origin), 45 % its surroundings (a shell 3 to 12 units out, thinning
    with distance); sizes log-normal around :data:`SIZE_AT_1M` units on the object at 1M
    gaussians (as 1/sqrt of the count), growing with distance outside it, anisotropic; opacities bimodal (a third faint, the rest mostly
    opaque, as training leaves them); SH degree 3 with small view-dependent terms."""
    rng = np.random.default_rng(seed)
    inner = int(round(0.55 * count))
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radius = np.empty(count)
    radius[:inner] = rng.uniform(0.0, 1.0, inner) ** (1.0 / 3.0)
    radius[inner:] = 3.0 + 9.0 * rng.uniform(0.0, 1.0, count - inner) ** 2
    positions = (directions * radius[:, None]).astype(np.float32)
    # Trained scenes tile their surfaces: more gaussians, smaller ones. At 1M, about 150
    # fragments a visible gaussian at 1920 x 1080, some 10^8 a frame at every size.
    size = SIZE_AT_1M * math.sqrt(1e6 / max(count, 1)) * np.maximum(radius, 1.0) ** 1.2
    scales = (size[:, None] * np.exp(rng.normal(0.0, 0.6, (count, 3)))).astype(np.float32)
    rotations = rng.normal(size=(count, 4)).astype(np.float32)
    rotations /= np.linalg.norm(rotations, axis=1, keepdims=True)
    faint = rng.uniform(0.0, 1.0, count) < 1.0 / 3.0
    opacities = np.where(faint, rng.uniform(0.01, 0.2, count), rng.beta(5.0, 1.2, count)).astype(np.float32)
    sh = np.empty((count, sh_coefficient_count(GENERATED_SH_DEGREE), 3), np.float32)
    sh[:, 0] = rng.uniform(-1.5, 1.5, (count, 3))
    sh[:, 1:] = rng.normal(0.0, 0.05, (count, sh.shape[1] - 1, 3))
    return Scene(positions, rotations, scales, opacities, sh, GENERATED_SH_DEGREE,
                 source=f"generated outdoor, {common.count_label(count)}")


def outdoor_camera(width: int, height: int) -> Camera:
    """2.5 units from the object's centre, looking at it: the object fills the middle of
    the view, its surroundings the rest, and a part of them is behind the camera."""
    return look_at((0.0, -0.4, -2.5), (0.0, 0.0, 0.0), width=width, height=height, fov_y_degrees=60.0)


@dataclass(frozen=True)
class GpuCase:
    """One scene in one view: ``eyes`` the cameras drawn (one, or the stereo pair's two
    around ``camera``, their midpoint); ``view`` "mono" or "stereo"."""

    name: str
    scene: Scene
    camera: Camera
    view: str
    rig: StereoRig | None = None

    def eyes(self, camera: Camera) -> tuple[Camera, ...]:
        return (camera,) if self.rig is None else eye_cameras(camera, self.rig)

    @property
    def size(self) -> str:
        eye = self.camera
        return f"{eye.width}×{eye.height}" + (" ×2" if self.rig is not None else "")

    @property
    def label(self) -> str:
        return f"{self.name.replace(' ', '-')}-{self.view}"


# --- measuring ------------------------------------------------------------------------------------

@dataclass
class GpuResult:
    name: str
    view: str
    size: str
    count: int
    visible: int = 0
    sort_ms: float = math.nan             # CPU cull + sort, median
    places_ms: float = math.nan           # CPU: grouping the order's places for records in draw order, median
    preprocess_ms: float = math.nan       # today's path, every eye, median
    draw_ms: float = math.nan
    floor_ms: float = math.nan            # the floor pass's draw
    gs_ms: float = math.nan               # EWA splatting, preprocess + draw
    rasterized: int = 0                   # fragments, every eye
    kept: int = 0
    frame_ms: dict[str, float] = field(default_factory=dict)  # today's and each option's whole frame, median
    #: Each option's image against today's (the first eye of the first frame): the
    #: largest difference over RGBA, and the PSNR of RGB (inf: identical to the bit).
    max_error: dict[str, float] = field(default_factory=dict)
    psnr: dict[str, float] = field(default_factory=dict)

    @property
    def raygs_ms(self) -> float:
        return self.preprocess_ms + self.draw_ms

    @property
    def fill_rate(self) -> float:
        """Rasterized fragments per second of the draw."""
        return self.rasterized / (self.draw_ms * 1e-3) if self.draw_ms > 0 else math.nan

    def ratio(self, option: str) -> float:
        """An option's whole frame over today's, measured in the same frames."""
        return self.frame_ms.get(option, math.nan) / self.frame_ms[TODAY]

    @property
    def label(self) -> str:
        return f"{self.name.replace(' ', '-')}-{self.view}"


class _Clock:
    """Times a piece of GL work: its GPU time (a timer query), or with ``drained`` the
    CPU's with the GL finished on both sides (a software renderer)."""

    def __init__(self, ctx, drained: bool):
        self.ctx = ctx
        self.drained = drained
        self.timer = GpuTimer(ctx)

    def ms(self, work: Callable[[], object]) -> float:
        if not self.drained:
            return self.timer.time_ms(work)
        self.ctx.finish()
        start = time.perf_counter()
        work()
        self.ctx.finish()
        return (time.perf_counter() - start) * 1e3


def measure_case(ctx, case: GpuCase, frames: int, drained: bool, options=OPTIONS) -> GpuResult:
    """Times ``frames`` moving-view frames of ``case`` after one untimed warm-up frame
    (which compiles every variant); see the module docstring for what and in what order."""
    settings = RenderSettings()
    gs_settings = replace(settings, mode="gs")
    clock = _Clock(ctx, drained)
    samples = ctx.query(samples=True)
    eye = case.camera
    targets = FloatTarget(ctx, eye.width, eye.height)
    views = (case.camera, nudged(case.camera, NUDGE_DEGREES))
    result = GpuResult(case.name, case.view, case.size, case.scene.count)
    times: dict[str, list[float]] = {}
    renderer = GLRenderer(ctx, case.scene)
    sorter = DepthSorter(case.scene)

    def record(name: str, value: float) -> None:
        times.setdefault(name, []).append(value)

    def clear() -> None:
        targets.use()
        targets.fbo.clear(0.0, 0.0, 0.0, 0.0)

    def whole(camera: Camera, order: Order, eye_settings: RenderSettings, layout: DrawLayout) -> float:
        """Every eye's preprocess + draw (+ resolve) into a float32 image, as a render does."""
        plan = renderer.plan(eye_settings, draw_layout=layout)
        total = 0.0
        for eye_camera in case.eyes(camera):
            renderer.forget_records()
            total += clock.ms(lambda: renderer.draw_planned(targets, eye_camera, plan, order,
                                                            color_origin=camera.center))
        return total

    def image(camera: Camera, order: Order, eye_settings: RenderSettings, layout: DrawLayout) -> np.ndarray:
        """The first eye's image, clipped to 0..1 as it is shown and saved."""
        renderer.draw_planned(targets, case.eyes(camera)[0], renderer.plan(eye_settings, draw_layout=layout), order,
                              color_origin=camera.center)
        return np.clip(targets.read(), 0.0, 1.0)

    try:
        for frame in range(frames + 1):
            camera = views[frame % 2]
            eyes = case.eyes(camera)
            request = sort_request(camera, settings, cull_cameras=eyes if case.rig is not None else None)
            sorted_ = sorter.sort(request)
            order = sorted_.order
            plan = renderer.plan(settings)  # today's layout, the renderer's own
            started = time.perf_counter()
            place_runs(order.indices, plan.layout)  # what records in draw order add on the CPU, per order
            places = (time.perf_counter() - started) * 1e3
            preprocess = draw = floor = 0.0
            for eye_camera in eyes:
                renderer.forget_records()
                renderer.upload_order(order)
                preprocess += clock.ms(lambda: renderer.preprocess(eye_camera, plan, order,
                                                                   color_origin=camera.center))
                clear()
                draw += clock.ms(lambda: renderer.draw(eye_camera, plan, order))
                clear()
                floor += clock.ms(lambda: renderer.draw(eye_camera, plan, order, floor=True))
                if frame == 0:  # fragments: counted once, untimed
                    clear()
                    with samples:
                        renderer.draw(eye_camera, plan, order)
                    result.kept += samples.samples
                    clear()
                    with samples:
                        renderer.draw(eye_camera, plan, order, floor=True)
                    result.rasterized += samples.samples
            gs_order = exact_order(sorter, camera, gs_settings,
                                   cull_cameras=eyes if case.rig is not None else None)
            gs_plan = renderer.plan(gs_settings)
            gs = 0.0
            for eye_camera in eyes:
                renderer.forget_records()
                renderer.upload_order(gs_order)
                gs += clock.ms(lambda: renderer.preprocess(eye_camera, gs_plan, gs_order, color_origin=camera.center))
                clear()
                gs += clock.ms(lambda: renderer.draw(eye_camera, gs_plan, gs_order))
            frame_times = {TODAY: whole(camera, order, settings, DEFAULT_DRAW_LAYOUT)}
            for name, changes, layout in options:
                frame_times[name] = whole(camera, order, replace(settings, **changes), layout)
            if frame == 0:  # untimed: what each option draws, against today's image
                result.visible = order.count
                today = image(camera, order, settings, DEFAULT_DRAW_LAYOUT)
                for name, changes, layout in options:
                    error = np.abs(image(camera, order, replace(settings, **changes), layout) - today)
                    result.max_error[name] = float(error.max())
                    result.psnr[name] = common.psnr(float(np.mean(np.square(error[..., :3], dtype=np.float64))))
                continue
            for name, value in (("sort", 1e3 * (sorted_.times["cull"] + sorted_.times["sort"])), ("places", places),
                                ("preprocess", preprocess), ("draw", draw), ("floor", floor), ("gs", gs),
                                *((f"frame {k}", v) for k, v in frame_times.items())):
                record(name, value)
    finally:
        sorter.close()
        renderer.release()
        targets.release()
    result.sort_ms, result.places_ms = common.median(times["sort"]), common.median(times["places"])
    result.preprocess_ms, result.draw_ms = common.median(times["preprocess"]), common.median(times["draw"])
    result.floor_ms, result.gs_ms = common.median(times["floor"]), common.median(times["gs"])
    result.frame_ms = {k.removeprefix("frame "): common.median(v) for k, v in times.items() if k.startswith("frame ")}
    return result


# --- the run --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class GpuOptions(common.ReportedRunOptions):
    counts: tuple[int, ...]
    scenes: tuple[str, ...]
    mono: tuple[int, int]
    eye_shrink: int
    frames: int
    command_line: str


@dataclass
class GpuResults:
    options: GpuOptions
    device: str
    drained: bool
    results: list[GpuResult]
    seconds: float
    notes: list[str]


def build_cases(options: GpuOptions):
    """Yields the cases one scene at a time (a 6M scene is made only when its turn comes)."""
    headset = HEADSET
    eye_size = (headset.width // options.eye_shrink, headset.height // options.eye_shrink)
    for count in options.counts:
        scene = outdoor_scene(count)
        pose = outdoor_camera(*options.mono)
        name = f"outdoor {common.count_label(count)}"
        yield GpuCase(name, scene, pose, "mono")
        yield GpuCase(name, scene, _eye_camera(pose, eye_size), "stereo", StereoRig())
    for item in common.load_scenes(options.scenes):
        yield GpuCase(item.name, item.scene, at_resolution(item.camera, *options.mono), "mono")
        yield GpuCase(item.name, item.scene, _eye_camera(item.camera, eye_size), "stereo", StereoRig())


def _eye_camera(pose: Camera, size: tuple[int, int]) -> Camera:
    """The headset's per-eye camera (its field of view) at ``size``, with ``pose``."""
    eye = HEADSET.camera(pose)
    scale_x, scale_y = size[0] / eye.width, size[1] / eye.height
    return replace(eye, width=size[0], height=size[1], fx=eye.fx * scale_x, fy=eye.fy * scale_y,
                   cx=size[0] / 2, cy=size[1] / 2)


def run_gpu(options: GpuOptions, ctx=None, out: TextIO | None = None) -> GpuResults:
    """Runs every case; prints a line per case as it finishes."""
    say = common.printer(out)
    started = time.perf_counter()
    with common.gl_context(ctx, options.gl_backend) as ctx:
        device = context_description(ctx)
        drained = common.software_renderer(device)
        say(f"device: {device}")
        say(f"clock: {'CPU, GL drained (a software renderer)' if drained else 'GPU timer queries'}")
        results = []
        for case in build_cases(options):
            result = measure_case(ctx, case, options.frames, drained)
            results.append(result)
            say(case_line(result))
    seconds, notes = common.run_end(
        "gpu", started, machine=device, notes=options.notes, say=say,
        software_note="a software renderer: its times say how the options compare on a CPU, not on a GPU")
    return GpuResults(options, device, drained, results, seconds, notes)


def case_line(r: GpuResult) -> str:
    options = ", ".join(f"{name} {common.fmt_ratio(r.ratio(name))}" for name, _, _ in OPTIONS)
    return (f"{r.label} {r.size}: {r.visible:,} of {r.count:,} visible; cull+sort {common.fmt_ms(r.sort_ms)}; "
            f"preprocess {common.fmt_ms(r.preprocess_ms)}, draw {common.fmt_ms(r.draw_ms)}; "
            f"{r.rasterized / 1e6:.2f} M fragments rasterized, {r.kept / 1e6:.2f} M kept; {_rate(r.fill_rate)} "
            f"fragments/s; against today: {options}")


def ratio_lines(results: GpuResults) -> list[str]:
    """``NAME@CASE VALUE`` for every option and case, then ``NAME VALUE``, the median over
    the cases; and each case's fill rate."""
    lines = []
    for r in results.results:
        lines.append(f"fragments-per-second@{r.label} {r.fill_rate:.4g}")
        lines += [f"{name}@{r.label} {common.fmt_ratio(r.ratio(name))}" for name, _, _ in OPTIONS]
        lines += [f"max-difference {name}@{r.label} {r.max_error.get(name, math.nan):.3g}" for name, _, _ in OPTIONS]
    lines += [f"{name} {common.fmt_ratio(common.median([r.ratio(name) for r in results.results]))}"
              for name, _, _ in OPTIONS]
    return lines


def _difference(result: GpuResult, name: str) -> str:
    if name not in result.max_error:
        return "n/a"
    if result.max_error[name] == 0:
        return "identical"
    return f"{result.psnr[name]:.1f} dB, {result.max_error[name]:.2g}"


def _rate(value: float) -> str:
    return f"{value / 1e9:.3g} G" if math.isfinite(value) else "n/a"


# --- report ---------------------------------------------------------------------------------------

def _todays_path_row(r: GpuResult) -> str:
    return (f"| {r.name} | {r.view} {r.size} | {r.visible:,} / {r.count:,} | {common.fmt_ms(r.sort_ms)} | "
            f"{common.fmt_ms(r.preprocess_ms)} | {common.fmt_ms(r.draw_ms)} | {r.rasterized / 1e6:.1f} M | "
            f"{r.kept / 1e6:.1f} M | {_rate(r.fill_rate)} | {common.fmt_ratio(r.raygs_ms / r.gs_ms)} | "
            f"{common.fmt_ratio(r.draw_ms / r.floor_ms)} |")


def format_report(results: GpuResults) -> str:
    options = results.options
    clock = ("CPU time with the GL drained around each piece of work (a software renderer runs passes after a "
             "timer query closes)" if results.drained else "GPU timer queries")
    lines = common.report_head(
        "GPU frame figures (generated)",
        f"Produced by `{options.command_line}` on {results.device}, in {results.seconds / 60:.1f} minutes. "
        f"Clock: {clock}. Every time is the median of {options.frames} moving-view frames; a stereo row is "
        f"both eyes. See `docs/performance.md`, \"On a GPU\", for what the columns mean.", results.notes)
    lines += ["## Today's path (float32 blend, instanced quads, records at scene index)", "",
              "| case | view | visible / N | CPU cull+sort | preprocess | draw | fragments rasterized | kept | "
              "fragments/s | RayGS/GS | draw/floor |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    lines += [_todays_path_row(r) for r in results.results]
    names = [name for name, _, _ in OPTIONS]
    lines += ["", "## Each option against today's path (whole frame, same frames; below 1 is faster)", "",
              "The last column is CPU time the GPU clock does not see: grouping a new order's places by "
              "scene chunk and splat block, which records in draw order need where the scene or the order "
              "spans more than one (`storage.place_runs`; none where one chunk holds the scene).", "",
              "| case | view | today | " + " | ".join(names) + " | CPU grouping |",
              "|---|---|---:|" + "---:|" * (len(names) + 1)]
    for r in results.results:
        lines.append(f"| {r.name} | {r.view} | {common.fmt_ms(r.frame_ms[TODAY])} | "
                     + " | ".join(common.fmt_ratio(r.ratio(name)) for name in names)
                     + f" | {common.fmt_ms(r.places_ms)} |")
    lines.append("| **median** | | | "
                 + " | ".join(common.fmt_ratio(common.median([r.ratio(n) for r in results.results])) for n in names)
                 + " | |")
    lines += ["", "## What each option draws, against today's image (first eye, shown 0..1)", "",
              "PSNR of RGB and the largest difference over RGBA; *identical* where every value is today's to "
              "the bit.", "", "| case | view | " + " | ".join(names) + " |", "|---|---|" + "---:|" * len(names)]
    for r in results.results:
        lines.append(f"| {r.name} | {r.view} | " + " | ".join(_difference(r, n) for n in names) + " |")
    lines += ["", f"## VR budget ({HEADSET.label}, both eyes' preprocess + draw, and the CPU sort beside it)", "",
              "| case | eyes | GPU, today | best option | its GPU time | " + " | ".join(
                  f"{rate} Hz" for rate, _, _ in frame_budget(0.0)) + " | CPU cull+sort |",
              "|---|---|---:|---|---:|" + "---:|" * len(frame_budget(0.0)) + "---:|"]
    for r in results.results:
        if r.view != "stereo":
            continue
        best = min(names, key=lambda n: r.frame_ms.get(n, math.inf))
        best_ms = r.frame_ms[TODAY] * r.ratio(best)
        today_ms = r.raygs_ms
        budget = " | ".join(f"{fraction:.2f}× ({common.fmt_ms(seconds * 1e3)})"
                            for _, seconds, fraction in frame_budget(today_ms * 1e-3))
        lines.append(f"| {r.name} | {r.size} | {common.fmt_ms(today_ms)} | {best} | {common.fmt_ms(best_ms)} | "
                     f"{budget} | {common.fmt_ms(r.sort_ms)} |")
    lines += ["", "Budget cells: today's GPU time as a fraction of the refresh's frame time (its frame time).", "",
              "Machine-readable lines (as printed):", "", "```"] + ratio_lines(results) + ["```", ""]
    return "\n".join(lines)
