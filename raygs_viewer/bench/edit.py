"""``raygs-viewer bench edit``: what selecting "what the view shows" costs, against a
frame of the same view, and whether it selects what the float64 weighing selects.

For each scene (generated cubes of gaussians with SH degree 3, and real scenes), from
the view framing it: the **frame** is the view drawn with ``RenderSettings()`` (the
global order, the viewer's default) at the run's size, drawn once untimed, then one
``renderer.render`` timed with the GL drained. A **selection** is a click (one pixel at
the centre), a brush stroke (radius 20 px, 300 px long, horizontal through the centre)
or a 200x200 rectangle at the centre (the shapes scale with the width where the run is
smaller than 1280 px), weighed in the global order and in the per-ray order
(``order="per-pixel"``) as the window weighs it (``render.gl.weighing``): one timed
span from ``start_weighing`` to its last ``step``, back to back, with the sorts of the
view's order culled to each slice it asks for, after one untimed click in that order
(its shaders compiled). Each slice aims at about the frame's time, as the window's
(:func:`window_slice`). Its time is given as a ratio to the frame's.

Each selection's weights are checked against the float64 weighing
(``render.contributions.max_weights``, in the view's own order): a
row is selected at weight >= :data:`THRESHOLD`. Rows whose float64 weight lies within
:data:`BAND` of it are left out (float32 may fall either side); every other row must be
selected by both or by neither, and one that is not fails the run loudly.
"""

from __future__ import annotations

import math
import os
import shlex
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, TextIO

import numpy as np

from raygs_viewer.bench import common, cube
from raygs_viewer.camera.pinhole import Camera, frame_points
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.errors import UserError
from raygs_viewer.files import write_atomically
from raygs_viewer.jsonfile import json_text
from raygs_viewer.render.contributions import bounds, max_weights
from raygs_viewer.render.gl.weighing import DEFAULT_SLICE_SECONDS, start_weighing
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order, part_orders
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.selection import ScreenShape
from raygs_viewer.scene.source import DEMO

DEFAULT_SIZE, QUICK_SIZE = (1280, 720), (320, 180)
COUNTS, QUICK_COUNTS = (1_000_000, 3_000_000), (200_000,)
REAL_SCENES = ("ss-fruit_drops_minimal.ply", "donut-mip-fused.ply", "gs3d-pr477-lod3_tile_0.ply",
               "metalsplatter-train3.ply", "schwa-centered_lastchance.splat")
QUICK_REAL_SCENES = REAL_SCENES[:1]
GENERATED_SH_DEGREE = 3  # as trained scenes have
#: The weight a row is selected at (the panel's default "shows at least").
THRESHOLD = 0.05
#: Rows whose float64 weight lies this close to the threshold are not compared.
BAND = 1e-4
#: The orders weighed, as the report and the JSON name them.
ORDERS = {"global": RenderSettings(), "per-ray": RenderSettings(order="per-pixel")}
SHAPES = ("click", "brush", "rectangle")
#: The goal on llvmpipe: a selection's time in frames, by order.
GOALS = {"global": 1.0, "per-ray": 3.0}
#: The shapes' sizes at DEFAULT_SIZE's width (pixels): brush radius and length, rectangle side.
BRUSH_RADIUS, BRUSH_LENGTH, RECTANGLE_SIDE = 20.0, 300.0, 200.0
#: Rows named in a line (in the band, or differing).
LISTED = 5
#: ``bench edit --help``'s description.
ABOUT = ("For generated scenes of 1M and 3M gaussians with SH degree 3 and the shared real scenes, from the view "
         "framing each at 1280x720: the time of one frame beside the time to a finished selection of what the view "
         "shows (a click, a brush stroke, a 200x200 rectangle; in the global and the per-ray order) as the window "
         "weighs it on the GPU, and how many rows it selects as the float64 weighing does at weight 0.05. Prints a "
         "markdown report; --json writes the figures.")
SOFTWARE_NOTE = ("This is a software OpenGL renderer (on the CPU): the frame and the weighing share its cores, so "
                 "the ratio says more than either time.")


