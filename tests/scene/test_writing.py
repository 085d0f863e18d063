"""Writing scenes (scene/writing.py): INRIA PLY and .splat read back by the project's own
readers, the file layouts checked independently with plyfile and numpy, and
write_scene's atomic, never-clobbering dispatch by suffix."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from plyfile import PlyData
from testkit import assert_user_error, random_scene

from raygs_viewer.errors import UserError
from raygs_viewer.scene import writing
from raygs_viewer.scene.compare import rotation_angles
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.spz_format import SpzEncoding
from raygs_viewer.scene.writing import (
    OPACITY_LOGIT_LIMIT,
    SMALLEST_SCALE,
    ply_bytes,
    ply_chunks,
    ply_property_names,
    splat_bytes,
    write_scene,
    writing_notes,
)

C0 = 0.28209479177387814
EPS32 = 2.0 ** -24  # float32's unit roundoff


def edge_scene(degree: int, n: int = 300, seed: int = 1) -> Scene:
    """A random scene plus the extremes a loaded scene can hold (none of which a reader
    drops): opacity exactly 0 and 1 and nearly so, tiny and huge scales, far positions,
    large SH coefficients."""
    base = random_scene(n=n, seed=seed, degree=degree)
    positions, scales = base.positions.copy(), base.scales.copy()
    opacities, sh = base.opacities.copy(), base.sh.copy()
    opacities[:6] = [0.0, 1.0, 1e-30, np.nextafter(np.float32(1), np.float32(0)), 0.5, 1e-7]
    scales[6] = [1e-30, 1e30, 3e-38]
    scales[7] = [1.0, 0.5, 2.0 ** -20]
    positions[8] = [1e20, -1e-20, 0.0]
    sh[9] = 1e6
    sh[10] = -1e-6
    return Scene(positions, base.rotations, scales, opacities, sh, degree)


def write_and_read(scene: Scene, path):
    written = write_scene(scene, path)
    assert written == path
    return load_scene(path)


# --------------------------------------------------------------------------- INRIA PLY


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_ply_round_trip_is_exact_but_for_float32_rounding_of_log_and_logit(tmp_path, degree):
    scene = edge_scene(degree)
    back = write_and_read(scene, tmp_path / "scene.ply")
    assert back.dropped == {} and back.count == scene.count and back.sh_degree == degree
    assert back.format == "INRIA PLY"
    # Copied as float32: exact.
    np.testing.assert_array_equal(back.positions, scene.positions)
    np.testing.assert_array_equal(back.sh, scene.sh)
    # The reader normalises the (already unit) quaternion again: a rounding or two.
    np.testing.assert_allclose(back.rotations, scene.rotations, rtol=0, atol=4 * EPS32)
    # exp(float32(ln s)): the rounding of the log-scale l (|l| eps) and of the result (eps).
    s = scene.scales.astype(np.float64)
    bound = (np.abs(np.log(s)) + 1.0) * EPS32 * 1.01
    normal = s >= np.finfo(np.float32).tiny  # subnormals carry fewer bits: checked below
    assert np.all(np.abs(back.scales / s - 1.0)[normal] <= bound[normal])
    assert np.all(back.scales[~normal] > 0)
    # sigmoid(float32(logit o)): d o / d x = o(1-o), then the rounding of o itself.
    o = scene.opacities.astype(np.float64)
    with np.errstate(divide="ignore"):
        x = np.clip(np.log(o) - np.log1p(-o), -OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT)
    error = np.abs(back.opacities.astype(np.float64) - o)
    assert np.all(error <= (o * (1 - o) * np.abs(x) + o) * EPS32 * 1.01)
    assert back.opacities[0] == 0.0 and back.opacities[1] == 1.0  # the clipped logits read back exactly


@pytest.mark.parametrize("degree", [0, 3])
def test_ply_file_layout_read_with_plyfile(tmp_path, degree):
    """The columns as the INRIA trainer writes them, read with plyfile (not our reader):
    so a layout mistake our reader happens to share cannot hide."""
    scene = random_scene(n=20, seed=4, degree=degree)
    path = write_scene(scene, tmp_path / "layout.ply")
    ply = PlyData.read(str(path))
    assert ply.text is False and ply.byte_order == "<"
    vertex = ply["vertex"]
    assert [p.name for p in vertex.properties] == ply_property_names(degree)
    assert all(p.val_dtype == "f4" for p in vertex.properties)
    data = vertex.data
    for axis, name in enumerate("xyz"):
        np.testing.assert_array_equal(data[name], scene.positions[:, axis])
        assert np.all(data["n" + name] == 0)
    k = sh_coefficient_count(degree) - 1
    for c in range(3):
        np.testing.assert_array_equal(data[f"f_dc_{c}"], scene.sh[:, 0, c])
        for j in range(k):  # channel-major: f_rest[c*K + j] is coefficient j+1 of channel c
            np.testing.assert_array_equal(data[f"f_rest_{c * k + j}"], scene.sh[:, j + 1, c])
    o = scene.opacities.astype(np.float64)
    np.testing.assert_allclose(data["opacity"], np.log(o / (1 - o)), rtol=1e-6)
    for a in range(3):
        np.testing.assert_allclose(data[f"scale_{a}"], np.log(scene.scales[:, a].astype(np.float64)), rtol=1e-6)
    for a in range(4):
        np.testing.assert_array_equal(data[f"rot_{a}"], scene.rotations[:, a])


def test_ply_chunks_give_the_same_bytes_as_one_piece():
    scene = random_scene(n=50, seed=2, degree=2)
    assert b"".join(ply_chunks(scene, chunk_rows=7)) == ply_bytes(scene)


def test_opacity_0_and_1_and_scale_0_are_written_finite_and_said(tmp_path):
    scene = random_scene(n=4, seed=3, degree=0)
    opacities, scales = scene.opacities.copy(), scene.scales.copy()
    opacities[:2] = [0.0, 1.0]
    scales[2, 1] = 0.0
    scene = Scene(scene.positions, scene.rotations, scales, opacities, scene.sh, 0)
    path = write_scene(scene, tmp_path / "edges.ply")
    data = PlyData.read(str(path))["vertex"].data
    assert list(data["opacity"][:2]) == [-OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT]
    assert data["scale_1"][2] == np.float32(np.log(SMALLEST_SCALE))
    for name in data.dtype.names:
        assert np.all(np.isfinite(data[name])), name
    back = load_scene(path)
    assert back.dropped == {}
    assert list(back.opacities[:2]) == [0.0, 1.0] and back.scales[2, 1] == np.float32(SMALLEST_SCALE)
    notes = " ".join(writing_notes(scene, ".ply"))
    assert "opacity exactly 1 (1 gaussians) or 0 (1)" in notes and f"{OPACITY_LOGIT_LIMIT:g}" in notes
    assert "1 gaussians have a scale of 0" in notes


def test_unwritable_values_are_refused_before_a_file_appears(tmp_path):
    scene = random_scene(n=3, seed=0, degree=0)
    opacities = scene.opacities.copy()
    opacities[1] = np.nan
    bad = Scene(scene.positions, scene.rotations, scene.scales, opacities, scene.sh, 0)
    with pytest.raises(ValueError, match="opacities"):
        write_scene(bad, tmp_path / "bad.ply")
    assert list(tmp_path.iterdir()) == []  # no file, no temporary left behind


# --------------------------------------------------------------------------- .splat


def test_splat_round_trip_within_its_quantisation(tmp_path):
    scene = edge_scene(3)
    back = write_and_read(scene, tmp_path / "scene.splat")
    assert back.dropped == {} and back.count == scene.count and back.format == ".splat"
    assert back.sh_degree == 0  # SH beyond the base colour is lost
    np.testing.assert_array_equal(back.positions, scene.positions)  # float32 as stored
    np.testing.assert_array_equal(back.scales, scene.scales)
    # RGB and alpha bytes: half a step of 1/255 (plus float32 rounding of the DC term),
    # against the colour clipped to 0..1, which is all a byte holds.
    rgb = np.clip(0.5 + C0 * scene.sh[:, 0].astype(np.float64), 0, 1)
    back_rgb = 0.5 + C0 * back.sh[:, 0].astype(np.float64)
    assert np.max(np.abs(back_rgb - rgb)) <= 0.5 / 255 + 1e-6
    assert np.max(np.abs(back.opacities - scene.opacities.astype(np.float64))) <= 0.5 / 255 + 1e-6
    # Each quaternion component to 1/128 (+1 clipped to 127/128): at most about 1.2 degrees.
    angles = np.degrees(rotation_angles(scene.rotations, back.rotations))
    assert np.max(angles) <= 1.2


def test_splat_rows_byte_for_byte():
    """One gaussian's 32 bytes, computed by hand: float32 position and scale, RGBA bytes,
    quaternion bytes q*128+128 (w first)."""
    sh = np.zeros((1, 16, 3), np.float32)
    sh[0, 0] = (np.array([0.8, 0.6, 0.4]) - 0.5) / C0
    sh[0, 5] = 9.0  # SH rest: not written
    scene = Scene(np.float32([[1.5, -2.0, 3.25]]), np.float32([[0.6, 0.0, -0.8, 0.0]]),
                  np.float32([[0.1, 0.2, 0.3]]), np.float32([0.25]), sh, 3)
    data = splat_bytes(scene)
    assert len(data) == 32
    assert np.frombuffer(data[:12], "<f4").tolist() == scene.positions[0].tolist()
    assert np.frombuffer(data[12:24], "<f4").tolist() == scene.scales[0].tolist()
    assert list(data[24:28]) == [204, 153, 102, 64]  # 0.8, 0.6, 0.4, 0.25 times 255, rounded
    assert list(data[28:32]) == [205, 128, 26, 128]  # 0.6, 0, -0.8, 0 -> q*128+128 rounded


def test_splat_notes_say_what_is_lost():
    scene = random_scene(n=30, seed=5, degree=3)  # DC ~ N(0, 1): some colours outside 0..1
    notes = " ".join(writing_notes(scene, ".splat"))
    assert "SH degree 3 -> 0" in notes and "outside 0..1" in notes
    assert writing_notes(random_scene(n=30, seed=5, degree=3), ".ply") == []
    # Colours a byte holds exactly (b/255 decoded, 1e-8 outside 0..1 after rounding) are not clipped.
    sh = np.zeros((2, 1, 3), np.float32)
    sh[:, 0] = (np.float32([[0.0, 1.0, 0.5], [-0.4 / 255, 1 + 0.4 / 255, 0.5]]) - 0.5) / np.float32(C0)
    exact = Scene(np.zeros((2, 3), np.float32), np.tile(np.float32([1, 0, 0, 0]), (2, 1)),
                  np.ones((2, 3), np.float32), np.ones(2, np.float32), sh, 0)
    assert writing_notes(exact, ".splat") == []


def test_spz_notes_count_what_its_bytes_clamp(tmp_path):
    scene = random_scene(n=40, seed=2, degree=1, log_scale=(-4.0, -1.5))
    assert writing_notes(scene, ".spz") == []
    scales, sh = scene.scales.copy(), scene.sh.copy()
    scales[:3, 1] = np.exp(np.float32(-12.0))   # below e^-10: three axes clamped
    scales[5, 2] = np.exp(np.float32(7.0))      # above e^5.94: one more
    sh[7, 0, 0] = 4.0                            # beyond the colour byte's +/-3.33
    notes = writing_notes(dataclasses.replace(scene, scales=scales, sh=sh), ".spz")
    assert len(notes) == 2 and notes[0].startswith("4 scale axes") and notes[1].startswith("1 gaussian has")
    # What the note says is what happens: the clamped scale reads back at the range's end.
    clamped = load_scene(writing.write_scene(dataclasses.replace(scene, scales=scales), tmp_path / "c.spz"))
    assert abs(np.log(clamped.scales[0, 1]) - (-10.0)) < 1e-6


@pytest.mark.parametrize("suffix", [".ply", ".splat"])
def test_an_empty_scene_round_trips(tmp_path, suffix):
    empty = random_scene(n=0, degree=0)
    back = write_and_read(empty, tmp_path / f"empty{suffix}")
    assert back.count == 0


# --------------------------------------------------------------------------- write_scene


@pytest.mark.parametrize("suffix", [".ply", ".splat", ".PLY"])
def test_write_scene_never_clobbers(tmp_path, suffix):
    path = tmp_path / f"there{suffix}"
    path.write_bytes(b"the user's file")
    scene = random_scene(n=5, degree=1)
    assert_user_error(lambda: write_scene(scene, path), path, "already exists", "--overwrite")
    assert path.read_bytes() == b"the user's file"
    write_scene(scene, path, overwrite=True)
    assert load_scene(path).count == 5
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left


def test_write_scene_refuses_what_it_cannot_write(tmp_path):
    scene = random_scene(n=2, degree=0)
    assert_user_error(lambda: write_scene(scene, tmp_path / "out.txt"), "out.txt", ".ply", ".splat", ".spz")
    assert_user_error(lambda: write_scene(scene, tmp_path / "no" / "out.ply"), "out.ply", "does not exist")
    assert_user_error(lambda: write_scene(scene, tmp_path / "out.spz", spz=SpzEncoding(2)), "out.spz", "version 2")
    (tmp_path / "folder.ply").mkdir()
    assert_user_error(lambda: write_scene(scene, tmp_path / "folder.ply", overwrite=True), "folder.ply", "folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder.ply"]


@pytest.mark.parametrize("version,axes", [(3, None), (4, None), (3, "rdf"), (4, "rub")])
def test_spz_goes_through_spz_bytes_with_its_version_and_axes(tmp_path, monkeypatch, version, axes):
    """The dispatch alone (the .spz encoder is scene/spz_file.py's, tested there)."""
    calls = []

    def fake_spz_bytes(scene, version, spz_axes):
        calls.append((scene.count, version, spz_axes))
        return b"NGSP fake"

    monkeypatch.setattr(writing, "spz_bytes", fake_spz_bytes)
    given = {} if axes is None else {"axes": axes}
    path = write_scene(random_scene(n=3, degree=0), tmp_path / "out.spz", spz=SpzEncoding(version, **given))
    assert calls == [(3, version, axes or "rub")] and path.read_bytes() == b"NGSP fake"


def test_an_unknown_spz_axes_is_refused_before_writing(tmp_path):
    for name in ("out.spz", "out.ply"):
        assert_user_error(lambda: write_scene(random_scene(n=3, degree=0), tmp_path / name,
                                              spz=SpzEncoding(axes="lub")),
                          "lub", "rub or rdf")
    assert list(tmp_path.iterdir()) == []


def test_spz_writer_failure_leaves_nothing(tmp_path, monkeypatch):
    def failing(scene, version, spz_axes):
        raise UserError("cannot encode")

    monkeypatch.setattr(writing, "spz_bytes", failing)
    with pytest.raises(UserError, match="cannot encode"):
        write_scene(random_scene(n=3, degree=0), tmp_path / "out.spz")
    assert list(tmp_path.iterdir()) == []
