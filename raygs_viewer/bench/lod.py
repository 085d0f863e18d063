"""``raygs-viewer bench lod``: what the view-dependent level of detail of a streamed SOG
costs and saves, against drawing its finest level (docs/lod.md).

Each streamed scene (``lod-meta.json``) is read as the viewer reads it (every level the
GPU holds, ``render.gl.memory.scene_fits``). Three views, all at the same resolution:

- ``framing``: a camera framing the levels' gaussians (``frame_points``, without the
  environment, which surrounds the scene from afar), at the benchmark width;
- ``closer``: that camera moved forward along its axis to CLOSER_FACTOR of its distance
  from the scene's centre (``views.far_view`` with a factor below 1);
- ``farther``: moved back to FARTHER_FACTOR of that distance.

In each view, the cases side by side: the finest level read, everywhere (the
reference: ``lod_choice.choose(..., level=finest)``), then the view-dependent choice
(``choose(..., budget=B)``) at budgets B of 100 %, 50 %, 25 % and 10 % of the finest
level's gaussians plus the environment's. For each case:

- ``chosen``: the gaussians of the choice (the rows the sort culls and sorts),
  ``counted``: those the budget counts (the environment and the leaves in view),
  ``drawn``: those the cull keeps (the order's length), and the leaves at each level;
- CPU times (medians over ``repeat`` frames): the choice, and the cull+sort restricted
  to it (``DepthSorter.sort`` of a ``SortRequest`` whose ``levels`` are the choice);
- the time of preprocess+draw (with the order's upload): the GPU timer's
  (``render.gl.timing.GpuTimer``) and the CPU's with the GPU drained on both sides (on
  a software rasterizer the timer may read only part of the work; the drained time is
  what it costs there);
- the ratios of those to the finest level's, medians taken in the same frames;
- the error of its image against the finest level's at the same camera: PSNR and the
  largest absolute difference over RGB.

The timed frames interleave the cases and alternate between the view and the view
turned by NUDGE_DEGREES, so that no render of a case repeats the one before it (every
pass runs, as while the user flies) and the machine's drift hits all cases alike.
Speed is measured and printed, never asserted.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, TextIO

import numpy as np

from raygs_viewer.bench import common
from raygs_viewer.bench.views import far_view, scene_centre, turned, with_width
from raygs_viewer.camera.pinhole import Camera, frame_points
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.memory import scene_fits
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.lod_file import LodScene, load_lod, lod_index_file, merged_spans
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import LodChoice, automatic_distance, choose, screen_radius
from raygs_viewer.sort.request import Order

#: The budgets measured, as fractions of the finest level's gaussians (the environment's added).
FRACTIONS = (1.0, 0.5, 0.25, 0.1)
FINEST = "finest"
VIEWS = ("framing", "closer", "farther")
#: The closer and farther views: this factor times the framing camera's distance from the
#: scene's centre (moved along its optical axis).
CLOSER_FACTOR, FARTHER_FACTOR = 0.5, 2.0
#: The second camera of the timed frames: the view turned this much about its vertical axis.
NUDGE_DEGREES = 0.1

DEFAULT_WIDTH, QUICK_WIDTH = 480, 320
DEFAULT_REPEAT, QUICK_REPEAT = 7, 5


def case_name(fraction: float | None) -> str:
    """"finest", or a budget's "100%", "50%", "25%", "10%" (one word: the machine lines')."""
    return FINEST if fraction is None else f"{fraction * 100:g}%"


CASES = (FINEST, *(case_name(f) for f in FRACTIONS))


@dataclass(frozen=True)
class LodOptions(common.ReportedRunOptions):
    scenes: tuple[str, ...]      # lod-meta.json files, or folders holding one
    width: int = DEFAULT_WIDTH
    repeat: int = DEFAULT_REPEAT
    distance: float | None = None  # the first level distance (None: automatic)
    command_line: str = "raygs-viewer bench lod"


@dataclass
class CaseRow:
    """One case of one view (see the module docstring); times in ms."""

    case: str
    budget: int | None           # gaussians (None: the finest level, no budget)
    chosen: int
    counted: int
    drawn: int
    per_level: tuple[int, ...]   # leaves drawing each level
    over_budget: bool
    choice_ms: float
    sort_ms: float
    gpu_ms: float
    gl_ms: float
    psnr: float
    max_abs: float
    ratios: dict[str, float] = field(default_factory=dict)   # drawn, sort, gpu, gl: against the finest


@dataclass
class ViewResult(common.MeasuredView):
    rows: list[CaseRow]

    def row(self, case: str) -> CaseRow:
        return next(row for row in self.rows if row.case == case)


@dataclass
class SceneInfo:
    """What was read of a streamed scene."""

    name: str
    path: str
    levels: int
    leaves: int
    counts: tuple[int, ...]      # gaussians of each level read (0: not read)
    environment: int
    finest: int                  # the finest level read: the reference
    distance: float              # the first level distance used
    automatic: bool              # ... the automatic one
    unread: str


@dataclass
class LodResults:
    options: LodOptions
    machine: str
    date: str
    scenes: list[SceneInfo]
    views: list[ViewResult]
    seconds: float = math.nan
    notes: list[str] = field(default_factory=list)


# --- scenes and views ----------------------------------------------------------------------------

def check_scenes(specs: tuple[str, ...]) -> list[str]:
    """The lod-meta.json of each of ``specs`` (a file or a folder holding one), all
    checked before any is read; UserError naming the first that is not a streamed SOG."""
    found = []
    for spec in specs:
        if not os.path.exists(spec):
            raise UserError(f"{spec}: no such file")
        index = lod_index_file(spec)
        if index is None:
            raise UserError(f"{spec}: not a streamed SOG (bench lod takes lod-meta.json files, or folders "
                            f"holding one)")
        found.append(index)
    return found


def scene_names(paths: list[str]) -> list[str]:
    """Each scene named after the folder of its lod-meta.json (its file's stem when that
    is not lod-meta), made unique with -2, -3, ..."""
    names, taken = [], set()
    for path in paths:
        p = Path(path).resolve()
        base = p.parent.name if p.stem == "lod-meta" else p.stem
        name, n = base or "scene", 2
        while name in taken:
            name, n = f"{base}-{n}", n + 1
        taken.add(name)
        names.append(name)
    return names


def level_positions(lod: LodScene) -> np.ndarray:
    """The positions of every level read, without the environment."""
    start, count = lod.environment
    positions = lod.scene.positions
    return np.concatenate([positions[:start], positions[start + count:]])


def finest_centre(lod: LodScene, finest: int) -> np.ndarray:
    """The median centre of the finest level's gaussians (the environment left out)."""
    rows = lod.rows[:, finest]
    return scene_centre(lod.subset(merged_spans(np.stack([rows[:, 0], rows[:, 0] + rows[:, 1]], axis=1))))


