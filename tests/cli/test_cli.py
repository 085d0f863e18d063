"""The ``raygs-viewer`` command line, run in-process through ``main(argv)``, plus one run
of the installed module as a user would start it."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from testkit import assert_one_line_error, listing, run_cli, sorted_render, write_inria_ply

import raygs_viewer
from raygs_viewer.bench.loading import write_generated_ply
from raygs_viewer.camera.pinhole import Camera, camera_to_json, look_at
from raygs_viewer.cli.main import BROKEN_PIPE_STATUS, main
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.storage import SceneBuffers
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.demo import demo_camera, demo_scene
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.depth import DepthSorter

SMALL = ["--width", "64"]  # demo camera 640x480 -> 64x48


# --------------------------------------------------------------------------- helpers










def gl_render(gl_ctx, scene, camera, settings=RenderSettings()):
    from raygs_viewer.render.gl.renderer import GLRenderer

    renderer = GLRenderer(gl_ctx, scene)
    try:
        return sorted_render(renderer, camera, settings)
    finally:
        renderer.release()




def small_camera():
    """An off-centre, fx != fy camera looking at the origin, 80x60."""
    pose = look_at([0.3, -0.4, -2.5], [0, 0, 0])
    return Camera(80, 60, 90.0, 70.0, 37.5, 33.25, pose.R, pose.t)


@pytest.fixture
def camera_file(tmp_path):
    """cameras.json with two cameras: 0 is the demo view at 48x36, 1 is small_camera()."""
    demo = demo_camera(48, 36)
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps([camera_to_json(demo, 0, "demo"), camera_to_json(small_camera(), 1, "small")]))
    return path


@pytest.fixture(scope="module")
def demo():
    return demo_scene()


# --------------------------------------------------------------------------- info


def test_info_demo(capsys):
    code, out, err = run_cli(capsys, "info", "demo")
    assert code == 0 and err == ""
    assert "3914" in out and "SH degree" in out and "demo" in out


def test_info_demo_json(capsys):
    code, out, err = run_cli(capsys, "info", "demo", "--json")
    assert code == 0 and err == ""
    info = json.loads(out)
    assert info["count"] == 3914 and info["sh_degree"] == 3
    assert info["dropped"]["total"] == 0


def test_info_ply(capsys, tmp_path):
    path = write_inria_ply(tmp_path / "small.ply", n=5)
    code, out, err = run_cli(capsys, "info", path)
    assert code == 0 and err == ""
    assert "small.ply" in out and "gaussians:" in out
    code, out, err = run_cli(capsys, "info", path, "--json")
    assert code == 0
    info = json.loads(out)
    assert info["count"] == 5 and info["sh_degree"] == 0
    assert info["filter_fused"] is False
    positions = load_scene(path).positions
    np.testing.assert_allclose(info["bbox"]["min"], positions.min(axis=0), rtol=1e-6)


def test_info_gives_the_gpu_memory_the_renderer_will_allocate(capsys, tmp_path, gl_ctx):
    """The figure is the one SceneBuffers computes for that scene (SH degree 3 here)."""
    path = write_generated_ply(tmp_path / "sh3.ply", 700, sh_degree=3)
    code, out, err = run_cli(capsys, "info", path, "--json")
    assert code == 0 and err == ""
    expected = SceneBuffers(gl_ctx, load_scene(path))
    try:
        assert json.loads(out)["gpu_bytes"] == expected.gpu_bytes == 700 * (48 + 16 * 12 + 16 + 112 + 4)
    finally:
        expected.release()
    code, out, err = run_cli(capsys, "info", path)
    assert f"GPU memory:   {expected.gpu_bytes / (1 << 20):,.1f} MiB of storage buffers" in out


# --------------------------------------------------------------------------- render


def test_render_demo_png(capsys, tmp_path):
    out = tmp_path / "demo.png"
    code, stdout, err = run_cli(capsys, "render", *SMALL, "--out", out)
    assert code == 0 and err == ""
    assert "64x48" in stdout
    with Image.open(out) as image:
        assert image.format == "PNG" and image.mode == "RGB" and image.size == (64, 48)
        pixels = np.asarray(image)
    assert pixels.dtype == np.uint8 and pixels.shape == (48, 64, 3)
    assert pixels.std() > 5  # shows something
    assert listing(tmp_path) == ["demo.png"]


def test_render_demo_npy_matches_gl(capsys, tmp_path, gl_ctx, demo):
    out = tmp_path / "demo.npy"
    code, _, err = run_cli(capsys, "render", "demo", "--width", "64", "--height", "40", "--out", out)
    assert code == 0 and err == ""
    image = np.load(out)
    assert image.dtype == np.float32 and image.shape == (40, 64, 4)
    assert np.all(np.isfinite(image))
    assert image[..., 3].min() >= 0 and image[..., 3].max() <= 1
    assert image[..., 3].max() > 0.9
    expected = gl_render(gl_ctx, demo, demo_camera().resized(64, 40))
    np.testing.assert_allclose(image, expected, atol=1e-5)
    # The PNG of the same render is its 8-bit rounding.
    png = tmp_path / "demo.png"
    assert run_cli(capsys, "render", "demo", "--width", "64", "--height", "40", "--out", png)[0] == 0
    with Image.open(png) as decoded:
        rgb8 = np.asarray(decoded).astype(int)
    assert np.abs(rgb8 - np.round(np.clip(image[..., :3], 0, 1) * 255)).max() <= 1


def test_render_with_camera_file_and_index(capsys, tmp_path, camera_file, gl_ctx, demo):
    first, second = tmp_path / "c0.npy", tmp_path / "c1.npy"
    assert run_cli(capsys, "render", "--camera", camera_file, "--out", first)[0] == 0
    assert run_cli(capsys, "render", "--camera", camera_file, "--camera-index", "1", "--out", second)[0] == 0
    image0, image1 = np.load(first), np.load(second)
    assert image0.shape == (36, 48, 4) and image1.shape == (60, 80, 4)
    np.testing.assert_allclose(image0, gl_render(gl_ctx, demo, demo_camera(48, 36)), atol=1e-5)
    np.testing.assert_allclose(image1, gl_render(gl_ctx, demo, small_camera()), atol=1e-5)


@pytest.mark.parametrize("size,expected", [
    (["--width", "40", "--height", "20"], (40, 20)),   # aspect ratio changed
    (["--width", "40"], (40, 30)),                      # one alone keeps it
    (["--height", "15"], (20, 15)),
])
def test_width_and_height_scale_the_intrinsics(capsys, tmp_path, camera_file, gl_ctx, demo, size, expected):
    out = tmp_path / "scaled.npy"
    code, _, err = run_cli(capsys, "render", "--camera", camera_file, "--camera-index", "1", *size, "--out", out)
    assert code == 0, err
    image = np.load(out)
    width, height = expected
    assert image.shape == (height, width, 4)
    camera = small_camera()
    resized = camera.resized(width, height)
    assert resized.fx == pytest.approx(camera.fx * width / 80) and resized.cx == pytest.approx(camera.cx * width / 80)
    assert resized.fy == pytest.approx(camera.fy * height / 60) and resized.cy == pytest.approx(camera.cy * height / 60)
    np.testing.assert_allclose(image, gl_render(gl_ctx, demo, resized), atol=1e-5)
    # Negative control: only the size changed, not fx, fy, cx, cy -> a different image.
    unscaled = Camera(width, height, camera.fx, camera.fy, camera.cx, camera.cy, camera.R, camera.t)
    assert np.abs(image - gl_render(gl_ctx, demo, unscaled)).max() > 0.05


def test_p_min(capsys, tmp_path, gl_ctx, demo):
    default, strict = tmp_path / "default.npy", tmp_path / "strict.npy"
    assert run_cli(capsys, "render", *SMALL, "--out", default)[0] == 0
    assert run_cli(capsys, "render", *SMALL, "--p-min", "0.2", "--out", strict)[0] == 0
    a, b = np.load(default), np.load(strict)
    assert np.abs(a - b).max() > 0.05
    assert b[..., 3].sum() < a[..., 3].sum()  # a higher cut-off drops fragments
    camera = demo_camera().resized(64, 48)
    np.testing.assert_allclose(b, gl_render(gl_ctx, demo, camera, RenderSettings(p_min=0.2)), atol=1e-5)


def test_background(capsys, tmp_path):
    """Empty pixels of a sparse scene are exactly the background; covered ones are
    colour over it."""
    scene = write_inria_ply(tmp_path / "sparse.ply", n=4, seed=3)
    out = tmp_path / "bg.npy"
    code, _, err = run_cli(capsys, "render", scene, "--width", "64", "--background", "0.25,0.5,0.75", "--out", out)
    assert code == 0, err
    image = np.load(out)
    empty = image[..., 3] == 0
    assert 0.1 < empty.mean() < 0.99  # both kinds of pixel present
    np.testing.assert_array_equal(image[empty][:, :3], np.tile(np.float32([0.25, 0.5, 0.75]), (empty.sum(), 1)))
    black = tmp_path / "black.npy"
    assert run_cli(capsys, "render", scene, "--width", "64", "--out", black)[0] == 0
    black_image = np.load(black)
    assert np.all(black_image[empty][:, :3] == 0)
    # Over a background: C_bg = C_black + (1 - alpha) * bg.
    np.testing.assert_allclose(image[..., :3], black_image[..., :3]
                               + (1 - black_image[..., 3:]) * np.float32([0.25, 0.5, 0.75]), atol=1e-5)
    np.testing.assert_array_equal(image[..., 3], black_image[..., 3])


def test_reference_render_is_close_to_gl(capsys, tmp_path):
    gl, ref = tmp_path / "gl.npy", tmp_path / "ref.npy"
    assert run_cli(capsys, "render", *SMALL, "--out", gl)[0] == 0
    code, stdout, _ = run_cli(capsys, "render", *SMALL, "--reference", "--out", ref)
    assert code == 0 and "reference" in stdout
    a, b = np.load(gl), np.load(ref)
    assert b.dtype == np.float32 and b.shape == a.shape == (48, 64, 4)
    diff = np.abs(a.astype(np.float64) - b)
    assert diff.max() < 1e-2 and diff.mean() < 1e-4, (diff.max(), diff.mean())
    assert np.abs(b[:, ::-1] - a).max() > 0.1  # control: a mirrored image would not pass


def test_render_ply_scene_frames_it(capsys, tmp_path):
    scene = write_inria_ply(tmp_path / "cloud.ply", n=40, seed=4)
    out = tmp_path / "cloud.png"
    code, stdout, err = run_cli(capsys, "render", scene, "--width", "48", "--out", out)
    assert code == 0, err
    assert "48x36" in stdout and "40 gaussians" in stdout
    with Image.open(out) as image:
        assert image.size == (48, 36)
        assert np.asarray(image).max() > 0


@pytest.mark.parametrize("suffix", [".png", ".npy"])
def test_existing_output_is_kept_unless_overwrite(capsys, tmp_path, suffix):
    out = tmp_path / f"image{suffix}"
    old = b"precious bytes, not an image"
    out.write_bytes(old)
    code, _, err = run_cli(capsys, "render", *SMALL, "--out", out)
    assert "already exists" in assert_one_line_error(code, err)
    assert out.read_bytes() == old
    assert listing(tmp_path) == [out.name]
    code, _, err = run_cli(capsys, "render", *SMALL, "--out", out, "--overwrite")
    assert code == 0, err
    assert out.read_bytes() != old
    if suffix == ".npy":
        assert np.load(out).shape == (48, 64, 4)
    else:
        with Image.open(out) as image:
            assert image.size == (64, 48)
    assert listing(tmp_path) == [out.name]


def test_no_temporary_files_left_after_failures(capsys, tmp_path):
    scene = tmp_path / "bad.ply"
    scene.write_text("not a ply\n")
    before = listing(tmp_path)
    for argv in (["render", scene, "--out", tmp_path / "a.png"],
                 ["render", "--camera", tmp_path / "none.json", "--out", tmp_path / "b.png"],
                 ["render", *SMALL, "--out", tmp_path / "c.jpg"]):
        assert_one_line_error(*run_cli(capsys, *argv)[::2])
    assert listing(tmp_path) == before


# --------------------------------------------------------------------------- error paths


def _bad_cases(tmp_path, write=True):
    """{case: argv}; with ``write`` the input files the cases name are created."""
    not_ply, empty, bad_json, bad_camera, good_camera = (
        tmp_path / name for name in ("notply.ply", "empty.ply", "bad.json", "badcam.json", "good.json"))
    if write:
        (tmp_path / "folder.png").mkdir()
        not_ply.write_text("hello, I am text\n")
        empty.write_bytes(b"")
        bad_json.write_text("{not json")
        bad_camera.write_text(json.dumps([{"width": 64, "height": 48, "position": [0, 0, 0],
                                           "rotation": [[2, 0, 0], [0, 2, 0], [0, 0, 2]], "fx": 50, "fy": 50}]))
        good_camera.write_text(json.dumps([camera_to_json(demo_camera(32, 24))]))
        (tmp_path / "taken.png").write_bytes(b"precious")
        (tmp_path / "sidecar.json").write_bytes(b"precious")
    out = str(tmp_path / "out.png")
    return {
        "missing_scene": ["render", tmp_path / "nowhere.ply", "--out", out],
        "missing_scene_info": ["info", tmp_path / "nowhere.ply"],
        "not_a_ply": ["render", not_ply, "--out", out],
        "not_a_ply_info": ["info", not_ply],
        "empty_ply_info": ["info", empty],
        "unknown_scene_type": ["info", bad_json],
        "scene_is_folder": ["info", tmp_path],
        "camera_not_json": ["render", "--camera", bad_json, "--out", out],
        "camera_not_rotation": ["render", "--camera", bad_camera, "--out", out],
        "camera_missing": ["render", "--camera", tmp_path / "nocams.json", "--out", out],
        "camera_index_out_of_range": ["render", "--camera", good_camera, "--camera-index", "1", "--out", out],
        "camera_index_negative_out_of_range": ["render", "--camera", good_camera, "--camera-index", "-2",
                                               "--out", out],
        "camera_index_not_int": ["render", "--camera", good_camera, "--camera-index", "one", "--out", out],
        "camera_index_minus_one": ["render", "--camera", good_camera, "--camera-index", "-1", "--out", out],
        "view_camera_index_minus_one": ["view", "--camera", good_camera, "--camera-index", "-1"],
        "background_above_one": ["render", "--background", "2,0,0", "--out", out],
        "background_negative": ["render", "--background=0,-0.5,0", "--out", out],
        "view_background_above_one": ["view", "--background", "0,0,1.5"],
        "verify_background_above_one": ["verify", "--background", "1,1,1.01"],
        "output_parent_is_a_file": ["render", "--out", tmp_path / "taken.png" / "out.png"],
        "p_min_zero": ["render", "--p-min", "0", "--out", out],
        "p_min_one": ["render", "--p-min", "1", "--out", out],
        "p_min_word": ["render", "--p-min", "x", "--out", out],
        "p_min_negative": ["render", "--p-min=-0.5", "--out", out],
        "p_min_nan": ["render", "--p-min", "nan", "--out", out],
        "background_two": ["render", "--background", "1,2", "--out", out],
        "background_words": ["render", "--background", "a,b,c", "--out", out],
        "background_nan": ["render", "--background", "nan,0,0", "--out", out],
        "background_empty": ["render", "--background", "", "--out", out],
        "width_zero": ["render", "--width", "0", "--out", out],
        "width_word": ["render", "--width", "wide", "--out", out],
        "height_huge": ["render", "--height", "100000", "--out", out],
        "unknown_suffix": ["render", "--out", tmp_path / "out.jpg"],
        "no_suffix": ["render", "--out", tmp_path / "out"],
        "output_folder_missing": ["render", "--out", tmp_path / "no" / "such" / "out.png"],
        "output_is_folder": ["render", "--out", tmp_path / "folder.png"],
        "unknown_subcommand": ["paint", "demo"],
        "subcommand_without_scene_look": ["paint"],
        "sh_degree_four": ["render", "--sh-degree", "4", "--out", out],
        "sh_degree_negative": ["render", "--sh-degree=-1", "--out", out],
        "sh_degree_word": ["verify", "--sh-degree", "all"],
        "view_frames_zero": ["view", "--frames", "0"],
        "view_frames_word": ["--frames", "many"],
        "view_scale_zero": ["view", "--screenshot-scale", "0"],
        "view_scale_negative": ["view", "--screenshot-scale=-2"],
        "view_scale_too_big": ["view", "--screenshot-scale", "8.5"],
        "view_scale_nan": ["view", "--screenshot-scale", "nan"],
        "view_scale_inf": ["view", "--screenshot-scale", "inf"],
        "view_up_axis_bad": ["view", "--up-axis", "up"],
        "view_up_axis_missing": ["view", "--up-axis"],
        "view_up_axis_option_next": ["--up-axis", "--frames", "3"],
        "view_platform_bad": ["view", "--window-platform", "cocoa"],
        "view_screenshot_jpg": ["view", "--screenshot", tmp_path / "shot.jpg"],
        "view_screenshot_no_folder": ["view", "--screenshot", tmp_path / "no" / "shot.png"],
        "view_screenshot_exists": ["view", "--screenshot", tmp_path / "taken.png"],
        "view_screenshot_sidecar_exists": ["view", "--screenshot", tmp_path / "sidecar.png"],
        "view_unknown_option": ["--colour", "red"],
        "view_render_option": ["view", "--out", out],
        "sidecar_with_camera": ["render", "--sidecar", good_camera, "--camera", good_camera, "--out", out],
        "sidecar_is_cameras_json": ["render", "--sidecar", good_camera, "--out", out],
        "missing_out": ["render", "demo"],
        "unknown_option": ["render", "--colour", "red", "--out", out],
        "info_missing_scene_argument": ["info"],
        "bad_gl_backend": ["render", "--gl-backend", "metal", "--out", out],
        "mode_unknown": ["render", "--mode", "ewa", "--out", out],
        "mode_missing": ["render", "--out", out, "--mode"],
        "mip_value": ["render", "--mip=yes", "--out", out],
        "mip_sigma2_negative": ["render", "--mip-sigma2=-0.1", "--out", out],
        "mip_sigma2_huge": ["render", "--mip-sigma2", "101", "--out", out],
        "mip_sigma2_nan": ["render", "--mip-sigma2", "nan", "--out", out],
        "mip_sigma2_word": ["render", "--mip-sigma2", "wide", "--out", out],
        "gs_compensation_value": ["render", "--gs-compensation=1", "--out", out],
        "supersample_zero": ["render", "--supersample", "0", "--out", out],
        "supersample_five": ["render", "--supersample", "5", "--out", out],
        "supersample_fraction": ["render", "--supersample", "1.5", "--out", out],
        "supersample_word": ["render", "--supersample", "two", "--out", out],
        "alpha_clamp_value": ["render", "--alpha-clamp=0.99", "--out", out],
        "transmittance_cutoff_value": ["render", "--transmittance-cutoff=1e-4", "--out", out],
        "view_mode_unknown": ["view", "--mode", "EWA"],
        "view_supersample_five": ["--supersample", "5"],
        "view_mip_sigma2_huge": ["view", "--mip-sigma2", "1e3"],
        "verify_mode_unknown": ["verify", "--mode", "nerf"],
        "sidecar_with_mode": ["render", "--sidecar", good_camera, "--mode", "gs", "--out", out],
        "sidecar_with_order": ["render", "--sidecar", good_camera, "--order", "distance", "--out", out],
        "order_unknown": ["render", "--order", "nearest", "--out", out],
        "order_k_seventeen": ["render", "--order-k", "17", "--out", out],
        "order_k_negative": ["render", "--order-k=-1", "--out", out],
        "order_k_word": ["render", "--order-k", "exact", "--out", out],
        "order_per_pixel_gs": ["render", "--order", "per-pixel", "--mode", "gs", "--out", out],
        "order_k_gs": ["render", "--order-k", "4", "--mode", "gs", "--out", out],
        "view_order_k_seventeen": ["view", "--order-k", "17"],
        "view_order_per_pixel_gs": ["view", "--order", "per-pixel", "--mode", "gs"],
        "verify_order_per_pixel_gs": ["verify", "--order", "per-pixel", "--mode", "gs"],
        "verify_order_unknown": ["verify", "--order", "z"],
        "bench_unknown_kind": ["bench", "speed"],
    }


CASES = sorted(_bad_cases(Path("unused"), write=False))


@pytest.mark.parametrize("case", CASES)
def test_error_paths_are_one_line(capsys, tmp_path, case, monkeypatch):
    import raygs_viewer.viewer.app as app

    monkeypatch.setattr(app, "run_viewer", lambda options, progress=None: pytest.fail(f"window opened with {options}"))
    argv = _bad_cases(tmp_path)[case]
    before = listing(tmp_path)
    code, _, err = run_cli(capsys, *argv)
    assert_one_line_error(code, err)
    assert listing(tmp_path) == before  # nothing written, no temporary file left


def test_error_messages_name_what_is_wrong(capsys, tmp_path, monkeypatch):
    import raygs_viewer.viewer.app as app

    monkeypatch.setattr(app, "run_viewer", lambda options, progress=None: pytest.fail(f"window opened with {options}"))
    cases = _bad_cases(tmp_path)
    expect = {
        "missing_scene": "nowhere.ply",
        "not_a_ply": "notply.ply",
        "camera_not_json": "bad.json",
        "camera_not_rotation": "badcam.json",
        "camera_index_out_of_range": "--camera-index must be 0..0, got 1",
        "camera_index_minus_one": "--camera-index must be 0..N-1",
        "view_camera_index_minus_one": "--camera-index must be 0..N-1",
        "background_above_one": "--background: '2,0,0' is not three numbers R,G,B in [0, 1]",
        "view_background_above_one": "--background",
        "output_parent_is_a_file": "(it is a file)",
        "p_min_zero": "p-min",
        "background_two": "background",
        "unknown_suffix": "out.jpg",
        "output_folder_missing": "does not exist",
        "unknown_subcommand": "paint",
        "missing_out": "--out",
        "sh_degree_four": "--sh-degree",
        "view_frames_zero": "--frames",
        "view_scale_too_big": "--screenshot-scale",
        "view_up_axis_bad": "--up-axis",
        "view_screenshot_exists": "taken.png",
        "view_screenshot_sidecar_exists": "sidecar.json",
        "sidecar_with_camera": "--camera",
        "mode_unknown": "--mode",
        "mip_sigma2_huge": "--mip-sigma2",
        "supersample_five": "--supersample",
        "supersample_fraction": "--supersample",
        "view_mode_unknown": "--mode",
        "sidecar_with_mode": "--mode",
        "sidecar_with_order": "--order",
        "order_unknown": "--order",
        "order_k_seventeen": "--order-k",
        "order_per_pixel_gs": "per-pixel order needs a RayGS mode",
        "order_k_gs": "per-pixel order needs a RayGS mode",
        "view_order_k_seventeen": "--order-k",
        "view_order_per_pixel_gs": "per-pixel order needs a RayGS mode",
        "verify_order_per_pixel_gs": "per-pixel order needs a RayGS mode",
    }
    for case, fragment in expect.items():
        code, _, err = run_cli(capsys, *cases[case])
        assert fragment in assert_one_line_error(code, err), (case, err)


def test_output_checks_come_before_slow_work(capsys, tmp_path, monkeypatch):
    """An unusable --out fails before the scene is loaded or anything rendered."""
    import raygs_viewer.cli.commands as cli

    def boom(name):
        raise AssertionError("scene loaded before the output was checked")

    monkeypatch.setattr(cli, "load_scene_argument", boom)
    code, _, err = run_cli(capsys, "render", "--out", tmp_path / "x.tiff")
    assert_one_line_error(code, err)


# --------------------------------------------------------------------------- accuracy options


ACCURACY_CASES = [
    # (argv, the RenderSettings fields it sets beyond the defaults)
    ([], {}),
    (["--mode", "gs"], {"mode": "gs"}),
    (["--mode", "raygs-exact-mip"], {"mode": "raygs-exact-mip"}),
    (["--mode", "raygs"], {}),
    (["--mip"], {"mip": True}),
    (["--no-mip"], {}),
    (["--mip", "--no-mip"], {}),  # the last one counts
    (["--mip-sigma2", "0.25"], {"mip": True, "mip_sigma2": 0.25}),           # implies --mip
    (["--mip-sigma2", "0"], {"mip": True, "mip_sigma2": 0.0}),
    (["--mip-sigma2", "100"], {"mip": True, "mip_sigma2": 100.0}),
    (["--mip-sigma2", "0.25", "--no-mip"], {"mip_sigma2": 0.25}),           # ... unless --no-mip
    (["--no-mip", "--mip-sigma2", "0.25"], {"mip_sigma2": 0.25}),
    (["--mip-modulation"], {"mip": True}),                                    # also implies --mip
    (["--no-mip-modulation"], {"mip": True, "mip_modulation": False}),
    (["--no-mip-modulation", "--no-mip"], {"mip_modulation": False}),
    (["--mode", "raygs-exact-mip", "--mip-sigma2", "0.3"], {"mode": "raygs-exact-mip", "mip": True, "mip_sigma2": 0.3}),
    (["--gs-compensation"], {"gs_compensation": True}),
    (["--supersample", "1"], {}),
    (["--supersample", "4"], {"supersample": 4}),
    (["--alpha-clamp"], {"alpha_clamp": True}),
    (["--transmittance-cutoff"], {"transmittance_cutoff": True}),
    (["--mode", "gs", "--gs-compensation", "--supersample", "3", "--alpha-clamp", "--transmittance-cutoff"],
     {"mode": "gs", "gs_compensation": True, "supersample": 3, "alpha_clamp": True, "transmittance_cutoff": True}),
    (["--order", "depth"], {}),
    (["--order", "distance"], {"order": "distance"}),
    (["--order", "distance", "--mode", "gs"], {"order": "distance", "mode": "gs"}),
    (["--order", "per-pixel"], {"order": "per-pixel"}),
    (["--order", "per-pixel", "--order-k", "0"], {"order": "per-pixel"}),
    (["--order-k", "4"], {"order": "per-pixel", "order_k": 4}),                 # implies --order per-pixel
    (["--order-k", "16", "--mode", "raygs-exact-mip"],
     {"order": "per-pixel", "order_k": 16, "mode": "raygs-exact-mip"}),
    (["--order", "distance", "--order-k", "3"], {"order": "distance", "order_k": 3}),  # K kept, unused
]


#: What `view` asks of the window unless told otherwise: the sort and blend this GL measured
#: (viewer.auto_defaults); ViewerOptions' own defaults are the safe ones the tests' windows use.
MEASURED = {"sort": "auto", "auto_precision": True}


@pytest.mark.parametrize("argv,fields", ACCURACY_CASES)
def test_accuracy_options_reach_the_window(capsys, viewer, argv, fields):
    from raygs_viewer.viewer.state import ViewerOptions

    code, _, err = run_cli(capsys, "view", *argv)
    assert code == 0, err
    assert viewer == [ViewerOptions(settings=RenderSettings(**fields), **MEASURED)]
    assert viewer[0].settings == RenderSettings(**fields)


@pytest.mark.parametrize("command", ["render", "verify"])
@pytest.mark.parametrize("argv,fields", ACCURACY_CASES)
def test_accuracy_options_reach_render_and_verify(command, argv, fields):
    from raygs_viewer.cli.main import build_parser
    from raygs_viewer.cli.options import render_settings as _settings

    args = build_parser().parse_args([command, *argv] + (["--out", "x.png"] if command == "render" else []))
    assert _settings(args) == RenderSettings(**fields)


def test_render_with_accuracy_options_is_the_gl_render_of_those_settings(capsys, tmp_path, gl_ctx, demo, monkeypatch):
    import raygs_viewer.capture.screenshot as screenshot

    used = []
    render_tiled = screenshot.render_tiled
    monkeypatch.setattr(screenshot, "render_tiled", lambda renderer, sorter, order, camera, settings, **options:
                        used.append(settings) or render_tiled(renderer, sorter, order, camera, settings, **options))
    out = tmp_path / "gs.npy"
    code, _, err = run_cli(capsys, "render", *SMALL, "--mode", "gs", "--supersample", "2", "--out", out)
    assert code == 0, err
    settings = RenderSettings(mode="gs", supersample=2)
    assert used == [settings]
    camera = demo_camera().resized(64, 48)
    image = np.load(out)
    with gl_ctx:
        np.testing.assert_allclose(image, gl_render(gl_ctx, demo, camera, settings), atol=1e-5)
        assert np.abs(image - gl_render(gl_ctx, demo, camera)).max() > 0.1  # not the default render
    out = tmp_path / "mip.npy"
    code, _, err = run_cli(capsys, "render", *SMALL, "--mip-sigma2", "0.5", "--no-mip-modulation", "--alpha-clamp",
                           "--out", out)
    assert code == 0, err
    settings = RenderSettings(mip=True, mip_sigma2=0.5, mip_modulation=False, alpha_clamp=True)
    assert used[-1] == settings
    with gl_ctx:
        np.testing.assert_allclose(np.load(out), gl_render(gl_ctx, demo, camera, settings), atol=1e-5)


def test_verify_reports_the_accuracy_settings(capsys):
    code, out, err = run_cli(capsys, "verify", "--width", "32", "--mode", "gs", "--supersample", "2", "--repeat", "1")
    assert code == 0, err
    assert "mode gs" in out and "supersample 2x2" in out and "max error" in out and "order depth" in out


@pytest.mark.parametrize("argv, words", [(["--order", "distance"], "order distance"),
                                         (["--order", "per-pixel"], "order per-pixel (exact)"),
                                         (["--order-k", "2"], "order per-pixel (K=2)")])
def test_verify_reports_the_order(capsys, argv, words):
    code, out, err = run_cli(capsys, "verify", "--width", "24", "--repeat", "1", *argv)
    assert code == 0, err
    assert words in out


def test_render_and_its_sidecar_take_the_order(capsys, tmp_path, gl_ctx, demo, monkeypatch):
    """render --order/--order-k reaches the GL render; a sidecar recording a per-pixel
    order (K) re-renders with it."""
    import raygs_viewer.capture.screenshot as screenshot
    from raygs_viewer.capture.sidecar import build_sidecar, demo_sha256, load_sidecar

    used = []
    render_tiled = screenshot.render_tiled
    monkeypatch.setattr(screenshot, "render_tiled", lambda renderer, sorter, order, camera, settings, **options:
                        used.append(settings) or render_tiled(renderer, sorter, order, camera, settings, **options))
    camera = demo_camera().resized(64, 48)
    for argv, settings in ((["--order", "distance"], RenderSettings(order="distance")),
                           (["--order-k", "3"], RenderSettings(order="per-pixel", order_k=3))):
        out = tmp_path / f"{settings.order}.npy"
        code, _, err = run_cli(capsys, "render", *SMALL, *argv, "--out", out)
        assert code == 0, err
        assert used[-1] == settings
        with gl_ctx:
            np.testing.assert_allclose(np.load(out), gl_render(gl_ctx, demo, camera, settings), atol=1e-5)
    # The sidecar records order and order_k, and render --sidecar renders with them.
    settings = RenderSettings(order="per-pixel", order_k=3, mip=True)
    path = tmp_path / "per-pixel.json"
    path.write_text(json.dumps(build_sidecar(scene_path="demo", scene_sha256=demo_sha256(), scene=demo,
                                             camera=camera, settings=settings, scale=1.0)))
    recorded = json.loads(path.read_text())["settings"]
    assert (recorded["order"], recorded["order_k"]) == ("per-pixel", 3)
    assert load_sidecar(path).settings == settings
    again = tmp_path / "again.npy"
    code, _, err = run_cli(capsys, "render", "--sidecar", path, "--out", again)
    assert code == 0, err
    assert used[-1] == settings
    with gl_ctx:
        np.testing.assert_allclose(np.load(again), gl_render(gl_ctx, demo, camera, settings), atol=1e-5)


def test_every_command_names_the_function_that_runs_it():
    from raygs_viewer.cli import bench, commands, convert, doctor, evaluate, path, view
    from raygs_viewer.cli.main import COMMANDS, build_parser
    minimal = {"render": ["--out", "x.png"], "render-path": ["demo", "orbit", "--out", "x.mp4"],
               "convert": ["demo", "x.ply"], "bench": ["accuracy"], "info": ["demo"], "evaluate": ["x"]}
    runs = {"view": view.command_view, "info": commands.command_info, "render": commands.command_render,
            "verify": commands.command_verify, "render-path": path.command_render_path,
            "convert": convert.command_convert, "bench": bench.command, "evaluate": evaluate.command_evaluate,
            "doctor": doctor.command_doctor}
    assert set(COMMANDS) == set(runs)
    for name in COMMANDS:
        assert build_parser().parse_args([name, *minimal.get(name, [])]).run is runs[name], name


def test_bench_is_a_command(capsys):
    from raygs_viewer.cli.main import COMMANDS, route
    assert "bench" in COMMANDS and route(["bench", "accuracy"]) == ["bench", "accuracy"]
    with pytest.raises(SystemExit) as info:
        main(["bench", "--help"])
    assert info.value.code == 0
    assert "accuracy" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "bench" in capsys.readouterr().out


# --------------------------------------------------------------------------- --sh-degree


def test_sh_degree(capsys, tmp_path, gl_ctx, demo):
    """--sh-degree reaches the renderer: fewer bands change the view-dependent colour."""
    images = {}
    for degree in (None, 0, 1, 3):
        out = tmp_path / f"sh{degree}.npy"
        extra = [] if degree is None else ["--sh-degree", str(degree)]
        code, _, err = run_cli(capsys, "render", *SMALL, *extra, "--out", out)
        assert code == 0, err
        images[degree] = np.load(out)
    camera = demo_camera().resized(64, 48)
    with gl_ctx:  # the CLI's own context was current last
        for degree in (0, 1):
            expected = gl_render(gl_ctx, demo, camera, RenderSettings(sh_degree=degree))
            np.testing.assert_allclose(images[degree], expected, atol=1e-5)
    np.testing.assert_array_equal(images[3], images[None])  # the demo has degree 3: all of it
    assert np.abs(images[0] - images[None]).max() > 0.05
    assert np.abs(images[1] - images[0]).max() > 0.05
    np.testing.assert_array_equal(images[0][..., 3], images[None][..., 3])  # colour only, not coverage


def test_sh_degree_capped_at_the_scene(capsys, tmp_path):
    scene = write_inria_ply(tmp_path / "dc.ply", n=20, seed=5)  # SH degree 0
    a, b = tmp_path / "a.npy", tmp_path / "b.npy"
    assert run_cli(capsys, "render", scene, "--width", "32", "--out", a)[0] == 0
    assert run_cli(capsys, "render", scene, "--width", "32", "--sh-degree", "3", "--out", b)[0] == 0
    np.testing.assert_array_equal(np.load(a), np.load(b))


def test_verify_takes_sh_degree(capsys):
    code, out, err = run_cli(capsys, "verify", "--width", "32", "--sh-degree", "1", "--repeat", "1")
    assert code == 0, err
    assert "max error" in out


# --------------------------------------------------------------------------- view and the default command


@pytest.fixture
def viewer(monkeypatch):
    """Replaces app.run_viewer: records the options it gets and returns 0."""
    import raygs_viewer.viewer.app as app

    calls = []

    def run_viewer(options, progress=None):
        calls.append(options)
        return 0

    monkeypatch.setattr(app, "run_viewer", run_viewer)
    return calls


@pytest.mark.parametrize("argv", [[], ["view"], ["demo"], ["view", "demo"]])
def test_no_arguments_open_the_demo(capsys, viewer, argv):
    from raygs_viewer.viewer.state import ViewerOptions

    code, out, err = run_cli(capsys, *argv)
    assert (code, out, err) == (0, "", "")
    assert viewer == [ViewerOptions(**MEASURED)]
    assert viewer[0].settings.p_min == 1 / 255 and viewer[0].settings.background == (0.0, 0.0, 0.0)


def test_scene_first_means_view(capsys, viewer, tmp_path):
    scene = write_inria_ply(tmp_path / "s.ply")
    no_suffix = tmp_path / "scene_without_suffix"
    no_suffix.write_bytes(scene.read_bytes())
    for argv, expected in (([scene], str(scene)),
                           ([tmp_path / "not_yet.ply"], str(tmp_path / "not_yet.ply")),  # the app reports it
                           ([tmp_path / "x.SPLAT"], str(tmp_path / "x.SPLAT")),
                           ([no_suffix], str(no_suffix)),
                           ([scene, "--frames", "3"], str(scene))):
        code, _, err = run_cli(capsys, *argv)
        assert code == 0, err
        assert viewer.pop().source == SceneSource(expected)
    assert run_cli(capsys, "--frames", "3")[0] == 0
    assert viewer.pop().frames == 3 and viewer == []


def test_every_view_option(capsys, viewer, tmp_path):
    from raygs_viewer.viewer.state import (
        NavigationChoices,
        ScreenshotOptions,
        ViewerOptions,
    )

    code, _, err = run_cli(capsys, "view", "scene.ply", "--cameras", "train.json", "--camera", "start.json",
                           "--camera-index", "4", "--width", "800", "--height", "600", "--p-min", "0.05",
                           "--background", "0.5,0.25,1", "--sh-degree", "2", "--frames", "10",
                           "--screenshot", tmp_path / "last.png", "--screenshot-dir", tmp_path / "shots",
                           "--screenshot-scale", "2.5", "--no-vsync", "--orbit", "--up-axis", "+z",
                           "--window-platform", "null")
    assert code == 0, err
    assert viewer == [ViewerOptions(
        source=SceneSource("scene.ply", "train.json"), camera="start.json", camera_index=4, width=800, height=600,
        settings=RenderSettings(p_min=0.05, background=(0.5, 0.25, 1.0), sh_degree=2), frames=10,
        screenshot=str(tmp_path / "last.png"),
        screenshots=ScreenshotOptions(folder=str(tmp_path / "shots"), scale=2.5), vsync=False,
        navigation=NavigationChoices(mode="orbit", up_axis="+z"), platform="null", **MEASURED)]
    assert listing(tmp_path) == []  # the CLI only checks the screenshot path; nothing created


@pytest.mark.parametrize("argv,axis", [
    (["--up-axis", "-y"], "-y"), (["--up-axis=-y"], "-y"), (["--up-axis", "-z"], "-z"),
    (["--up-axis=+x"], "+x"), (["view", "--up-axis", "-x", "--frames", "2"], "-x"),
    (["demo", "--frames", "1", "--up-axis", "+y"], "+y"), ([], None),  # None: the window takes the cameras' up
])
def test_up_axis(capsys, viewer, argv, axis):
    code, _, err = run_cli(capsys, *argv)
    assert code == 0, err
    assert viewer.pop().navigation.up_axis == axis


def test_up_axes_are_the_six_signed_world_axes(capsys):
    """--up-axis offers each signed world axis once, in this order, and each name means
    the axis its sign and letter say: checked against a literal list, the help's choices
    and a vector built from the name, not against the navigation's own table."""
    from raygs_viewer.camera.navigation import up_vector

    expected = ("-y", "+y", "+z", "-z", "+x", "-x")
    with pytest.raises(SystemExit):
        main(["view", "--help"])
    assert "{" + ",".join(expected) + "}" in capsys.readouterr().out
    for name in expected:
        axis = np.zeros(3)
        axis["xyz".index(name[1])] = 1.0 if name[0] == "+" else -1.0
        np.testing.assert_array_equal(up_vector(name), axis)


