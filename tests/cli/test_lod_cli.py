"""Streamed SOG on the command line: the contract (``render DIR/lod-meta.json --lod 0``
renders the finest level; ``convert DIR/lod-meta.json --lod N OUT.ply`` writes level N),
``--lod-budget`` and its sidecar, ``info``'s levels, render-path, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from lod_kit import random_gaussians, write_streamed_sog
from testkit import assert_matches, assert_one_line_error, run_cli, write_inria_ply

from raygs_viewer.camera.pinhole import camera_to_json, look_at
from raygs_viewer.capture.sidecar import build_sidecar
from raygs_viewer.render.gl.storage import gpu_bytes
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.content_hash import file_sha256
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.lod_file import load_lod
from raygs_viewer.sort.lod_choice import choose

CAMERA = look_at([0.0, -0.3, -2.0], [1.5, 0.0, 3.0], width=40, height=30)


@pytest.fixture(scope="module")
def streamed(tmp_path_factory):
    leaves = [[random_gaussians(24 >> level, centre=(1.2 * k, 0.0, 2.0 + 1.5 * k), spread=0.3,
                                scale=0.05 * 1.6 ** level, seed=5 * k + level) for level in range(3)] for k in range(4)]
    environment = random_gaussians(8, spread=30.0, scale=1.5, seed=1)
    folder = tmp_path_factory.mktemp("cli-lod")
    return write_streamed_sog(folder / "scene", leaves, environment=environment)


def camera_file(tmp_path):
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps([camera_to_json(CAMERA, 0, "view")]))
    return path


def test_render_lod_0_renders_the_finest_level(capsys, tmp_path, streamed):
    out = tmp_path / "finest.npy"
    code, stdout, _ = run_cli(capsys, "render", streamed, "--lod", "0", "--camera", camera_file(tmp_path),
                              "--out", out)
    assert code == 0 and "8 + 0" not in stdout
    image = np.load(out)
    settings = RenderSettings()
    assert_matches(image, render_reference(load_scene(streamed, lod=0), CAMERA, settings))
    coarse = tmp_path / "coarse.npy"
    assert run_cli(capsys, "render", streamed.parent, "--lod", "2", "--camera", camera_file(tmp_path),
                   "--out", coarse)[0] == 0
    assert np.abs(np.load(coarse) - image).max() > 0.05  # another level, another picture


def test_convert_lod_n_writes_level_n_with_its_environment(capsys, tmp_path, streamed):
    out = tmp_path / "level1.ply"
    code, stdout, _ = run_cli(capsys, "convert", streamed, "--lod", "1", out)
    assert code == 0 and "level 1 of 0..2 with its environment (8)" in stdout
    written, level = load_scene(out), load_scene(streamed, lod=1)
    assert written.count == 8 + 4 * 12
    np.testing.assert_array_equal(written.positions, level.positions)


def test_info_lists_the_levels(capsys, streamed):
    code, stdout, _ = run_cli(capsys, "info", streamed)
    assert code == 0
    assert "levels:       3 (0 the finest; gaussians per level 0: 96, 1: 48, 2: 24); 4 parts in 3 files; " \
           "environment 8 gaussians" in stdout
    code, stdout, _ = run_cli(capsys, "info", streamed, "--json")
    lod = json.loads(stdout)["lod"]
    assert lod.pop("gpu_bytes") == gpu_bytes(8 + 96 + 48 + 24, 0)
    assert lod == {"levels": 3, "counts": [96, 48, 24], "leaves": 4, "files": 3, "environment": 8}


def test_a_budget_renders_the_choice_and_its_sidecar_renders_it_again(capsys, tmp_path, streamed):
    settings = RenderSettings(lod_budget=60, lod_distance=3.0)
    lod = load_lod(streamed)
    choice = choose(lod, CAMERA, budget=60, distance=3.0)
    assert len(set(choice.levels.tolist())) > 1 and choice.count <= 60
    out = tmp_path / "budget.npy"
    code, stdout, _ = run_cli(capsys, "render", streamed, "--lod-budget", "60", "--lod-distance", "3",
                              "--camera", camera_file(tmp_path), "--out", out)
    assert code == 0 and f"{choice.count} of {lod.scene.count} gaussians" in stdout
    assert_matches(np.load(out), render_reference(lod.subset(choice.spans), CAMERA, RenderSettings()))
    sidecar = tmp_path / "shot.json"
    sidecar.write_text(json.dumps(build_sidecar(
        scene_path=str(streamed), scene_sha256=file_sha256(streamed), scene=lod.scene, camera=CAMERA,
        settings=settings, scale=1.0)))
    again = tmp_path / "again.npy"
    assert run_cli(capsys, "render", "--sidecar", sidecar, "--out", again)[0] == 0
    np.testing.assert_array_equal(np.load(again), np.load(out))
    reference = tmp_path / "reference.npy"
    assert run_cli(capsys, "render", "--sidecar", sidecar, "--reference", "--out", reference)[0] == 0
    assert_matches(np.load(out), np.load(reference))


def test_render_path_chooses_for_each_frame(capsys, tmp_path, streamed):
    out = tmp_path / "frames"
    code, _, err = run_cli(capsys, "render-path", streamed, "orbit", "--out", out, "--size", "32x24",
                           "--duration", "0.2", "--fps", "10", "--lod-budget", "40", "--progress", "none")
    assert code == 0, err
    assert len(list(out.glob("*.png"))) == 2


@pytest.mark.parametrize("argv,fragment", [
    (["render", "{ply}", "--lod", "1"], "not a streamed SOG: --lod applies to a lod-meta.json scene"),
    (["render", "demo", "--lod-budget", "10"], "the demo scene: not a streamed SOG"),
    (["render", "{lod}", "--lod", "3"], "has levels 0..2; level 3 does not exist"),
    (["render", "{lod}", "--lod-budget", "0"], "--lod-budget"),
    (["convert", "{ply}", "--lod", "1", "{out}"], "not a streamed SOG"),
])
def test_bad_level_options_are_one_line(capsys, tmp_path, streamed, argv, fragment):
    ply = write_inria_ply(tmp_path / "plain.ply")
    names = {"ply": ply, "lod": streamed, "out": tmp_path / "x.ply"}
    argv = [a.format(**names) for a in argv]
    if argv[0] == "render":
        argv += ["--out", str(tmp_path / "x.png")]
    code, _, err = run_cli(capsys, *argv)
    assert fragment in assert_one_line_error(code, err)


def test_a_sidecar_taken_before_the_finer_levels_were_read_renders_from_those_read(capsys, tmp_path, streamed):
    partial = load_lod(streamed, levels=(1, 2))
    choice = choose(partial, CAMERA, distance=5.0)
    assert choice.wanted.min() == 0 and choice.levels.min() == 1  # level 0 wanted, not yet read
    data = build_sidecar(scene_path=str(streamed), scene_sha256=file_sha256(streamed), scene=partial.scene,
                         camera=CAMERA, settings=RenderSettings(lod_distance=5.0), scale=1.0, levels=(2, 1))
    assert data["scene"]["lod_levels"] == [1, 2]
    sidecar = tmp_path / "early.json"
    sidecar.write_text(json.dumps(data))
    out = tmp_path / "early.npy"
    code, stdout, _ = run_cli(capsys, "render", "--sidecar", sidecar, "--out", out)
    assert code == 0 and f"{choice.count} of {partial.scene.count} gaussians" in stdout
    assert_matches(np.load(out), render_reference(partial.subset(choice.spans), CAMERA, RenderSettings()))
    data["scene"]["lod_levels"] = [1, 40]
    sidecar.write_text(json.dumps(data))
    code, _, err = run_cli(capsys, "render", "--sidecar", sidecar, "--out", tmp_path / "bad.npy")
    assert "'scene.lod_levels' must list levels from 0 to 31" in assert_one_line_error(code, err)