@dataclass(frozen=True, kw_only=True)
class EditOptions(common.RunOptions):
    """``counts``: generated scenes (SH 3, ``bench.cube``'s); ``scenes``: files (checked
    to exist before the first is measured); ``json``: where the results go (None: printed only)."""

    counts: tuple[int, ...] = ()
    scenes: tuple[str, ...] = ()
    width: int = DEFAULT_SIZE[0]
    height: int = DEFAULT_SIZE[1]
    json: Path | None = None
    overwrite: bool = False
    slice_seconds: float | None = None      # None: as the window slices (:func:`window_slice`)
    command_line: str = "raygs-viewer bench edit"


@dataclass(frozen=True)
class RowCheck:
    """The GPU's selection against the float64 one at :data:`THRESHOLD`: ``equal`` of
    ``compared`` rows agree; ``in_band`` rows (float64 weight within :data:`BAND` of the
    threshold) are not compared; ``differing``: the compared rows that disagree."""

    equal: int
    compared: int
    in_band: tuple[int, ...]
    differing: tuple[int, ...]
    selected: int            # by the float64 weighing


@dataclass(frozen=True)
class Case:
    shape: str
    order: str
    seconds: float
    slices: int
    where: str
    rows: RowCheck


@dataclass
class SceneResult:
    scene: str
    gaussians: int
    width: int
    height: int
    frame_seconds: float
    slice_seconds: float
    cases: list[Case]

    def ratio(self, case: Case) -> float:
        return case.seconds / self.frame_seconds if self.frame_seconds > 0 else math.nan


@dataclass
class EditResults:
    options: EditOptions
    scenes: list[SceneResult]
    machine: str
    cpu_count: int
    date: str
    notes: list[str]
    seconds: float = math.nan

    @property
    def failures(self) -> list[str]:
        """One line per case whose compared rows differ from the float64 weighing's."""
        return [f"{s.scene}, {c.order} order, {c.shape}: {len(c.rows.differing):,} rows outside the band differ "
                f"from the float64 weighing (rows {_listed(c.rows.differing)})"
                for s in self.scenes for c in s.cases if c.rows.differing]


def edit_options(*, scenes: tuple[str, ...], counts: list[int] | None, quick: bool, size: tuple[int, int] | None,
                 json: str | None, overwrite: bool, gl_backend: str | None, command_line: str) -> EditOptions:
    """The options of a run, checked before any work (one line each: a scene file missing,
    --json not writable or already there). ``scenes`` empty: the shared real scenes (with
    a note for each missing); ``counts`` None: the default generated scenes, none where
    scene files are given."""
    notes: list[str] = []
    given = bool(scenes)
    if not given:
        scenes, notes = common.shared_scene_paths(QUICK_REAL_SCENES if quick else REAL_SCENES)
    for scene in scenes:
        if scene != DEMO and not os.path.exists(scene):
            raise UserError(f"{scene}: no such file")
    if counts is None:
        counts = [] if given else list(QUICK_COUNTS if quick else COUNTS)
    if not counts and not scenes:
        raise UserError("bench edit: nothing to measure (no generated scene and no scene file)")
    width, height = size or (QUICK_SIZE if quick else DEFAULT_SIZE)
    if (width, height) != DEFAULT_SIZE:
        notes.append(f"{width}x{height}, not {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}: the shapes are scaled by "
                     f"{width / DEFAULT_SIZE[0]:g}")
    return EditOptions(counts=tuple(dict.fromkeys(counts)), scenes=tuple(scenes), width=width, height=height,
                       json=None if json is None else check_output_path(json, overwrite, (".json",)),
                       overwrite=overwrite, command_line=command_line, gl_backend=gl_backend, notes=tuple(notes))


def command_line(flags, scenes) -> str:
    """``raygs-viewer bench edit``, each of ``flags`` ((option, value) pairs) given (a
    switch alone where its value is True; a list as its words; left out where None or
    False), then the scenes."""
    words = [word for flag, value in flags if value is not None and value is not False
             for word in [flag, *map(str, () if value is True else value)]]
    return shlex.join(["raygs-viewer", "bench", "edit", *words, *scenes])


# --- the scenes ------------------------------------------------------------------------------------

def generated_scene(count: int, seed: int = 0) -> Scene:
    """``bench.cube``'s cube of ``count`` gaussians with SH degree 3: its colours as the DC
    term and small random view-dependent terms (trained scenes' degree and memory)."""
    base = cube.generated_scene(count, seed)
    rng = np.random.default_rng(seed + 1)
    sh = np.empty((count, sh_coefficient_count(GENERATED_SH_DEGREE), 3), np.float32)
    sh[:, :1] = base.sh
    sh[:, 1:] = rng.normal(0.0, 0.1, (count, sh.shape[1] - 1, 3))
    return Scene(base.positions, base.rotations, base.scales, base.opacities, sh, GENERATED_SH_DEGREE,
                 source="generated")


