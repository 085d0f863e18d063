"""What the benchmarks share: their scenes (the demo and the shared real scenes, each
with a training-like camera), a headless GL context of their own, the error metrics
against a ground truth, medians that skip invalid timings, and writing their reports.
"""

from __future__ import annotations

import contextlib
import datetime
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Sequence, TextIO

import numpy as np

from raygs_viewer.camera.pinhole import Camera, frame_points
from raygs_viewer.errors import UserError
from raygs_viewer.files import write_atomically
from raygs_viewer.render.gl.context import context_description, create_headless_context
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.source import DEMO, SceneSource
from raygs_viewer.sort.depth import DepthSorter


@dataclass(frozen=True, kw_only=True)
class RunOptions:
    """What every benchmark's options hold besides their own (keyword-only, so that each
    benchmark's own fields keep their places): the GL backend, and notes on what the
    run measures (a scene missing, ...) for its report."""

    gl_backend: str | None = None
    notes: tuple[str, ...] = ()


@dataclass(frozen=True, kw_only=True)
class ReportedRunOptions(RunOptions):
    """The options of a benchmark whose markdown report ``--out`` names (``None``: printed
    only), checked before any work; keyword-only as the fields of ``RunOptions`` are."""

    out: Path | None = None
    overwrite: bool = False


@dataclass
class MeasuredView:
    """Which view of which scene a per-view result measured, at what size: the first
    fields of each benchmark's, which adds its own after them (so not keyword-only)."""

    scene: str
    view: str
    width: int
    height: int


@dataclass
class BenchScene:
    name: str
    scene: Scene
    camera: Camera        # the training camera, at its own resolution
    description: str
    path: str | None = None   # the file it was loaded from (None: the demo)


# --- scenes ---------------------------------------------------------------------------------------

def shared_scenes_dir() -> Path | None:
    """``../shared/scenes`` next to the current directory, else next to this repository."""
    for base in (Path.cwd(), Path(__file__).resolve().parents[2]):
        candidate = base.parent / "shared" / "scenes"
        if candidate.is_dir():
            return candidate
    return None


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


def load_scenes(specs: tuple[str, ...]) -> list[BenchScene]:
    """Every scene of ``specs`` ("demo" or a file; all checked to exist before the first
    loads), named after its file (made unique), with its first camera or one framing it."""
    loaded, names = [], set()
    sources = [SceneSource(spec) for spec in specs]
    for source in sources:
        if not source.is_demo and not os.path.exists(source.path):  # a folder may be an unbundled SOG scene
            raise UserError(f"{source.path}: no such file")
    for spec, source in zip(specs, sources):
        result = load_now(source)
        for warning in result.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        scene = result.scene
        if result.cameras:
            camera, origin = result.cameras[0], ("its first view" if source.is_demo
                                                 else f"the first camera of {result.cameras_path}")
        else:
            camera, origin = frame_points(scene.positions), "a camera framing its gaussians (no cameras.json)"
        name = DEMO if source.is_demo else Path(spec).stem
        base, n = name, 2
        while name in names:
            name, n = f"{base}-{n}", n + 1
        names.add(name)
        description = f"{scene.count:,} gaussians, SH degree {scene.sh_degree}; training-like view: {origin}"
        loaded.append(BenchScene(name, scene, camera, description, None if source.is_demo else spec))
    return loaded


# --- running ----------------------------------------------------------------------------------------

@contextlib.contextmanager
def gl_context(ctx=None, backend: str | None = None) -> Iterator:
    """``ctx``, or a new headless context (``backend``) released on leaving."""
    if ctx is not None:
        yield ctx
        return
    ctx = create_headless_context(backend)
    try:
        yield ctx
    finally:
        ctx.release()


@contextlib.contextmanager
def current_context(ctx=None, backend: str | None = None) -> Iterator[tuple[object, str]]:
    """(context, its one-line description): ``gl_context`` made current for the run."""
    with gl_context(ctx, backend) as ctx, ctx:
        yield ctx, context_description(ctx)


