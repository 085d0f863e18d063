"""``--spz-axes rub|rdf`` on every command that reads a scene, and convert's
``--out-spz-axes``: info names the convention, convert re-labels a file for the other
convention's tools, render-path takes the one its path file recorded, and a bad value
is one line with exit status 2. (render --sidecar: tests/capture/test_sidecar.py; the
window: tests/viewer/test_app_spz_axes.py.)"""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from testkit import assert_one_line_error, listing, random_scene, run_cli, write_inria_ply

from raygs_viewer.camera.path import path_through_cameras
from raygs_viewer.camera.pinhole import frame_points, look_at
from raygs_viewer.capture.path_file import PathDocument, save_path_document
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.spz_format import SpzEncoding
from raygs_viewer.scene.writing import write_scene

F = np.array([1.0, -1.0, -1.0])


@pytest.fixture
def scene():
    return random_scene(n=60, seed=3, degree=2)


@pytest.fixture
def st_spz(tmp_path, scene):
    """A .spz in the PLY's axes, as splat-transform writes it."""
    return write_scene(scene, tmp_path / "st.spz", spz=SpzEncoding(axes="rdf"))


def stored_positions(path) -> np.ndarray:
    """The coordinates as the file stores them: read as RDF, the reader converts nothing
    (tests/scene/test_spz_axes.py checks that against the plain codec)."""
    return load_scene(SceneSource(path, spz_axes="rdf")).positions


# --------------------------------------------------------------------------- info


def test_info_names_the_convention_it_assumed(capsys, st_spz, tmp_path):
    code, out, err = run_cli(capsys, "info", st_spz)
    assert code == 0, err
    assert "axes:         RUB assumed (the .spz specification's; --spz-axes rdf for files splat-transform wrote)" in out
    code, out, err = run_cli(capsys, "info", st_spz, "--spz-axes", "rdf")
    assert code == 0 and "axes:         RDF assumed" in out, err
    code, out, err = run_cli(capsys, "info", st_spz, "--spz-axes", "rdf", "--json")
    info = json.loads(out)
    assert info["axes"] == {"stored": "RDF", "declared": False, "spz_axes": "rdf"}
    code, rub, err = run_cli(capsys, "info", st_spz, "--json")
    assert json.loads(rub)["bbox"]["min"][1] == pytest.approx(-info["bbox"]["max"][1])  # flipped in y
    ply = write_inria_ply(tmp_path / "s.ply")
    code, out, err = run_cli(capsys, "info", ply, "--spz-axes", "rdf")
    assert code == 0 and "axes:" not in out
    assert json.loads(run_cli(capsys, "info", ply, "--json")[1])["axes"] is None


# --------------------------------------------------------------------------- convert


def test_convert_relabels_a_splat_transform_file_for_the_specification(capsys, tmp_path, scene, st_spz):
    out = tmp_path / "niantic.spz"
    code, stdout, err = run_cli(capsys, "convert", st_spz, "--spz-axes", "rdf", "--out-spz-axes", "rub", out)
    assert code == 0, err
    assert f"read {st_spz}: spz v3, RDF axes" in stdout and f"read back {out}: spz v3, RUB axes" in stdout
    # The same gaussians, stored mirrored: now the right way up for readers of the specification.
    np.testing.assert_array_equal(stored_positions(out), stored_positions(st_spz) * F)
    back = load_scene(out)
    assert np.abs(back.positions - scene.positions).max() <= 2.0 ** -13 + 1e-6
    # And back again.
    again = tmp_path / "again.spz"
    assert run_cli(capsys, "convert", out, "--out-spz-axes", "rdf", again)[0] == 0
    np.testing.assert_array_equal(stored_positions(again), stored_positions(st_spz))


