"""``raygs-viewer convert IN OUT``: written, read back, reported; never over a file
without --overwrite; one line and exit status 2 on bad input."""

from __future__ import annotations

import re

import numpy as np
import pytest
from testkit import assert_one_line_error, listing, random_scene, run_cli, write_inria_ply

from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.writing import write_scene


def reported(out: str, attribute: str) -> float:
    """The first number after ``attribute`` and 'max' in convert's report."""
    line = next(line for line in out.splitlines() if line.split()[:1] == [attribute])
    return float(re.search(r"max (?:relative )?([-+0-9.e]+)", line).group(1))


@pytest.fixture
def sh3_ply(tmp_path):
    return write_scene(random_scene(n=120, seed=6, degree=3), tmp_path / "in.ply")


def test_ply_to_ply_is_lossless(capsys, tmp_path):
    source = write_inria_ply(tmp_path / "in.ply", n=40, seed=2)  # written by plyfile, not by us
    code, out, err = run_cli(capsys, "convert", source, tmp_path / "out.ply")
    assert code == 0, err
    assert "lossless" in out and "INRIA PLY, 40 gaussians" in out
    for attribute in ("position", "colour", "opacity"):
        assert reported(out, attribute) <= 1e-6, out
    assert reported(out, "rotation") <= 1e-4  # degrees: re-normalising a unit quaternion
    a, b = load_scene(source), load_scene(tmp_path / "out.ply")
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.sh, b.sh)


def test_ply_to_splat_reports_the_quantisation_and_the_sh_lost(capsys, tmp_path, sh3_ply):
    code, out, err = run_cli(capsys, "convert", sh3_ply, tmp_path / "out.splat")
    assert code == 0, err
    assert "quantised" in out and "lossless" not in out
    assert "SH degree 3 -> 0" in out and "SH rest    degree 3 -> 0: lost" in out
    assert "wrote " in out and f"{120 * 32:,} bytes" in out
    assert reported(out, "position") == 0 and reported(out, "scale") == 0
    assert 0 < reported(out, "opacity") <= 0.5 / 255 + 1e-6
    assert 0 < reported(out, "rotation") <= 1.2
    assert load_scene(tmp_path / "out.splat").count == 120


def test_existing_output_is_never_replaced_without_overwrite(capsys, tmp_path, sh3_ply):
    target = tmp_path / "out.splat"
    target.write_bytes(b"keep me")
    code, out, err = run_cli(capsys, "convert", sh3_ply, target)
    assert "already exists" in assert_one_line_error(code, err) and out == ""  # refused before reading IN
    assert target.read_bytes() == b"keep me"
    code, out, err = run_cli(capsys, "convert", sh3_ply, target, "--overwrite")
    assert code == 0, err
    assert load_scene(target).count == 120
    assert listing(tmp_path) == ["in.ply", "out.splat"]


@pytest.mark.parametrize("name", ["out.txt", "out", "out.ksplat", "out.ply.gz"])
def test_unwritable_suffix_is_one_line_listing_the_targets(capsys, tmp_path, sh3_ply, name):
    code, out, err = run_cli(capsys, "convert", sh3_ply, tmp_path / name)
    message = assert_one_line_error(code, err)
    assert all(suffix in message for suffix in (".ply", ".splat", ".spz")), message
    assert listing(tmp_path) == ["in.ply"]


@pytest.mark.parametrize("spelling", ["same", "dotted", "link"])
def test_input_as_output_is_refused_even_with_overwrite(capsys, tmp_path, sh3_ply, spelling):
    target = {"same": sh3_ply, "dotted": tmp_path / "sub" / ".." / "in.ply", "link": tmp_path / "link.ply"}[spelling]
    (tmp_path / "sub").mkdir()
    if spelling == "link":
        target.symlink_to(sh3_ply)
    before = sh3_ply.read_bytes()
    code, out, err = run_cli(capsys, "convert", sh3_ply, target, "--overwrite")
    assert "is the input too" in assert_one_line_error(code, err)
    assert sh3_ply.read_bytes() == before


@pytest.mark.parametrize("content", [None, b"", b"ply\nformat ascii 1.0\nend_header\n", b"not a scene at all"])
def test_unreadable_input_is_one_line_and_writes_nothing(capsys, tmp_path, content):
    source = tmp_path / "in.ply"
    if content is not None:
        source.write_bytes(content)
    code, out, err = run_cli(capsys, "convert", source, tmp_path / "out.ply")
    assert "in.ply" in assert_one_line_error(code, err)
    assert "out.ply" not in listing(tmp_path)


def test_bad_options_are_one_line(capsys, tmp_path, sh3_ply):
    code, out, err = run_cli(capsys, "convert", sh3_ply, tmp_path / "out.spz", "--spz-version", "2")
    assert "--spz-version" in assert_one_line_error(code, err)
    code, out, err = run_cli(capsys, "convert", sh3_ply)
    assert_one_line_error(code, err)
    code, out, err = run_cli(capsys, "convert", sh3_ply, tmp_path / "missing" / "out.ply")
    assert "does not exist" in assert_one_line_error(code, err)


def test_demo_converts(capsys, tmp_path):
    code, out, err = run_cli(capsys, "convert", "demo", tmp_path / "demo.ply")
    assert code == 0, err
    assert load_scene(tmp_path / "demo.ply").sh_degree == 3


@pytest.mark.parametrize("version", [3, 4])
def test_ply_to_spz_round_trips_within_its_quantisation(capsys, tmp_path, sh3_ply, version):
    code, out, err = run_cli(capsys, "convert", sh3_ply, tmp_path / "out.spz", "--spz-version", version)
    assert code == 0, err
    assert f"spz v{version}" in out and "quantised" in out and "SH rest    max" in out
    back, scene = load_scene(tmp_path / "out.spz"), load_scene(sh3_ply)
    assert back.count == 120 and back.sh_degree == 3
    # Half a step of the 12 fractional bits, and of an opacity byte.
    assert np.abs(back.positions - scene.positions).max() <= 2.0 ** -13 + 1e-7
    assert np.abs(back.opacities - scene.opacities).max() <= 0.5 / 255 + 1e-7
    assert reported(out, "position") <= np.sqrt(3) * 2.0 ** -13 + 1e-6  # a distance: three axes
