"""``render --channels`` and ``render-path --channels``: the plumbing from the command
line to the files (which channels, in which order, under which names, in which space);
the GL outputs' accuracy against the reference is tested in tests/render."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from PIL import Image
from testkit import assert_one_line_error, listing, run_cli, sorted_channels, write_inria_ply

import raygs_viewer.capture.screenshot as screenshot
from raygs_viewer.camera.pinhole import Camera, camera_to_json, look_at
from raygs_viewer.camera.stereo import StereoRig, StereoView
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.capture.sidecar import build_sidecar, demo_sha256
from raygs_viewer.render import reference
from raygs_viewer.render.channel_pictures import ALPHA_THRESHOLD, ChannelView, automatic_range, depth_picture
from raygs_viewer.render.channels import ChannelImage
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.demo import demo_camera, demo_scene
from raygs_viewer.scene.io import load_scene

GEOMETRY = "alpha,depth,median_depth,normal"
render_tiled_channels = screenshot.render_tiled_channels  # the original, for a test that wraps it


def tiny_camera() -> Camera:
    """40x30, off-centre, fx != fy, looking at the generated scene from an oblique side
    (so camera and world normals differ in every axis)."""
    pose = look_at([0.7, -0.5, -2.0], [0, 0, 0])
    return Camera(40, 30, 42.0, 40.0, 19.25, 15.5, pose.R, pose.t)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """(scene.ply, cameras.json) of 40 small generated gaussians and tiny_camera() as
    camera 1 (camera 0 another view, so --camera-index matters)."""
    folder = tmp_path_factory.mktemp("tiny")
    scene = write_inria_ply(folder / "scene.ply", n=40, seed=3, spread=0.4)
    cameras = folder / "cameras.json"
    pose = look_at([0, 0, -2.5], [0, 0, 0])
    other = Camera(40, 30, 40.0, 40.0, 20.0, 15.0, pose.R, pose.t)
    cameras.write_text(json.dumps([camera_to_json(other, 0, "other"), camera_to_json(tiny_camera(), 1, "tiny")]))
    return scene, cameras


def gl_channels(gl_ctx, scene_path, camera, settings=RenderSettings()) -> ChannelImage:
    with gl_ctx:
        renderer = GLRenderer(gl_ctx, load_scene(scene_path))
        try:
            return sorted_channels(renderer, camera, settings)
        finally:
            renderer.release()


def render(capsys, *argv):
    code, out, err = run_cli(capsys, "render", *argv)
    assert code == 0 and err == "", err
    return out


def read_exr(path) -> tuple[dict, dict[str, np.ndarray]]:
    exr = OpenEXR.File(str(path), separate_channels=True)
    return exr.header(), {name: channel.pixels for name, channel in exr.channels().items()}


def png(path) -> tuple[np.ndarray, dict]:
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB")), dict(image.text)


# --------------------------------------------------------------------------- the contract


def test_the_contract_command_writes_float32_hxwx6_in_order(capsys, tmp_path, tiny, gl_ctx, monkeypatch):
    """render SCENE --camera CAMS --camera-index I --order per-pixel --channels
    alpha,depth,median_depth,normal --out G.npy: alpha, depth, median depth, normal x, y, z."""
    scene, cameras = tiny
    tiled = []
    monkeypatch.setattr(screenshot, "render_tiled_channels", lambda *args, **kwargs: tiled.append(args[3:])
                        or render_tiled_channels(*args, **kwargs))
    out = tmp_path / "G.npy"
    stdout = render(capsys, scene, "--camera", cameras, "--camera-index", "1", "--order", "per-pixel",
                    "--channels", GEOMETRY, "--out", out)
    assert f"{out}: 40x30" in stdout and GEOMETRY in stdout
    assert [camera.width for camera, _ in tiled] == [40] and tiled[0][1].order == "per-pixel"  # the tiled path
    image = np.load(out)
    assert image.dtype == np.float32 and image.shape == (30, 40, 6)
    expected = gl_channels(gl_ctx, scene, tiny_camera(), RenderSettings(order="per-pixel"))
    np.testing.assert_allclose(image[..., 0], expected.alpha, atol=1e-5)
    np.testing.assert_allclose(image[..., 1], expected.depth, atol=1e-5)
    np.testing.assert_allclose(image[..., 2], expected.median_depth, atol=1e-5)
    np.testing.assert_allclose(image[..., 3:6], expected.normal, atol=1e-5)
    covered = image[..., 0] > 0.5
    assert covered.mean() > 0.05 and np.all(image[covered, 1] > 1.0)  # sees the scene, ~2 units away
    np.testing.assert_allclose(np.linalg.norm(image[covered, 3:6], axis=-1), 1.0, atol=1e-5)


def test_exr_holds_the_same_values_as_the_npy_under_their_names(capsys, tmp_path, tiny):
    scene, cameras = tiny
    channels = "rgb,alpha,depth,median_depth,normal"
    view = ["--camera", cameras, "--camera-index", "1", "--channels", channels]
    render(capsys, scene, *view, "--out", tmp_path / "g.npy")
    render(capsys, scene, *view, "--out", tmp_path / "g.exr")
    stacked = np.load(tmp_path / "g.npy")
    header, planes = read_exr(tmp_path / "g.exr")
    names = ["R", "G", "B", "A", "Z", "Z.median", "N.X", "N.Y", "N.Z"]
    assert sorted(planes) == sorted(names) and header["raygsChannels"] == channels
    for index, name in enumerate(names):
        np.testing.assert_array_equal(planes[name], stacked[..., index], err_msg=name)


def test_default_exr_is_colour_and_alpha(capsys, tmp_path):
    render(capsys, "--width", "32", "--out", tmp_path / "c.exr")
    render(capsys, "--width", "32", "--out", tmp_path / "c.npy")
    _, planes = read_exr(tmp_path / "c.exr")
    assert sorted(planes) == ["A", "B", "G", "R"]
    np.testing.assert_array_equal(np.stack([planes[n] for n in "RGBA"], axis=-1), np.load(tmp_path / "c.npy"))


# --------------------------------------------------------------------------- spaces and pictures


def test_world_normals_are_the_camera_normals_turned_by_r_transposed(capsys, tmp_path, tiny):
    scene, cameras = tiny
    view = ["--camera", cameras, "--camera-index", "1", "--channels", "normal,depth"]
    render(capsys, scene, *view, "--out", tmp_path / "camera.npy")
    render(capsys, scene, *view, "--normal-space", "world", "--out", tmp_path / "world.npy")
    camera_space, world = np.load(tmp_path / "camera.npy"), np.load(tmp_path / "world.npy")
    R = tiny_camera().R
    expected = np.einsum("ij,hwi->hwj", R, camera_space[..., :3].astype(np.float64))  # R^T n per pixel
    np.testing.assert_allclose(world[..., :3], expected, atol=1e-6)
    np.testing.assert_array_equal(world[..., 3], camera_space[..., 3])  # depth is no vector
    assert np.abs(world[..., :3] - camera_space[..., :3]).max() > 0.3  # the spaces differ here
    render(capsys, scene, *view, "--normal-space", "world", "--out", tmp_path / "world.exr")
    header, planes = read_exr(tmp_path / "world.exr")
    assert header["raygsNormalSpace"] == "world"
    np.testing.assert_array_equal(np.stack([planes["N.X"], planes["N.Y"], planes["N.Z"]], -1), world[..., :3])


@pytest.mark.parametrize("channel", ["depth", "median_depth"])
def test_depth_picture_states_its_range(capsys, tmp_path, tiny, channel):
    scene, cameras = tiny
    view = ["--camera", cameras, "--camera-index", "1"]
    render(capsys, scene, *view, "--channels", f"alpha,{channel}", "--out", tmp_path / "d.npy")
    alpha, raw = np.load(tmp_path / "d.npy").transpose(2, 0, 1)
    depth = np.where(alpha >= np.float32(ALPHA_THRESHOLD), raw, 0.0)  # the picture masks faint pixels by default
    # A median needs alpha 0.5, far above the threshold: the mask changes the expected depth only.
    assert (depth != raw).any() == (channel == "depth")
    automatic = render(capsys, scene, *view, "--channels", channel, "--out", tmp_path / "auto.png")
    near, far = automatic_range(depth)
    assert f"{channel} range {near:.6g} to {far:.6g} (automatic" in automatic.splitlines()[0]
    pixels, text = png(tmp_path / "auto.png")
    assert text["raygs-viewer channel"] == channel
    assert float(text["raygs-viewer alpha threshold"]) == ALPHA_THRESHOLD
    assert tuple(float(v) for v in text["raygs-viewer depth range"].split()) == (near, far)
    np.testing.assert_array_equal(pixels, to_rgb8(depth_picture(depth, (near, far))[0]))
    given = render(capsys, scene, *view, "--channels", channel, "--depth-range", "1.5,2.5",
                   "--out", tmp_path / "given.png")
    assert f"{channel} range 1.5 to 2.5 (given" in given
    pixels, text = png(tmp_path / "given.png")
    assert text["raygs-viewer depth range"] == "1.5 2.5"
    np.testing.assert_array_equal(pixels, to_rgb8(depth_picture(depth, (1.5, 2.5))[0]))
    # --alpha-threshold 0: every covered pixel, as the raw depths have it.
    render(capsys, scene, *view, "--channels", channel, "--depth-range", "1.5,2.5", "--alpha-threshold", "0",
           "--out", tmp_path / "raw.png")
    pixels, text = png(tmp_path / "raw.png")
    assert text["raygs-viewer alpha threshold"] == "0.0"
    np.testing.assert_array_equal(pixels, to_rgb8(depth_picture(raw, (1.5, 2.5))[0]))


def test_normal_and_alpha_pictures(capsys, tmp_path, tiny):
    scene, cameras = tiny
    view = ["--camera", cameras, "--camera-index", "1"]
    render(capsys, scene, *view, "--channels", "normal,alpha", "--normal-space", "world", "--out", tmp_path / "n.npy")
    values = np.load(tmp_path / "n.npy")
    render(capsys, scene, *view, "--channels", "normal", "--normal-space", "world", "--out", tmp_path / "n.png")
    pixels, text = png(tmp_path / "n.png")
    assert text["raygs-viewer normal space"] == "world"
    normal, kept = values[..., :3], values[..., 3:] >= np.float32(ALPHA_THRESHOLD)
    assert (np.any(normal != 0, axis=-1, keepdims=True) & ~kept).any()  # the mask shows here
    expected = np.where(np.any(normal != 0, axis=-1, keepdims=True) & kept, 0.5 + 0.5 * normal, 0.0)
    np.testing.assert_array_equal(pixels, to_rgb8(expected))
    render(capsys, scene, *view, "--channels", "alpha", "--out", tmp_path / "a.png")
    np.testing.assert_array_equal(png(tmp_path / "a.png")[0][..., 0], to_rgb8(values[..., 3:4].repeat(3, -1))[..., 0])


def test_npy_and_exr_keep_the_depths_the_picture_masks(capsys, tmp_path, tiny):
    """The alpha threshold is for the eye: the raw files keep every covered pixel's values."""
    scene, cameras = tiny
    view = ["--camera", cameras, "--camera-index", "1"]
    render(capsys, scene, *view, "--channels", "alpha,depth,normal", "--out", tmp_path / "g.npy")
    render(capsys, scene, *view, "--channels", "alpha,depth,normal", "--out", tmp_path / "g.exr")
    values = np.load(tmp_path / "g.npy")
    alpha, depth, normal = values[..., 0], values[..., 1], values[..., 2:5]
    faint = (alpha > 0) & (alpha < ALPHA_THRESHOLD)
    assert faint.any() and (depth[faint] > 0).all() and np.any(normal[faint] != 0, axis=-1).all()
    planes = read_exr(tmp_path / "g.exr")[1]
    np.testing.assert_array_equal(planes["Z"], depth)
    np.testing.assert_array_equal(np.stack([planes["N.X"], planes["N.Y"], planes["N.Z"]], -1), normal)
    render(capsys, scene, *view, "--channels", "depth", "--out", tmp_path / "d.png")
    assert not png(tmp_path / "d.png")[0][faint].any()  # where the picture shows none


