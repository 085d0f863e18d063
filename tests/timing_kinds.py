"""Where the suite's time goes: ``pytest --time-kinds FILE.md`` writes the time per test
package, per kind of set-up a test pays for, and per fixture, as Markdown tables
(docs/testing.md quotes them). Serial or under pytest-xdist: each worker files what it
saw in the test's report, and the process that prints the summary adds them up.

A test's kind is the most expensive thing it was seen to use, in this order:
a window (GLFW created one during the test), a subprocess (one was started), a GL
context (a GL fixture, or a context made during the test), the float64 reference
(called during the test), none of these (CPU only). The time inside the reference and
inside subprocesses is measured too, as wall time between entry and return.
"""

from __future__ import annotations

import subprocess
import time
from collections import defaultdict
from pathlib import Path

import pytest

KINDS = ("window", "subprocess", "GL context", "float64 reference", "CPU only")
GL_FIXTURES = {"gl_ctx", "gl_session_ctx", "gl_render", "demo_renderer", "restore_gl_ctx"}
_KEY = "timing_kinds"


class Seen:
    """What the test running in this process has used so far."""

    def __init__(self):
        self.item = None
        self.flags: set[str] = set()
        self.inside: dict[str, float] = defaultdict(float)
        self.fixtures: dict[str, float] = {}
        self.depth = 0

    def start(self, item) -> None:
        self.item, self.flags, self.inside, self.fixtures = item, set(), defaultdict(float), {}


SEEN = Seen()


def _flagging(owner, name: str, flag: str) -> None:
    original = getattr(owner, name)

    def flagged(*args, **kwargs):
        SEEN.flags.add(flag)
        return original(*args, **kwargs)

    setattr(owner, name, flagged)


def _timing(owner, name: str, flag: str) -> None:
    """``owner.name`` timed, nested calls counted once (the reference calls itself)."""
    original = getattr(owner, name)

    def timed(*args, **kwargs):
        SEEN.flags.add(flag)
        SEEN.depth += 1
        started = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            SEEN.depth -= 1
            if SEEN.depth == 0:
                SEEN.inside[flag] += time.perf_counter() - started

    setattr(owner, name, timed)


def _watch_subprocesses() -> None:
    original_init, original_wait = subprocess.Popen.__init__, subprocess.Popen.wait

    def init(self, *args, **kwargs):
        SEEN.flags.add("subprocess")
        self._timing_kinds_started = time.perf_counter()
        original_init(self, *args, **kwargs)

    def wait(self, *args, **kwargs):
        try:
            return original_wait(self, *args, **kwargs)
        finally:
            started = getattr(self, "_timing_kinds_started", None)
            if started is not None and self.returncode is not None:
                SEEN.inside["subprocess"] += time.perf_counter() - started
                self._timing_kinds_started = None

    subprocess.Popen.__init__, subprocess.Popen.wait = init, wait


def install() -> None:
    """Wraps what marks a kind; before any test module imports the names it wraps."""
    from imgui_bundle import imgui  # noqa: F401  before glfw, as viewer.window says

    # isort: split
    import glfw
    import moderngl

    from raygs_viewer.render import reference

    _flagging(glfw, "create_window", "window")
    _flagging(moderngl, "create_context", "GL context")
    _flagging(moderngl, "create_standalone_context", "GL context")
    for name in ("render_reference", "render_reference_channels", "ground_truth"):
        _timing(reference, name, "float64 reference")
    _watch_subprocesses()


def kind_of(flags: set[str]) -> str:
    return next((kind for kind in KINDS[:-1] if kind in flags), KINDS[-1])


