"""``doctor``'s XR section: the active OpenXR runtime as the headset mode meets it, and a
measured run of headset frames.

When a runtime is active (``XR_RUNTIME_JSON``, or an ``active_runtime.json``:
``xr.runtime.active_manifest``), a child process (``python -m
raygs_viewer.bench.doctor_xr``) opens a session the way ``bench xr`` does (a GL context
the runtime can bind: ``bench.xr.headset_context``) and reports: the runtime and its
version, the headset ("system"), the view configuration, each eye's recommended and
largest size, the swapchain formats offered (GL names where known) and those chosen, the
extensions enabled and the binding, the controller bindings as suggested to the runtime
(``xr.actions.binding_lines``) and whether it took them; then :data:`FRAMES` headset frames
of the demo drawn as the window draws them by default (one sort, both eyes, no depth
layer: ``HeadsetChoices.depth``, submitted): their work outside ``xrWaitFrame`` and their pace against the
runtime's display period, how many were late or skipped.

Why a child: a runtime lives inside the process that loads it. This Monado closes file
descriptor 0 when a swapchain is destroyed, a runtime that crashes would take doctor
with it, and the session needs a context of its own current (doctor's may be OSMesa,
which no runtime binds). The child's standard input is /dev/null; whatever goes wrong
there comes back as a line of the section, never as doctor's failure.

No runtime active: one line ("no OpenXR runtime active"); pyopenxr missing: one line
naming ``pip install 'raygs-viewer[xr]'``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from raygs_viewer.bench import common
from raygs_viewer.bench.xr import (
    WARMUP_FRAMES,
    HeadsetFrames,
    HeadsetSummary,
    summarize,
)
from raygs_viewer.bench.xr_session import (
    SessionFacts,
    end_session,
    headset_context,
    session_facts,
    start_session,
)
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.source import DEMO
from raygs_viewer.xr.actions import BINDINGS, ControllerActions, binding_lines
from raygs_viewer.xr.eyes import EyeDrawer
from raygs_viewer.xr.runtime import (
    DEPTH_EXTENSION,
    EGL_EXTENSION,
    INSTALL_HINT,
    OPENGL_EXTENSION,
    active_manifest,
    manifest_problem,
)
from raygs_viewer.xr.swapchain import format_name, kept_stdin

#: Headset frames the full run draws (after WARMUP_FRAMES untimed), and --quick's.
FRAMES, QUICK_FRAMES = 30, 10
#: The child's report on its standard output: this prefix, then JSON.
MARK = "doctor-xr: "
#: The child's time: to start (imports, the runtime, the session) and per frame, on a
#: software renderer; past it the child is hung, not slow.
CHILD_SECONDS, FRAME_SECONDS = 120.0, 10.0
ROOT = Path(__file__).resolve().parents[2]
NO_RUNTIME = "no OpenXR runtime active"
#: What each extension the session may enable is for.
EXTENSION_USES = {OPENGL_EXTENSION: "OpenGL", EGL_EXTENSION: "the EGL binding",
                  DEPTH_EXTENSION: "depth layers"}


@dataclass(frozen=True)
class XrSection:
    """The section's markdown lines; ``ran``: a runtime was active and the child ran;
    ``seconds`` it took."""

    lines: list[str]
    ran: bool = False
    seconds: float = 0.0


def xr_section(frames: int, say: Callable[[str], None]) -> XrSection:
    """The section (the module docstring): ``frames`` headset frames drawn (0: the runtime
    described only). Never raises."""
    try:
        manifest = active_manifest()
        if manifest is None and sys.platform.startswith("linux"):
            return XrSection([NO_RUNTIME + " (XR_RUNTIME_JSON is not set and no active_runtime.json was found): "
                                           "nothing to check"])
        problem = manifest_problem(manifest) if manifest is not None else None
        if problem is not None:
            return XrSection([f"{NO_RUNTIME}: {problem}"])
        if not pyopenxr_installed():
            missing = f"an OpenXR runtime is active ({manifest}), but pyopenxr is not installed: {INSTALL_HINT}"
            return XrSection([missing])
        say(f"XR: the runtime of {manifest or 'the registry'}: a session and {frames} headset frames in a child "
            f"process")
        began = time.perf_counter()
        lines = run_child(frames)
        seconds = time.perf_counter() - began
        say(f"XR: {next((line for line in lines if line.startswith('stopped:')), 'done')} ({seconds:.1f} s)")
        return XrSection(lines, True, seconds)
    except Exception as exc:  # noqa: BLE001 - the section says what failed; doctor goes on
        return XrSection([f"stopped: {type(exc).__name__}: {one_line(exc, 300)}"])


def pyopenxr_installed() -> bool:
    """Whether pyopenxr's ``xr`` module can be imported (looked up, not loaded: the child loads it)."""
    try:
        return importlib.util.find_spec("xr") is not None
    except (ImportError, ValueError):  # a module of that name without a spec: not pyopenxr
        return False


