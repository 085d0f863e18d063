"""``raygs-viewer bench edit``: the rows' comparison with its band, a tiny run's
selections against the float64 weighing, the JSON it writes, a differing row made loud,
and the one-line errors before any work. No test reads the times."""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import numpy as np
import pytest
from testkit import assert_one_line_error

from raygs_viewer.bench import edit as bench_edit
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.cli.main import main
from raygs_viewer.scene.writing import ply_bytes

#: Small enough for llvmpipe to weigh every case in seconds; the shapes scale with the width.
WIDTH, HEIGHT = 96, 54
SCENE_KEYS = {"scene", "gaussians", "width", "height", "frame_seconds", "cases"}
CASE_KEYS = {"shape", "order", "seconds", "rows_equal", "rows_compared", "rows_in_band"}


def parse(*argv) -> argparse.Namespace:
    """What the CLI hands to cli.bench.command for ``raygs-viewer bench edit ARGV``."""
    parser = argparse.ArgumentParser()
    bench_cli.add_parsers(parser.add_subparsers(dest="command"))
    return parser.parse_args(["bench", "edit", *map(str, argv)])


@pytest.fixture(scope="module")
def tiny_ply(tmp_path_factory):
    path = tmp_path_factory.mktemp("edit") / "tiny.ply"
    path.write_bytes(ply_bytes(bench_edit.generated_scene(1200, seed=3)))
    return path


@pytest.fixture(scope="module")
def tiny_run(gl_session_ctx, tiny_ply):
    """One run of a generated scene and a scene file, at WIDTH x HEIGHT."""
    gl_session_ctx.__enter__()
    options = bench_edit.EditOptions(counts=(2000,), scenes=(str(tiny_ply),), width=WIDTH, height=HEIGHT)
    return bench_edit.run_edit(options, gl_session_ctx)


# --- the rows' comparison ----------------------------------------------------------------------

def test_compare_rows_finds_a_differing_row_and_leaves_the_band_out():
    t, band = bench_edit.THRESHOLD, bench_edit.BAND
    reference = np.array([0.0, 0.5, t + band / 2, t - band / 2, 0.2, 0.01])
    weights = np.array([0.0, 0.5, t - band, t + band, 0.01, 0.01], np.float32)  # rows 2, 3 flip in the band; row 4 not
    check = bench_edit.compare_rows(weights, reference)
    assert check.in_band == (2, 3)
    assert check.compared == 4 and check.equal == 3
    assert check.differing == (4,)
    assert check.selected == 3  # rows 1, 2, 4 by the float64 weights


def test_compare_rows_counts_every_row_equal_when_the_selections_agree():
    reference = np.array([0.0, 0.06, 0.9, 0.049])
    check = bench_edit.compare_rows(reference.astype(np.float32) + np.float32(1e-6), reference)
    assert (check.equal, check.compared, check.in_band, check.differing) == (4, 4, (), ())


# --- a tiny run ------------------------------------------------------------------------------------

def test_every_selection_equals_the_float64_weighings_outside_the_band(tiny_run):
    assert not tiny_run.failures
    assert [s.gaussians for s in tiny_run.scenes] == [2000, 1200]
    for scene in tiny_run.scenes:
        assert scene.slice_seconds == bench_edit.window_slice(scene.frame_seconds) >= 0.05  # as the window slices
        assert [(c.order, c.shape) for c in scene.cases] == \
            [(order, shape) for order in bench_edit.ORDERS for shape in bench_edit.SHAPES]
        for case in scene.cases:
            rows = case.rows
            assert rows.equal == rows.compared == scene.gaussians - len(rows.in_band), (scene.scene, case)
            assert case.where.startswith("GPU"), case.where
        # Not a vacuous agreement: the rectangle selects gaussians in both orders.
        assert all(c.rows.selected > 0 for c in scene.cases if c.shape == "rectangle")


def test_json_holds_exactly_the_fields_named(tiny_run, tmp_path):
    path = tmp_path / "edit.json"
    bench_edit.write_json(tiny_run, path, overwrite=False)
    document = json.loads(path.read_text())
    assert set(document) == {"scenes"} and len(document["scenes"]) == 2
    for scene, result in zip(document["scenes"], tiny_run.scenes):
        assert set(scene) == SCENE_KEYS
        assert (scene["width"], scene["height"], scene["gaussians"]) == (WIDTH, HEIGHT, result.gaussians)
        assert scene["frame_seconds"] > 0
        assert len(scene["cases"]) == len(bench_edit.ORDERS) * len(bench_edit.SHAPES)
        for case in scene["cases"]:
            assert set(case) == CASE_KEYS
            assert case["shape"] in ("click", "brush", "rectangle") and case["order"] in ("global", "per-ray")
            assert case["seconds"] > 0 and isinstance(case["rows_in_band"], list)
            assert case["rows_compared"] + len(case["rows_in_band"]) == scene["gaussians"]


def test_report_names_the_paths_and_the_goal(tiny_run):
    report = bench_edit.format_report(tiny_run)
    assert "GPU, framebuffer fetch" in report or "GPU, fragment lists" in report
    assert "Every selection equals the float64 weighing's outside the band." in report and "FAILED" not in report
    assert "the global order within 1 frame's time, the per-ray order within 3" in report


# --- the command line ------------------------------------------------------------------------------

def test_cli_writes_the_json_and_a_differing_row_fails_loudly(gl_ctx, tiny_ply, tmp_path, monkeypatch, capsys):
    timed = bench_edit.timed_weighing

    def wrong_row(*args, **kwargs):
        """The weighing with row 0 raised far past the threshold: a selection the float64 one is unlikely to make."""
        weighed = timed(*args, **kwargs)
        weights = weighed.weights.copy()
        weights[0] = 0.99
        return replace(weighed, weights=weights)

    out = tmp_path / "edit.json"
    args = ("--size", f"{WIDTH}x{HEIGHT}", "--json", out)
    assert bench_cli.command(parse(tiny_ply, *args), ctx=gl_ctx) == 0
    assert "FAILED" not in capsys.readouterr().out
    first = json.loads(out.read_text())
    assert [s["gaussians"] for s in first["scenes"]] == [1200]  # a scene named: no generated one

    monkeypatch.setattr(bench_edit, "timed_weighing", wrong_row)
    assert bench_cli.command(parse(tiny_ply, *args, "--overwrite"), ctx=gl_ctx) == 1
    captured = capsys.readouterr()
    assert "**FAILED:" in captured.out and "bench edit: FAILED:" in captured.err
    assert "(rows 0)" in captured.err
    cases = json.loads(out.read_text())["scenes"][0]["cases"]
    assert any(c["rows_equal"] < c["rows_compared"] for c in cases)


@pytest.mark.parametrize("argv, fragment", [
    (["bench", "edit", "missing.ply"], "missing.ply: no such file"),
    (["bench", "edit", "--counts", "10", "--json", "no-such-folder/x.json"], "does not exist"),
    (["bench", "edit", "--counts", "10", "--json", "x.txt"], "must end in .json"),
    (["bench", "edit", "--counts", "10", "--json", "taken.json"], "already exists"),
])
def test_bad_input_is_one_error_line_before_any_work(argv, fragment, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taken.json").write_text("{}")
    monkeypatch.setattr(bench_edit, "run_edit", lambda *a, **k: pytest.fail("ran with bad input"))
    code = main(argv)
    err = assert_one_line_error(code, capsys.readouterr().err)
    assert fragment in err
