"""The window and a .spz's two axis conventions: the Scene section's switch reads the
scene again flipped, screenshots and camera paths record the axes, ``view --spz-axes``
opens in them, and a file that declares its axes (or a PLY) shows no switch."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, headless, window_image
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from PIL import Image
from testkit import assert_matches, random_scene, write_inria_ply

from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.spz_file import spz_bytes
from raygs_viewer.scene.spz_format import SpzEncoding
from raygs_viewer.scene.writing import write_scene

SWITCH = "RDF axes (splat-transform's .spz)"


@pytest.fixture
def st_spz(tmp_path):
    """A .spz written in the PLY's axes, as splat-transform writes it, of a scene lying
    well off the x axis (so that flipping y and z moves it)."""
    scene = random_scene(n=80, seed=4, degree=1, spread=0.6)
    shifted = scene.positions + np.float32([0.0, 0.8, 0.4])
    scene = type(scene)(shifted, scene.rotations, scene.scales, scene.opacities, scene.sh, scene.sh_degree)
    return write_scene(scene, tmp_path / "st.spz", spz=SpzEncoding(axes="rdf"))


def test_the_switch_reads_the_scene_again_flipped(open_viewer, st_spz):
    viewer, drive = open_viewer(str(st_spz), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(1)
    before = viewer.loaded.scene
    assert before.axes == FileAxes("rub") and SWITCH in drive.panel
    drive.reveal(SWITCH)
    drive.click(SWITCH)
    drive.wait_for_load()
    after = viewer.loaded.scene
    assert viewer.panel.error == "" and after.axes == FileAxes("rdf") and viewer.scenes.reading.spz_axes == "rdf"
    assert after is not before and viewer.loaded.path == str(st_spz)
    # Exactly the gaussians read before, seen through diag(1, -1, -1).
    np.testing.assert_array_equal(after.positions, before.positions * np.float32([1, -1, -1]))
    np.testing.assert_array_equal(after.rotations, before.rotations * np.float32([1, 1, -1, -1]))
    np.testing.assert_array_equal(after.sh[:, 0], before.sh[:, 0])
    np.testing.assert_array_equal(after.sh[:, 1], -before.sh[:, 1])  # the SH function in y
    np.testing.assert_array_equal(after.positions, load_scene(SceneSource(st_spz, spz_axes="rdf")).positions)
    drive.settle()
    assert_matches(window_image(viewer), headless(viewer))  # the window shows the scene read again
    # And back.
    drive.reveal(SWITCH)
    drive.click(SWITCH)
    drive.wait_for_load()
    assert viewer.loaded.scene.axes == FileAxes("rub")
    np.testing.assert_array_equal(viewer.loaded.scene.positions, before.positions)


def test_screenshots_and_paths_record_the_axes_and_render_again_from_them(open_viewer, st_spz, tmp_path):
    from raygs_viewer.cli.main import main

    viewer, drive = open_viewer(SceneSource(st_spz, spz_axes="rdf"), hide_panel=True)
    assert viewer.loaded.scene.axes == FileAxes("rdf")
    drive.settle()
    drive.tap(imgui.Key.f12)
    png, sidecar = viewer.captures.last
    data = json.loads(sidecar.read_text())
    assert data["scene"]["spz_axes"] == "rdf" and data["version"] == 4
    out = tmp_path / "again.png"
    assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
    np.testing.assert_array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(png)))
    # The same view of the scene read in the other axes is another picture.
    flipped = tmp_path / "flipped.json"
    data["scene"]["spz_axes"], data["version"] = "rub", 1
    flipped.write_text(json.dumps(data))
    assert main(["render", "--sidecar", str(flipped), "--out", str(tmp_path / "rub.png")]) == 0
    assert np.abs(np.asarray(Image.open(tmp_path / "rub.png")).astype(int) - np.asarray(Image.open(png))).max() > 50
    viewer.camera_path.add_view(viewer.view)
    assert viewer.camera_path.document(viewer.path_scene()).scene_axes == FileAxes("rdf")  # render-path reads it so


def test_no_switch_for_a_ply_nor_a_file_that_declares_its_axes(open_viewer, tmp_path):
    viewer, drive = open_viewer(str(write_inria_ply(tmp_path / "s.ply", n=20)), width=PANEL_WIDTH,
                                height=PANEL_HEIGHT)
    drive.frames(1)
    assert SWITCH not in drive.panel and viewer.loaded.scene.axes is None
    # A version 4 file with the coordinate-system extension (RDF) after its header.
    plain = spz_bytes(random_scene(n=20, seed=1, degree=0), 4)
    extension = struct.pack("<III", 0xADBE0003, 4, 6)
    header = bytearray(plain[:32])
    header[14] |= 2  # flags: extensions follow
    header[16:20] = struct.pack("<I", 32 + len(extension))  # the table of contents moves past them
    declared = tmp_path / "declared.spz"
    declared.write_bytes(bytes(header) + extension + plain[32:])
    viewer.open_scene(str(declared))
    drive.wait_for_load()
    assert viewer.panel.error == "" and viewer.loaded.scene.axes == FileAxes("rub", "RDF")
    drive.frames(1)
    assert SWITCH not in drive.panel and "axes: RDF, declared by the file" in drive.panel


def test_view_spz_axes_opens_the_scene_in_them(restore_gl_ctx, st_spz, tmp_path):
    from raygs_viewer.cli.main import main

    shots = {}
    for axes in ("rdf", "rub"):
        shots[axes] = tmp_path / f"{axes}.png"
        assert main(["view", str(st_spz), "--spz-axes", axes, "--frames", "2", "--screenshot", str(shots[axes]),
                     "--width", "96", "--height", "72", "--window-platform", "null"]) == 0
        assert json.loads(shots[axes].with_suffix(".json").read_text())["scene"]["spz_axes"] == axes
    # Each framed on its own scene; the pictures are not mirror images of each other by chance.
    assert not np.array_equal(np.asarray(Image.open(shots["rdf"])), np.asarray(Image.open(shots["rub"])))
