"""``raygs-viewer bench perf``: where a frame's time goes, stage by stage, and what the
savings are worth, measured side by side in one run.

Each case (generated gaussians, small or large on screen, or a real scene, at one
resolution) renders ``frames`` frames of a moving view: the camera alternates between
two views 0.1 degree apart, so that culling, the sort, the upload and the
preprocessing all run every frame, as they do while the user flies. The cull and the
sort are one :meth:`DepthSorter.sort`, split by its own clock (``SortResult.times``);
every GL stage is timed on the CPU with the GPU drained before and after it
(``ctx.finish``), and the preprocessing and draw also with GPU timer queries. The stages:

- cull: the cull of :meth:`DepthSorter.sort` (conservative: nothing whose support reaches
  the view is dropped) with the depth keys of what it keeps, its ``times["cull"]``;
- sort: the sort of those keys (uint16 keys, numpy's radix sort), its ``times["sort"]``;
- upload: the order into its storage buffer;
- preprocess: the compute pass writing every gaussian's per-view record;
- draw: the instanced quads into a float32 target.

In the same frames, interleaved so that drift affects all alike, each case also times
EWA splatting (GS) with its own order, the floor pass (the same quads with a constant
fragment), the general shader variant, and a float argsort of the same depths. The
ratios, each a ratio of medians over the frames:

- ``RayGS/GS``: preprocess + draw, RayGS over EWA splatting;
- ``RayGS/quads``: the draw over the floor pass's;
- ``specialised/general``: preprocess + draw, the specialised variant over the general one;
- ``radix/argsort``: the uint16 radix sort over a float32 argsort of the same depths;
- ``fragments-kept``: fragments that pass the p_min cut-off over those the quads
  rasterize (samples-passed queries; how tight the quads are);
- ``geometry/colour``: preprocess + draw with the depth and normal outputs blended beside
  colour (render/gl/geometry.py, its GPU work without the read-back) over colour alone;
- ``median/colour``: the same with the median depth too, which takes the fragment lists
  (count, fill and resolve passes; more parts where the fragments overflow the pool);
- ``depth-view/colour``: the window's depth view (the blended geometry, an automatic
  range's samples read back, the picture pass) over colour alone.

Each is printed per case as ``NAME@CASE VALUE`` and, as the median over the cases, as
``NAME VALUE``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TextIO

import numpy as np

from raygs_viewer.bench.common import (
    RunOptions,
    count_label,
    fmt_ms,
    fmt_ratio,
    gl_context,
    load_scenes,
    median,
    printer,
    report_head,
    write_plot,
    write_report,
)
from raygs_viewer.bench.plot import Panel, Point, ScatterRow, scatter_png
from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order, sort_request
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.keys import sort_back_to_front

STAGES = ("cull", "sort", "upload", "preprocess", "draw")
RATIOS = ("RayGS/GS", "RayGS/quads", "specialised/general", "radix/argsort", "fragments-kept", "geometry/colour",
          "median/colour", "depth-view/colour")
RATIO_TARGETS = {"RayGS/GS": "<= 1.10", "RayGS/quads": "<= 1.5"}

COUNTS = (10_000, 100_000, 1_000_000)
QUICK_COUNTS = (10_000, 100_000)
RESOLUTIONS = ((1280, 720), (1920, 1080))
QUICK_RESOLUTIONS = ((1280, 720),)
#: Footprint of a generated gaussian: its mean standard deviation in pixels at 720 rows
#: (its quad, at p_min 1/255 and opacity 0.6, is about 6.5 of them across).
SIZES = {"small": 1.0, "large": 4.0}
GENERATED_SH_DEGREE = 3  # as trained scenes have
DEFAULT_FRAMES = 10
QUICK_REAL_SCENES = ("ss-fruit_drops_minimal.ply",)
REAL_SCENES = ("ss-fruit_drops_minimal.ply", "donut-mip-fused.ply", "gs3d-pr477-lod3_tile_0.ply",
               "schwa-centered_lastchance.splat")
#: The two views of a case differ by this rotation about the camera's own y axis.
NUDGE_DEGREES = 0.1
GENERATED_DISTANCE = 3.0
GENERATED_FOV_Y = 60.0
DEFAULT_REPORT = "docs/performance-figures.md"
DEFAULT_PLOT = "docs/images/performance.png"
#: The window's depth view, automatic range (``depth-view/colour``).
DEPTH_VIEW = ChannelView("depth")


# --- cases ----------------------------------------------------------------------------------------

def generated_scene(count: int, size: str, seed: int = 0) -> Scene:
    """``count`` gaussians filling a cube of side 2 at the origin, every one in view of
    :func:`generated_camera`: random rotations, anisotropic scales around ``SIZES[size]``
    pixels (at 720 rows, seen from the cube's centre distance), opacities 0.2..1, SH
    degree 3 with small view-dependent terms."""
    if size not in SIZES:
        raise UserError(f"unknown footprint '{size}': use one of {', '.join(SIZES)}")
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-1.0, 1.0, (count, 3)).astype(np.float32)
    rotations = rng.normal(size=(count, 4)).astype(np.float32)
    rotations /= np.linalg.norm(rotations, axis=1, keepdims=True)
    focal = 360.0 / math.tan(math.radians(GENERATED_FOV_Y) / 2)  # at 720 rows
    sigma = SIZES[size] * GENERATED_DISTANCE / focal
    scales = (sigma * rng.uniform(0.5, 1.5, (count, 3))).astype(np.float32)
    opacities = rng.uniform(0.2, 1.0, count).astype(np.float32)
    sh = np.empty((count, sh_coefficient_count(GENERATED_SH_DEGREE), 3), np.float32)
    sh[:, 0] = rng.uniform(-1.5, 1.5, (count, 3))
    sh[:, 1:] = rng.normal(0.0, 0.1, (count, sh.shape[1] - 1, 3))
    return Scene(positions, rotations, scales, opacities, sh, GENERATED_SH_DEGREE, source=f"generated {size}")


def generated_camera(width: int, height: int) -> Camera:
    return look_at((0.0, 0.0, -GENERATED_DISTANCE), (0.0, 0.0, 0.0), width=width, height=height,
                   fov_y_degrees=GENERATED_FOV_Y)


def at_resolution(camera: Camera, width: int, height: int) -> Camera:
    """``camera``'s view at ``width`` x ``height``: its vertical field of view, square
    pixels, the principal point centred."""
    fy = camera.fy * height / camera.height
    return replace(camera, width=width, height=height, fx=fy, fy=fy, cx=width / 2, cy=height / 2)


def nudged(camera: Camera, degrees: float) -> Camera:
    """``camera`` turned about its own y axis (its centre stays)."""
    a = math.radians(degrees)
    turn = np.array([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0], [-math.sin(a), 0.0, math.cos(a)]])
    return replace(camera, R=turn @ camera.R, t=turn @ camera.t)


@dataclass(frozen=True)
class PerfCase:
    """One scene at one resolution. ``kind``: "small", "large" (generated) or "scene"."""

    name: str
    scene: Scene
    camera: Camera
    kind: str

    @property
    def label(self) -> str:
        """For ``NAME@LABEL VALUE`` lines: no spaces."""
        return f"{self.name.replace(' ', '-')}-{self.camera.width}x{self.camera.height}"


# --- measuring ------------------------------------------------------------------------------------

@dataclass
class CaseResult:
    name: str
    kind: str
    count: int
    width: int
    height: int
    visible: int = 0
    stages: dict[str, float] = field(default_factory=dict)      # ms, median over frames (CPU, GPU drained)
    gpu: dict[str, float] = field(default_factory=dict)         # ms, median timer-query time: preprocess, draw
    other: dict[str, float] = field(default_factory=dict)       # ms, medians: gs, quads, general, argsort
    ratios: dict[str, float] = field(default_factory=dict)
    frames: int = 0

    @property
    def frame_ms(self) -> float:
        """Every stage of a moving-view frame, one after the other."""
        return sum(self.stages[s] for s in STAGES)

    @property
    def label(self) -> str:
        return f"{self.name.replace(' ', '-')}-{self.width}x{self.height}"


class _Clock:
    """CPU time of a piece of GL work with the GPU drained on both sides, and (when
    asked) its GPU time from a timer query."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.timer = GpuTimer(ctx)

    def cpu(self, work) -> float:
        self.ctx.finish()
        start = time.perf_counter()
        work()
        self.ctx.finish()
        return (time.perf_counter() - start) * 1e3

    def both(self, work) -> tuple[float, float]:
        """(CPU ms, GPU ms) of ``work``, its GPU time measured inside the CPU span."""
        gpu: list[float] = []
        cpu = self.cpu(lambda: gpu.append(self.timer.time_ms(work)))
        return cpu, gpu[0]


def measure_case(ctx, case: PerfCase, frames: int, settings: RenderSettings = RenderSettings(),
                 renderer_type: type[GLRenderer] = GLRenderer) -> CaseResult:
    """Times ``frames`` moving-view frames of ``case`` (after one untimed warm-up frame
    that compiles every variant). ``renderer_type``: makes the specialised and the
    general renderer."""
    gs_settings = replace(settings, mode="gs")
    renderer = renderer_type(ctx, case.scene)
    general = None
    target = FloatTarget(ctx, case.camera.width, case.camera.height)
    clock = _Clock(ctx)
    samples = ctx.query(samples=True)
    views = (case.camera, nudged(case.camera, NUDGE_DEGREES))
    times: dict[str, list[float]] = {}
    result = CaseResult(case.name, case.kind, case.scene.count, case.camera.width, case.camera.height, frames=frames)

    def record(name: str, value: float) -> None:
        times.setdefault(name, []).append(value)

    def clear() -> None:
        target.use()
        target.fbo.clear(*settings.background, 0.0)

    sorter = DepthSorter(case.scene)
    try:
        general = renderer_type(ctx, case.scene, general=True)
        plan, gs_plan, general_plan = renderer.plan(settings), renderer.plan(gs_settings), general.plan(settings)
        blended_geometry, lists_geometry = renderer.plan(settings, "geometry"), renderer.plan(settings, "median")
        for frame in range(frames + 1):
            camera = views[frame % 2]
            timed = frame > 0
            # One sort, split by its own clock: "cull" is the cull with the depth keys of
            # what it keeps, "sort" the sort of those keys. The GPU is idle: the last
            # stage of the frame before drained it.
            sorted_ = sorter.sort(sort_request(camera, settings))
            cull, sort = 1e3 * sorted_.times["cull"], 1e3 * sorted_.times["sort"]
            order = sorted_.order
            visible = np.sort(order.indices)  # what the cull kept, in scene order: the radix/argsort input
            upload = clock.cpu(lambda: renderer.upload_order(order))
            preprocess, preprocess_gpu = clock.both(lambda: renderer.preprocess(camera, plan))
            clear()
            draw, draw_gpu = clock.both(lambda: renderer.draw(camera, plan, order))
            clear()
            quads = clock.cpu(lambda: renderer.draw(camera, plan, order, floor=True))
            channels = renderer.geometry.image(camera)
            geometry = clock.cpu(lambda: renderer.draw_planned(channels, camera, blended_geometry, order))
            with_median = clock.cpu(lambda: renderer.draw_planned(channels, camera, lists_geometry, order))
            depth_view = clock.cpu(lambda: renderer.render_into(target, camera, settings, order, view=DEPTH_VIEW))
            if frame == 0:  # fragments: counted once, untimed
                result.visible = order.count
                clear()
                with samples:
                    renderer.draw(camera, plan, order)
                kept = samples.samples
                clear()
                with samples:
                    renderer.draw(camera, plan, order, floor=True)
                rasterized = samples.samples
                result.ratios["fragments-kept"] = kept / rasterized if rasterized else math.nan
            gs_order = exact_order(sorter, camera, gs_settings)  # its own cull: EWA's footprint has no bounding sphere
            renderer.upload_order(gs_order)
            gs_pre = clock.cpu(lambda: renderer.preprocess(camera, gs_plan))
            clear()
            gs_draw = clock.cpu(lambda: renderer.draw(camera, gs_plan, gs_order))
            general.upload_order(order)
            general_pre = clock.cpu(lambda: general.preprocess(camera, general_plan))
            clear()
            general_draw = clock.cpu(lambda: general.draw(camera, general_plan, order))
            depth = case.scene.positions[visible] @ camera.R.astype(np.float32)[2] + np.float32(camera.t[2])
            radix = _cpu(lambda: sort_back_to_front(depth, "radix"))
            argsort = _cpu(lambda: sort_back_to_front(depth, "float"))
            if not timed:
                continue
            for name, value in (("cull", cull), ("sort", sort), ("upload", upload), ("preprocess", preprocess),
                                ("draw", draw), ("gpu preprocess", preprocess_gpu), ("gpu draw", draw_gpu),
                                ("quads", quads), ("gs", gs_pre + gs_draw), ("general", general_pre + general_draw),
                                ("raygs", preprocess + draw), ("radix", radix), ("argsort", argsort),
                                ("geometry", geometry), ("median", with_median), ("depth view", depth_view)):
                record(name, value)
    finally:
        sorter.close()
        renderer.release()
        if general is not None:
            general.release()
        target.release()

    result.stages = {s: median(times[s]) for s in STAGES}
    result.gpu = {"preprocess": median(times["gpu preprocess"]), "draw": median(times["gpu draw"])}
    result.other = {name: median(times[name])
                    for name in ("quads", "gs", "general", "raygs", "radix", "argsort", "geometry", "median",
                                 "depth view")}
    raygs = result.other["raygs"]
    result.ratios.update({
        "RayGS/GS": raygs / result.other["gs"],
        "RayGS/quads": result.stages["draw"] / result.other["quads"],
        "specialised/general": raygs / result.other["general"],
        "radix/argsort": result.other["radix"] / result.other["argsort"],
        "geometry/colour": result.other["geometry"] / raygs,
        "median/colour": result.other["median"] / raygs,
        "depth-view/colour": result.other["depth view"] / raygs,
    })
    return result


def _cpu(work) -> float:
    start = time.perf_counter()
    work()
    return (time.perf_counter() - start) * 1e3


# --- the run --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PerfOptions(RunOptions):
    counts: tuple[int, ...]
    sizes: tuple[str, ...]
    resolutions: tuple[tuple[int, int], ...]
    scenes: tuple[str, ...]
    frames: int
    command_line: str
    report: Path | None = None
    plot: Path | None = None
    overwrite: bool = False


@dataclass
class PerfResults:
    options: PerfOptions
    device: str
    cases: list[CaseResult]
    seconds: float

    def summary(self) -> dict[str, float]:
        """Each ratio's median over the cases."""
        return {name: median([c.ratios.get(name, math.nan) for c in self.cases]) for name in RATIOS}


def build_cases(options: PerfOptions):
    """Yields the cases one at a time (a 1M scene is made only when its turn comes)."""
    for count in options.counts:
        for size in options.sizes:
            scene = generated_scene(count, size)
            for width, height in options.resolutions:
                yield PerfCase(f"{count_label(count)} {size}", scene, generated_camera(width, height), size)
    for item in load_scenes(options.scenes):
        for width, height in options.resolutions:
            yield PerfCase(item.name, item.scene, at_resolution(item.camera, width, height), "scene")


def run_perf(options: PerfOptions, ctx=None, out: TextIO | None = None) -> PerfResults:
    """Runs every case; prints a line per case as it finishes and the ratio lines at the end."""
    say = printer(out)
    start = time.perf_counter()
    with gl_context(ctx, options.gl_backend) as ctx:
        device = context_description(ctx)
        say(f"device: {device}")
        cases = []
        for case in build_cases(options):
            result = measure_case(ctx, case, options.frames)
            cases.append(result)
            say(case_line(result))
    results = PerfResults(options, device, cases, time.perf_counter() - start)
    say()
    for line in ratio_lines(results):
        say(line)
    return results


def case_line(result: CaseResult) -> str:
    stages = ", ".join(f"{s} {fmt_ms(result.stages[s])}" for s in STAGES)
    return (f"{result.label}: {result.visible:,} of {result.count:,} visible; {stages}; frame "
            f"{fmt_ms(result.frame_ms)} ({1000 / result.frame_ms:.1f} fps)")


def ratio_lines(results: PerfResults) -> list[str]:
    """``NAME@CASE VALUE`` for every case, then ``NAME VALUE`` (the median over cases)."""
    lines = [f"{name}@{case.label} {fmt_ratio(case.ratios[name])}" for case in results.cases for name in RATIOS]
    lines += [f"{name} {fmt_ratio(value)}" for name, value in results.summary().items()]
    return lines


# --- report ---------------------------------------------------------------------------------------

def format_report(results: PerfResults) -> str:
    options = results.options
    lines = report_head("Performance figures (generated)",
                        f"Produced by `{options.command_line}` on {results.device}, in {results.seconds / 60:.1f} "
                        f"minutes. Every time is the median of {options.frames} moving-view frames; see "
                        f"`docs/performance.md` for what the stages and ratios mean.", options.notes)
    lines += ["## Stages (CPU ms with the GPU drained around each stage)", "",
              "| case | size | visible / N | cull | sort | upload | preprocess | draw | frame | fps | "
              "timer queries: preprocess, draw |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for c in results.cases:
        lines.append(f"| {c.name} | {c.width}×{c.height} | {c.visible:,} / {c.count:,} | "
                     + " | ".join(fmt_ms(c.stages[s]) for s in STAGES)
                     + f" | {fmt_ms(c.frame_ms)} | {1000 / c.frame_ms:.1f} | {fmt_ms(c.gpu['preprocess'])}, "
                       f"{fmt_ms(c.gpu['draw'])} |")
    lines += ["", "## Side by side (ms) and ratios", "",
              "| case | size | RayGS pre+draw | GS pre+draw | general pre+draw | floor draw | radix | argsort | "
              + " | ".join(RATIOS) + " |",
              "|---|---|" + "---:|" * (6 + len(RATIOS))]
    for c in results.cases:
        lines.append(f"| {c.name} | {c.width}×{c.height} | "
                     + " | ".join(fmt_ms(c.other[k]) for k in ("raygs", "gs", "general", "quads", "radix", "argsort"))
                     + " | " + " | ".join(fmt_ratio(c.ratios[name]) for name in RATIOS) + " |")
    lines += ["", "## Ratios: median over the cases", "", "| ratio | median | range | target |", "|---|---:|---|---|"]
    for name, value in results.summary().items():
        values = [c.ratios[name] for c in results.cases if math.isfinite(c.ratios[name])]
        spread = f"{min(values):.3f} – {max(values):.3f}" if values else "n/a"
        lines.append(f"| {name} | {fmt_ratio(value)} | {spread} | {RATIO_TARGETS.get(name, '')} |")
    lines += ["", "Machine-readable lines (as printed):", "", "```"] + ratio_lines(results)[-len(RATIOS):] + ["```", ""]
    return "\n".join(lines)


def draw_plot(results: PerfResults) -> bytes:
    """A PNG: frame time (every stage) against N for the generated cases, one panel per
    resolution, a colour and marker per footprint, RayGS filled and GS hollow."""
    sizes = [s for s in SIZES if any(c.kind == s for c in results.cases)]
    labels = {size: f"{size} ({SIZES[size]:g} px std. dev. at 720 rows)" for size in sizes}
    panels = []
    for width, height in results.options.resolutions:
        panel = Panel(f"{width} x {height}")
        for c in results.cases:
            if c.kind in SIZES and (c.width, c.height) == (width, height):
                panel.points.append(Point(c.count, c.frame_ms, labels[c.kind], "RayGS"))
                panel.points.append(Point(c.count, c.other["gs"] + c.stages["cull"] + c.stages["sort"]
                                          + c.stages["upload"], labels[c.kind], "GS (EWA)"))
        panels.append(panel)
    return scatter_png([ScatterRow(f"Frame time against N ({results.device.split(' (')[0]})", panels, "gaussians",
                                   "ms per frame (log)", list(labels.values()), ["RayGS", "GS (EWA)"], log_y=True)])


def write_outputs(results: PerfResults) -> list[Path]:
    """Writes the report and the plot that the options ask for; their paths."""
    options, written = results.options, []
    if options.report is not None:
        write_report(options.report, format_report(results), options.overwrite)
        written.append(options.report)
    if options.plot is not None:
        write_plot(options.plot, draw_plot(results), options.overwrite)
        written.append(options.plot)
    return written
