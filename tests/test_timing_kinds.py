"""``pytest --time-kinds FILE.md`` (tests/timing_kinds.py): a small suite of one test of
each kind, run in its own pytest process (the plugin wraps glfw, moderngl, the reference
and subprocess for the whole process it runs in), files each test under its kind and
adds up the time per package, per kind, per file, inside the reference and subprocesses,
and per fixture."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
from pathlib import Path

TESTS = Path(__file__).resolve().parent

CONFTEST = f"""
import sys
sys.path.insert(0, {str(TESTS)!r})
import pytest
import timing_kinds

def pytest_addoption(parser):
    timing_kinds.add_option(parser)

def pytest_configure(config):
    timing_kinds.configure(config)

@pytest.fixture
def gl_ctx():  # named as the suite's GL fixture: a test asking for it is a GL test
    return None

@pytest.fixture(scope="module")
def slow_fixture():
    import time
    time.sleep(0.3)
"""

SUITE = """
import subprocess, sys, time
import numpy as np

def test_cpu(slow_fixture):
    assert sum(range(10)) == 45

def test_subprocess():
    time.sleep(0.2)
    subprocess.run([sys.executable, "-c", "import time; time.sleep(0.4)"], check=True)

def test_gl(gl_ctx):
    pass

def test_reference():
    from raygs_viewer.render.reference import render_reference
    from raygs_viewer.scene.demo import demo_camera, demo_scene
    image = render_reference(demo_scene(), demo_camera(8, 6))
    assert image.shape == (6, 8, 4)
"""


def table(text: str, heading: str) -> dict[str, list[str]]:
    """The rows of the Markdown table whose header starts with ``heading``: first cell -> the rest."""
    block = text.split(f"| {heading}", 1)[1].split("\n\n", 1)[0]
    rows = [line.strip("|").split("|") for line in block.splitlines()[2:]]
    return {cells[0].strip(): [cell.strip() for cell in cells[1:]] for cells in rows}


def test_each_test_is_filed_under_its_kind_and_the_times_add_up(tmp_path):
    (tmp_path / "conftest.py").write_text(CONFTEST)
    package = tmp_path / "tests" / "pkg"
    package.mkdir(parents=True)
    (package / "test_kinds.py").write_text(textwrap.dedent(SUITE))
    out = tmp_path / "T.md"
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:xdist", "-p", "no:cacheprovider",
                           "-o", "addopts=", "--rootdir", str(tmp_path), "--time-kinds", str(out), "tests"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert f"timing by kind written to {out}" in done.stdout
    text = out.read_text()
    assert re.match(r"wall time [\d.]+ s; test time \(setup \+ call \+ teardown, all workers\) [\d.]+ s, 4 tests\n",
                    text), text.splitlines()[0]

    kinds = table(text, "kind")
    assert {name: row[0] for name, row in kinds.items()} == {
        "window": "0", "subprocess": "1", "GL context": "1", "float64 reference": "1", "CPU only": "1"}
    assert float(kinds["subprocess"][1]) >= 0.6  # its own sleep and its child's
    assert float(kinds["CPU only"][1]) >= 0.3    # the module fixture's set-up is the first test's

    inside = table(text, "inside")
    assert 0.4 <= float(inside["subprocess"][0]) < float(kinds["subprocess"][1])
    assert 0 < float(inside["float64 reference"][0]) <= float(kinds["float64 reference"][1])

    packages, files = table(text, "package"), table(text, "test file")
    assert list(packages) == ["pkg"] and packages["pkg"][0] == "4"
    assert list(files) == ["tests/pkg/test_kinds.py"]
    assert float(files["tests/pkg/test_kinds.py"][0]) == float(packages["pkg"][1])
    set_ups, seconds = table(text, "fixture")["slow_fixture"]
    assert set_ups == "1" and float(seconds) >= 0.3  # made once for the module
    most = table(text, "test (most time inside the subprocess")
    assert list(most) == ["tests/pkg/test_kinds.py::test_subprocess"]
