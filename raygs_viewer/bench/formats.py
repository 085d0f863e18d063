"""``raygs-viewer bench formats``: what each file format keeps of a scene, and what it
costs to load.

Each reference scene (the demo, the shared INRIA PLYs and the shared samples in
PlayCanvas's formats) is loaded from its own file (its size and load time), then
written as ``.ply``, ``.splat``, ``.spz`` v3 and v4 into a temporary folder and read
back. For each: the file's size, its load time (median of ``repeat`` loads in this
process), the per-attribute error against the scene
(:func:`raygs_viewer.scene.compare.attribute_errors`) and the PSNR of its GL render
against the scene's own, at the training-like view. The shared sample with a twin in
another format (``metalsplatter-train3.spz`` and ``.ply``) is compared with it the same
way.
"""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from raygs_viewer.bench.common import (
    RunOptions,
    error_metrics,
    gl_context,
    load_scenes,
    median,
    printer,
    report_head,
    run_date,
    scene_renderer,
    shared_scenes_dir,
)
from raygs_viewer.bench.views import training_view
from raygs_viewer.camera.pinhole import Camera, frame_points
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.compare import AttributeErrors, attribute_errors
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.spz_format import SpzEncoding
from raygs_viewer.scene.writing import write_scene

#: The targets every reference scene is written to: (label, suffix, spz version).
TARGETS = (("INRIA PLY", ".ply", 3), (".splat", ".splat", 3), ("spz v3", ".spz", 3), ("spz v4", ".spz", 4))
#: Shared samples and the twin in another format each is compared with.
TWINS = (("formats/metalsplatter-train3.spz", "metalsplatter-train3.ply"),)
DEFAULT_SCENES = ("ss-fruit_drops_minimal.ply", "donut-mip-fused.ply", "gs3d-pr477-lod3_tile_0.ply",
                  "formats/pc-guitar.compressed.ply", "formats/pcwc-angel-kneeling.sog")
DEFAULT_WIDTH, DEFAULT_REPEAT = 320, 5
#: The label of a reference scene's own file (no error: it is the reference).
AS_READ = "as read"
QUICK_WIDTH, QUICK_REPEAT = 128, 2


@dataclass(frozen=True)
class FormatsOptions(RunOptions):
    scenes: tuple[str, ...]      # reference scenes: "demo" or files
    samples: bool                # also the shared samples with twins
    width: int
    repeat: int
    command_line: str


@dataclass(frozen=True)
class Row:
    """One file: its format's label, size (bytes), median load (ms), count and format
    as read, and against its reference (None: none) the errors and render PSNR (dB)."""

    label: str
    size: int
    load_ms: float
    count: int
    format: str
    errors: AttributeErrors | None
    psnr: float | None


@dataclass(frozen=True)
class Reference:
    """What a file read back is held against: the scene it was written from (or its
    twin), the view, and that scene's own render there ((H, W, 4) float32)."""

    scene: Scene
    camera: Camera
    image: np.ndarray


@dataclass(frozen=True)
class FormatsResults:
    options: FormatsOptions
    machine: str
    date: str
    scenes: list[tuple[str, str, list[Row]]]      # (name, description, rows)


def run_formats(options: FormatsOptions, ctx=None) -> FormatsResults:
    say = printer()
    with gl_context(ctx, options.gl_backend) as ctx:
        results = FormatsResults(options, context_description(ctx), run_date(), [])
        with tempfile.TemporaryDirectory(prefix="raygs-formats-") as folder:
            for bench_scene in load_scenes(options.scenes):
                say(f"{bench_scene.name}: writing and reading {len(TARGETS)} formats")
                camera = training_view(bench_scene.camera, options.width)
                reference = Reference(bench_scene.scene, camera, _render(ctx, bench_scene.scene, camera))
                rows = []
                if bench_scene.path is not None:
                    rows.append(_row(ctx, AS_READ, Path(bench_scene.path), repeat=options.repeat))
                for label, suffix, version in TARGETS:
                    path = write_scene(bench_scene.scene, Path(folder) / f"{bench_scene.name}-{label[-2:]}{suffix}",
                                       spz=SpzEncoding(version))
                    rows.append(_row(ctx, label, path, repeat=options.repeat, reference=reference))
                results.scenes.append((bench_scene.name, bench_scene.description, rows))
        if options.samples:
            results.scenes.extend(_samples(ctx, options, say))
    return results


def _samples(ctx, options: FormatsOptions, say) -> list[tuple[str, str, list[Row]]]:
    folder = shared_scenes_dir()
    if folder is None:
        say("no ../shared/scenes folder: no shared samples")
        return []
    found = []
    for sample, twin in TWINS:
        path = folder / sample
        if not (path.is_file() and (folder / twin).is_file()):
            say(f"{sample} or {twin} not found: skipped")
            continue
        say(f"{sample}: loading")
        scene = load_scene(folder / twin)
        camera = training_view(frame_points(scene.positions), options.width)
        row = _row(ctx, Path(sample).suffix, path, repeat=options.repeat,
                   reference=Reference(scene, camera, _render(ctx, scene, camera)))
        found.append((Path(sample).name, f"against {twin}, its twin in INRIA PLY", [row]))
    return found


def _row(ctx, label: str, path: Path, *, repeat: int, reference: Reference | None = None) -> Row:
    """The row of the file at ``path``: its median of ``repeat`` loads, and its errors
    against ``reference`` (None: it is the reference's own file)."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        scene = load_scene(path)
        times.append((time.perf_counter() - start) * 1000)
    errors = psnr = None
    if reference is not None:
        errors = attribute_errors(reference.scene, scene)
        psnr = error_metrics(_render(ctx, scene, reference.camera), reference.image)["psnr"]
    return Row(label, os.path.getsize(path), median(times), scene.count, scene.format, errors, psnr)


def _render(ctx, scene: Scene, camera: Camera) -> np.ndarray:
    settings = RenderSettings()
    with scene_renderer(ctx, scene) as (renderer, sorter):
        return renderer.render(camera, settings, exact_order(sorter, camera, settings))


def format_report(results: FormatsResults) -> str:
    options = results.options
    intro = (f"`{options.command_line}` on {results.date}; GL: {results.machine}. Render PSNR at the "
             f"training-like view, {options.width} px wide, default settings, against the reference scene's own "
             f"render; load: median of {options.repeat} loads in one process.")
    lines = report_head("File formats: what each keeps, and its load time", intro)
    header = ("| format | size | load | position (rel.) | scale (rel.) | colour | SH rest | opacity | rotation "
              "| render PSNR |")
    for name, description, rows in results.scenes:
        lines += [f"## {name}", "", description, "", header, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for row in rows:
            lines.append(_table_row(row))
        lines.append("")
    return "\n".join(lines)


def _table_row(row: Row) -> str:
    size = f"{row.size / 1e6:.2f} MB" if row.size >= 1e5 else f"{row.size / 1e3:.1f} kB"
    cells = [f"as read: {row.format}" if row.label == AS_READ else row.format, size, f"{row.load_ms:.1f} ms"]
    e = row.errors
    if e is None:
        cells += ["–"] * 7
    else:
        relative = "–" if e.position_relative is None else f"{e.position_relative:.1e}"
        rest = "lost" if e.sh_degree_lost else f"{e.sh_rest_max:.3g}"
        cells += [relative, f"{e.scale_relative:.3g}", f"{e.colour_max_clipped:.3g}", rest, f"{e.opacity_max:.3g}",
                  f"{e.rotation_degrees:.3g}°", "exact" if row.psnr == float("inf") else f"{row.psnr:.1f} dB"]
    return "| " + " | ".join(cells) + " |"