@pytest.mark.parametrize("scale", ["8", "0.25", "1e-3"])
def test_screenshot_scale_range(capsys, viewer, scale):
    assert run_cli(capsys, "--screenshot-scale", scale)[0] == 0
    assert viewer.pop().screenshots.scale == float(scale)


def test_view_returns_the_viewers_status(capsys, monkeypatch):
    import raygs_viewer.viewer.app as app

    monkeypatch.setattr(app, "run_viewer", lambda options, progress=None: 3)
    assert run_cli(capsys, "view")[0] == 3


def test_view_user_errors_are_one_line(capsys, monkeypatch):
    import raygs_viewer.viewer.app as app
    from raygs_viewer.errors import UserError

    def fail(options, progress=None):
        raise UserError(f"{options.source.path}: no such file")

    monkeypatch.setattr(app, "run_viewer", fail)
    code, _, err = run_cli(capsys, "missing.ply")
    assert "missing.ply: no such file" in assert_one_line_error(code, err)


def test_help_and_version_stay_top_level(capsys, viewer):
    for argv in (["-h"], ["--help"], ["--version"]):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 0
    out = capsys.readouterr().out
    assert "view" in out and "render" in out and "raygs-viewer 0" in out
    with pytest.raises(SystemExit):
        main(["view", "--help"])
    assert "--screenshot-scale" in capsys.readouterr().out
    assert viewer == []