def view_cameras(lod: LodScene, width: int) -> dict[str, Camera]:
    """The three views (module docstring), ``width`` pixels across, 4:3."""
    framing = with_width(frame_points(level_positions(lod)), width)
    centre = finest_centre(lod, lod.finest_loaded)
    return {"framing": framing,
            "closer": far_view(framing, centre, CLOSER_FACTOR, 1),
            "farther": far_view(framing, centre, FARTHER_FACTOR, 1)}


def budgets(lod: LodScene, finest: int) -> dict[str, int]:
    """{case: budget} of each fraction: of the finest level's gaussians read, plus the
    environment's (at least 1)."""
    count = int(lod.rows[:, finest, 1].sum())
    return {case_name(f): max(1, round(f * count) + lod.environment[1]) for f in FRACTIONS}


def counted(lod: LodScene, choice: LodChoice, camera: Camera) -> int:
    """What the budget counts of ``choice``: the environment and the leaves in view."""
    in_view, _ = screen_radius(lod.index.bounds, camera)
    leaves = np.flatnonzero(in_view & (choice.levels >= 0))
    return lod.environment[1] + int(lod.rows[leaves, choice.levels[leaves], 1].sum())


# --- measuring -----------------------------------------------------------------------------------

def _cpu_ms(work: Callable[[], object]) -> tuple[float, object]:
    start = time.perf_counter()
    value = work()
    return (time.perf_counter() - start) * 1e3, value


