"""What every ``raygs-viewer bench`` subcommand shares (``cli.bench`` builds them): the
parser's skeleton (--quick, --scenes, --width/--repeat, --out/--overwrite/--gl-backend),
the command line each run records so that its report says how to reproduce it, the
checked output paths, and printing the report and what was written.
"""

from __future__ import annotations

import argparse
import os
import shlex
from pathlib import Path
from types import ModuleType
from typing import Callable

from raygs_viewer.bench import perf
from raygs_viewer.bench.common import DEMO, RunOptions, write_report
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.bench_about import ABOUT
from raygs_viewer.errors import UserError


#: The options each benchmark's recorded command names, in their order there.
RECORDED_FLAGS: dict[str, tuple[str, ...]] = {
    "accuracy": ("--quick", "--scenes", "--width", "--repeat", "--gt-samples", "--gt-p-min", "--photos",
                 "--photos-views", "--gl-backend", "--report", "--plot", "--overwrite"),
    "stereo": ("--quick", "--scenes", "--presets", "--width", "--repeat", "--out", "--gl-backend", "--overwrite"),
    "perf": ("--quick", "--counts", "--sizes", "--resolutions", "--scenes", "--frames", "--report", "--plot",
             "--gl-backend", "--overwrite"),
    "order": ("--quick", "--scenes", "--width", "--frames", "--repeat", "--gt-samples", "--out", "--gl-backend",
              "--overwrite"),
    "sort": ("--quick", "--counts", "--repeat", "--no-freshness", "--no-load", "--out", "--gl-backend", "--overwrite"),
    "formats": ("--quick", "--scenes", "--no-samples", "--width", "--repeat", "--out", "--gl-backend", "--overwrite"),
    "lod": ("--quick", "--scenes", "--width", "--repeat", "--lod-distance", "--out", "--gl-backend", "--overwrite"),
    "gpu": ("--quick", "--counts", "--scenes", "--frames", "--out", "--gl-backend", "--overwrite"),
    "xr": ("--quick", "--frames", "--xr-scale", "--xr-no-depth", "--out", "--overwrite"),
}
#: Options a recorded command leaves out at these values (by argparse dest).
RECORDED_DEFAULTS: dict[str, dict[str, object]] = {"perf": {"frames": perf.DEFAULT_FRAMES}}


def recorded_command(kind: str, args: argparse.Namespace) -> str:
    """``raygs-viewer bench KIND`` and, in the order of ``RECORDED_FLAGS[kind]``, every
    option given: a switch alone, a list (even empty) as its words, WxH sizes as such. An
    option whose value is None, False or its entry in ``RECORDED_DEFAULTS`` is left out."""
    parts = ["raygs-viewer", "bench", kind]
    defaults = RECORDED_DEFAULTS.get(kind)
    for flag in RECORDED_FLAGS[kind]:
        dest = flag.removeprefix("--").replace("-", "_")
        value = getattr(args, dest)
        if value is None or value is False or (defaults and dest in defaults and value == defaults[dest]):
            continue
        if value is True:
            parts.append(flag)
        else:
            words = value if isinstance(value, list) else [value]
            parts += [flag, *("x".join(map(str, w)) if isinstance(w, tuple) else str(w) for w in words)]
    return shlex.join(parts)


def report_path(path: str | Path | None, overwrite: bool) -> Path | None:
    return None if path is None else check_output_path(path, overwrite, (".md",))


def plot_path(path: str | Path | None, overwrite: bool) -> Path | None:
    return None if path is None else check_output_path(path, overwrite, (".png",))


def check_distinct(report: Path, plot: Path) -> None:
    if os.path.abspath(report) == os.path.abspath(plot):
        raise UserError(f"{report}: the report and the plot must be different files")


def bench_parser(kinds, kind: str, quick: str, scenes: bool = False) -> argparse.ArgumentParser:
    """The parser of ``bench KIND`` (its ABOUT entry) with --quick (help ``quick``) and, with
    ``scenes``, the --scenes of accuracy, stereo, order and formats."""
    parser = kinds.add_parser(kind, help=ABOUT[kind][0], description=ABOUT[kind][1])
    parser.add_argument("--quick", action="store_true", help=quick)
    if scenes:
        add_scenes_option(parser)
    return parser


def add_scenes_option(parser: argparse.ArgumentParser) -> None:
    """accuracy's and stereo's --scenes (perf's may be empty: generated scenes only)."""
    parser.add_argument("--scenes", nargs="+", metavar="SCENE",
                        help=f"scene files (or '{DEMO}') instead of the demo and the real scenes in ../shared/scenes")


def add_width_and_repeat(parser: argparse.ArgumentParser, width_help: str, repeat_help: str) -> None:
    """accuracy's and stereo's --width (of the views measured) and --repeat (timed frames)."""
    parser.add_argument("--width", type=argtypes.whole_number(4, argtypes.MAX_SIDE), metavar="PX", help=width_help)
    parser.add_argument("--repeat", type=argtypes.whole_number(1, 100000), metavar="N", help=repeat_help)


def add_out_options(parser: argparse.ArgumentParser, out_help: str = "also write the markdown report there") -> None:
    """The last options of stereo, order, sort and formats: --out (the markdown report),
    --overwrite and --gl-backend."""
    parser.add_argument("--out", metavar="PATH.md", help=out_help)
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    argtypes.add_backend_option(parser)


def show_report(report: str, out: Path | None, overwrite: bool) -> int:
    """Prints a benchmark's markdown report and writes it to ``out`` (if given); exit status 0."""
    print("", flush=True)
    print(report, flush=True)
    if out is not None:
        write_report(out, report, overwrite)
        print(f"wrote {out}", flush=True)
    return 0


def print_notes(notes: tuple[str, ...]) -> None:
    for note in notes:
        print(f"note: {note}", flush=True)


def scene_choice(args: argparse.Namespace,
                  default: Callable[[], tuple[tuple[str, ...], list[str]]]) -> tuple[tuple[str, ...], list[str]]:
    """The scenes of --scenes as given, else ``default()``; with the notes on scenes not found."""
    return (tuple(args.scenes), []) if args.scenes is not None else default()


def quick_or_default(args: argparse.Namespace, bench: ModuleType, names: tuple[str, ...]) -> dict[str, object]:
    """{name: the option as given, else the benchmark module's QUICK_<NAME> with --quick, else
    its DEFAULT_<NAME>}: the sizes every benchmark names the same way."""
    prefix = "QUICK" if args.quick else "DEFAULT"
    return {name: getattr(args, name) or getattr(bench, f"{prefix}_{name.upper()}") for name in names}


def run_fields(kind: str, args: argparse.Namespace, notes: list[str]) -> dict[str, object]:
    """The fields of ``bench.common.RunOptions`` and the recorded command line, for any benchmark."""
    return {"command_line": recorded_command(kind, args), "gl_backend": args.gl_backend, "notes": tuple(notes)}


def run_reported(make_options: Callable[[argparse.Namespace], RunOptions], run: Callable,
                  report: Callable[..., str], args: argparse.Namespace, ctx) -> int:
    """Makes the options (checking them before any work) and the --out path, prints the
    notes, runs the benchmark and shows its report (written to --out, if given)."""
    options = make_options(args)
    out = report_path(args.out, args.overwrite)
    print_notes(options.notes)
    return show_report(report(run(options, ctx)), out, args.overwrite)


def print_written(*paths: Path | None) -> None:
    for path in paths:
        if path is not None:
            print(f"wrote {path}", flush=True)
