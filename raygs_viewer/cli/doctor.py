"""``raygs-viewer doctor``: the GL, what is correct and what is fast on this machine, in one
report to paste into a bug report (``bench.doctor``; docs/performance.md, "doctor").

Exit status 0 when every correctness row passes, 1 when one fails (its one-line summary
on stderr too), 2 on bad input (``error: ...``, before any work: an existing --report
without --overwrite, a folder that does not exist, an unknown option value).
"""

from __future__ import annotations

import argparse
import shlex
import sys

from raygs_viewer.bench import doctor_xr
from raygs_viewer.bench.common import write_report
from raygs_viewer.bench.doctor import doctor_options, format_report, run_doctor, summary_line
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.bench_shared import report_path

#: Measured on this project's machine (2 CPU cores, llvmpipe 15, Mesa 22.3.6) on 2026-12-05.
QUICK_TIME = "18 to 20 s"
FULL_TIME = "3.4 minutes (203 s: the renders 17 s, the sort rows 12 s, the speed rows 167 s, the probe 6 s)"
ABOUT = ("the GL (vendor, renderer, version, driver, context, the limits and extensions the viewer relies on and "
         "the fallback each missing one selects); correct here: the demo and the hard cases in every mode, "
         "precision, order, draw layout and sort this GL supports against the float64 reference, and the GPU "
         "sort against the CPU sort on 1M keys, random and adversarial; fast here: fill, a 1920x1080 frame and a "
         "Quest 3 pair of a generated 1M scene in today's defaults and each faster correct option, the CPU "
         f"against the GPU sort at 1M and 3M, the VR budget; what --sort auto and --precision auto choose; the "
         "active OpenXR runtime (its headset, views, sizes, swapchain formats, extensions, controller bindings) and "
         "a run of headset frames, in a child process. Exit "
         f"status 0 when every correctness row passes, 1 (with a one-line summary) when one fails, 2 on bad "
         f"input. The full run took {FULL_TIME} on two CPU cores with llvmpipe (2026-12-05); on a desktop GPU "
         f"it is meant to take under a minute")


def add_parsers(commands) -> None:
    """Adds ``doctor`` to the CLI's subparsers."""
    parser = commands.add_parser("doctor", help="what is correct and what is fast on this machine's GL: a report "
                                                "for a bug report", description=ABOUT)
    parser.set_defaults(run=command_doctor)
    parser.add_argument("--quick", action="store_true",
                        help=f"for CI and a first look: the hard cases in the render modes only, the sort rows at "
                             f"200k, bench gpu --quick's sizes, the sorts timed at 100k and 300k ({QUICK_TIME} on "
                             f"two CPU cores with llvmpipe, 2026-12-05)")
    parser.add_argument("--case", action="append", metavar="NAME", dest="cases",
                        help="only this correctness case (repeat for more; 'demo' or a hard case's name, as the "
                             "report's rows name them): re-checks what failed without the rest")
    parser.add_argument("--no-speed", action="store_true",
                        help="the correctness sections only (the GL, the renders, the sort rows): no speed rows, "
                             "no auto choices and no headset frames (the XR section describes the runtime), for a "
                             "check that needs no timing")
    parser.add_argument("--xr-only", action="store_true",
                        help="the XR section alone (the active OpenXR runtime and its headset frames): no GL checks, "
                             "no correctness rows")
    parser.add_argument("--xr-frames", type=argtypes.whole_number(0, 10_000), metavar="N",
                        help=f"headset frames the XR section draws (default {doctor_xr.FRAMES}, --quick "
                             f"{doctor_xr.QUICK_FRAMES}, --no-speed 0; 0: the runtime described only)")
    parser.add_argument("--report", metavar="FILE.md",
                        help="also write the report there (never over an existing file without --overwrite)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --report file")
    argtypes.add_backend_option(parser)


def recorded_command(args: argparse.Namespace) -> str:
    parts = ["raygs-viewer", "doctor"] + (["--quick"] if args.quick else [])
    parts += ["--no-speed"] if args.no_speed else []
    parts += ["--xr-only"] if args.xr_only else []
    parts += ["--xr-frames", str(args.xr_frames)] if args.xr_frames is not None else []
    for name in args.cases or ():
        parts += ["--case", name]
    if args.gl_backend:
        parts += ["--gl-backend", args.gl_backend]
    return shlex.join(parts)


def command_doctor(args: argparse.Namespace, ctx=None, **changes) -> int:
    """Runs ``doctor``: the report printed (and written to --report), then the summary
    line; the exit status. ``ctx``: a GL context to use (tests); ``changes``: fields of
    ``bench.doctor.DoctorOptions`` over the command line's (tests make a run small)."""
    out = report_path(args.report, args.overwrite)  # before any work
    chosen = {"cases": tuple(dict.fromkeys(args.cases))} if args.cases else {}
    if args.no_speed:
        chosen |= {"speed": None, "auto": False, "xr_frames": 0}
    if args.xr_only:
        chosen |= {"xr_only": True}
    if args.xr_frames is not None:
        chosen |= {"xr_frames": args.xr_frames}
    options = doctor_options(args.quick, command_line=recorded_command(args), gl_backend=args.gl_backend,
                             **{**chosen, **changes})
    result = run_doctor(options, ctx)
    report = format_report(result)
    print("", flush=True)
    print(report, flush=True)
    if out is not None:
        write_report(out, report, args.overwrite)
        print(f"wrote {out}", flush=True)
    line = summary_line(result)
    print(line, flush=True)
    if result.status:
        print(line, file=sys.stderr, flush=True)
    return result.status