class _Case:
    """One case's choice for a camera, its timings and image."""

    def __init__(self, name: str, finest: int, budget: int | None, distance: float | None):
        self.name, self.finest, self.budget, self.distance = name, finest, budget, distance
        self.times: dict[str, list[float]] = {"choice": [], "sort": [], "gpu": [], "gl": []}

    def choose(self, lod: LodScene, camera: Camera) -> LodChoice:
        if self.budget is None:
            return choose(lod, camera, level=self.finest, distance=self.distance)
        return choose(lod, camera, budget=self.budget, distance=self.distance)


class _Runner:
    """The renderer and the sorter of one scene, its target and clocks."""

    def __init__(self, ctx, lod: LodScene, settings: RenderSettings):
        self.ctx, self.lod, self.settings = ctx, lod, settings
        self.renderer = GLRenderer(ctx, lod.scene)
        self.sorter = DepthSorter(lod.scene)
        self.timer = GpuTimer(ctx)
        self.target: FloatTarget | None = None

    def order(self, camera: Camera, choice: LodChoice) -> Order:
        """The order of ``choice``'s rows (the choice made already: the sort only culls and sorts)."""
        return exact_order(self.sorter, camera, self.settings, levels=choice)

    def _sized(self, camera: Camera) -> FloatTarget:
        if self.target is None or self.target.size != (camera.width, camera.height):
            if self.target is not None:
                self.target.release()
            self.target = FloatTarget(self.ctx, camera.width, camera.height)
        return self.target

    def frame(self, case: _Case, camera: Camera, record: bool) -> None:
        """One timed frame of ``case``: choice, cull+sort, then preprocess+draw into the
        cleared target, under the GPU timer and the drained CPU clock."""
        choice_ms, choice = _cpu_ms(lambda: case.choose(self.lod, camera))
        sort_ms, order = _cpu_ms(lambda: self.order(camera, choice))
        target = self._sized(camera)
        settings = self.settings
        plan = self.renderer.plan(settings)

        def work() -> None:
            self.renderer.preprocess(camera, plan, order)
            target.use()
            target.fbo.clear(*settings.background, 0.0)
            self.renderer.draw(camera, plan, order)

        gpu: list[float] = []
        self.ctx.finish()
        start = time.perf_counter()
        gpu.append(self.timer.time_ms(work))
        self.ctx.finish()
        gl_ms = (time.perf_counter() - start) * 1e3
        if record:
            for key, value in (("choice", choice_ms), ("sort", sort_ms), ("gpu", gpu[0]), ("gl", gl_ms)):
                case.times[key].append(value)

    def image(self, case: _Case, camera: Camera) -> tuple[LodChoice, Order, np.ndarray]:
        """The choice, order and (H, W, 4) image of ``case`` at ``camera``."""
        choice = case.choose(self.lod, camera)
        order = self.order(camera, choice)
        target = self._sized(camera)
        self.renderer.render_into(target, camera, self.settings, order)
        return choice, order, target.read()

    def release(self) -> None:
        if self.target is not None:
            self.target.release()
        self.sorter.close()
        self.renderer.release()