def shapes(camera: Camera) -> dict[str, ScreenShape]:
    """The click, brush stroke and rectangle at the centre of ``camera``'s image, their
    sizes scaled by its width against :data:`DEFAULT_SIZE`'s."""
    scale = camera.width / DEFAULT_SIZE[0]
    u, v = camera.width // 2, camera.height // 2
    half_stroke, half_side = BRUSH_LENGTH * scale / 2, max(0.5, RECTANGLE_SIDE * scale / 2)
    return {"click": ScreenShape("rectangle", camera, ((u, v), (u + 1, v + 1))),
            "brush": ScreenShape("brush", camera, ((u - half_stroke, v), (u + half_stroke, v)),
                                 max(0.5, BRUSH_RADIUS * scale)),
            "rectangle": ScreenShape("rectangle", camera, ((u - half_side, v - half_side),
                                                           (u + half_side, v + half_side)))}


# --- measuring -------------------------------------------------------------------------------------

def compare_rows(weights: np.ndarray, reference: np.ndarray, threshold: float = THRESHOLD,
                 band: float = BAND) -> RowCheck:
    """``weights`` (the GPU's, (N,)) against ``reference`` (float64, (N,)) selected at
    ``threshold``, the rows within ``band`` of it left out."""
    weights, reference = np.asarray(weights, np.float64), np.asarray(reference, np.float64)
    if weights.shape != reference.shape:
        raise ValueError(f"weights {weights.shape} and reference {reference.shape} differ in shape")
    near = np.abs(reference - threshold) <= band
    differs = ((weights >= threshold) != (reference >= threshold)) & ~near
    compared = int(reference.size - np.count_nonzero(near))
    return RowCheck(compared - int(np.count_nonzero(differs)), compared, tuple(np.flatnonzero(near).tolist()),
                    tuple(np.flatnonzero(differs).tolist()), int(np.count_nonzero(reference >= threshold)))


def reference_weights(scene: Scene, indices: np.ndarray, camera: Camera, settings: RenderSettings,
                      inside: np.ndarray) -> np.ndarray:
    """The float64 weights of the pixels ``inside``, in the view's order ``indices``; a
    box past ``max_weights``' fragment limit is weighed in halves of its rows (each
    pixel's weights are its own, so the largest over the halves is the whole's)."""
    if not inside.any():
        return np.zeros(scene.count)
    rows, _ = bounds(inside)
    try:
        return max_weights(scene, camera, settings, np.asarray(indices), inside)
    except UserError:
        if rows.stop - rows.start < 2:
            raise
        middle = (rows.start + rows.stop) // 2
        halves = []
        for part in (slice(0, middle), slice(middle, None)):
            half = np.zeros_like(inside)
            half[part] = inside[part]
            halves.append(reference_weights(scene, indices, camera, settings, half))
        return np.maximum(*halves)


def window_slice(frame: float) -> float:
    """The time a slice aims at where a frame takes ``frame`` seconds: about a frame, at
    least ``DEFAULT_SLICE_SECONDS``, as the window's Edit tool asks (viewer.edit_tool: so
    a slow view weighs in few slices, each paying its sort and its gaussians' setup once)."""
    return max(DEFAULT_SLICE_SECONDS, frame)


@dataclass(frozen=True)
class Weighed:
    """A timed weighing: seconds from ``start_weighing`` to its last step, the steps
    (slices) it took, its weights and its path."""

    seconds: float
    slices: int
    weights: np.ndarray
    where: str


def timed_weighing(renderer, camera: Camera, settings: RenderSettings, sort, inside: np.ndarray, *,
                   slice_seconds: float) -> Weighed:
    """One weighing, every step back to back (the module docstring)."""
    started = time.perf_counter()
    weighing = start_weighing(renderer, camera, settings, sort, inside, slice_seconds=slice_seconds)
    try:
        slices = 1
        while not weighing.step():
            slices += 1
        seconds = time.perf_counter() - started
        return Weighed(seconds, slices, weighing.weights, weighing.where)
    finally:
        weighing.release()