def test_convert_writes_in_the_input_axes_unless_told(capsys, tmp_path, scene, st_spz):
    same = tmp_path / "same.spz"
    code, stdout, err = run_cli(capsys, "convert", st_spz, "--spz-axes", "rdf", same, "--spz-version", "4")
    assert code == 0 and f"read back {same}: spz v4, RDF axes" in stdout, err
    np.testing.assert_array_equal(stored_positions(same), stored_positions(st_spz))
    # To a PLY: the right way up only when IN was read in its own axes.
    for axes, sign in (("rdf", 1.0), ("rub", -1.0)):
        ply = tmp_path / f"{axes}.ply"
        assert run_cli(capsys, "convert", st_spz, "--spz-axes", axes, ply)[0] == 0
        np.testing.assert_allclose(load_scene(ply).positions[:, 1:], sign * scene.positions[:, 1:],
                                   atol=2.0 ** -13 + 1e-6)
    # A PLY written out as .spz in rdf holds the PLY's own coordinates.
    ply_in = write_scene(scene, tmp_path / "in.ply")
    out = tmp_path / "from-ply.spz"
    assert run_cli(capsys, "convert", ply_in, "--out-spz-axes", "rdf", out)[0] == 0
    np.testing.assert_allclose(stored_positions(out), scene.positions, atol=2.0 ** -13 + 1e-6)


# --------------------------------------------------------------------------- render-path


def test_render_path_reads_the_spz_in_the_axes_its_path_file_recorded(tmp_path, st_spz):
    from raygs_viewer.cli.main import main

    rdf = load_scene(SceneSource(st_spz, spz_axes="rdf"))
    camera = frame_points(rdf.positions, 32, 24)
    other = look_at(camera.center * 1.1 + [0.1, 0.0, 0.0], rdf.positions.mean(axis=0), width=32, height=24)
    path = path_through_cameras([camera, other], duration=0.5, fps=4)
    runs = {}
    for recorded, option in ((None, None), ("rdf", None), ("rdf", "rdf"), ("rdf", "rub")):
        doc = PathDocument(path, 32, 24, RenderSettings(), None, str(st_spz), None,
                           scene_axes=None if recorded is None else FileAxes(recorded))
        file = save_path_document(doc, tmp_path / f"fly-{recorded}-{option}.json")
        frames = tmp_path / f"frames-{recorded}-{option}"
        argv = ["render-path", str(st_spz), str(file), "--out", str(frames), "--progress", "none"]
        assert main(argv + ([] if option is None else ["--spz-axes", option])) == 0
        runs[recorded, option] = [np.asarray(Image.open(p)) for p in sorted(frames.glob("frame_*.png"))]
    assert len(runs["rdf", None]) == 2
    np.testing.assert_array_equal(runs["rdf", None], runs["rdf", "rdf"])   # the recorded axes...
    np.testing.assert_array_equal(runs[None, None], runs["rdf", "rub"])    # ...or the option's, which wins
    assert np.abs(np.int32(runs["rdf", None]) - runs[None, None]).max() > 50  # and they differ


# --------------------------------------------------------------------------- bad values


@pytest.mark.parametrize("argv", [
    ["info", "SPZ"],
    ["render", "SPZ", "--out", "OUT/x.png"],
    ["verify", "SPZ"],
    ["render-path", "SPZ", "orbit", "--out", "OUT/frames"],
    ["view", "SPZ", "--frames", "1"],
    ["evaluate", "OUT", "--scene", "SPZ"],
    ["convert", "SPZ", "OUT/x.ply"],
    ["convert", "SPZ", "OUT/x.spz", "--out-spz-axes=RUB", "--spz-axes", "rdf"],
], ids=["info", "render", "verify", "render-path", "view", "evaluate", "convert", "convert-out"])
def test_a_bad_value_is_one_line_with_status_2_before_any_work(capsys, tmp_path, st_spz, argv):
    (tmp_path / "OUT").mkdir()
    argv = [str(st_spz) if a == "SPZ" else str(tmp_path / a[4:]) if a.startswith("OUT/") else
            str(tmp_path / "OUT") if a == "OUT" else a for a in argv]
    if "--out-spz-axes=RUB" not in argv:
        argv += ["--spz-axes", "up"]
    code, out, err = run_cli(capsys, *argv)
    message = assert_one_line_error(code, err)
    assert "spz-axes" in message and ("'up'" in message or "'RUB'" in message) and "rub" in message
    assert listing(tmp_path / "OUT") == []
