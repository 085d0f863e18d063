"""``raygs-viewer bench accuracy|stereo|perf|order|sort|formats|lod|gpu|xr|edit``: their options,
the options handed to each benchmark (everything that can be checked is, before any
work) and the dispatch; what they share (the parser's skeleton, the recorded command
line, the report's output) is ``cli.bench_shared``.
"""

from __future__ import annotations

import argparse
import os
import shlex
from pathlib import Path

from raygs_viewer.bench import accuracy, accuracy_report, freshness, perf
from raygs_viewer.bench import edit as edit_bench
from raygs_viewer.bench import formats as formats_bench
from raygs_viewer.bench import gpu as gpu_bench
from raygs_viewer.bench import lod as lod_bench
from raygs_viewer.bench import order as order_bench
from raygs_viewer.bench import sort as sort_bench
from raygs_viewer.bench import stereo as stereo_bench
from raygs_viewer.bench import xr as xr_bench
from raygs_viewer.bench.common import (
    DEMO,
    count_label,
    shared_scene_paths,
    shared_scenes_dir,
)
from raygs_viewer.camera import stereo as camera_stereo
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.bench_about import SORT_COUNTS
from raygs_viewer.cli.bench_shared import (
    add_out_options,
    add_width_and_repeat,
    bench_parser,
    check_distinct,
    plot_path,
    print_notes,
    print_written,
    quick_or_default,
    recorded_command,
    report_path,
    run_fields,
    run_reported,
    scene_choice,
    show_report,
)
from raygs_viewer.errors import UserError
from raygs_viewer.scene.lod_meta import LOD_META_NAME
from raygs_viewer.xr.runtime import check_runtime


def add_parsers(commands) -> None:
    """Adds ``bench`` and its subcommands to the CLI's subparsers."""
    bench = commands.add_parser("bench", help="benchmarks (accuracy against time; stereo sharing error and "
                                              "frame budget; per-stage frame times and cost ratios; "
                                              "order modes and popping; CPU cull and sort at millions, "
                                              "and the order's freshness in motion)")
    bench.set_defaults(run=command)
    kinds = bench.add_subparsers(dest="bench", required=True, parser_class=type(bench))
    _add_accuracy_parser(kinds)
    _add_stereo_parser(kinds)
    _add_perf_parser(kinds)
    _add_order_parser(kinds)
    _add_sort_parser(kinds)
    _add_formats_parser(kinds)
    _add_lod_parser(kinds)
    _add_gpu_parser(kinds)
    _add_xr_parser(kinds)
    _add_edit_parser(kinds)


def command(args: argparse.Namespace, ctx=None) -> int:
    """Runs ``bench <kind>``. ``ctx``: a GL context to use instead of a new one (tests)."""
    # The benchmarks that print a markdown report (and write it to --out): their options, run and report.
    reported = {"stereo": (stereo_options, stereo_bench.run_stereo, stereo_bench.format_report),
                "order": (order_options, order_bench.run_order, order_bench.format_report),
                "sort": (sort_options, sort_bench.run_sort, sort_bench.format_report),
                "formats": (formats_options, formats_bench.run_formats, formats_bench.format_report),
                "lod": (lod_options, lod_bench.run_lod, lod_bench.format_report),
                "gpu": (gpu_options, gpu_bench.run_gpu, gpu_bench.format_report),
                "xr": (xr_options, xr_bench.run_xr, xr_bench.format_report)}
    runs = {"accuracy": _run_accuracy, "perf": _run_perf, "edit": _run_edit}
    if args.bench in reported:
        return run_reported(*reported[args.bench], args, ctx)
    if args.bench not in runs:
        raise UserError(f"unknown benchmark '{args.bench}'")
    return runs[args.bench](args, ctx)


def reported_run_fields(kind: str, args: argparse.Namespace, notes: list[str]) -> dict[str, object]:
    """The fields of ``bench.common.ReportedRunOptions``: --out (checked before any work),
    --overwrite and ``run_fields``."""
    return {"out": report_path(args.out, args.overwrite), "overwrite": args.overwrite,
            **run_fields(kind, args, notes)}