def frame_seconds(renderer, sorter, camera: Camera) -> float:
    """One frame of the view in ``RenderSettings()``, after one untimed (the order sorted before)."""
    settings = RenderSettings()
    order = exact_order(sorter, camera, settings)
    renderer.render(camera, settings, order)
    renderer.ctx.finish()
    started = time.perf_counter()
    renderer.render(camera, settings, order)
    renderer.ctx.finish()
    return time.perf_counter() - started


def measure_scene(ctx, name: str, scene: Scene, camera: Camera, *, options: EditOptions,
                  progress: Callable[..., None]) -> SceneResult:
    """The frame and every shape in every order of one scene (the module docstring)."""
    with common.scene_renderer(ctx, scene) as (renderer, sorter):
        progress(f"bench edit: {name} ({scene.count:,} gaussians), {camera.width}x{camera.height}: the frame")
        frame = frame_seconds(renderer, sorter, camera)
        slice_seconds = options.slice_seconds or window_slice(frame)
        result = SceneResult(name, scene.count, camera.width, camera.height, frame, slice_seconds, [])
        progress(f"bench edit: {name}: frame {frame:.3f} s, slices of {slice_seconds:.3f} s")
        u, v = camera.width // 4, camera.height // 4
        warm = ScreenShape("rectangle", camera, ((u, v), (u + 1, v + 1)))
        for order_name, settings in ORDERS.items():
            view = exact_order(sorter, camera, settings)  # what the view draws
            view_indices = np.asarray(view.indices.read() if view.on_device else view.indices)
            sort = part_orders(sorter, camera, settings, view)
            timed_weighing(renderer, camera, settings, sort, warm.pixel_mask(), slice_seconds=slice_seconds)
            for shape_name, shape in shapes(camera).items():
                inside = shape.pixel_mask()
                weighed = timed_weighing(renderer, camera, settings, sort, inside, slice_seconds=slice_seconds)
                progress(f"bench edit: {name}: {order_name} {shape_name}: {weighed.seconds:.3f} s "
                         f"({weighed.where}); the float64 weighing")
                checked = compare_rows(weighed.weights, reference_weights(scene, view_indices, camera, settings, inside))
                case = Case(shape_name, order_name, weighed.seconds, weighed.slices, weighed.where, checked)
                result.cases.append(case)
                progress(case_line(result, case))
    return result


def run_edit(options: EditOptions, given=None, progress: TextIO | None = None) -> EditResults:
    """Every scene of ``options`` (generated first), measured in ``given`` (default: a
    headless context of its own); progress lines to ``progress`` (stderr)."""
    say_progress = common.printer(progress or sys.stderr)
    real = common.load_scenes(options.scenes) if options.scenes else []
    if not options.counts and not real:
        raise UserError("bench edit: nothing to measure (no generated scene and no scene file)")
    started = time.perf_counter()
    results = []
    with common.current_context(given, options.gl_backend) as (ctx, machine):
        say_progress(f"bench edit: {options.width}x{options.height} on {machine}")
        for count in options.counts:
            camera = cube.view_camera(options.width, options.height)
            name = f"generated {common.count_label(count)} (SH {GENERATED_SH_DEGREE})"
            results.append(measure_scene(ctx, name, generated_scene(count), camera, options=options,
                                         progress=say_progress))
        for item in real:
            camera = frame_points(item.scene.positions, options.width, options.height)
            results.append(measure_scene(ctx, item.name, item.scene, camera, options=options, progress=say_progress))
    finished = common.finished_run_fields("edit", started, machine=machine, notes=options.notes,
                                          software_note=SOFTWARE_NOTE, say=say_progress)
    edited = EditResults(options, results, **finished)
    for line in edited.failures:
        say_progress(f"bench edit: FAILED: {line}")
    return edited


# --- output ----------------------------------------------------------------------------------------

def _listed(rows: tuple[int, ...]) -> str:
    shown = ", ".join(str(row) for row in rows[:LISTED])
    return shown + (f", ... ({len(rows):,} in all)" if len(rows) > LISTED else "")