@contextlib.contextmanager
def scene_renderer(ctx, scene: Scene) -> Iterator[tuple[GLRenderer, DepthSorter]]:
    """A renderer of ``scene`` and a sorter for the orders it draws (the renderer owns
    none), both released on leaving."""
    renderer = GLRenderer(ctx, scene)
    try:
        with DepthSorter(scene) as sorter:
            yield renderer, sorter
    finally:
        renderer.release()


def printer(out: TextIO | None = None) -> Callable[..., None]:
    """say(line): one line to ``out`` (stdout), flushed so progress shows while it runs."""
    out = out or sys.stdout

    def say(line: str = "") -> None:
        print(line, file=out, flush=True)

    return say


def count_label(count: int) -> str:
    """3_000_000 -> "3M", 100_000 -> "100k", 1_500_000 -> "1.5M", 512 -> "512"."""
    for unit, suffix in ((1_000_000, "M"), (1_000, "k")):
        if count >= unit:
            return f"{count / unit:g}{suffix}"
    return str(count)


def run_date() -> str:
    """Now, local time, as the reports print it: "2026-11-24 01:14 UTC"."""
    return datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")


def software_renderer(machine: str) -> bool:
    """Whether ``machine`` (a context description) is a software OpenGL renderer."""
    return "llvmpipe" in machine or "softpipe" in machine


def run_end(kind: str, started: float, *, machine: str, notes: Iterable[str], software_note: str,
            say: Callable[..., None]) -> tuple[float, list[str]]:
    """The seconds since ``started`` (``time.perf_counter()``), printed as ``bench KIND: done
    in S s``, and the run's notes, ``software_note`` added when ``machine`` is a software
    renderer (its times say little about a GPU's)."""
    seconds = time.perf_counter() - started
    say(f"bench {kind}: done in {seconds:.1f} s")
    notes = list(notes)
    if software_renderer(machine):
        notes.append(software_note)
    return seconds, notes


def finished_run_fields(kind: str, started: float, *, machine: str, notes: Iterable[str], software_note: str,
                        say: Callable[..., None]) -> dict[str, object]:
    """``run_end``'s seconds and notes, with the machine, its CPU cores and the date: the
    fields, by name, of a benchmark's results that say where and how long it ran."""
    seconds, notes = run_end(kind, started, machine=machine, notes=notes, software_note=software_note, say=say)
    return {"machine": machine, "cpu_count": os.cpu_count() or 1, "date": run_date(), "seconds": seconds,
            "notes": notes}


def median(values: list[float]) -> float:
    """The median of the finite values (NaN marks a timing the driver did not deliver);
    NaN for none."""
    finite = [v for v in values if math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


# --- error metrics ----------------------------------------------------------------------------------

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


def fmt_ms(value: float) -> str:
    """A time for a table: "n/a" when not measured, else 3 significant digits or so."""
    if not math.isfinite(value):
        return "n/a"
    return f"{value:.2f} ms" if value < 10 else f"{value:.1f} ms" if value < 100 else f"{value:.0f} ms"


def fmt_ratio(value: float) -> str:
    """A ratio for a table or a ``NAME VALUE`` line: three decimals, "nan" when undefined."""
    return f"{value:.3f}" if math.isfinite(value) else "nan"


def fmt_error(value: float) -> str:
    """An absolute error for a table: two significant digits when small, else three decimals."""
    return "nan" if math.isnan(value) else f"{value:.2g}" if value < 0.01 else f"{value:.3f}"


# --- outputs ----------------------------------------------------------------------------------------

def report_head(title: str, intro: str, notes: Sequence[str] = ()) -> list[str]:
    """The first lines of a markdown report: its title, the paragraph that says how it was
    made, and a ``- note:`` line per note."""
    lines = [f"# {title}", "", intro, ""]
    if notes:
        lines += [f"- note: {note}" for note in notes] + [""]
    return lines


def write_report(path: Path, text: str, overwrite: bool) -> None:
    """A markdown report, written atomically (UTF-8)."""
    write_atomically(path, text.encode("utf-8"), overwrite)


def write_plot(path: Path, png: bytes, overwrite: bool) -> None:
    """A plot (PNG bytes, from ``bench.plot``), written atomically."""
    write_atomically(path, png, overwrite)
