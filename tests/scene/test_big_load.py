"""Scenes of millions (issue 16, part 4): the PLY reader streams fixed-size rows from the
file into the final arrays a chunk at a time. These tests run it on generated files
(small by default; ``RAYGS_LOAD_TEST_COUNT=3000000`` runs the real size) against a
frozen copy of the reader it replaced (ply_reference.py). Time and memory are measured
by ``raygs-viewer bench sort`` (raygs_viewer.bench.loading), never asserted here.
"""

from __future__ import annotations

import os
from unittest import mock

import numpy as np
import plyfile
import pytest
from ply_reference import reference_load_ply
from testkit import gaussian_columns, write_ply

from raygs_viewer.bench.loading import ply_property_names, write_generated_ply
from raygs_viewer.errors import UserError
from raygs_viewer.scene import io as scene_io
from raygs_viewer.scene.io import load_scene

_COUNT = int(os.environ.get("RAYGS_LOAD_TEST_COUNT", "20000"))
_FIELDS = ("positions", "rotations", "scales", "opacities", "sh")


def load_as_before(path, **kwargs):
    with mock.patch.object(scene_io, "load_ply", reference_load_ply):
        return load_scene(path, **kwargs)


def assert_bitwise_equal(scene, reference):
    for field in _FIELDS:
        ours, theirs = getattr(scene, field), getattr(reference, field)
        assert (ours.dtype, ours.shape) == (theirs.dtype, theirs.shape), field
        assert ours.tobytes() == theirs.tobytes(), field
    assert (scene.count, scene.sh_degree, scene.filter_fused, scene.dropped) == \
        (reference.count, reference.sh_degree, reference.filter_fused, reference.dropped)


def spoil(path, count, sh_degree, seed=1):
    """Writes every drop reason and activation edge into scattered rows of a generated
    file: NaN, infinities, zero and overflowing scales, zero quaternions, logits of +-inf."""
    names = ply_property_names(sh_degree)
    header = path.read_bytes()[:4096]
    offset = header.index(b"end_header\n") + len(b"end_header\n")
    rows = np.memmap(path, np.float32, "r+", offset, (count, len(names)))
    rng = np.random.default_rng(seed)
    column = {name: i for i, name in enumerate(names)}
    edits = [("x", np.nan), ("y", np.inf), ("scale_1", 200.0), ("scale_0", -np.inf), ("scale_2", -120.0),
             ("rot_0", np.inf), ("f_dc_2", -np.inf), (names[-9], np.inf), ("opacity", np.inf),
             ("opacity", -np.inf), ("opacity", np.nan), ("nx", np.nan)]
    for name, value in edits:
        rows[rng.integers(0, count, max(1, count // 500)), column[name]] = value
    zero_quaternion = rng.integers(0, count, max(1, count // 500))
    for axis in range(4):
        rows[zero_quaternion, column[f"rot_{axis}"]] = 0.0
    rows.flush()
    del rows


@pytest.mark.parametrize("sh_degree", [3, 1])
def test_a_generated_scene_loads_bit_for_bit_as_before(tmp_path, sh_degree):
    """Many chunks (64 KiB each), invalid gaussians in most of them: the same Scene as
    the reader before issue 16, dropped counts and the compacted arrays included."""
    path = write_generated_ply(tmp_path / "generated.ply", _COUNT, sh_degree=sh_degree, seed=7)
    spoil(path, _COUNT, sh_degree)
    scene = load_scene(path, chunk_bytes=64 << 10)
    reference = load_as_before(path)
    assert set(scene.dropped) >= {"nan", "infinite position", "infinite scale", "zero scale",
                                  "infinite rotation", "zero quaternion", "infinite colour"}
    assert_bitwise_equal(scene, reference)


def test_fixed_size_rows_are_read_without_plyfile(tmp_path, monkeypatch):
    """The fast path is the one taken: plyfile (a memory map gathered column by column)
    only reads files whose other elements hold lists."""
    cols = gaussian_columns(50, degree=3, normals=True)
    plain = write_ply(tmp_path / "plain.ply", cols, elements_before=[("element meta 2\nproperty double t", bytes(16))])
    listed = write_ply(tmp_path / "listed.ply", cols,
                       elements_after=[("element face 1\nproperty list uchar int idx", bytes([1]) + bytes(4))])
    expected = load_scene(listed)

    def refuse(*args, **kwargs):
        raise AssertionError("plyfile read the file")

    monkeypatch.setattr(plyfile.PlyData, "read", refuse)
    assert_bitwise_equal(load_scene(plain, chunk_bytes=1000), expected)
    with pytest.raises(AssertionError, match="plyfile read the file"):
        load_scene(listed)


def test_a_file_that_shrinks_while_loading_is_a_user_error(tmp_path):
    path = write_ply(tmp_path / "shrinks.ply", gaussian_columns(40, degree=1))

    def progress(fraction, stage):
        if stage == "reading" and fraction > 0:  # after the first chunk: cut the file short
            os.truncate(path, path.stat().st_size // 2)

    with pytest.raises(UserError) as info:
        load_scene(path, progress=progress, chunk_bytes=256)
    assert str(info.value) == f"{path}: truncated PLY file (the file shrank while reading)"


@pytest.mark.parametrize("where, inserted, line", [(2, b"", 3), (4, b"obj_info made by hand", 5)])
def test_headers_plyfile_refused_still_fail_unless_empty(tmp_path, where, inserted, line):
    """An empty header line or an obj_info after an element: plyfile refused those before
    issue 16, so such a file still fails to load, except with no gaussians (their data,
    which plyfile read, was never needed)."""
    for count in (3, 0):
        lines = write_ply(tmp_path / "base.ply", gaussian_columns(count)).read_bytes().split(b"\n")
        lines.insert(where, inserted)  # after "ply", "format ..."; after "element vertex N", "property x"
        path = tmp_path / f"odd{count}.ply"
        path.write_bytes(b"\n".join(lines))
        if count:
            with pytest.raises(UserError, match=f"cannot read PLY data \\(PLY header line {line}: "):
                load_scene(path)
            with pytest.raises(UserError, match="cannot read PLY data"):
                load_as_before(path)
        else:
            assert load_scene(path).count == load_as_before(path).count == 0
