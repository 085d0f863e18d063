"""``raygs-viewer doctor`` on the command line: a --quick --no-speed run, in a real process,
exits 0 here and writes the report (the GL, the correctness rows with their errors, the
GPU-against-CPU sort rows); the speed rows and the auto choices, run through the same
command in-process at sizes smaller than --quick's (--quick's own sizes are checked in
tests/bench/test_doctor.py), fill the report's speed sections; --report never replaces a
file without --overwrite; bad input is one line and exit status 2, before any work."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from testkit import assert_one_line_error, run_cli

from raygs_viewer.bench.doctor_speed import SpeedSizes
from raygs_viewer.cli.doctor import command_doctor
from raygs_viewer.cli.main import build_parser


CASES = ("--case", "demo", "--case", "straddling-camera-plane")


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """``raygs-viewer doctor --quick --no-speed --report R.md --overwrite`` over a file
    already there, in its own process (and config folder: the probe remembers nothing)."""
    folder = tmp_path_factory.mktemp("doctor")
    report = folder / "R.md"
    report.write_text("an earlier report")
    env = {**os.environ, "XDG_CONFIG_HOME": str(folder / "config")}
    # Two of the 16 cases (the demo in every axis, one hard case in the modes): every
    # case's rows are checked in-process (tests/bench/test_hard_cases.py, test_doctor.py).
    done = subprocess.run([sys.executable, "-m", "raygs_viewer.cli.main", "doctor", "--quick", "--no-speed", *CASES,
                           "--report",
                           str(report), "--overwrite"], capture_output=True, text=True, env=env, timeout=300)
    return done, report


def test_quick_exits_0_here_and_says_so_last(quick_run):
    done, report = quick_run
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stderr == ""
    lines = done.stdout.rstrip().splitlines()
    assert re.fullmatch(r"doctor: all \d+ correctness rows passed", lines[-1]), lines[-1]
    assert lines[-2] == f"wrote {report}"


def test_the_report_has_the_gl_the_rows_and_the_sort(quick_run):
    done, report = quick_run
    text = report.read_text()
    assert text.startswith("# raygs-viewer doctor\n\n`raygs-viewer doctor --quick --no-speed --case demo --case "
                           "straddling-camera-plane` on ")
    cases = set(re.findall(r"^\| ([a-z-]+) \| (?:mode|RayGS|order|precision|draw|sort)", text, re.M))
    assert cases == {"demo", "straddling-camera-plane"}
    assert text in done.stdout  # the report printed is the report written
    for heading in ("## The GL", "## Correct here: renders against the float64 reference",
                    "## Correct here: the GPU sort against the CPU sort"):
        assert heading in text, heading
    assert "## Fast here" not in text and "choose here" not in text
    for row in ("| renderer | ", "| driver | ", "| context | ", "| GL_EXT_shader_framebuffer_fetch | ",
                "| storage block size | ", "| GPU memory for buffers | "):
        assert row in text, row
    error = r"\| (?:\d\.\d+|\d\.?\d*e-\d+) \| max "
    for setting in ("mode GS", "precision 8-bit", "order per-pixel exact \\(fragment lists\\)",
                    "draw layout indexed", "sort GPU"):
        assert re.search(rf"^\| demo \| {setting} {error}.* \| pass \|$", text, re.M), setting
    assert re.search(rf"^\| straddling-camera-plane \| mode exact MIP {error}", text, re.M)
    assert re.search(r"^\| culled \| 200,000 \| float \| [\d,]+, [\d,]+ \| (identical|not supported here: .*) \|$",
                     text, re.M)


def test_the_speed_rows_and_the_auto_choices_fill_their_sections(capsys, gl_ctx):
    """The command's speed and auto sections, in-process, with no correctness rows and
    speed sizes a fifteenth of --quick's."""
    args = build_parser().parse_args(["doctor", "--quick"])
    tiny = SpeedSizes(2_000, (64, 36), 16, 1, 1, (2_000, 3_000), 1)
    assert command_doctor(args, gl_ctx, cases=(), sort_count=0, speed=tiny) == 0
    text = capsys.readouterr().out
    assert "## Fast here" in text and "## What `--sort auto` and `--precision auto` choose here" in text
    assert "## Correct here: the GPU sort" not in text
    assert re.search(r"^\| outdoor 2k mono \| 64×36 \| .* \| [\d.,]+ M/s \|$", text, re.M)
    assert re.search(r"^\| 3k gaussians \| [\d.]+ ms \| ", text, re.M)
    assert re.search(r"^- sort: (CPU|GPU), .*$", text, re.M) and re.search(r"^- blend: .*$", text, re.M)


def test_an_existing_report_is_kept_without_overwrite(capsys, tmp_path):
    existing = tmp_path / "R.md"
    existing.write_text("mine")
    code, out, err = run_cli(capsys, "doctor", "--quick", "--report", existing)
    assert_one_line_error(code, err)
    assert "already exists" in err and out == ""
    assert existing.read_text() == "mine"


@pytest.mark.parametrize("argv, words", [
    (("--report", "missing-folder/R.md"), "missing-folder"),
    (("--report", "R.txt"), "must end in .md"),
    (("--gl-backend", "vulkan"), "vulkan"),
    (("--quick", "--frames", "3"), "unrecognized arguments"),
    (("--case", "demo", "--case", "donut"), "unknown case 'donut': use one of demo, camera-at-centre"),
])
def test_bad_input_is_one_line_and_status_2(capsys, tmp_path, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(capsys, "doctor", *argv)
    assert_one_line_error(code, err)
    assert words in err and out == ""
    assert list(tmp_path.iterdir()) == []