def measure_view(runner: _Runner, cases: list[_Case], camera: Camera, repeat: int) -> list[CaseRow]:
    """Every case at ``camera``: images, counts and errors, then ``repeat`` timed frames
    (after one untimed) interleaving the cases, alternating the view and its nudge."""
    lod = runner.lod
    for case in cases:  # this view's times only
        case.times = {key: [] for key in case.times}
    cameras = (camera, turned(camera, NUDGE_DEGREES))
    shots = {case.name: runner.image(case, camera) for case in cases}
    reference = shots[FINEST][2]
    turn = 0
    for frame in range(repeat + 1):
        for case in cases:
            runner.frame(case, cameras[turn % 2], record=frame > 0)
            turn += 1
    rows = []
    for case in cases:
        choice, order, image = shots[case.name]
        errors = common.error_metrics(image, reference)
        rows.append(CaseRow(case.name, case.budget, choice.count, counted(lod, choice, camera), order.count,
                            tuple(int(n) for n in choice.per_level(lod.levels)), choice.over_budget,
                            *(common.median(case.times[key]) for key in ("choice", "sort", "gpu", "gl")),
                            errors["psnr"], errors["max"]))
    finest = rows[0]
    for row in rows:
        row.ratios = {"drawn": _ratio(row.drawn, finest.drawn), "sort": _ratio(row.sort_ms, finest.sort_ms),
                      "gpu": _ratio(row.gpu_ms, finest.gpu_ms), "gl": _ratio(row.gl_ms, finest.gl_ms)}
    return rows


def _ratio(value: float, reference: float) -> float:
    return value / reference if reference and math.isfinite(reference) and reference > 0 else math.nan


def run_lod(options: LodOptions, ctx=None, out: TextIO | None = None) -> LodResults:
    """Measures every scene of ``options``; prints progress and the machine-readable lines
    to ``out`` (stdout). ``ctx``: a GL context to use (default: a new headless one)."""
    say = common.printer(out)
    paths = check_scenes(options.scenes)
    settings = RenderSettings()
    started = time.perf_counter()
    with common.gl_context(ctx, options.gl_backend) as ctx, ctx:  # made current for the run
        machine = context_description(ctx)
        results = LodResults(options, machine, common.run_date(), [], [])
        say(f"bench lod: {len(paths)} scene(s) x {len(VIEWS)} views x {len(CASES)} cases, {options.repeat} timed "
            f"frames each, {options.width} px wide, on {machine}")
        fits, _ = scene_fits(ctx)
        for path, name in zip(paths, scene_names(paths)):
            lod = load_lod(path, fits=fits)
            finest = lod.finest_loaded
            info = SceneInfo(name, path, lod.levels, lod.index.leaves,
                             tuple(int(n) for n in lod.rows[:, :, 1].sum(axis=0)), lod.environment[1], finest,
                             automatic_distance(lod) if options.distance is None else options.distance,
                             options.distance is None, lod.unread)
            results.scenes.append(info)
            say(f"[{name}] {describe_scene(info)}")
            cases = [_Case(FINEST, finest, None, options.distance)]
            cases += [_Case(case, finest, budget, options.distance) for case, budget in budgets(lod, finest).items()]
            runner = _Runner(ctx, lod, settings)
            try:
                for view, camera in view_cameras(lod, options.width).items():
                    say(f"[{name} / {view}] {camera.width}x{camera.height} ...")
                    result = ViewResult(name, view, camera.width, camera.height,
                                        measure_view(runner, cases, camera, options.repeat))
                    results.views.append(result)
                    for line in view_lines(result):
                        say(line)
            finally:
                runner.release()
    results.seconds, results.notes = common.run_end(
        "lod", started, machine=machine, notes=options.notes, say=say,
        software_note="This is a software OpenGL renderer (on the CPU): its GPU timer may read only part of the "
                      "work (the passes can run after the query closes), so the drained GL times are the ones to "
                      "read; a GPU's differ.")
    return results


# --- output --------------------------------------------------------------------------------------

def describe_scene(info: SceneInfo) -> str:
    counts = ", ".join(f"{n:,}" for n in info.counts)
    distance = f"{info.distance:.4g}" + (" (automatic)" if info.automatic else "")
    text = (f"{info.levels} levels ({counts} gaussians, level 0 first), {info.leaves} leaves, environment "
            f"{info.environment:,}; reference: level {info.finest}; first level distance {distance}")
    return text + (f"; {info.unread}" if info.unread else "")


def _db(value: float) -> str:
    if math.isnan(value):
        return "nan"
    return "inf" if math.isinf(value) else f"{value:.1f}"


def _number(value: float, digits: str = ".3f") -> str:
    return "nan" if math.isnan(value) else format(value, digits)