def run_child(frames: int) -> list[str]:
    """The section's lines from a child process (the module docstring)."""
    timeout = CHILD_SECONDS + FRAME_SECONDS * (frames + WARMUP_FRAMES)
    command = [sys.executable, "-m", "raygs_viewer.bench.doctor_xr", "--frames", str(frames)]
    env = dict(os.environ)
    if env.get("XR_RUNTIME_JSON"):  # the child runs in the package's folder: a relative manifest made absolute
        env["XR_RUNTIME_JSON"] = os.path.abspath(env["XR_RUNTIME_JSON"])
    try:
        done = subprocess.run(command, stdin=subprocess.DEVNULL, capture_output=True, text=True, errors="replace",
                              timeout=timeout, cwd=ROOT, env=env, check=False)
    except subprocess.TimeoutExpired:
        return [f"stopped: the XR check did not finish within {timeout:.0f} s (the runtime hung?)"]
    for line in reversed(done.stdout.splitlines()):
        if line.startswith(MARK):
            try:
                lines = json.loads(line[len(MARK):])["lines"]
            except (ValueError, KeyError, TypeError):
                break
            if isinstance(lines, list) and all(isinstance(item, str) for item in lines):
                return lines
            break
    tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
    why = one_line(ValueError(tail), 300)
    return [f"stopped: the XR check's process ended without its report (exit status {done.returncode}): {why}"]


# --- in the child -------------------------------------------------------------------------------

def fact_lines(facts: SessionFacts, *, manifest: Path | None, device: str) -> list[str]:
    """The table of what the runtime gave the session."""
    def sizes(values) -> str:
        return ", ".join(f"{w}x{h}" for w, h in values)

    offered = ", ".join(format_name(value) for value in facts.formats) or "none"
    width, height = facts.sizes[0]
    depth = (f"{format_name(facts.depth_format)} ({DEPTH_EXTENSION})" if facts.depth_format is not None
             else "none (the runtime takes no depth layers, or no depth format it offers suits)")
    used = ", ".join(f"{name} ({EXTENSION_USES.get(name, 'asked for')})" for name in facts.extensions)
    rows = [("runtime", f"{facts.runtime} {facts.version}" + (f" (manifest `{manifest}`)" if manifest else "")),
            ("system", facts.system),
            ("view configuration", f"primary stereo, {len(facts.recommended)} views"),
            ("per eye, recommended", sizes(facts.recommended)),
            ("per eye, maximum", sizes(facts.maximum)),
            ("swapchain formats offered", offered),
            ("colour swapchains", f"{format_name(facts.colour_format)}, {width}x{height} per eye"),
            ("depth swapchains", depth),
            ("extensions used", used),
            ("OpenGL binding", f"{facts.binding.upper()}: {device}")]
    return ["| | |", "|---|---|"] + [f"| {what} | {value} |" for what, value in rows]


def bindings_check(session) -> str:
    """Whether the runtime takes the controllers' suggested bindings (one line)."""
    try:
        actions = ControllerActions.create(session.runtime.instance)
    except UserError as exc:
        return f"Controller bindings, as suggested to the runtime: refused: {one_line(exc)}"
    try:
        actions.attach(session.session)
        return f"Controller bindings, as suggested to the runtime (all {len(BINDINGS)} profiles taken):"
    except UserError as exc:
        return f"Controller bindings, as suggested to the runtime (taken, but not attached: {one_line(exc)}):"
    finally:
        try:
            actions.destroy()
        except session.xr.ResultException:
            pass  # a runtime gone has nothing left to free