# --------------------------------------------------------------------------- the old output


def test_default_output_is_unchanged_and_renders_no_geometry(capsys, tmp_path, monkeypatch):
    """The default (rgb,alpha) to .npy and .png is what render always wrote, through
    the colour-only render."""
    monkeypatch.setattr(GLRenderer, "render_channels", lambda *args, **kwargs: pytest.fail("geometry rendered"))
    before = {suffix: tmp_path / f"before{suffix}" for suffix in (".npy", ".png")}
    for suffix, path in before.items():
        render(capsys, "--width", "32", "--out", path)
        render(capsys, "--width", "32", "--channels", "rgb,alpha", "--out", tmp_path / f"after{suffix}")
        assert (tmp_path / f"after{suffix}").read_bytes() == path.read_bytes()
    render(capsys, "--width", "32", "--channels", "rgb", "--out", tmp_path / "rgb.png")
    assert png(tmp_path / "rgb.png")[0].tobytes() == png(before[".png"])[0].tobytes()
    render(capsys, "--width", "32", "--channels", "alpha,rgb", "--out", tmp_path / "swapped.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "swapped.npy"), np.load(before[".npy"])[..., [3, 0, 1, 2]])


# --------------------------------------------------------------------------- sidecars


def test_a_sidecar_of_a_depth_picture_renders_that_picture_again(capsys, tmp_path, gl_ctx):
    camera = demo_camera(32, 24)
    view = ChannelView("depth", (3.0, 6.5))
    sidecar = tmp_path / "shot.json"
    sidecar.write_text(json.dumps(build_sidecar(scene_path="demo", scene_sha256=demo_sha256(), scene=demo_scene(),
                                                camera=camera, settings=RenderSettings(), scale=1.0,
                                                channel_view=view)))
    stdout = render(capsys, "--sidecar", sidecar, "--out", tmp_path / "again.png")
    assert "depth range 3 to 6.5 (given" in stdout
    cameras = tmp_path / "cameras.json"
    cameras.write_text(json.dumps([camera_to_json(camera)]))
    render(capsys, "--camera", cameras, "--channels", "depth", "--depth-range", "3,6.5", "--out", tmp_path / "d.png")
    assert png(tmp_path / "again.png")[0].tobytes() == png(tmp_path / "d.png")[0].tobytes()
    # --channels over the sidecar's picture: the depths as numbers, none of its range.
    render(capsys, "--sidecar", sidecar, "--channels", "depth,normal", "--out", tmp_path / "again.exr")
    assert sorted(read_exr(tmp_path / "again.exr")[1]) == ["N.X", "N.Y", "N.Z", "Z"]


def test_a_sidecar_records_the_alpha_threshold_and_an_older_one_is_unmasked(capsys, tmp_path, gl_ctx):
    camera = demo_camera(32, 24)
    cameras = tmp_path / "cameras.json"
    cameras.write_text(json.dumps([camera_to_json(camera)]))
    pictures = {}
    for threshold in ("0", "0.3"):
        render(capsys, "--camera", cameras, "--channels", "depth", "--depth-range", "3,6.5",
               "--alpha-threshold", threshold, "--out", tmp_path / f"d{threshold}.png")
        pictures[threshold] = png(tmp_path / f"d{threshold}.png")[0]
    assert (pictures["0"] != pictures["0.3"]).any()  # the threshold matters in this view
    entry = build_sidecar(scene_path="demo", scene_sha256=demo_sha256(), scene=demo_scene(), camera=camera,
                          settings=RenderSettings(), scale=1.0,
                          channel_view=ChannelView("depth", (3.0, 6.5), alpha_threshold=0.3))
    assert entry["channel_view"]["alpha_threshold"] == 0.3
    sidecar = tmp_path / "shot.json"
    sidecar.write_text(json.dumps(entry))
    render(capsys, "--sidecar", sidecar, "--out", tmp_path / "again.png")
    assert png(tmp_path / "again.png")[0].tobytes() == pictures["0.3"].tobytes()
    # --alpha-threshold over the sidecar's.
    render(capsys, "--sidecar", sidecar, "--alpha-threshold", "0", "--out", tmp_path / "off.png")
    assert png(tmp_path / "off.png")[0].tobytes() == pictures["0"].tobytes()
    # A sidecar written before the threshold existed drew its picture unmasked.
    del entry["channel_view"]["alpha_threshold"]
    sidecar.write_text(json.dumps(entry))
    render(capsys, "--sidecar", sidecar, "--out", tmp_path / "old.png")
    assert png(tmp_path / "old.png")[0].tobytes() == pictures["0"].tobytes()


# --------------------------------------------------------------------------- the reference


def test_reference_channels_go_through_render_reference_channels(capsys, tmp_path, monkeypatch):
    """--reference with geometry channels writes what render_reference_channels gives
    (its accuracy is tested with the reference itself)."""
    calls = []
    rng = np.random.default_rng(0)
    made = ChannelImage(*(rng.uniform(0.1, 1, shape).astype(np.float32)
                          for shape in ((24, 32, 3), (24, 32), (24, 32), (24, 32), (24, 32, 3))))

    def fake(scene, camera, settings=RenderSettings(), order=None):
        calls.append((camera.width, camera.height, settings.order))
        return made

    monkeypatch.setattr(reference, "render_reference_channels", fake, raising=False)
    render(capsys, "--width", "32", "--reference", "--order", "per-pixel", "--channels", "normal,depth",
           "--out", tmp_path / "r.npy")
    assert calls == [(32, 24, "per-pixel")]
    np.testing.assert_array_equal(np.load(tmp_path / "r.npy"), made.stack(("normal", "depth")))


# --------------------------------------------------------------------------- render-path


def test_render_path_writes_an_exr_per_frame_equal_to_render(capsys, tmp_path):
    frames, cameras = tmp_path / "frames", tmp_path / "cameras.json"
    code, out, err = run_cli(capsys, "render-path", "demo", "orbit", "--size", "32x24", "--duration", "0.1",
                             "--fps", "20", "--channels", "depth,normal", "--normal-space", "world",
                             "--out", frames, "--cameras-out", cameras)
    assert code == 0, err
    assert listing(frames) == ["frame_00000.exr", "frame_00001.exr"]
    for k, name in enumerate(listing(frames)):
        single = tmp_path / f"single{k}.exr"
        render(capsys, "--camera", cameras, "--camera-index", k, "--channels", "depth,normal", "--normal-space",
               "world", "--out", single)
        header, planes = read_exr(frames / name)
        assert header["raygsChannels"] == "depth,normal" and header["raygsNormalSpace"] == "world"
        expected = read_exr(single)[1]
        assert sorted(planes) == sorted(expected) == ["N.X", "N.Y", "N.Z", "Z"]
        for channel in planes:
            np.testing.assert_array_equal(planes[channel], expected[channel], err_msg=f"{name} {channel}")
        assert planes["Z"].max() > 0


# --------------------------------------------------------------------------- bad input


def bad_cases(tmp_path) -> dict[str, list]:
    out = tmp_path / "out.png"
    return {
        "unknown_channel": ["render", "--channels", "disparity", "--out", tmp_path / "o.npy"],
        "repeated_channel": ["render", "--channels", "depth,depth", "--out", tmp_path / "o.npy"],
        "empty_channel": ["render", "--channels", "depth,", "--out", tmp_path / "o.npy"],
        "png_several": ["render", "--channels", "depth,normal", "--out", out],
        "png_default_swapped": ["render", "--channels", "alpha,rgb", "--out", out],
        "depth_range_npy": ["render", "--channels", "depth", "--depth-range", "1,2", "--out", tmp_path / "o.npy"],
        "depth_range_normal": ["render", "--channels", "normal", "--depth-range", "1,2", "--out", out],
        "depth_range_reversed": ["render", "--channels", "depth", "--depth-range", "2,1", "--out", out],
        "depth_range_words": ["render", "--channels", "depth", "--depth-range", "near,far", "--out", out],
        "alpha_threshold_above_1": ["render", "--channels", "depth", "--alpha-threshold", "1.5", "--out", out],
        "alpha_threshold_negative": ["render", "--channels", "depth", "--alpha-threshold", "-0.1", "--out", out],
        "alpha_threshold_words": ["render", "--channels", "depth", "--alpha-threshold", "half", "--out", out],
        "alpha_threshold_npy": ["render", "--channels", "depth", "--alpha-threshold", "0.1",
                                "--out", tmp_path / "o.npy"],
        "alpha_threshold_exr": ["render", "--channels", "depth", "--alpha-threshold", "0.1",
                                "--out", tmp_path / "o.exr"],
        "alpha_threshold_alpha": ["render", "--channels", "alpha", "--alpha-threshold", "0.1", "--out", out],
        "normal_space_unknown": ["render", "--channels", "normal", "--normal-space", "object", "--out", out],
        "normal_space_without_normal": ["render", "--channels", "depth", "--normal-space", "world",
                                        "--out", tmp_path / "o.npy"],
        "stereo_geometry": ["render", "--stereo", "--channels", "depth", "--out", tmp_path / "o.npy"],
        "unknown_suffix": ["render", "--channels", "depth", "--out", tmp_path / "o.tiff"],
        "path_mp4": ["render-path", "demo", "orbit", "--channels", "depth", "--out", tmp_path / "fly.mp4"],
        "path_unknown_channel": ["render-path", "demo", "orbit", "--channels", "z", "--out", tmp_path / "f"],
        "path_stereo_geometry": ["render-path", "demo", "orbit", "--stereo", "--channels", "normal",
                                 "--out", tmp_path / "f"],
        "path_normal_space_alone": ["render-path", "demo", "orbit", "--normal-space", "world",
                                    "--out", tmp_path / "f"],
    }


@pytest.mark.parametrize("case", sorted(bad_cases(Path("unused"))))
def test_bad_channel_options_are_one_line_errors_that_write_nothing(capsys, tmp_path, case):
    argv = bad_cases(tmp_path)[case]
    before = listing(tmp_path)
    code, _, err = run_cli(capsys, *argv)
    assert_one_line_error(code, err)
    assert listing(tmp_path) == before


def test_error_messages_say_what_to_do(capsys, tmp_path):
    expect = {"png_several": "a .png shows one channel", "unknown_channel": "choose from rgb, alpha",
              "stereo_geometry": "--stereo", "path_mp4": "--channels writes EXR frames into a folder",
              "depth_range_npy": "--depth-range", "normal_space_without_normal": "add normal to --channels",
              "alpha_threshold_above_1": "not an alpha from 0 to 1",
              "alpha_threshold_npy": ".npy files keep every pixel's value",
              "alpha_threshold_alpha": "depth, median_depth or normal, not of alpha"}
    cases = bad_cases(tmp_path)
    for case, fragment in expect.items():
        err = run_cli(capsys, *cases[case])[2]
        assert fragment in err, (case, err)


def test_a_stereo_sidecar_cannot_be_rendered_again_as_depth(capsys, tmp_path):
    sidecar = tmp_path / "pair.json"
    sidecar.write_text(json.dumps(build_sidecar(scene_path="demo", scene_sha256=demo_sha256(), scene=demo_scene(),
                                                camera=demo_camera(32, 24), settings=RenderSettings(), scale=1.0,
                                                stereo=StereoView(StereoRig()), channel_view=ChannelView("depth"))))
    for argv in ([], ["--channels", "normal"]):
        code, _, err = run_cli(capsys, "render", "--sidecar", sidecar, *argv, "--out", tmp_path / "again.png")
        assert "the stereo image composes colour" in assert_one_line_error(code, err)
    assert listing(tmp_path) == ["pair.json"]


def test_stereo_images_write_their_colour_channels(capsys, tmp_path):
    """A stereo layout composes colour and alpha, so those channels go to any format."""
    stereo = ["--width", "24", "--stereo", "--layout", "sbs"]
    render(capsys, *stereo, "--out", tmp_path / "pair.npy")
    render(capsys, *stereo, "--channels", "alpha,rgb", "--out", tmp_path / "pair.exr")
    pair = np.load(tmp_path / "pair.npy")
    _, planes = read_exr(tmp_path / "pair.exr")
    assert pair.shape == (18, 48, 4) and sorted(planes) == ["A", "B", "G", "R"]
    np.testing.assert_array_equal(np.stack([planes[n] for n in "RGBA"], axis=-1), pair)