def test_dash_values_are_joined_up_to_a_double_dash():
    from raygs_viewer.cli.argtypes import join_dash_values
    from raygs_viewer.cli.main import DASH_VALUES
    assert join_dash_values(["--up-axis", "-y", "--", "--up-axis", "-y"], DASH_VALUES) == \
        ["--up-axis=-y", "--", "--up-axis", "-y"]
    assert join_dash_values(["--up-axis", "--frames"], DASH_VALUES) == ["--up-axis", "--frames"]
    assert join_dash_values(["--crop-box", "-1,-2,-3,1,2,3", "--crop-sphere", "-1e3,0,0,5"], DASH_VALUES) == \
        ["--crop-box=-1,-2,-3,1,2,3", "--crop-sphere=-1e3,0,0,5"]
    assert join_dash_values(["--crop-box", "--overwrite"], DASH_VALUES) == ["--crop-box", "--overwrite"]


# --------------------------------------------------------------------------- as installed


def test_installed_module_runs_outside_the_source_tree(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = tmp_path / "x.png"
    result = subprocess.run([sys.executable, "-m", "raygs_viewer", "render", "--width", "64", "--out", str(out)],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    with Image.open(out) as image:
        assert image.size == (64, 48) and image.mode == "RGB"
    assert listing(tmp_path) == ["x.png"]

    result = subprocess.run([sys.executable, "-m", "raygs_viewer", "info", "/nonexistent.ply"],
                            cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1, result.stderr
    assert "Traceback" not in result.stderr and "nonexistent.ply" in result.stderr


def test_a_closed_pipe_ends_quietly(tmp_path):
    """``raygs-viewer info X | head -1``: the reader goes away, which is no error to
    report. The pipe's read end is closed before the command starts, so its first write
    fails every time (no race with a reader that might still be reading)."""
    env = {**os.environ, "PYTHONPATH": str(Path(raygs_viewer.__file__).parents[1])}  # this tree, not an install
    for argv in (["info", "demo"], ["info", "demo", "--json"]):
        read_end, write_end = os.pipe()
        os.close(read_end)
        try:
            result = subprocess.run([sys.executable, "-m", "raygs_viewer", *argv], cwd=tmp_path, env=env,
                                    stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=120)
        finally:
            os.close(write_end)
        assert result.stderr == "", result.stderr
        assert result.returncode == BROKEN_PIPE_STATUS


def test_output_folder_must_be_writable_before_any_work(capsys, tmp_path, monkeypatch):
    """A folder this user may not write in is refused before the scene is read.
    Simulated (these tests may run as root, whom permission bits do not stop); the
    test below checks a real read-only folder where the user is not root."""
    import raygs_viewer.cli.commands as cli

    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == locked else real_access(p, mode))
    monkeypatch.setattr(cli, "open_scene_argument", lambda *a, **k: pytest.fail("scene read before the check"))
    for argv in (["render", "--out", locked / "x.png"], ["convert", "demo", locked / "x.ply"],
                 ["bench", "order", "--out", locked / "x.md"], ["bench", "perf", "--plot", locked / "x.png"],
                 ["bench", "accuracy", "--report", locked / "x.md"]):
        code, _, err = run_cli(capsys, *argv)
        assert "not writable" in assert_one_line_error(code, err), argv
    assert listing(locked) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_output_folder_is_refused(capsys, tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    code, _, err = run_cli(capsys, "render", "--out", locked / "x.png")
    assert "not writable" in assert_one_line_error(code, err)


# --------------------------------------------------------------------------- stereo

def test_render_stereo_writes_the_eyes_in_the_chosen_layout(capsys, tmp_path, gl_ctx, demo):
    from raygs_viewer.camera.stereo import StereoRig, compose
    from raygs_viewer.render.gl.renderer import GLRenderer
    from raygs_viewer.render.gl.stereo_frame import render_stereo

    camera = demo_camera().resized(64, 48)
    rig = StereoRig(ipd=0.07, convergence=3.0, scene_scale=0.5)
    outputs = {}
    for layout in (None, "cross", "anaglyph", "right"):
        out = tmp_path / f"{layout}.npy"
        extra = [] if layout is None else ["--layout", layout]
        code, stdout, err = run_cli(capsys, "render", *SMALL, "--stereo", "--ipd", "0.07", "--convergence", "3",
                                    "--scene-scale", "0.5", *extra, "--out", out)
        assert code == 0, err
        outputs[layout] = np.load(out)
    with gl_ctx:
        renderer = GLRenderer(gl_ctx, demo)
        try:
            with DepthSorter(demo) as sorter:
                left, right = render_stereo(renderer, sorter, camera, RenderSettings(), rig)
        finally:
            renderer.release()
    assert outputs[None].shape == (48, 128, 4)  # side by side by default, each eye the camera's size
    np.testing.assert_allclose(outputs[None], compose(left, right, "sbs"), atol=1e-6)
    np.testing.assert_allclose(outputs["cross"], compose(left, right, "cross"), atol=1e-6)
    np.testing.assert_allclose(outputs["anaglyph"], compose(left, right, "anaglyph"), atol=1e-6)
    np.testing.assert_allclose(outputs["right"], right, atol=1e-6)
    assert np.abs(left - right).max() > 0.05  # the eyes differ: the options reached the rig


@pytest.mark.parametrize("argv, fragment", [
    (["--ipd", "0.06"], "--ipd needs --stereo"),
    (["--layout", "sbs", "--scene-scale", "2"], "need --stereo"),
    (["--stereo", "--reference"], "drop --reference"),
    (["--stereo", "--ipd", "-1"], "--ipd"),
    (["--stereo", "--convergence", "0"], "--convergence"),
    (["--stereo", "--scene-scale", "nan"], "--scene-scale"),
    (["--stereo", "--layout", "top-bottom"], "--layout"),
])
def test_bad_stereo_options_are_one_line_errors(capsys, tmp_path, argv, fragment):
    out = tmp_path / "x.png"
    code, _, err = run_cli(capsys, "render", *SMALL, *argv, "--out", out)
    assert fragment in assert_one_line_error(code, err)
    assert not out.exists()


@pytest.mark.parametrize("flag, low, high", [("--ipd", 0.0, 1.0), ("--convergence", 1e-3, 1e6),
                                             ("--scene-scale", 1e-9, 1e9)])
def test_the_command_line_and_the_rig_take_the_same_values(flag, low, high):
    """One limit per rig field, read by both the options and StereoRig."""
    from raygs_viewer.camera.stereo import StereoRig
    from raygs_viewer.cli.main import build_parser
    from raygs_viewer.cli.options import stereo_rig

    name = flag[2:].replace("-", "_")
    for value, accepted in ((low, True), (high, True), (low * 0.999 if low else -1e-9, False), (high * 1.001, False)):
        argv = ["render", "--stereo", f"{flag}={value!r}", "--out", "x.png"]
        if accepted:
            assert getattr(stereo_rig(build_parser().parse_args(argv)), name) == value
            assert getattr(StereoRig(**{name: value}), name) == value
        else:
            with pytest.raises(UserError, match=flag):
                build_parser().parse_args(argv)
            with pytest.raises(UserError, match=name.replace("_", " ")):
                StereoRig(**{name: value})


@pytest.mark.parametrize("argv, fields", [
    ([], {}),
    (["--stereo"], {"stereo": True}),
    (["--stereo", "--ipd", "0.07", "--convergence", "4", "--scene-scale", "0.1", "--layout", "anaglyph",
      "--lens-preview", "--save-eyes", "--eyes-at-headset-size"],
     {"stereo": True, "ipd": 0.07, "convergence": 4.0, "scene_scale": 0.1, "stereo_layout": "anaglyph",
      "lens_preview": True, "save_eyes": True, "headset_size": True}),
    (["--ipd", "0.058"], {"ipd": 0.058}),  # the panel's start value, for switching stereo on later
    (["--stereo", "--headset", "index"], {"stereo": True, "headset": "index"}),
    (["--stereo", "--headset-size", "1832x1920", "--headset-fov", "104,98"],
     {"stereo": True, "headset": ("custom", 1832, 1920, 104.0, 98.0)}),
    (["--headset", "custom", "--headset-size", "800X600", "--headset-fov", "90,70"],
     {"headset": ("custom", 800, 600, 90.0, 70.0)}),
])
def test_stereo_options_reach_the_window(capsys, viewer, argv, fields):
    from raygs_viewer.camera.stereo import PRESETS, StereoRig, custom_preset
    from raygs_viewer.viewer.state import StereoPreview, ViewerOptions

    code, _, err = run_cli(capsys, "view", *argv)
    assert code == 0, err
    headset = fields.pop("headset", "quest3")
    fields["headset"] = PRESETS[headset] if isinstance(headset, str) else custom_preset(*headset[1:])
    # The table's ViewerOptions-era names, as the StereoPreview they describe.
    rig = StereoRig(**{name: fields.pop(name) for name in ("ipd", "convergence", "scene_scale") if name in fields})
    stereo = StereoPreview.of(fields.pop("headset"), on=fields.pop("stereo", False), rig=rig,
                              layout=fields.pop("stereo_layout", "sbs"), **fields)
    assert viewer == [ViewerOptions(stereo=stereo, **MEASURED)]


@pytest.mark.parametrize("argv, fragment", [
    (["--headset-size", "800x600"], "needs both --headset-size"),
    (["--headset", "custom"], "needs both"),
    (["--headset", "index", "--headset-fov", "90,90"], "drop --headset index"),
    (["--headset-size", "0x600", "--headset-fov", "90,90"], "resolution"),
    (["--headset-size", "800x600", "--headset-fov", "90,200"], "field of view"),
    (["--headset-size", "800 by 600"], "--headset-size"),
    (["--headset-fov", "90"], "--headset-fov"),
    (["--stereo", "--ipd", "2"], "--ipd"),
    (["--stereo", "--layout", "over-under"], "--layout"),
])
def test_bad_view_stereo_options_are_one_line_errors(capsys, viewer, argv, fragment):
    code, _, err = run_cli(capsys, "view", *argv)
    assert fragment in assert_one_line_error(code, err)
    assert viewer == []


def test_render_stereo_lens_preview_and_sidecar(capsys, tmp_path, gl_ctx, demo):
    from raygs_viewer.camera.lens_model import DEFAULT_LENS, lens_warp_reference
    from raygs_viewer.camera.stereo import StereoRig, StereoView, compose, eye_cameras
    from raygs_viewer.capture.sidecar import build_sidecar, demo_sha256
    from raygs_viewer.render.gl.renderer import GLRenderer
    from raygs_viewer.render.gl.stereo_frame import render_stereo

    camera = demo_camera().resized(64, 48)
    out = tmp_path / "lens.npy"
    code, _, err = run_cli(capsys, "render", *SMALL, "--stereo", "--lens-preview", "--out", out)
    assert code == 0, err
    with gl_ctx:
        renderer = GLRenderer(gl_ctx, demo)
        try:
            with DepthSorter(demo) as sorter:
                left, right = render_stereo(renderer, sorter, camera, RenderSettings(), StereoRig())
        finally:
            renderer.release()
    eyes = eye_cameras(camera, StereoRig())
    expected = compose(lens_warp_reference(left, eyes[0], DEFAULT_LENS),
                       lens_warp_reference(right, eyes[1], DEFAULT_LENS), "sbs")
    image = np.load(out)
    assert image.shape == (48, 128, 4)
    assert np.abs(image[..., :3] - expected[..., :3]).max() < 2e-3
    assert np.abs(image - compose(left, right, "sbs")).max() > 0.05  # the lens was applied
    # A stereo sidecar renders the stereo image it describes.
    view = StereoView(StereoRig(), "cross", DEFAULT_LENS)
    sidecar = tmp_path / "pair.json"
    sidecar.write_text(json.dumps(build_sidecar(scene_path="demo", scene_sha256=demo_sha256(), scene=demo,
                                                camera=camera, settings=RenderSettings(), scale=1.0, stereo=view)))
    again = tmp_path / "again.npy"
    code, _, err = run_cli(capsys, "render", "--sidecar", sidecar, "--out", again)
    assert code == 0, err
    np.testing.assert_array_equal(np.load(again), compose(image[:, :64], image[:, 64:], "cross"))
    # --stereo cannot also be given: the sidecar says it.
    code, _, err = run_cli(capsys, "render", "--sidecar", sidecar, "--stereo", "--out", tmp_path / "x.png")
    assert "drop --stereo" in assert_one_line_error(code, err)


def test_view_stereo_scripted_run_saves_the_pair(capsys, tmp_path, restore_gl_ctx):
    from raygs_viewer.capture.sidecar import load_sidecar

    shot = tmp_path / "pair.png"
    code, out, err = run_cli(capsys, "view", "--stereo", "--headset-size", "80x60", "--headset-fov", "90,75",
                             "--frames", "2", "--window-platform", "null", "--width", "320", "--height", "120",
                             "--screenshot", shot)
    assert code == 0, err
    assert "stereo custom 80x60 per eye" in out and "both eyes GPU" in out
    from PIL import Image
    assert Image.open(shot).size == (160, 60)
    loaded = load_sidecar(tmp_path / "pair.json")
    assert loaded.stereo.layout == "sbs" and loaded.stereo.headset.width == 80