class Collector:
    """Adds up the reports, wherever they were made."""

    def __init__(self, out: Path):
        self.out = out
        self.started = time.perf_counter()
        self.duration: dict[str, float] = defaultdict(float)
        self.kind: dict[str, str] = {}
        self.inside: dict[str, float] = defaultdict(float)
        self.inside_by_test: dict[str, dict[str, float]] = defaultdict(dict)
        self.fixtures: dict[str, list[float]] = defaultdict(list)

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(self, item, nextitem):
        SEEN.start(item)
        yield

    @pytest.hookimpl(hookwrapper=True)
    def pytest_fixture_setup(self, fixturedef, request):
        started = time.perf_counter()
        yield
        SEEN.fixtures[fixturedef.argname] = SEEN.fixtures.get(fixturedef.argname, 0.0) + time.perf_counter() - started

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_makereport(self, item, call):
        if call.when == "teardown":
            flags = set(SEEN.flags)
            if GL_FIXTURES & set(item.fixturenames):
                flags.add("GL context")
            item.user_properties.append((_KEY, {"kind": kind_of(flags), "inside": dict(SEEN.inside),
                                                "fixtures": dict(SEEN.fixtures)}))
        yield

    def pytest_runtest_logreport(self, report):
        self.duration[report.nodeid] += report.duration
        for key, value in report.user_properties:
            if key == _KEY:
                self.kind[report.nodeid] = value["kind"]
                for name, seconds in value["inside"].items():
                    self.inside[name] += seconds
                    self.inside_by_test[report.nodeid][name] = seconds
                for name, seconds in value["fixtures"].items():
                    self.fixtures[name].append(seconds)

    def pytest_terminal_summary(self, terminalreporter):
        # The controller adds the workers' up. Asked of the config, not of the environment:
        # a pytest this suite starts in a subprocess inherits a worker's PYTEST_XDIST_WORKER.
        if hasattr(terminalreporter.config, "workerinput"):
            return
        text = self.markdown(time.perf_counter() - self.started)
        self.out.write_text(text)
        terminalreporter.write_line(f"timing by kind written to {self.out}")

    def markdown(self, wall: float) -> str:
        total = sum(self.duration.values())
        packages: dict[str, list[float]] = defaultdict(list)
        kinds: dict[str, list[float]] = defaultdict(list)
        for nodeid, seconds in self.duration.items():
            parts = nodeid.split("::")[0].split("/")
            packages[parts[1] if len(parts) > 2 else "(top)"].append(seconds)
            kinds[self.kind.get(nodeid, KINDS[-1])].append(seconds)
        lines = [f"wall time {wall:.1f} s; test time (setup + call + teardown, all workers) {total:.1f} s, "
                 f"{len(self.duration)} tests", "", "| package | tests | seconds | share |", "| --- | ---: | ---: | ---: |"]
        for name, times in sorted(packages.items(), key=lambda kv: -sum(kv[1])):
            lines.append(f"| {name} | {len(times)} | {sum(times):.1f} | {sum(times) / total:.0%} |")
        lines += ["", "| kind (the most expensive thing a test used) | tests | seconds | share |",
                  "| --- | ---: | ---: | ---: |"]
        for name in KINDS:
            times = kinds.get(name, [])
            lines.append(f"| {name} | {len(times)} | {sum(times):.1f} | {sum(times) / total:.0%} |")
        lines += ["", "| inside | seconds |", "| --- | ---: |"]
        lines += [f"| {name} | {seconds:.1f} |" for name, seconds in sorted(self.inside.items())]
        files: dict[str, float] = defaultdict(float)
        for nodeid, seconds in self.duration.items():
            files[nodeid.split("::")[0]] += seconds
        # Under --dist loadfile a file is the unit a worker takes: the slowest one bounds
        # how evenly two workers can finish.
        lines += ["", "| test file (slowest 15) | seconds |", "| --- | ---: |"]
        lines += [f"| {name} | {seconds:.1f} |" for name, seconds in sorted(files.items(), key=lambda kv: -kv[1])[:15]]
        for name in sorted(self.inside):
            ranked = sorted(((t.get(name, 0.0), nodeid) for nodeid, t in self.inside_by_test.items()), reverse=True)
            lines += ["", f"| test (most time inside the {name}, 10) | seconds |", "| --- | ---: |"]
            lines += [f"| {nodeid} | {seconds:.1f} |" for seconds, nodeid in ranked[:10] if seconds > 0]
        lines += ["", "| fixture (set-up time, slowest 15) | set-ups | seconds |", "| --- | ---: | ---: |"]
        slowest = sorted(self.fixtures.items(), key=lambda kv: -sum(kv[1]))[:15]
        lines += [f"| {name} | {len(times)} | {sum(times):.1f} |" for name, times in slowest]
        return "\n".join(lines) + "\n"


def add_option(parser) -> None:
    parser.addoption("--time-kinds", metavar="FILE.md", default=None,
                     help="write the time per package, per kind of set-up and per fixture to FILE.md")


def configure(config) -> None:
    out = config.getoption("--time-kinds")
    if out is None:
        return
    install()
    config.pluginmanager.register(Collector(Path(out)), "timing-kinds")
