"""``raygs-viewer doctor``: what a user runs on their machine and pastes into a bug report
(docs/performance.md, "doctor").

In one run, on one headless GL context:

1. the GL and the limits and extensions the viewer relies on, with the fallback each
   missing one selects (:mod:`raygs_viewer.bench.doctor_gl`);
2. correct here: the demo and the hard cases in every setting this GL supports against
   the float64 reference (:mod:`raygs_viewer.bench.doctor_checks`), and the GPU sort
   against the CPU sort (:mod:`raygs_viewer.bench.doctor_sort`);
3. fast here: fill, a frame and a stereo pair in today's defaults and each faster
   correct option, the CPU against the GPU sort, the VR budget
   (:mod:`raygs_viewer.bench.doctor_speed`);
4. what ``--sort auto`` and ``--precision auto`` choose here (``render.gl.probe``);
5. the active OpenXR runtime and a run of headset frames, in a child process of its own
   (:mod:`raygs_viewer.bench.doctor_xr`); ``xr_only``: this section alone.

Every correctness row passes: exit status 0; else 1, and one line names the rows that
failed. ``quick``: smaller sizes (:func:`doctor_options`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, TextIO

from raygs_viewer.bench import doctor_sort, doctor_xr
from raygs_viewer.bench.common import fmt_error, gl_context, printer, run_date, software_renderer
from raygs_viewer.bench.doctor_checks import (
    DEMO,
    QUICK_HARD_AXES,
    VARIANTS,
    CheckRow,
    check_cases,
    check_renders,
    error_words,
)
from raygs_viewer.bench.doctor_gl import gl_tables
from raygs_viewer.bench.doctor_speed import (
    FULL_SPEED,
    QUICK_SPEED,
    SpeedResult,
    SpeedSizes,
    measure_speed,
    speed_tables,
)
from raygs_viewer.bench.gpu import OPTIONS
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.gl.plan import DEFAULT_DRAW_LAYOUT
from raygs_viewer.render.gl.probe import measure_profile
from raygs_viewer.render.gl.profile import gl_identity, load_profile, profile_path, remember_profile
from raygs_viewer.render.sorting import measured_sort

AXES = tuple(dict.fromkeys(variant.axis for variant in VARIANTS))
#: The scene size the sort choice is shown for.
AUTO_SORT_COUNT = 1_000_000
#: --quick's probe, where no profile is remembered: smaller than the window's, so not remembered.
QUICK_PROBE = {"sort_counts": (100_000,), "blend_count": 50_000, "blend_size": (320, 180), "repeats": 2}
#: The failing rows the summary line names before "and N more", and the characters of each one's reasons.
NAMED_FAILURES = 3
SUMMARY_REASON = 160


@dataclass(frozen=True)
class DoctorOptions:
    """What a run measures: ``cases`` (None: the demo and every hard case), the axes
    each case varies (the demo's, the hard cases'), the sort rows' size (0: none) and
    scenes (None: all), the speed rows' sizes (None: none), ``auto``: the auto defaults'
    section; ``quick`` as given, for the report and the probe; ``xr_frames``: the headset
    frames the XR section draws (0: the runtime described only); ``xr_only``: the XR
    section alone (no GL context of doctor's own, no correctness rows)."""

    quick: bool = False
    command_line: str = "raygs-viewer doctor"
    gl_backend: str | None = None
    cases: tuple[str, ...] | None = None
    demo_axes: tuple[str, ...] = AXES
    hard_axes: tuple[str, ...] = AXES
    sort_count: int = doctor_sort.SORT_COUNT
    sort_scenes: tuple[str, ...] | None = None
    speed: SpeedSizes | None = FULL_SPEED
    auto: bool = True
    xr_frames: int = doctor_xr.FRAMES
    xr_only: bool = False


def doctor_options(quick: bool, **changes) -> DoctorOptions:
    """The full run, or ``quick``'s (every axis for the demo, the modes for the hard
    cases, the sort rows at 200k, ``bench gpu --quick``'s sizes, fewer headset frames);
    ``changes`` on top."""
    sizes = {"hard_axes": QUICK_HARD_AXES, "sort_count": doctor_sort.QUICK_SORT_COUNT, "speed": QUICK_SPEED,
             "xr_frames": doctor_xr.QUICK_FRAMES} if quick else {}
    return DoctorOptions(quick=quick, **{**sizes, **changes})


@dataclass
class DoctorResult:
    options: DoctorOptions
    device: str
    date: str
    gl: list[str]
    checks: list[CheckRow]
    sorts: list[doctor_sort.SortRow]
    speed: SpeedResult | None
    auto: list[str]
    seconds: dict[str, float] = field(default_factory=dict)
    stopped: dict[str, str] = field(default_factory=dict)   # section -> the error that ended it
    xr: list[str] = field(default_factory=list)             # the XR section's lines (doctor_xr)

    @property
    def judged(self) -> list:
        """The correctness rows that were held to a tolerance (not "not supported here")."""
        return [row for row in (*self.checks, *self.sorts) if row.judged]

    @property
    def failed(self) -> list:
        return [row for row in self.judged if row.failed]

    @property
    def status(self) -> int:
        return 1 if self.failed else 0


def run_doctor(options: DoctorOptions, ctx=None, out: TextIO | None = None) -> DoctorResult:
    """Every section (the module's docstring), a progress line per case and figure."""
    say = printer(out)
    seconds: dict[str, float] = {}
    stopped: dict[str, str] = {}

    def timed(name: str, work: Callable[[], object], guarded: bool = False):
        """``work()``, timed; ``guarded``: an error ends the section (said in the report), not the run."""
        began = time.perf_counter()
        try:
            return work()
        except Exception as exc:  # noqa: BLE001 - a figure that cannot be measured here is reported as such
            if not guarded:
                raise
            stopped[name] = one_line(exc) if isinstance(exc, UserError) else error_words(exc)
            say(f"{name}: stopped: {stopped[name]}")
            return None
        finally:
            seconds[name] = time.perf_counter() - began

    cases = check_cases(options.cases)  # unknown names: before any work
    device, gl, checks, sorts, speed, auto = "", [], [], [], None, []
    if not options.xr_only:
        with gl_context(ctx, options.gl_backend) as ctx:
            device = context_description(ctx)
            say(f"doctor: {device}")
            gl = timed("GL", lambda: gl_tables(ctx))
            checks = timed("renders", lambda: check_renders(
                ctx, cases, lambda name: options.demo_axes if name == DEMO else options.hard_axes, say))
            sorts = [] if not options.sort_count else timed(
                "sorts", lambda: doctor_sort.check_sorts(ctx, options.sort_count, say, options.sort_scenes))
            speed = None if options.speed is None else timed("speed", lambda: measure_speed(
                ctx, options.speed, software_renderer(device), lambda name: option_problem(name, checks), say),
                True)
            auto = (timed("auto", lambda: auto_choices_section(ctx, options.quick, say), True) or []) \
                if options.auto else []
    xr = doctor_xr.xr_section(options.xr_frames, say)  # after doctor's own context is gone; never raises
    if xr.ran:
        seconds["XR"] = xr.seconds
    return DoctorResult(options, device, run_date(), gl, checks, sorts, speed, auto, seconds, stopped, xr.lines)


def option_problem(name: str, checks: list[CheckRow]) -> str | None:
    """Why ``bench gpu``'s option ``name`` is not measured: its precision's or its draw
    layout's correctness rows failed or cannot run here; None where they passed."""
    _, changes, layout = next(option for option in OPTIONS if option[0] == name)
    mine = [row for row in checks
            if (row.variant.axis == "precision" and row.variant.settings.precision == changes.get("precision"))
            or (row.variant.axis == "draw layout" and layout != DEFAULT_DRAW_LAYOUT and row.variant.layout == layout)]
    unsupported = [row for row in mine if not row.supported]
    if unsupported:
        return f"not supported here: {unsupported[0].problem}"
    failed = [row for row in mine if row.failed]
    if failed:
        return f"{len(failed)} of its correctness rows failed here ({failed[0].label})"
    return None


def auto_choices_section(ctx, quick: bool, say: Callable[[str], None]) -> list[str]:
    """What ``--sort auto`` and ``--precision auto`` choose on this GL, each with its why
    (``render.gl.profile``): from a profile measured now (``render.gl.probe``) and
    remembered, as the window would; ``quick`` uses the remembered one where there is
    one, else measures a smaller probe (:data:`QUICK_PROBE`) that it does not remember."""
    profile, warning = load_profile(*gl_identity(ctx))
    notes = [warning] if warning else []
    if quick and profile is not None:
        source = f"the profile remembered in `{profile_path()}`, measured {profile.measured}"
    else:
        say("auto: measuring this GL's profile (render.gl.probe)")
        profile = measure_profile(ctx, **(QUICK_PROBE if quick else {}))
        if quick:
            source = ("a smaller probe measured now (--quick; not remembered: the window and a full `doctor` "
                      "measure the full one)")
        else:
            problem = remember_profile(profile)
            notes += [problem] if problem else []
            source = f"a probe measured now, remembered in `{profile_path()}`"
    choices = [measured_sort(profile, ctx, AUTO_SORT_COUNT).why, profile.precision_choice().why]
    say(f"auto: {choices[0]}")
    say(f"auto: {choices[1]}")
    return [f"From {source}:", ""] + [f"- {line}" for line in choices + notes]


# --- output ----------------------------------------------------------------------------------------

def _failure(row) -> str:
    reasons = (", " if isinstance(row, CheckRow) else "; ").join(row.faults)
    return f"{row.label} ({reasons if len(reasons) <= SUMMARY_REASON else reasons[:SUMMARY_REASON - 3] + '...'})"


def summary_line(result: DoctorResult) -> str:
    """``doctor: all 57 correctness rows passed`` or ``doctor: 1 of 57 correctness rows
    failed: demo, draw layout indexed (max error 0.31 > 0.008)``."""
    judged, failed = result.judged, result.failed
    if result.options.xr_only:
        return "doctor: the XR section only (--xr-only): no correctness rows checked"
    if not failed:
        return f"doctor: all {len(judged)} correctness rows passed"
    named = "; ".join(_failure(row) for row in failed[:NAMED_FAILURES])
    more = f"; and {len(failed) - NAMED_FAILURES} more" if len(failed) > NAMED_FAILURES else ""
    return f"doctor: {len(failed)} of {len(judged)} correctness rows failed: {named}{more}"


def _result(row: CheckRow) -> str:
    if not row.supported:
        return f"not supported here: {row.problem}"
    if row.unbounded:
        return row.unbounded
    return "**FAIL**: " + "; ".join(row.faults) if row.failed else "pass"


def _sort_result(row: doctor_sort.SortRow) -> str:
    if not row.supported:
        return f"not supported here: {row.problem}"
    return "**FAIL**: " + "; ".join(row.faults) if row.failed else "identical"


def format_report(result: DoctorResult) -> str:
    options = result.options
    took = ", ".join(f"{name} {value:.1f} s" for name, value in result.seconds.items())
    timing = f", {sum(result.seconds.values()):.0f} s ({took})" if result.seconds else ""
    lines = ["# raygs-viewer doctor", "", f"`{options.command_line}` on {result.date}{timing}.", "",
             f"**{summary_line(result)}**"]
    if not options.xr_only:
        lines += [""] + _gl_and_renders(result)
    if result.sorts:
        lines += ["", "## Correct here: the GPU sort against the CPU sort", "",
                  "Generated scenes (`bench.doctor_sort`): both keys over one cull, quantised (auto) and float keys; "
                  "identical means the same indices to the element.", "",
                  "| scene | gaussians | keys | kept (depth, distance) | result |", "|---|---:|---|---:|---|"]
        for row in result.sorts:
            kept = ", ".join(f"{n:,}" for n in row.kept)
            lines.append(f"| {row.scene} | {row.count:,} | {row.method} | {kept} | {_sort_result(row)} |")
    if "speed" in result.stopped:
        lines += ["", "## Fast here", "", f"Not measured: {result.stopped['speed']}"]
    if result.speed is not None:
        clock = "the CPU's, the GL drained (a software renderer)" if result.speed.drained else "GPU timer queries"
        lines += ["", "## Fast here", "",
                  f"Clock: {clock}; medians of {result.speed.frames} moving-view frame(s) (`bench gpu`'s).", ""]
        lines += speed_tables(result.speed)
    if result.auto or "auto" in result.stopped:
        lines += ["", "## What `--sort auto` and `--precision auto` choose here", ""]
        lines += result.auto or [f"Not measured: {result.stopped['auto']}"]
    lines += ["", "## XR: the headset runtime (OpenXR)", ""] + result.xr
    return "\n".join(lines) + "\n"


def _gl_and_renders(result: DoctorResult) -> list[str]:
    """The GL's tables and the renders' rows."""
    lines = ["## The GL", ""] + result.gl
    lines += ["", "## Correct here: renders against the float64 reference", "",
              "Each case drawn small by GL and by the float64 reference, one axis at a time varied from the base "
              "(mode, blend precision, order, draw layout, sort); the error is the largest over pixels and "
              "channels (RGBA), held to the tolerance the tests use (`render.tolerance`).", "",
              "| case | setting | max error | tolerance | result |", "|---|---|---:|---|---|"]
    for row in result.checks:
        error = "" if row.agreement is None else fmt_error(row.agreement.max)
        limit = "" if row.tolerance is None else row.tolerance.words()
        lines.append(f"| {row.case} | {row.variant.label} | {error} | {limit} | {_result(row)} |")
    return lines