def frame_lines(summary: HeadsetSummary, *, size: tuple[int, int], depth: bool, scene: str) -> list[str]:
    """The measured frames: their work against the runtime's display period."""
    low, high = summary.period_range_ms
    periods = summary.work_ms / low if low > 0 else float("nan")
    pace = (f"the work fits the shortest display period the runtime gave ({periods:.0%} of it)" if periods <= 1
            else f"the work takes {periods:.1f} times the shortest display period the runtime gave: frames are "
                 f"missed")
    head = (f"{summary.frames} headset frames of the {scene} at {size[0]}x{size[1]} per eye, "
            f"{'with' if depth else 'without'} depth, as the window draws them (one sort from the eyes' midpoint, "
            f"both eyes, the GL drained, submitted), after {WARMUP_FRAMES} untimed:")
    period = f"{common.fmt_ms(summary.period_ms)} ({common.fmt_ms(low)} to {common.fmt_ms(high)})"
    gpu = f"left {common.fmt_ms(summary.gpu_left_ms)}, right {common.fmt_ms(summary.gpu_right_ms)}"
    counts = (f"{summary.frames - summary.skipped} of {summary.frames} submitted with the eyes' layer, "
              f"{summary.skipped} skipped, {summary.late} late; {pace}.")
    return [head, "", "| | median |", "|---|---:|",
            f"| work a frame, outside xrWaitFrame | {common.fmt_ms(summary.work_ms)} |",
            f"| waited in xrWaitFrame | {common.fmt_ms(summary.waited_ms)} |",
            f"| frame to frame | {common.fmt_ms(summary.interval_ms)} |",
            f"| the runtime's display period | {period} |",
            f"| GPU per eye (timer queries) | {gpu} |", "", counts]


def measure_frames(session, clock, *, frames: int) -> list[str]:
    """``frames`` headset frames of the demo on the running ``session``: their lines."""
    item = common.load_scenes((DEMO,))[0]
    ctx = session.ctx
    with common.scene_renderer(ctx, item.scene) as (renderer, sorter):
        drawing = HeadsetFrames(session, clock, renderer=renderer, sorter=sorter, view=item.camera,
                                settings=RenderSettings())
        drawer, timed = EyeDrawer(ctx), []
        for index in range(WARMUP_FRAMES + frames):
            times = drawing.draw(drawer, depth=False)  # the window's default
            if times is None:
                raise UserError(f"the headset session ended after {index} frames: {drawing.ended_why}")
            if index >= WARMUP_FRAMES:
                timed.append(times)
        return frame_lines(summarize(timed, drawer, skip=WARMUP_FRAMES), size=session.sizes[0],
                           depth=False, scene=f"{item.name} ({item.scene.count:,} gaussians)")


def child_lines(frames: int) -> list[str]:
    """The section's lines, measured in this process (the child's work); never raises."""
    lines: list[str] = []
    try:
        with kept_stdin(), headset_context() as ctx:
            session, clock = start_session(ctx, scale=1.0, depth=True)
            try:
                lines += fact_lines(session_facts(session), manifest=active_manifest(),
                                    device=context_description(ctx))
                lines += ["", bindings_check(session), ""] + [f"- {line}" for line in binding_lines()] + [""]
                if frames:
                    lines += measure_frames(session, clock, frames=frames)
            finally:
                end_session(session)
    except UserError as exc:
        lines += [f"stopped: {one_line(exc, 300)}"]
    except Exception as exc:  # noqa: BLE001 - the section says what failed; doctor goes on
        lines += [f"stopped: {type(exc).__name__}: {one_line(exc, 300)}"]
    return lines


def main(argv: list[str] | None = None) -> int:
    """The child: the section's lines as JSON after :data:`MARK` on one line of stdout."""
    parser = argparse.ArgumentParser(prog="python -m raygs_viewer.bench.doctor_xr")
    parser.add_argument("--frames", type=int, default=FRAMES)
    args = parser.parse_args(argv)
    lines = child_lines(max(0, args.frames))
    print(MARK + json.dumps({"lines": lines}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
