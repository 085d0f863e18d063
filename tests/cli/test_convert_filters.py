"""``convert IN OUT`` with filters: exactly the gaussians a numpy mask of the same rules
keeps, in order, each kept PLY row the source's to the bit (extra properties and
``filter_3D`` included); the count each filter removed; bad values are one line, exit 2
and nothing written."""

from __future__ import annotations

import numpy as np
import pytest
from edit_kit import numpy_truth, rich_rows, write_rows
from plyfile import PlyData
from testkit import assert_one_line_error, listing, run_cli

from raygs_viewer.scene.io import load_scene

@pytest.mark.parametrize("filter_3d", [True, False])
def test_the_kept_rows_are_the_numpy_masks_bit_for_bit_in_order(capsys, tmp_path, filter_3d):
    rows = rich_rows(filter_3d=filter_3d)
    source = write_rows(tmp_path / "in.ply", rows)
    target = tmp_path / "out.ply"
    code, out, err = run_cli(capsys, "convert", source, target, "--crop-box", "-1.8,-1.6,-2,1.7,1.9,1.5",
                             "--crop-sphere", "0.2,-0.1,0,2.6", "--min-opacity", "0.12", "--max-scale", "1.2")
    assert code == 0, err
    truth = numpy_truth(rows, (-1.8, -1.6, -2), (1.7, 1.9, 1.5), np.array([0.2, -0.1, 0]), 2.6, 0.12, 1.2)
    written = PlyData.read(str(target))
    assert written["vertex"].data.dtype == rows.dtype
    assert written["vertex"].data.tobytes() == rows[truth].tobytes()
    assert list(written.comments) == ["made for a test"]
    assert f"kept {truth.size:,} of 398 gaussians" in out  # the two NaN rows dropped at load
    removed = [int(line.rsplit(" ", 1)[1].replace(",", "")) for line in out.splitlines() if ": removed " in line]
    assert len(removed) == 4 and min(removed) > 0 and sum(removed) == 398 - truth.size, out


def test_each_filter_says_what_it_removed_of_those_left(capsys, tmp_path):
    rows = rich_rows(n=200, seed=9, invalid=())
    source = write_rows(tmp_path / "in.ply", rows)
    code, out, err = run_cli(capsys, "convert", source, tmp_path / "out.ply", "--crop-box", "-1,-1,-1,1,1,1",
                             "--max-scale", "0.05")
    assert code == 0, err
    in_box = numpy_truth(rows, (-1, -1, -1), (1, 1, 1))
    both = numpy_truth(rows, (-1, -1, -1), (1, 1, 1), max_scale=0.05)
    assert f"crop box -1,-1,-1,1,1,1: removed {200 - in_box.size}" in out
    assert f"max scale 0.05: removed {in_box.size - both.size}" in out
    assert f"kept {both.size} of 200 gaussians" in out


def test_a_ply_copied_whole_keeps_every_byte_of_every_row(capsys, tmp_path):
    rows = rich_rows(n=60, invalid=())
    source = write_rows(tmp_path / "in.ply", rows)
    code, out, err = run_cli(capsys, "convert", source, tmp_path / "out.ply")
    assert code == 0, err
    assert (tmp_path / "out.ply").read_bytes() == source.read_bytes()
    assert "note:" not in out  # nothing fused or clamped: the rows are the file's


def test_filters_into_a_lossy_format_keep_the_same_gaussians_in_order(capsys, tmp_path):
    rows = rich_rows(n=300, seed=4, filter_3d=False)
    source = write_rows(tmp_path / "in.ply", rows)
    code, out, err = run_cli(capsys, "convert", source, tmp_path / "out.spz", "--crop-sphere", "0,0,0,1.5",
                             "--min-opacity", "0.2")
    assert code == 0, err
    truth = numpy_truth(rows, centre=np.zeros(3), radius=1.5, min_opacity=0.2)
    scene, back = load_scene(source), load_scene(tmp_path / "out.spz")
    expected = scene.positions[np.searchsorted(scene.rows_in_file, truth)]
    assert back.count == truth.size
    np.testing.assert_allclose(back.positions, expected, atol=2e-3)  # .spz's fixed point


def test_values_that_start_with_a_minus_are_taken_as_values(capsys, tmp_path):
    source = write_rows(tmp_path / "in.ply", rich_rows(n=50, invalid=()))
    code, out, err = run_cli(capsys, "convert", source, tmp_path / "out.ply", "--crop-box", "-3,-3,-3,0,3,3",
                             "--crop-sphere", "-1,0,0,2.5")
    assert code == 0, err
    assert "crop sphere -1,0,0,2.5: removed" in out


@pytest.mark.parametrize("argv, words", [
    (["--crop-box", "1,0,0,0,1,1"], "--crop-box: X0 = 1 is greater than X1 = 0"),
    (["--crop-box", "0,0,2,1,1,1"], "Z0 = 2 is greater than Z1 = 1"),
    (["--crop-box", "0,0,0,1,1"], "is not 6 finite numbers"),
    (["--crop-box", "0,0,0,1,1,nan"], "is not 6 finite numbers"),
    (["--crop-sphere", "0,0,0,-1"], "--crop-sphere: the radius R = -1"),
    (["--min-opacity", "1.5"], "--min-opacity: 1.5 is outside 0..1"),
    (["--min-opacity", "-0.1"], "--min-opacity: -0.1 is outside 0..1"),
    (["--max-scale", "0"], "--max-scale: 0 is not a finite number > 0"),
    (["--crop-box", "5,5,5,6,6,6"], "keep none of the 50 gaussians"),
    (["--min-opacity", "1", "--max-scale", "1e-9"], "keep none of the 50 gaussians"),
])
def test_bad_filters_are_one_line_and_write_nothing(capsys, tmp_path, argv, words):
    source = write_rows(tmp_path / "in.ply", rich_rows(n=50, invalid=()))
    code, out, err = run_cli(capsys, "convert", source, tmp_path / "out.ply", *argv)
    assert words in assert_one_line_error(code, err)
    assert listing(tmp_path) == ["in.ply"]


def test_a_source_changed_since_it_was_read_is_refused(tmp_path):
    from raygs_viewer.errors import UserError
    from raygs_viewer.scene.ply_rows import PlyRows
    source = write_rows(tmp_path / "in.ply", rich_rows(n=20, invalid=()))
    with pytest.raises(UserError, match="changed since"):
        PlyRows(source, expected=21)
    with pytest.raises(UserError, match="changed since"):  # a subset's rows past a file that shrank
        PlyRows(source).write(np.array([3, 20]), tmp_path / "out.ply")
    assert not (tmp_path / "out.ply").exists()