# --- accuracy ------------------------------------------------------------------------------------


def _add_accuracy_parser(kinds) -> None:
    parser = bench_parser(kinds, "accuracy",
                           f"the demo and one small real scene, {accuracy.QUICK_WIDTH} px wide, "
                           f"{accuracy.QUICK_REPEAT} timed frames, ground truth "
                           f"{accuracy.QUICK_GT_SAMPLES}x{accuracy.QUICK_GT_SAMPLES} samples (1 to 1.5 minutes on two CPU cores with "
                           f"llvmpipe: 74 s on 2026-11-28)",
                           scenes=True)
    add_width_and_repeat(parser,
                          f"width of the training-like view (default {accuracy.DEFAULT_WIDTH}, --quick "
                          f"{accuracy.QUICK_WIDTH}); the far view has a quarter of it",
                          f"timed frames per configuration (default {accuracy.DEFAULT_REPEAT}, --quick "
                          f"{accuracy.QUICK_REPEAT}); use at least 10")
    parser.add_argument("--gt-samples", type=argtypes.whole_number(1, 64), metavar="N",
                        help=f"ground-truth samples per pixel axis for the training-like and close views "
                             f"(default {accuracy.DEFAULT_GT_SAMPLES}, --quick {accuracy.QUICK_GT_SAMPLES}); the "
                             f"far view uses {accuracy.FAR_GT_FACTOR} times as many")
    parser.add_argument("--gt-p-min", type=argtypes.p_min, metavar="P",
                        help=f"opacity cut-off of the ground truth (default {accuracy.GT_P_MIN:g}, below every "
                             f"configuration's, so that the p_min rows are judged against the faint tails too)")
    parser.add_argument("--photos", metavar="MODEL",
                        help="also measure this trained model (an INRIA model folder) at its test views against "
                             "their photos: PSNR and SSIM beside the float64 truth's")
    parser.add_argument("--photos-views", type=argtypes.whole_number(1, 1000), metavar="N",
                        help=f"how many test views --photos measures (default {accuracy.DEFAULT_PHOTO_VIEWS})")
    # No default paths: a run from any folder prints its report and writes nothing it was
    # not asked to (the docs' own files are named explicitly where they are regenerated).
    parser.add_argument("--report", metavar="PATH.md",
                        help=f"also write the markdown report there (the docs' is {accuracy.DEFAULT_REPORT})")
    parser.add_argument("--plot", metavar="PATH.png",
                        help=f"also write the plot of PSNR against time there (the docs' is {accuracy.DEFAULT_PLOT})")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing report and plot (the report's human verdict is kept)")
    argtypes.add_backend_option(parser)


def accuracy_command_line(args: argparse.Namespace) -> str:
    """The command that reproduces this run (options in a fixed order)."""
    return recorded_command("accuracy", args)


def accuracy_options(args: argparse.Namespace) -> accuracy.AccuracyOptions:
    scenes, notes = scene_choice(args, lambda: accuracy.default_scenes(args.quick))
    if args.report is not None and args.plot is not None:
        check_distinct(Path(args.report), Path(args.plot))
    report, plot = report_path(args.report, args.overwrite), plot_path(args.plot, args.overwrite)
    return accuracy.AccuracyOptions(
        scenes=scenes, **quick_or_default(args, accuracy, ("width", "repeat", "gt_samples")),
        report=report, plot=plot, overwrite=args.overwrite,
        gt_p_min=accuracy.GT_P_MIN if args.gt_p_min is None else args.gt_p_min,
        photos=args.photos,
        photos_views=accuracy.DEFAULT_PHOTO_VIEWS if args.photos_views is None else args.photos_views,
        **run_fields("accuracy", args, notes))


def _run_accuracy(args: argparse.Namespace, ctx) -> int:
    options = accuracy_options(args)
    print_notes(options.notes)
    results = accuracy.run_accuracy(options, ctx)
    report = accuracy_report.write_outputs(results, options.report, options.plot, options.overwrite)
    print("", flush=True)
    print(report, flush=True)
    print_written(options.report, options.plot)
    return 0


# --- stereo --------------------------------------------------------------------------------------


def _add_stereo_parser(kinds) -> None:
    parser = bench_parser(kinds, "stereo",
                           f"the demo scene only, {stereo_bench.QUICK_REPEAT} timed frames per preset (a few seconds)",
                           scenes=True)
    parser.add_argument("--presets", nargs="+", metavar="PRESET",
                        help="headset presets to time (default: all of " + ", ".join(camera_stereo.PRESETS) + ")")
    add_width_and_repeat(parser,
                          f"width of the views the sharing error is measured in (default {stereo_bench.DEFAULT_WIDTH})",
                          f"timed frames per preset (default {stereo_bench.DEFAULT_REPEAT}, --quick "
                          f"{stereo_bench.QUICK_REPEAT})")
    add_out_options(parser)


def stereo_command_line(args: argparse.Namespace) -> str:
    """The command that reproduces this run (options in a fixed order)."""
    return recorded_command("stereo", args)


def stereo_options(args: argparse.Namespace) -> stereo_bench.StereoOptions:
    """Checks everything that can be checked before any work (presets, the output path)."""
    presets = tuple(dict.fromkeys(args.presets or camera_stereo.PRESETS))
    for name in presets:
        if name not in camera_stereo.PRESETS:
            raise UserError(f"unknown headset preset '{name}': use one of {', '.join(camera_stereo.PRESETS)}")
    scenes, notes = scene_choice(args, lambda: ((DEMO,), []) if args.quick else accuracy.default_scenes(False))
    return stereo_bench.StereoOptions(
        scenes=scenes, presets=presets, width=args.width or stereo_bench.DEFAULT_WIDTH,
        **quick_or_default(args, stereo_bench, ("repeat",)), **reported_run_fields("stereo", args, notes))


# --- perf ----------------------------------------------------------------------------------------


def _add_perf_parser(kinds) -> None:
    parser = bench_parser(kinds, "perf",
                           "10k and 100k gaussians, one real scene, 1280x720 only (6 to 11 minutes on two CPU cores "
                           "with llvmpipe: 353 s in an earlier run, 10.6 minutes on 2026-11-28 on an idle machine)")
    parser.add_argument("--counts", nargs="+", type=argtypes.whole_number(1, 100_000_000), metavar="N",
                        help="generated scene sizes (default 10000 100000 1000000; --quick 10000 100000)")
    parser.add_argument("--sizes", nargs="+", choices=tuple(perf.SIZES), help="footprints (default: both)")
    parser.add_argument("--resolutions", nargs="+", type=argtypes.resolution, metavar="WxH",
                        help="default 1280x720 1920x1080; --quick 1280x720")
    parser.add_argument("--scenes", nargs="*", metavar="SCENE",
                        help="real scene files (or 'demo') instead of those found in ../shared/scenes; "
                             "none: generated scenes only")
    parser.add_argument("--frames", type=argtypes.whole_number(1, 100000), default=perf.DEFAULT_FRAMES, metavar="N",
                        help=f"timed frames per case, after one warm-up (default {perf.DEFAULT_FRAMES})")
    parser.add_argument("--report", metavar="PATH.md", help="also write a markdown report there")
    parser.add_argument("--plot", metavar="PATH.png", help="also write the plot of frame time against N there")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing report or plot")
    argtypes.add_backend_option(parser)


def perf_command_line(args: argparse.Namespace) -> str:
    """The command that reproduces this run (options in a fixed order, --frames only when not the default)."""
    return recorded_command("perf", args)


def perf_options(args: argparse.Namespace) -> perf.PerfOptions:
    """Checks everything that can be checked before any work."""
    scenes, notes = scene_choice(
        args, lambda: shared_scene_paths(perf.QUICK_REAL_SCENES if args.quick else perf.REAL_SCENES))
    report = report_path(args.report, args.overwrite)
    plot = plot_path(args.plot, args.overwrite)
    if report is not None and plot is not None:
        check_distinct(report, plot)
    return perf.PerfOptions(
        counts=tuple(dict.fromkeys(args.counts or (perf.QUICK_COUNTS if args.quick else perf.COUNTS))),
        sizes=tuple(dict.fromkeys(args.sizes or perf.SIZES)),
        resolutions=tuple(dict.fromkeys(args.resolutions
                                        or (perf.QUICK_RESOLUTIONS if args.quick else perf.RESOLUTIONS))),
        scenes=scenes, frames=args.frames, report=report, plot=plot, overwrite=args.overwrite,
        **run_fields("perf", args, notes))


def _run_perf(args: argparse.Namespace, ctx) -> int:
    options = perf_options(args)
    print_notes(options.notes)
    results = perf.run_perf(options, ctx)
    print("", flush=True)
    print(perf.format_report(results), flush=True)  # printed like every benchmark's; written when asked
    print_written(*perf.write_outputs(results))
    return 0


# --- order ---------------------------------------------------------------------------------------


def _add_order_parser(kinds) -> None:
    parser = bench_parser(kinds, "order",
                           f"the demo and one small real scene, {order_bench.QUICK_WIDTH} px wide, sweeps of "
                           f"{order_bench.QUICK_FRAMES} frames (30 to 60 s on two CPU cores with llvmpipe: 38 s on "
                           f"2026-11-28)", scenes=True)
    add_width_and_repeat(parser,
                          f"width of the views (default {order_bench.DEFAULT_WIDTH}, --quick {order_bench.QUICK_WIDTH})",
                          f"timed frames per mode (default {order_bench.DEFAULT_REPEAT}, --quick "
                          f"{order_bench.QUICK_REPEAT})")
    parser.add_argument("--frames", type=argtypes.whole_number(2, 10000), metavar="N",
                        help=f"frames per sweep (default {order_bench.DEFAULT_FRAMES}, --quick "
                             f"{order_bench.QUICK_FRAMES})")
    parser.add_argument("--gt-samples", type=argtypes.whole_number(1, 64), metavar="N",
                        help=f"ground-truth samples per pixel axis (default {order_bench.DEFAULT_GT_SAMPLES}, "
                             f"--quick {order_bench.QUICK_GT_SAMPLES})")
    add_out_options(parser, f"also write the markdown report there (the docs' is {order_bench.DEFAULT_REPORT})")


def order_options(args: argparse.Namespace) -> order_bench.OrderOptions:
    scenes, notes = scene_choice(args, lambda: accuracy.default_scenes(args.quick))
    return order_bench.OrderOptions(
        scenes=scenes, **quick_or_default(args, order_bench, ("width", "frames", "repeat", "gt_samples")),
        **reported_run_fields("order", args, notes))


# --- sort ----------------------------------------------------------------------------------------


def _add_sort_parser(kinds) -> None:
    parser = bench_parser(kinds, "sort",
                           f"stop at {count_label(sort_bench.QUICK_COUNTS[-1])}, {sort_bench.QUICK_REPEAT} runs; "
                           f"the freshness ({len(freshness.QUICK_SAMPLE_TIMES)} rendered frames per motion) "
                           f"for scenes up to {count_label(sort_bench.QUICK_FRESHNESS_MAX)} gaussians only (1 to 3 "
                           f"minutes on two CPU cores: 69 s on 2026-11-28)")
    parser.add_argument("--counts", nargs="+", type=argtypes.whole_number(1, 100_000_000), metavar="N",
                        help=f"scene sizes (default {SORT_COUNTS}; --quick stops at "
                             f"{count_label(sort_bench.QUICK_COUNTS[-1])})")
    parser.add_argument("--repeat", type=argtypes.whole_number(1, 1000), metavar="N",
                        help=f"timed runs per worker count (default {sort_bench.DEFAULT_REPEAT}, --quick "
                             f"{sort_bench.QUICK_REPEAT})")
    parser.add_argument("--no-freshness", action="store_true", help="times only: no rendered motion")
    parser.add_argument("--no-load", action="store_true",
                        help=f"no load measurements (by default each size from "
                             f"{count_label(sort_bench.LOAD_MIN)} up is written as an SH-3 PLY to a "
                             f"temporary folder, loaded in a fresh process and deleted)")
    add_out_options(parser)


def sort_options(args: argparse.Namespace) -> sort_bench.SortOptions:
    quick = args.quick
    return sort_bench.SortOptions(
        counts=tuple(dict.fromkeys(args.counts or (sort_bench.QUICK_COUNTS if quick else sort_bench.COUNTS))),
        **quick_or_default(args, sort_bench, ("repeat",)),
        sample_times=freshness.QUICK_SAMPLE_TIMES if quick else freshness.SAMPLE_TIMES,
        ladder_frames=freshness.QUICK_LADDER_FRAMES if quick else freshness.LADDER_FRAMES,
        freshness=not args.no_freshness, loads=not args.no_load,
        freshness_max=sort_bench.QUICK_FRESHNESS_MAX if quick else None,
        **run_fields("sort", args, []))


# --- formats ---------------------------------------------------------------------------------------


def _add_formats_parser(kinds) -> None:
    parser = bench_parser(kinds, "formats",
                           f"the demo and one real scene, {formats_bench.QUICK_WIDTH} px, "
                           f"{formats_bench.QUICK_REPEAT} loads each", scenes=True)
    parser.add_argument("--no-samples", action="store_true",
                        help="not the shared .spz sample against its INRIA PLY twin")
    add_width_and_repeat(parser, f"render width (default {formats_bench.DEFAULT_WIDTH}, --quick "
                                  f"{formats_bench.QUICK_WIDTH})",
                          f"loads timed per file (default {formats_bench.DEFAULT_REPEAT}, --quick "
                          f"{formats_bench.QUICK_REPEAT})")
    add_out_options(parser)


def _formats_scenes(quick: bool) -> tuple[tuple[str, ...], list[str]]:
    """The demo and the shared reference scenes found (the first alone with --quick)."""
    found, notes = shared_scene_paths(formats_bench.DEFAULT_SCENES[:1] if quick else formats_bench.DEFAULT_SCENES)
    return ("demo", *found), notes


def formats_options(args: argparse.Namespace) -> formats_bench.FormatsOptions:
    scenes, notes = scene_choice(args, lambda: _formats_scenes(args.quick))
    return formats_bench.FormatsOptions(
        scenes=scenes, samples=not args.no_samples, **quick_or_default(args, formats_bench, ("width", "repeat")),
        **run_fields("formats", args, notes))


# --- lod -------------------------------------------------------------------------------------------


def _add_lod_parser(kinds) -> None:
    parser = bench_parser(kinds, "lod",
                           f"{lod_bench.QUICK_WIDTH} px, {lod_bench.QUICK_REPEAT} timed frames per case "
                           f"(under a minute for a scene of 100k gaussians on two CPU cores)")
    parser.add_argument("--scenes", nargs="+", metavar="LOD.json",
                        help="streamed SOGs (lod-meta.json, or folders holding one) instead of every "
                             "lod-meta.json under ../shared/scenes")
    add_width_and_repeat(parser, f"width of the views (default {lod_bench.DEFAULT_WIDTH}, --quick "
                                  f"{lod_bench.QUICK_WIDTH})",
                          f"timed frames per case (default {lod_bench.DEFAULT_REPEAT}, --quick "
                          f"{lod_bench.QUICK_REPEAT})")
    parser.add_argument("--lod-distance", metavar="D",
                        type=argtypes.real_number(lambda v: 0 < v <= 1e30, "not a distance above 0"),
                        help="the distance (scene units) from which level 1 is chosen, as render's "
                             "--lod-distance (default: automatic, four half-diagonals of the median part)")
    add_out_options(parser)


def _lod_scenes() -> tuple[tuple[str, ...], list[str]]:
    """Every lod-meta.json under ../shared/scenes (sorted); UserError when there is none."""
    folder = shared_scenes_dir()
    found = [] if folder is None else sorted(os.path.relpath(p) for p in folder.rglob(LOD_META_NAME) if p.is_file())
    if not found:
        where = ("no ../shared/scenes folder" if folder is None
                 else f"no {LOD_META_NAME} under {os.path.relpath(folder)}")
        raise UserError(f"bench lod: {where}; pass --scenes LOD.json ... (a streamed SOG, e.g. one made by "
                        f"docs/lod_real_scene.sh)")
    return tuple(found), []


def lod_options(args: argparse.Namespace) -> lod_bench.LodOptions:
    scenes, notes = scene_choice(args, _lod_scenes)
    lod_bench.check_scenes(scenes)  # before any work
    return lod_bench.LodOptions(
        scenes=scenes, **quick_or_default(args, lod_bench, ("width", "repeat")), distance=args.lod_distance,
        **reported_run_fields("lod", args, notes))


# --- gpu -------------------------------------------------------------------------------------------


def _add_gpu_parser(kinds) -> None:
    quick_help = (f"one generated scene of {count_label(gpu_bench.QUICK_COUNTS[0])} gaussians, "
                  f"{gpu_bench.QUICK_MONO[0]}x{gpu_bench.QUICK_MONO[1]} and a stereo pair at 1/"
                  f"{gpu_bench.QUICK_EYE_SHRINK} of the headset's size, {gpu_bench.QUICK_FRAMES} timed "
                  f"frames: a smoke test (under 2 minutes on llvmpipe and two CPU cores)")
    parser = bench_parser(kinds, "gpu", quick_help)
    parser.add_argument("--counts", nargs="*", type=argtypes.whole_number(1, 100_000_000), metavar="N",
                        help="sizes of the generated scenes (default "
                             + ", ".join(count_label(n) for n in gpu_bench.COUNTS) + "; none: real scenes only)")
    parser.add_argument("--scenes", nargs="*", metavar="SCENE",
                        help="scene files (or 'demo') instead of the shared real scenes (none: generated only)")
    parser.add_argument("--frames", type=argtypes.whole_number(1, 1000), metavar="N",
                        help=f"timed frames per case (default {gpu_bench.DEFAULT_FRAMES}, --quick "
                             f"{gpu_bench.QUICK_FRAMES})")
    add_out_options(parser)


def gpu_options(args: argparse.Namespace) -> gpu_bench.GpuOptions:
    quick = args.quick
    if args.scenes is not None:
        scenes, notes = tuple(args.scenes), []
    elif quick:
        scenes, notes = gpu_bench.QUICK_REAL_SCENES, []
    else:
        scenes, notes = shared_scene_paths(gpu_bench.REAL_SCENES)
    counts = args.counts if args.counts is not None else (gpu_bench.QUICK_COUNTS if quick else gpu_bench.COUNTS)
    if not counts and not scenes:
        raise UserError("bench gpu: nothing to measure (no --counts and no scenes)")
    for scene in scenes:  # before any work
        if scene != DEMO and not os.path.exists(scene):
            raise UserError(f"{scene}: no such file")
    return gpu_bench.GpuOptions(
        counts=tuple(dict.fromkeys(counts)), scenes=scenes,
        mono=gpu_bench.QUICK_MONO if quick else gpu_bench.MONO,
        eye_shrink=gpu_bench.QUICK_EYE_SHRINK if quick else 1,
        frames=args.frames or (gpu_bench.QUICK_FRAMES if quick else gpu_bench.DEFAULT_FRAMES),
        **reported_run_fields("gpu", args, notes))


# --- xr --------------------------------------------------------------------------------------------


def _add_xr_parser(kinds) -> None:
    parser = bench_parser(kinds, "xr", f"{xr_bench.QUICK_FRAMES} timed frames of each kind (seconds with the demo "
                                       f"on llvmpipe)")
    parser.add_argument("scene", nargs="?", default=DEMO, metavar="SCENE",
                        help="the scene file (default: the built-in demo)")
    parser.add_argument("--frames", type=argtypes.whole_number(1, 100_000), metavar="N",
                        help=f"timed frames of each kind (default {xr_bench.DEFAULT_FRAMES}, --quick "
                             f"{xr_bench.QUICK_FRAMES}), after {xr_bench.WARMUP_FRAMES} untimed")
    parser.add_argument("--xr-scale", type=argtypes.real_in(0.1, 2.0, "times the runtime's recommended size"),
                        metavar="F", help="each eye's size as a fraction of the runtime's recommended size "
                                          "(default 1, as view --xr-scale)")
    parser.add_argument("--xr-no-depth", action="store_true",
                        help="no depth swapchains: the headset frame with depth is not measured")
    parser.add_argument("--out", metavar="PATH.md", help="also write the markdown report there")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out file")


def xr_options(args: argparse.Namespace) -> xr_bench.XrOptions:
    """Checks everything that can be checked before any work: the scene, pyopenxr and an
    active runtime (each a one-line error)."""
    if args.scene != DEMO and not os.path.exists(args.scene):
        raise UserError(f"{args.scene}: no such file")
    check_runtime()
    command_line = recorded_command("xr", args) + ("" if args.scene == DEMO else " " + shlex.quote(args.scene))
    return xr_bench.XrOptions(
        scene=args.scene, frames=args.frames or (xr_bench.QUICK_FRAMES if args.quick else xr_bench.DEFAULT_FRAMES),
        scale=args.xr_scale or 1.0, depth=not args.xr_no_depth, command_line=command_line,
        out=report_path(args.out, args.overwrite), overwrite=args.overwrite)


# --- edit ------------------------------------------------------------------------------------------


def _add_edit_parser(kinds) -> None:
    (width, height), default = edit_bench.QUICK_SIZE, edit_bench.DEFAULT_SIZE
    parser = kinds.add_parser("edit", help="what a selection of what the view shows costs against a frame",
                              description=edit_bench.ABOUT)
    parser.add_argument("scenes", nargs="*", metavar="SCENE",
                        help="scene files instead of the shared real scenes (then no generated scene unless --counts)")
    parser.add_argument("--quick", action="store_true",
                        help=f"one generated scene of {count_label(edit_bench.QUICK_COUNTS[0])} gaussians and one real "
                             f"scene at {width}x{height}, the shapes scaled to it (under a minute on llvmpipe)")
    parser.add_argument("--counts", nargs="*", type=argtypes.whole_number(1, 100_000_000), metavar="N",
                        help=f"generated scenes' sizes (default {' '.join(map(count_label, edit_bench.COUNTS))})")
    parser.add_argument("--size", type=argtypes.resolution, metavar="WxH",
                        help=f"the view's size (default {default[0]}x{default[1]}, --quick {width}x{height})")
    parser.add_argument("--json", metavar="PATH.json", help="also write the figures there")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --json file")
    argtypes.add_backend_option(parser)


def _run_edit(args: argparse.Namespace, ctx) -> int:
    """Exit status 1 where a selection differs from the float64 weighing outside the band."""
    size, json_path = args.size and ["x".join(map(str, args.size))], args.json and [args.json]
    flags = (("--quick", args.quick), ("--counts", args.counts), ("--size", size), ("--json", json_path),
             ("--gl-backend", args.gl_backend and [args.gl_backend]), ("--overwrite", args.overwrite))
    options = edit_bench.edit_options(
        scenes=tuple(args.scenes), counts=args.counts, quick=args.quick, size=args.size, json=args.json,
        overwrite=args.overwrite, gl_backend=args.gl_backend, command_line=edit_bench.command_line(flags, args.scenes))
    print_notes(options.notes)
    results = edit_bench.run_edit(options, ctx)
    show_report(edit_bench.format_report(results), None, False)
    if options.json is not None:
        edit_bench.write_json(results, options.json, options.overwrite)
        print_written(options.json)
    return 1 if results.failures else 0
