"""``raygs-viewer bench xr``: what a headset frame costs against the active OpenXR runtime,
beside a mono frame of one eye measured in the same run.

A **headset frame** is what the window does each frame in the headset
(``viewer.headset``): ``xrWaitFrame`` (the runtime paces the app), ``xrBeginFrame``, the
eyes located, one sort from their midpoint culled for both (``render.sorting.exact_order``),
both eyes drawn into the swapchain images (``xr.eyes.EyeDrawer``), the GL drained,
``xrEndFrame``. The runtime's wait is no work of the viewer's: a runtime holds the app
back to its display's pace (Monado's null compositor at 20 Hz, and a longer period once
frames come late), so a headset frame's wall time is mostly waiting. Its **cost** is the
work outside ``xrWaitFrame``: from the return of that call (timed by :class:`WaitClock`
around the session's own call) to the return of ``xrEndFrame``.

The **mono frame**: the same scene, settings and camera as the left eye of the headset
frame before it, one sort for that camera alone, drawn into an offscreen 8-bit target of
the eye's size (the swapchain images' kind), the GL drained; no session. Both eyes' GL
work is drained in the headset frame too (before ``xrEndFrame``, which on Monado drains
it anyway), so each time holds its GPU work on any runtime. The kinds are interleaved
frame by frame (headset, [headset with depth,] mono, ...), so the machine's drift hits
all alike; the ratio headset / mono is what the second eye and the headset's own work
add (the goal: at most :data:`GOAL_RATIO`). Where the runtime takes depth
(``XR_KHR_composition_layer_depth``; the window's depth toggle, off by default) a third kind, the
headset frame with each eye's depth drawn and submitted, is interleaved too.

The GL context is one the runtime can bind and that is current on this thread
(``bench.xr_session.headset_context``: a headless EGL context where the runtime offers
``XR_MNDX_egl_enable``, Monado and WiVRn; else a hidden GLFW window's GLX context under
X11, SteamVR). Output: progress and ``xr KIND KEY VALUE`` lines while it runs, then a
markdown report (``--out`` writes it).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TextIO

import moderngl
import numpy as np

from raygs_viewer.bench import common
from raygs_viewer.bench.xr_session import (
    SessionFacts,
    WaitClock,
    end_session,
    headset_context,
    session_facts,
    start_session,
)
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import DEFAULT_SCENE_SCALE
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.context import (
    context_description,
)
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.targets import FloatTarget, sized
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.xr.eyes import EyeDrawer, HeadsetEyes, headset_eyes
from raygs_viewer.xr.room import Room, midpoint, room_at_view
from raygs_viewer.xr.runtime import check_runtime
from raygs_viewer.xr.session import HeadsetSession
from raygs_viewer.xr.swapchain import format_name, kept_stdin

DEFAULT_FRAMES, QUICK_FRAMES = 40, 8
#: Untimed frames of each kind first: shaders compile, the targets and the runtime settle.
WARMUP_FRAMES = 2
#: What a headset frame may cost against a mono frame of one eye (two eyes, one sort).
GOAL_RATIO = 2.1
HEADSET, HEADSET_DEPTH, MONO = "headset", "headset+depth", "mono"
TITLES = {HEADSET: "headset", HEADSET_DEPTH: "headset, with depth", MONO: "mono (left eye's camera, offscreen)"}
SOFTWARE_NOTE = ("This is a software OpenGL renderer (on the CPU): its timer queries read only part of the work "
                 "(docs/performance.md), so the GPU columns say little; the drained times and the ratio are "
                 "the result.")


# --- the frames ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class HeadsetTimes:
    """One headset frame, in seconds. ``work``: from the return of ``xrWaitFrame`` to the
    return of ``xrEndFrame`` (the frame's cost); ``waited``: in ``xrWaitFrame``; ``sort``;
    ``draw``: acquiring the images and drawing both eyes, the GL drained; ``submit``:
    ``xrEndFrame`` with the images' release; ``interval``: since the last frame's wait
    returned (NaN for the first); ``period``: the runtime's display period. ``layered``:
    the eyes' layer went (else the frame was skipped: not to be rendered, no eyes
    located, an image not given); ``late``: the predicted display time moved on by more
    than one and a half periods since the last frame (a display frame missed)."""

    work: float
    waited: float
    sort: float
    draw: float
    submit: float
    interval: float
    period: float
    layered: bool
    late: bool


class HeadsetFrames:
    """Headset frames of one scene on a running session, drawn as the window draws them
    (the module docstring). The room starts where ``view`` is (its image's up as the
    scene's up, :data:`DEFAULT_SCENE_SCALE` metres per unit); :attr:`left_eye` is the left
    eye of the newest frame that located its eyes."""

    def __init__(self, session: HeadsetSession, clock: WaitClock, *, renderer: GLRenderer, sorter: DepthSorter,
                 view: Camera, settings: RenderSettings):
        self.session, self.clock = session, clock
        self.renderer, self.sorter, self.settings = renderer, sorter, settings
        self.view = view
        self.room: Room | None = None
        self.left_eye: Camera | None = None
        self.ended_why: str | None = None
        self._last_display: int | None = None
        self._last_return = math.nan

    def draw(self, drawer: EyeDrawer, *, depth: bool) -> HeadsetTimes | None:
        """One headset frame (``depth``: each eye's depth too, where the session has
        depth swapchains); None when the session is no longer running (:attr:`ended_why`)."""
        session = self.session
        for news in session.poll():
            if news.error:
                self.ended_why = news.text
        if not session.running:
            self.ended_why = self.ended_why or f"the headset session left the running state ({session.state})"
            return None
        began = time.perf_counter()
        frame = session.wait()
        returned = time.perf_counter()
        if frame is None:  # the session failed in the wait
            self.ended_why = self.ended_why or "the headset session was lost while waiting for a frame"
            return None
        late = self._last_display is not None and frame.period > 0 and \
            frame.display_time - self._last_display > 1.5 * frame.period * 1e9
        interval, self._last_display, self._last_return = returned - self._last_return, frame.display_time, returned
        eyes = self._eyes(frame) if frame.should_render else None
        sorted_at, drawn, with_depth = returned, False, False
        if eyes is not None:
            order = exact_order(self.sorter, eyes.midpoint, self.settings, cull_cameras=eyes.cameras)
            sorted_at = time.perf_counter()
            images = session.acquire()
            if images is not None:
                colours, depths = images
                with_depth = depth and bool(depths)
                drawer.draw(self.renderer, colours, depths, eyes, settings=self.settings, order=order,
                            depth=with_depth, units_per_metre=self.room.units_per_metre)
                self.renderer.ctx.finish()
                drawn = True
        drawn_at = time.perf_counter()
        layered = session.submit(frame, drawn=drawn, depth=with_depth)
        ended = time.perf_counter()
        return HeadsetTimes(ended - began - self.clock.waited, self.clock.waited, sorted_at - returned,
                            drawn_at - sorted_at, ended - drawn_at, interval, frame.period, layered, late)

    def _eyes(self, frame) -> HeadsetEyes | None:
        if frame.views is None:
            return None
        if self.room is None:
            head = midpoint(frame.views[0][0], frame.views[1][0])
            up = -np.asarray(self.view.R, np.float64)[1]
            self.room = room_at_view(self.view, head, up, 1.0 / DEFAULT_SCENE_SCALE)
        eyes = headset_eyes(frame, self.room, self.session.sizes)
        if eyes is not None:
            self.left_eye = eyes.cameras[0]
        return eyes


@dataclass(frozen=True)
class MonoTimes:
    """One mono frame, in seconds: ``work`` in all, ``sort``, ``draw`` (the GL drained)."""

    work: float
    sort: float
    draw: float


class MonoFrames:
    """The mono frame (module docstring): one sort for ``camera`` alone, drawn into an
    offscreen 8-bit target of its size, the GL drained; under a GPU timer."""

    def __init__(self, renderer: GLRenderer, sorter: DepthSorter, settings: RenderSettings):
        self.renderer, self.sorter, self.settings = renderer, sorter, settings
        self.timer = GpuTimer(renderer.ctx)
        self.target: FloatTarget | None = None

    def draw(self, camera: Camera) -> MonoTimes:
        ctx = self.renderer.ctx
        began = time.perf_counter()
        order = exact_order(self.sorter, camera, self.settings)
        sorted_at = time.perf_counter()
        self.target = sized(self.target, ctx, camera.width, camera.height, dtype="f1")
        with self.timer.measure():
            self.renderer.render_into(self.target, camera, self.settings, order)
        ctx.finish()
        ended = time.perf_counter()
        return MonoTimes(ended - began, sorted_at - began, ended - sorted_at)

    def release(self) -> None:
        if self.target is not None:
            self.target.release()
            self.target = None


def timer_ms(timer: GpuTimer, skip: int) -> list[float]:
    """Every time ``timer`` measured after the first ``skip``, in ms (its pending ones read)."""
    timer.flush()
    return [seconds * 1e3 for seconds in list(timer.history)[skip:]]


@dataclass(frozen=True)
class HeadsetSummary:
    """Medians (ms) of one kind's timed headset frames, and its counts."""

    frames: int
    work_ms: float
    waited_ms: float
    sort_ms: float
    draw_ms: float
    submit_ms: float
    interval_ms: float
    period_ms: float
    period_range_ms: tuple[float, float]
    gpu_left_ms: float
    gpu_right_ms: float
    skipped: int
    late: int


def summarize(times: list[HeadsetTimes], drawer: EyeDrawer, *, skip: int) -> HeadsetSummary:
    """``times``' medians and counts; each eye's GPU time from ``drawer``'s timers, past
    the first ``skip`` frames it measured."""
    periods = [t.period * 1e3 for t in times] or [math.nan]
    left, right = (timer_ms(timer, skip) for timer in drawer.timers)
    return HeadsetSummary(len(times), median_ms(t.work for t in times), median_ms(t.waited for t in times),
                          median_ms(t.sort for t in times), median_ms(t.draw for t in times),
                          median_ms(t.submit for t in times), median_ms(t.interval for t in times),
                          common.median(periods), (min(periods), max(periods)), common.median(left),
                          common.median(right), sum(not t.layered for t in times), sum(t.late for t in times))


def median_ms(seconds) -> float:
    """The median of finite ``seconds``, in ms (NaN for none)."""
    return common.median([value * 1e3 for value in seconds])


@dataclass(frozen=True)
class MonoSummary:
    """Medians (ms) of the timed mono frames."""

    frames: int
    work_ms: float
    sort_ms: float
    draw_ms: float
    gpu_ms: float


# --- running it ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class XrOptions(common.ReportedRunOptions):
    scene: str
    frames: int
    scale: float = 1.0
    depth: bool = True
    command_line: str = "raygs-viewer bench xr"


@dataclass
class XrResults:
    options: XrOptions
    scene: str                              # its description
    facts: SessionFacts
    headset: dict[str, HeadsetSummary]      # by kind: HEADSET, HEADSET_DEPTH
    mono: MonoSummary
    machine: str
    cpu_count: int
    date: str
    notes: list[str]
    seconds: float = math.nan

    def ratio(self, kind: str = HEADSET) -> float:
        """The headset frame's cost (its work outside xrWaitFrame) over the mono frame's."""
        summary = self.headset.get(kind)
        return summary.work_ms / self.mono.work_ms if summary is not None and self.mono.work_ms > 0 else math.nan


def summary_lines(kind: str, summary: HeadsetSummary) -> list[str]:
    """``xr KIND KEY VALUE`` lines of one kind."""
    values = {"work-ms": summary.work_ms, "waited-ms": summary.waited_ms, "sort-ms": summary.sort_ms,
              "draw-ms": summary.draw_ms, "submit-ms": summary.submit_ms, "gpu-left-ms": summary.gpu_left_ms,
              "gpu-right-ms": summary.gpu_right_ms, "period-ms": summary.period_ms}
    lines = [f"xr {kind} {key} {value:.6g}" for key, value in values.items()]
    return lines + [f"xr {kind} skipped {summary.skipped}", f"xr {kind} late {summary.late}"]


def run_xr(options: XrOptions, given: moderngl.Context | None = None, out: TextIO | None = None) -> XrResults:
    """The interleaved run (module docstring); progress and the ``xr ...`` lines to ``out``
    (stdout). ``given``: a context to use, current and one the runtime can bind (default:
    :func:`headset_context`'s)."""
    say = common.printer(out)
    check_runtime()
    item = common.load_scenes((options.scene,))[0]
    started = time.perf_counter()
    with kept_stdin(), headset_context(given) as ctx:
        machine = context_description(ctx)
        with common.scene_renderer(ctx, item.scene) as (renderer, sorter):
            session, clock = start_session(ctx, scale=options.scale, depth=options.depth)
            try:
                facts = session_facts(session)
                kinds = (HEADSET, HEADSET_DEPTH) if session.depth else (HEADSET,)
                say(f"bench xr: {facts.runtime} {facts.version}, {facts.system}; {item.name} ({item.description}); "
                    f"{facts.sizes[0][0]}x{facts.sizes[0][1]} per eye; {options.frames} timed frames of each of "
                    f"{', '.join(kinds)} and mono, interleaved, after {WARMUP_FRAMES} untimed; on {machine}")
                frames = HeadsetFrames(session, clock, renderer=renderer, sorter=sorter, view=item.camera,
                                       settings=RenderSettings())
                headset, mono = _measure(frames, kinds, options.frames, say)
            finally:
                end_session(session)
    for kind, summary in headset.items():
        for line in summary_lines(kind, summary):
            say(line)
    for key, value in (("work-ms", mono.work_ms), ("sort-ms", mono.sort_ms), ("draw-ms", mono.draw_ms),
                       ("gpu-ms", mono.gpu_ms)):
        say(f"xr mono {key} {value:.6g}")
    finished = common.finished_run_fields("xr", started, machine=machine, notes=options.notes,
                                          software_note=SOFTWARE_NOTE, say=say)
    results = XrResults(options, f"{item.name}: {item.description}", facts, headset, mono, **finished)
    for kind in headset:
        say(f"xr {kind} ratio-to-mono {results.ratio(kind):.6g}")
    return results


def _measure(frames: HeadsetFrames, kinds: tuple[str, ...], count: int,
             say) -> tuple[dict[str, HeadsetSummary], MonoSummary]:
    """Each headset kind's summary and the mono frames', ``count`` timed rounds of each."""
    drawers = {kind: EyeDrawer(frames.renderer.ctx) for kind in kinds}
    mono = MonoFrames(frames.renderer, frames.sorter, frames.settings)
    try:
        timed = _interleave(frames, drawers, mono, count, say)
        monos = timed[MONO]
        mono_summary = MonoSummary(len(monos), median_ms(t.work for t in monos), median_ms(t.sort for t in monos),
                                   median_ms(t.draw for t in monos),
                                   common.median(timer_ms(mono.timer, WARMUP_FRAMES)))
        return {kind: summarize(timed[kind], drawers[kind], skip=WARMUP_FRAMES) for kind in kinds}, mono_summary
    finally:
        mono.release()


def _interleave(frames: HeadsetFrames, drawers: dict[str, EyeDrawer], mono: MonoFrames, count: int,
                say) -> dict[str, list]:
    """{kind: the timed frames' HeadsetTimes; MONO: their MonoTimes}: per round each headset kind,
    then the mono frame with the last left eye; :data:`WARMUP_FRAMES` rounds untimed."""
    timed: dict[str, list] = {kind: [] for kind in (*drawers, MONO)}
    for index in range(WARMUP_FRAMES + count):
        for kind, drawer in drawers.items():
            times = frames.draw(drawer, depth=kind == HEADSET_DEPTH)
            if times is None:
                raise UserError(f"the headset session ended after {index} of {WARMUP_FRAMES + count} rounds: "
                                f"{frames.ended_why}")
            if index >= WARMUP_FRAMES:
                timed[kind].append(times)
        if frames.left_eye is None:
            raise UserError("the OpenXR runtime located no eyes (no tracking): nothing to draw")
        times = mono.draw(frames.left_eye)
        if index >= WARMUP_FRAMES:
            timed[MONO].append(times)
        done = index + 1 - WARMUP_FRAMES
        if done > 0 and (done % 10 == 0 or done == count):
            say(f"bench xr: {done} of {count} timed rounds")
    return timed


# --- the report ---------------------------------------------------------------------------------

COLUMNS = ("frame", "cost (median)", "sort", "draw", "xrEndFrame", "waited in xrWaitFrame", "GPU left eye",
           "GPU right eye", "skipped", "late", "to mono")


def _verdict(ratio: float) -> str:
    if not math.isfinite(ratio):
        return "not measured"
    return f"goal at most {GOAL_RATIO:g}: {'met' if ratio <= GOAL_RATIO else 'missed'}"


def format_report(results: XrResults) -> str:
    """The markdown report: where and what ran, the ratio, the table of the kinds."""
    options, facts = results.options, results.facts
    width, height = facts.sizes[0]
    depth = f"depth swapchains {format_name(facts.depth_format)}" if facts.depth_format else "no depth layer"
    runtime = (f"{facts.runtime} {facts.version}, {facts.system}; {facts.binding.upper()} binding; "
               f"{format_name(facts.colour_format)} swapchains, {width}x{height} per eye; {depth}")
    ratio = results.ratio()
    how = ("A headset frame's wall time includes the runtime's wait: `xrWaitFrame` holds the app back to the "
           "display's pace, so the cost of a headset frame is its work outside `xrWaitFrame`: `xrBeginFrame`, the "
           "eyes located, one sort from their midpoint culled for both, both eyes drawn into the swapchain images "
           "and the GL drained, `xrEndFrame`. The mono frame: the left eye's camera, one sort for it alone, drawn "
           f"into an offscreen target of the eye's size, the GL drained. Medians of {options.frames} frames of "
           f"each kind, interleaved, after {WARMUP_FRAMES} untimed; GPU times are timer queries.")
    lines = common.report_head(
        "A headset frame against a mono frame (OpenXR)",
        f"Generated by `{options.command_line}` on {results.date}, {results.seconds:.0f} s.", results.notes)
    lines += [f"- Machine: {results.machine}, {results.cpu_count} CPU cores", f"- Runtime: {runtime}",
              f"- Scene: {results.scene}",
              "- Settings: `RenderSettings()`; one CPU sort a frame (`render.sorting.exact_order`)", "",
              f"**headset / mono: {common.fmt_ratio(ratio)}** ({_verdict(ratio)})", "", how, "",
              "| " + " | ".join(COLUMNS) + " |", "|---" + "|---:" * (len(COLUMNS) - 1) + "|"]
    ms = common.fmt_ms
    for kind, row in results.headset.items():
        cells = [TITLES[kind], ms(row.work_ms), ms(row.sort_ms), ms(row.draw_ms), ms(row.submit_ms),
                 ms(row.waited_ms), ms(row.gpu_left_ms), ms(row.gpu_right_ms), f"{row.skipped} of {row.frames}",
                 str(row.late), common.fmt_ratio(results.ratio(kind))]
        lines.append("| " + " | ".join(cells) + " |")
    mono = results.mono
    cells = [TITLES[MONO], ms(mono.work_ms), ms(mono.sort_ms), ms(mono.draw_ms), "", "", ms(mono.gpu_ms), "", "",
             "", "1"]
    lines.append("| " + " | ".join(cells) + " |")
    low, high = results.headset[HEADSET].period_range_ms
    period = (f"The runtime's display period: median {ms(results.headset[HEADSET].period_ms)} ({ms(low)} to "
              f"{ms(high)}; a runtime lengthens it while frames come late). *Late*: the predicted display time "
              "moved on by more than one and a half periods since the frame before (the mono frames in between "
              "count against it); *skipped*: ended without the eyes' layer.")
    lines += ["", period, ""]
    return "\n".join(lines)