def view_lines(result: ViewResult) -> list[str]:
    """Machine-readable lines ``lod SCENE VIEW CASE KEY VALUE``: KEY budget (gaussians, 0
    for the finest), chosen, counted, drawn, over-budget (0/1), choice-ms, sort-ms,
    gpu-ms, gl-ms, the ratios drawn-ratio, sort-ratio, gpu-ratio, gl-ratio (against the
    finest level) and psnr (dB, inf: the same image), max (absolute, over RGB)."""
    lines = []
    for row in result.rows:
        head = f"lod {result.scene} {result.view} {row.case}"
        values = (("budget", str(row.budget or 0)), ("chosen", str(row.chosen)), ("counted", str(row.counted)),
                  ("drawn", str(row.drawn)), ("over-budget", str(int(row.over_budget))),
                  ("choice-ms", _number(row.choice_ms)), ("sort-ms", _number(row.sort_ms)),
                  ("gpu-ms", _number(row.gpu_ms)), ("gl-ms", _number(row.gl_ms)),
                  *((f"{key}-ratio", _number(row.ratios[key])) for key in ("drawn", "sort", "gpu", "gl")),
                  ("psnr", _db(row.psnr)), ("max", f"{row.max_abs:.6g}"))
        lines += [f"{head} {key} {value}" for key, value in values]
    return lines


TABLE_HEADER = ("| case | budget | chosen | drawn | drawn / finest | leaves per level | choice | cull+sort | / finest "
                "| GPU timer | / finest | GL drained | / finest | PSNR | max abs |")
TABLE_RULE = "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"


def table_row(row: CaseRow) -> str:
    budget = "–" if row.budget is None else f"{row.budget:,}"
    drawn = f"{row.drawn:,}"
    levels = " / ".join(str(n) for n in row.per_level)
    over = " (coarsest alone over)" if row.over_budget else ""
    cells = [row.case if row.case != FINEST else "finest level", budget + over, f"{row.chosen:,}", drawn,
             _number(row.ratios["drawn"], ".2f"), levels, f"{_number(row.choice_ms, '.2f')} ms",
             f"{_number(row.sort_ms, '.2f')} ms", _number(row.ratios["sort"], ".2f"),
             f"{_number(row.gpu_ms, '.2f')} ms", _number(row.ratios["gpu"], ".2f"),
             f"{_number(row.gl_ms, '.1f')} ms", _number(row.ratios["gl"], ".2f"),
             "exact" if math.isinf(row.psnr) else f"{_db(row.psnr)} dB", f"{row.max_abs:.3g}"]
    return "| " + " | ".join(cells) + " |"


def format_report(results: LodResults) -> str:
    options = results.options
    intro = (f"`{options.command_line}` on {results.date}, {results.seconds:.0f} s; GL: {results.machine}. "
             f"Views {options.width} px wide (framing the levels; moved to {CLOSER_FACTOR:g}x and "
             f"{FARTHER_FACTOR:g}x its distance from the scene's centre). Budgets: fractions of the finest "
             f"level's gaussians plus the environment's. Times: medians of {options.repeat} frames, cases "
             f"interleaved; ratios against the finest level in the same frames. Chosen: the gaussians the "
             f"cull+sort covers; drawn: those it keeps; leaves per level: level 0 first. GPU timer: "
             f"preprocess+draw under a timer query; GL drained: the same on the CPU clock with the GPU "
             f"drained on both sides. PSNR and max abs: RGB against the finest level's image at the same "
             f"camera.")
    lines = common.report_head("Level of detail: what each budget costs and saves", intro, results.notes)
    for info in results.scenes:
        lines += [f"## {info.name}", "", f"`{info.path}`: {describe_scene(info)}.", ""]
        for view in (v for v in results.views if v.scene == info.name):
            lines += [f"### {view.view} ({view.width}x{view.height})", "", TABLE_HEADER, TABLE_RULE]
            lines += [table_row(row) for row in view.rows]
            lines.append("")
    return "\n".join(lines)