def case_line(scene: SceneResult, case: Case) -> str:
    """One case on one line, as progress prints it."""
    rows = case.rows
    band = f"; in band: {_listed(rows.in_band)}" if rows.in_band else ""
    differ = f"; DIFFERING: {_listed(rows.differing)}" if rows.differing else ""
    return (f"edit {scene.scene} {case.order} {case.shape}: {case.seconds:.3f} s in {case.slices} slices, "
            f"{common.fmt_ratio(scene.ratio(case))} frames, {case.where}; "
            f"rows equal {rows.equal:,} of {rows.compared:,}{band}{differ}")


def _verdict(scene: SceneResult, case: Case) -> str:
    ratio, goal = scene.ratio(case), GOALS[case.order]
    if not math.isfinite(ratio):
        return "not measured"
    return "met" if ratio <= goal else "missed"


def format_report(results: EditResults) -> str:
    """The markdown report: where it ran, the verdict on the rows, a table per scene."""
    options = results.options
    scale = options.width / DEFAULT_SIZE[0]
    shape_words = (f"a click (1 pixel at the centre), a brush stroke (radius {BRUSH_RADIUS * scale:g} px, "
                   f"{BRUSH_LENGTH * scale:g} px long through the centre), a {RECTANGLE_SIDE * scale:g}x"
                   f"{RECTANGLE_SIDE * scale:g} rectangle at the centre")
    lines = common.report_head(
        "Selecting what the view shows, against a frame",
        f"Generated by `{options.command_line}` on {results.date}, {results.seconds:.0f} s.", results.notes)
    failures = results.failures
    slice_words = (f"about a frame's time (at least {DEFAULT_SLICE_SECONDS * 1000:g} ms), as the window's"
                   if options.slice_seconds is None
                   else f"{options.slice_seconds * 1000:g} ms")
    verdict = (f"**FAILED: {len(failures)} selections differ from the float64 weighing outside the band**"
               if failures else "Every selection equals the float64 weighing's outside the band.")
    lines += [f"- Machine: {results.machine}, {results.cpu_count} CPU cores",
              f"- Size: {options.width}x{options.height}; shapes: {shape_words}",
              "- Frame: the view drawn with `RenderSettings()` (the global order), once untimed, then one "
              "`renderer.render` timed with the GL drained",
              "- Selection: `start_weighing` to its last step, back to back, the sorts it asks for included, "
              f"each slice aiming at {slice_words}, after one untimed click in that order",
              f"- Rows: selected at weight >= {THRESHOLD:g}, against the float64 weighing; rows whose float64 "
              f"weight lies within {BAND:g} of it are in the band and not compared",
              f"- Goal (llvmpipe): the global order within {GOALS['global']:g} frame's time, the per-ray order "
              f"within {GOALS['per-ray']:g}", "", verdict, ""]
    lines += [f"- {line}" for line in failures] + ([""] if failures else [])
    for scene in results.scenes:
        lines += [f"## {scene.scene}: {scene.gaussians:,} gaussians, {scene.width}x{scene.height}, "
                  f"frame {common.fmt_ms(scene.frame_seconds * 1000)}, slices of "
                  f"{common.fmt_ms(scene.slice_seconds * 1000)}", "",
                  "| order | shape | selection | frames | goal | slices | path | rows equal | in band |",
                  "|---|---|---:|---:|---|---:|---|---:|---|"]
        for case in scene.cases:
            rows = case.rows
            equal = f"{rows.equal:,} of {rows.compared:,}" + (" **(differ)**" if rows.differing else "")
            cells = [case.order, case.shape, common.fmt_ms(case.seconds * 1000), common.fmt_ratio(scene.ratio(case)),
                     _verdict(scene, case), str(case.slices), case.where, equal, _listed(rows.in_band) or "none"]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def json_document(results: EditResults) -> dict:
    """What ``--json`` writes: the scenes, each with its cases (every row in the band listed)."""
    return {"scenes": [{"scene": s.scene, "gaussians": s.gaussians, "width": s.width, "height": s.height,
                        "frame_seconds": s.frame_seconds,
                        "cases": [{"shape": c.shape, "order": c.order, "seconds": c.seconds,
                                   "rows_equal": c.rows.equal, "rows_compared": c.rows.compared,
                                   "rows_in_band": list(c.rows.in_band)} for c in s.cases]}
                       for s in results.scenes]}


def write_json(results: EditResults, path: Path, overwrite: bool) -> None:
    """The JSON document, written atomically."""
    write_atomically(path, json_text(json_document(results)).encode("utf-8"), overwrite)
