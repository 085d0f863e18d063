""".spz's two axis conventions: "rub" (the specification's, the default) and "rdf" (the
PLY's own, which PlayCanvas's splat-transform writes and reads unmarked).

A file written in "rdf" is checked three ways: its raw bytes (decoded by the plain codec
in spz_reference.py, which flips nothing) hold the scene's own coordinates; read back
in "rdf" it is the scene within the quantisation; read in "rub" it is the same decoded
gaussians seen through F = diag(1, -1, -1), with the SH signs derived from the basis
itself, not from the module's tables.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
import spz_reference as ref
import testkit
from test_spz import (
    DC_BOUND,
    LOG_SCALE_BOUND,
    OPACITY_BOUND,
    POSITION_BOUND,
    ROTATION_BOUND_DEG,
    ROTATION_BOUND_V2_DEG,
    SH1_BOUND,
    SH_REST_BOUND,
    SHARED_PLY,
    rdf_scene,
    rotation_angles_deg,
    rub_gaussians,
    write,
)

from raygs_viewer.scene.describe import describe, format_description
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import FileAxes, Scene
from raygs_viewer.scene.sh import sh_basis
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.spz_file import spz_bytes
from raygs_viewer.scene.writing import write_scene

F = np.array([1.0, -1.0, -1.0])
#: Made by splat-transform 3.7.0 from the shared metalsplatter-train3.ply (tests/fixtures/README.md).
SPLAT_TRANSFORM_SPZ = Path(__file__).resolve().parents[1] / "fixtures" / "metalsplatter-train3.splat-transform.spz"


def sh_signs(degree: int) -> np.ndarray:
    """(k,) the sign each SH coefficient takes under F: Y_k(F d) / Y_k(d) at a generic d."""
    d = np.array([[0.3, 0.5, 0.8]]) / np.linalg.norm([0.3, 0.5, 0.8])
    return np.sign(sh_basis(d * F, degree)[0] / sh_basis(d, degree)[0])


def assert_within_quantisation(back: Scene, scene: Scene, version: int) -> None:
    assert back.count == scene.count and back.sh_degree == scene.sh_degree
    assert np.abs(back.positions - scene.positions).max() <= POSITION_BOUND + 2.0 ** -22
    assert np.abs(np.log(back.scales / scene.scales)).max() <= LOG_SCALE_BOUND + 1e-5
    assert np.abs(back.opacities - scene.opacities).max() <= OPACITY_BOUND + 1e-6
    assert np.abs(back.sh[:, 0] - scene.sh[:, 0]).max() <= DC_BOUND + 1e-6
    assert np.abs(back.sh[:, 1:4] - scene.sh[:, 1:4]).max(initial=0) <= SH1_BOUND + 1e-6
    assert np.abs(back.sh[:, 4:] - scene.sh[:, 4:]).max(initial=0) <= SH_REST_BOUND + 1e-6
    bound = ROTATION_BOUND_V2_DEG if version == 2 else ROTATION_BOUND_DEG
    assert rotation_angles_deg(back.rotations, scene.rotations).max() <= bound


def assert_flipped(rub: Scene, rdf: Scene) -> None:
    """``rub`` is exactly ``rdf`` seen through F: positions F p, the quaternion's y and z
    negated (the rotation F R F), each SH coefficient odd under F negated."""
    np.testing.assert_array_equal(rub.positions, rdf.positions * F.astype(np.float32))
    np.testing.assert_array_equal(rub.rotations, rdf.rotations * np.float32([1, 1, -1, -1]))
    signs = sh_signs(rdf.sh_degree).astype(np.float32)
    np.testing.assert_array_equal(rub.sh, rdf.sh * signs[None, :, None])
    np.testing.assert_array_equal(rub.scales, rdf.scales)
    np.testing.assert_array_equal(rub.opacities, rdf.opacities)


@pytest.mark.parametrize("version", [2, 3, 4])
def test_a_file_written_in_rdf_reads_back_in_rdf_and_flipped_in_rub(tmp_path, version):
    scene = rdf_scene(n=500, degree=3, seed=10 + version, w_min=0.3 if version == 2 else 0.0)
    path = write(tmp_path, spz_bytes(scene, version, spz_axes="rdf"))
    raw = ref.unpack(path.read_bytes())  # no axes at all: the bytes as stored
    assert np.abs(np.asarray(raw["positions"]) - scene.positions).max() <= POSITION_BOUND + 2.0 ** -22
    rdf = load_scene(SceneSource(path, spz_axes="rdf"))
    assert rdf.axes == FileAxes("rdf") and rdf.axes.stored == "RDF"
    assert_within_quantisation(rdf, scene, version)
    rub = load_scene(SceneSource(path, spz_axes="rub"))
    assert rub.axes == FileAxes("rub") and rub.axes.stored == "RUB"
    assert_flipped(rub, rdf)
    assert (np.abs(rub.positions[:, 1:] - scene.positions[:, 1:]) > 0.1).any()  # the flip is no small change
    default = load_scene(path)
    np.testing.assert_array_equal(default.positions, rub.positions)
    assert default.axes == FileAxes("rub")


def test_rub_and_rdf_files_hold_the_same_scene_in_mirrored_bytes(tmp_path):
    """The default writes RUB: the raw positions of the two files differ by F."""
    scene = rdf_scene(n=50, degree=1, seed=4)
    rub = ref.unpack(spz_bytes(scene, 3))
    rdf = ref.unpack(spz_bytes(scene, 3, spz_axes="rdf"))
    np.testing.assert_array_equal(np.asarray(rub["positions"]), np.asarray(rdf["positions"]) * F)
    both = [load_scene(SceneSource(write(tmp_path, spz_bytes(scene, 3, spz_axes=axes), f"{axes}.spz"), spz_axes=axes))
            for axes in ("rub", "rdf")]
    for back in both:
        assert_within_quantisation(back, scene, 3)


@pytest.mark.parametrize("declared,name", [(4, "RUB"), (6, "RDF"), (2, "RDB")])
def test_a_declared_coordinate_system_wins_over_the_option(tmp_path, declared, name):
    g = rub_gaussians(n=10, degree=2, seed=5)
    extension = struct.pack("<III", 0xADBE0003, 4, declared)
    path = write(tmp_path, ref.pack(g, 4, flags=2, extensions=extension))
    stored = np.asarray(ref.unpack(ref.pack(g, 4))["positions"], np.float32)
    flips = {4: F, 6: np.ones(3), 2: np.array([1.0, 1.0, -1.0])}[declared].astype(np.float32)
    for option in ("rub", "rdf"):
        scene = load_scene(SceneSource(path, spz_axes=option))
        np.testing.assert_array_equal(scene.positions, stored * flips)
        assert scene.axes == FileAxes(option, name) and scene.axes.stored == name


def test_an_unknown_convention_is_a_one_line_error_before_reading(tmp_path):
    path = write(tmp_path, spz_bytes(rdf_scene(n=3, degree=0)))
    # The source refuses it when it is made, before any file is opened.
    testkit.assert_user_error(lambda: load_scene(SceneSource(path, spz_axes="RDF")), "RDF", "rub or rdf")
    testkit.assert_user_error(lambda: SceneSource(tmp_path / "absent.ply", spz_axes="up"), "up", "rub or rdf")
    testkit.assert_user_error(lambda: spz_bytes(rdf_scene(n=3, degree=0), 3, spz_axes="luf"), "luf", "rub or rdf")


def test_other_formats_have_no_axes_and_info_names_the_convention(tmp_path):
    scene = rdf_scene(n=20, degree=1, seed=2)
    assert load_scene(SceneSource(write_scene(scene, tmp_path / "s.ply"), spz_axes="rdf")).axes is None
    path = write(tmp_path, spz_bytes(scene, 4, spz_axes="rdf"))
    lines = {}
    for option in ("rub", "rdf"):
        info = describe(load_scene(SceneSource(path, spz_axes=option)))
        assert info["axes"] == {"stored": option.upper(), "declared": False, "spz_axes": option}
        lines[option] = [line for line in format_description(info).splitlines() if line.startswith("axes:")]
    assert len(lines["rub"]) == 1 and "RUB assumed" in lines["rub"][0] and "--spz-axes rdf" in lines["rub"][0]
    assert len(lines["rdf"]) == 1 and "RDF assumed" in lines["rdf"][0] and "splat-transform" in lines["rdf"][0]
    declared = describe(load_scene(write(tmp_path, ref.pack(rub_gaussians(n=3, degree=0), 4, flags=2,
                                                            extensions=struct.pack("<III", 0xADBE0003, 4, 6)),
                                         "declared.spz")))
    assert declared["axes"] == {"stored": "RDF", "declared": True, "spz_axes": "rub"}
    assert "axes:         RDF declared by the file" in format_description(declared)
    assert "axes:" not in format_description(describe(scene))
    assert describe(scene)["axes"] is None


# --------------------------------------------------------------------------- splat-transform's own file


def test_the_splat_transform_fixture_is_a_small_unmarked_v4_file():
    data = SPLAT_TRANSFORM_SPZ.read_bytes()
    assert len(data) < 1000
    head, _ = ref.payload(data)
    assert (head["version"], head["n"], head["degree"], head["flags"]) == (4, 3, 3, 0)  # no extension
    assert load_scene(SPLAT_TRANSFORM_SPZ).axes == FileAxes("rub")


@pytest.mark.skipif(not SHARED_PLY.exists(), reason="shared scenes folder absent")
def test_splat_transforms_file_matches_its_ply_in_rdf_and_opens_flipped_by_default():
    ply = load_scene(SHARED_PLY)
    rdf = load_scene(SceneSource(SPLAT_TRANSFORM_SPZ, spz_axes="rdf"))
    assert_within_quantisation(rdf, ply, 4)
    rub = load_scene(SPLAT_TRANSFORM_SPZ)
    assert_flipped(rub, rdf)
    # Upside down and back to front: y and z of every gaussian on the wrong side.
    np.testing.assert_allclose(rub.positions[:, 1:], -ply.positions[:, 1:], atol=POSITION_BOUND + 2.0 ** -22)
    assert np.abs(rub.positions[:, 1:] - ply.positions[:, 1:]).max() > 0.1
