"""Screenshots: the scaled camera, tiled rendering against one whole render, and saving
PNG + sidecar atomically without ever replacing a file."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from testkit import assert_differs, assert_matches, assert_user_error, sort_indices, sorted_channels, sorted_render

import raygs_viewer.capture.screenshot as screenshot
from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.capture.image_io import encode_image, to_rgb8
from raygs_viewer.capture.screenshot import (
    MAX_SCALE,
    MAX_SCREENSHOT_SIDE,
    check_screenshot_path,
    next_screenshot_path,
    render_tiled,
    render_tiled_channels,
    save_screenshot,
    save_screenshots,
    scaled_camera,
)
from raygs_viewer.errors import UserError
from raygs_viewer.render.channels import CHANNELS
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

NOW = datetime(2025, 3, 4, 5, 6, 7)
STEM = "raygs-20250304-050607"


def off_centre_camera(width=64, height=48):
    """fx != fy and an off-centre principal point, so a tile offset applied to the
    wrong axis or with the wrong sign shows."""
    pose = look_at([0.6, -1.1, -4.2], [0.2, 0.1, 1.0])
    return Camera(width, height, 70.0 * width / 64, 55.0 * height / 48, 30.5 * width / 64, 26.25 * height / 48,
                  pose.R, pose.t)


def listing(folder):
    return sorted(p.name for p in Path(folder).iterdir())


@pytest.fixture
def renderer(demo_renderer):
    """The demo's renderer, its context made current: a context another test created
    and released (the CLI's) may be current since, and GL calls would go nowhere."""
    with demo_renderer.ctx:
        yield demo_renderer


@pytest.fixture
def fixed_now(monkeypatch):
    """save_screenshot names its file from datetime.now(): pin it."""
    class Fixed(datetime):
        @classmethod
        def now(cls, tz=None):
            return NOW

    monkeypatch.setattr(screenshot, "datetime", Fixed)


def small_image(seed=0, height=6, width=8):
    rng = np.random.default_rng(seed)
    image = rng.uniform(0, 1, (height, width, 4)).astype(np.float32)
    return image


def sidecar_dict(**extra):
    return {"format": "test", "scene": {"path": "demo"}, **extra}


# --------------------------------------------------------------------------- scaled camera


def test_scaled_camera_scales_size_and_intrinsics():
    camera = off_centre_camera()
    double = scaled_camera(camera, 2.0)
    assert (double.width, double.height) == (128, 96)
    assert (double.fx, double.fy, double.cx, double.cy) == (camera.fx * 2, camera.fy * 2, camera.cx * 2, camera.cy * 2)
    np.testing.assert_array_equal(double.R, camera.R)
    np.testing.assert_array_equal(double.t, camera.t)
    odd = scaled_camera(camera, 1.3)  # 83.2 x 62.4 -> 83 x 62: fx follows the rounded width
    assert (odd.width, odd.height) == (83, 62)
    assert odd.fx == pytest.approx(camera.fx * 83 / 64) and odd.cy == pytest.approx(camera.cy * 62 / 48)
    same = scaled_camera(camera, 1.0)
    assert (same.width, same.height, same.fx, same.cx) == (camera.width, camera.height, camera.fx, camera.cx)
    assert scaled_camera(camera, MAX_SCALE).width == 64 * 8


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), float("inf"), MAX_SCALE * 1.001, 100.0, True, "2"])
def test_scaled_camera_rejects_bad_scales(scale):
    with pytest.raises(UserError, match="scale"):
        scaled_camera(off_centre_camera(), scale)


def test_scaled_camera_limits_the_size():
    big = off_centre_camera(4096, 3072)
    assert scaled_camera(big, 4.0).width == MAX_SCREENSHOT_SIDE
    with pytest.raises(UserError, match=str(MAX_SCREENSHOT_SIDE)):
        scaled_camera(big, 4.01)
    with pytest.raises(UserError, match="0x0|1x0|0x1"):
        scaled_camera(off_centre_camera(), 0.001)


# --------------------------------------------------------------------------- tiled rendering


def tiled_render(renderer, camera, settings=RenderSettings(), **options):
    """render_tiled of ``camera``'s exact order, with a DepthSorter of the renderer's
    scene (what screenshots and ``render`` do); ``options``: its ``tile``."""
    with DepthSorter(renderer.scene) as sorter:
        return render_tiled(renderer, sorter, exact_order(sorter, camera, settings), camera, settings, **options)


def tiled_channels(renderer, camera, settings=RenderSettings(), **options):
    """render_tiled_channels as :func:`tiled_render`."""
    with DepthSorter(renderer.scene) as sorter:
        return render_tiled_channels(renderer, sorter, exact_order(sorter, camera, settings), camera, settings,
                                     **options)


def _count_render_sizes(renderer, monkeypatch) -> list[tuple[int, int]]:
    """The list the (width, height) of every ``renderer.render`` call is appended to."""
    sizes = []
    render = renderer.render

    def counting(camera, *args, **kwargs):
        sizes.append((camera.width, camera.height))
        return render(camera, *args, **kwargs)

    monkeypatch.setattr(renderer, "render", counting)
    return sizes


@pytest.mark.parametrize("tile", [16, 20, 7])  # exact grid; edge tiles of 4 and 8 px; many odd tiles
@pytest.mark.parametrize("settings", [RenderSettings(),
                                      RenderSettings(p_min=0.02, background=(0.1, 0.2, 0.3), sh_degree=1)],
                         ids=["default", "custom"])
def test_render_tiled_equals_one_whole_render(renderer, tile, settings, monkeypatch):
    camera = off_centre_camera()
    whole = sorted_render(renderer, camera, settings)

    sizes = _count_render_sizes(renderer, monkeypatch)
    tiled = tiled_render(renderer, camera, settings, tile=tile)
    monkeypatch.undo()
    assert len(sizes) == -(-64 // tile) * -(-48 // tile) and set(sizes) == {(tile, tile)}  # really tiled
    assert tiled.dtype == np.float32 and tiled.shape == (48, 64, 4)
    assert tiled[..., 3].max() > 0.9 and tiled.std() > 0.05  # shows the scene
    # Only the rasterizer's rounding differs between tile projections: a few pixels
    # whose fragment sits at p_min flip (at most p_min * colour); the rest agree to ~1e-5.
    stats = assert_matches(tiled, whole, max_error=2 * settings.p_min, pixel_fraction=0.002, p999=1e-4)
    assert stats["mean"] < 1e-5, stats
    # Negative controls: a tile offset off by one pixel, in x or in y, would not pass.
    assert_differs(tiled, np.roll(whole, 1, axis=1), max_error=2 * settings.p_min, p999=1e-4)
    assert_differs(tiled, np.roll(whole, 1, axis=0), max_error=2 * settings.p_min, p999=1e-4)


@pytest.mark.parametrize("settings", [RenderSettings(supersample=2),
                                      RenderSettings(supersample=3, mode="raygs-exact-mip", p_min=0.02)],
                         ids=["raygs-2x2", "exact-mip-3x3"])
def test_supersampled_tiles_keep_the_gpu_target_within_the_tile(renderer, settings, monkeypatch):
    """k x k supersampling renders tiles of tile // k pixels (k times that on the GPU),
    and the tiles still make up the whole supersampled render."""
    camera = off_centre_camera()
    whole = sorted_render(renderer, camera, settings)
    assert_differs(whole, sorted_render(renderer, camera, replace(settings, supersample=1)))  # supersampling shows
    sizes = _count_render_sizes(renderer, monkeypatch)
    tiled = tiled_render(renderer, camera, settings, tile=48)
    monkeypatch.undo()
    side = 48 // settings.supersample
    assert set(sizes) == {(side, side)} and len(sizes) == -(-64 // side) * -(-48 // side)
    assert_matches(tiled, whole, max_error=2 * settings.p_min, pixel_fraction=0.002, p999=1e-4)


@pytest.mark.parametrize("supersample", [1, 2])
def test_gs_tiles_equal_one_whole_render(renderer, supersample):
    """GS clamps its rays to the whole image's borders, not each tile's."""
    camera = off_centre_camera()
    settings = RenderSettings(mode="gs", supersample=supersample)
    assert_matches(tiled_render(renderer, camera, settings, tile=16), sorted_render(renderer, camera, settings),
                   max_error=2 * settings.p_min, pixel_fraction=0.002, p999=1e-4)


def test_render_tiled_negative_control_wrong_offset(renderer):
    """Tiles whose principal point is not shifted by the tile offset (each tile would
    show the image's top-left corner) are caught by the comparison above."""
    camera = off_centre_camera()
    whole = sorted_render(renderer, camera)
    wrong = np.empty_like(whole)
    for y0 in range(0, 48, 16):
        for x0 in range(0, 64, 16):
            part = screenshot.tile_camera(camera, x0, y0, 16, 16)
            shifted = screenshot.tile_camera(camera, x0 + 1, y0, 16, 16)  # off by one in x
            np.testing.assert_array_equal(part.R, camera.R)
            assert (part.cx, part.cy) == (camera.cx - x0, camera.cy - y0)
            wrong[y0:y0 + 16, x0:x0 + 16] = sorted_render(renderer, shifted)
    assert_differs(wrong, whole)


def test_render_tiled_keeps_the_whole_images_blending_order(gl_render, gl_ctx):
    """Two overlapping gaussians 0.001 apart in depth share one 16-bit depth key over
    the whole image's depth range (so scene order decides: red, then green on top),
    but not over a left tile's, where the far blue one is culled: sorting each tile on
    its own would put red on top and change the pixels."""
    from testkit import make_scene

    from raygs_viewer.render.gl.renderer import GLRenderer
    from raygs_viewer.sort.depth import DepthSorter

    scene = make_scene([[-0.5, 0, 2.0], [-0.5, 0, 2.001], [400, 0, 1000], [0.3, 0, 1.0]],
                       [[0.1] * 3, [0.1] * 3, [1.0] * 3, [0.05] * 3], opacities=0.9,
                       colors=[[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    camera = Camera(64, 48, 64.0, 64.0, 32.0, 24.0, np.eye(3), np.zeros(3))
    sorter = DepthSorter(scene)
    assert sort_indices(sorter, camera, 1 / 255).tolist() == [2, 0, 1, 3]  # premise: a tie, scene order
    assert sort_indices(sorter, screenshot.tile_camera(camera, 0, 0, 32, 32), 1 / 255).tolist() == [1, 0]
    with gl_ctx:
        whole = gl_render(scene, camera)
        renderer = GLRenderer(gl_ctx, scene)
        try:
            tiled = tiled_render(renderer, camera, tile=32)
        finally:
            renderer.release()
    assert whole[24, 16, 1] > 0.8 and whole[24, 16, 0] < 0.2  # green on top
    np.testing.assert_allclose(tiled, whole, atol=1e-5)


def test_render_tiled_refuses_oversized_images(renderer):
    camera = off_centre_camera(MAX_SCREENSHOT_SIDE + 1, 48)
    with pytest.raises(UserError, match=f"{MAX_SCREENSHOT_SIDE + 1}x48"):
        tiled_render(renderer, camera)


def test_render_tiled_with_one_tile_is_the_plain_render(renderer):
    camera = off_centre_camera(40, 30)
    np.testing.assert_array_equal(tiled_render(renderer, camera, tile=40), sorted_render(renderer, camera))
    np.testing.assert_array_equal(tiled_render(renderer, camera), sorted_render(renderer, camera))


# --------------------------------------------------------------------------- names


def test_next_screenshot_path(tmp_path):
    assert next_screenshot_path(tmp_path, NOW) == tmp_path / f"{STEM}.png"
    (tmp_path / f"{STEM}.png").write_bytes(b"x")
    assert next_screenshot_path(tmp_path, NOW) == tmp_path / f"{STEM}-2.png"
    (tmp_path / f"{STEM}-2.json").write_bytes(b"x")  # a sidecar alone also takes the name
    assert next_screenshot_path(tmp_path, NOW) == tmp_path / f"{STEM}-3.png"
    assert next_screenshot_path(tmp_path / "absent", NOW) == tmp_path / "absent" / f"{STEM}.png"
    assert next_screenshot_path(tmp_path).name.startswith("raygs-2")


@pytest.mark.parametrize("name,fragment", [
    ("shot.jpg", ".png"), ("shot", ".png"), ("no/such/shot.png", "does not exist"),
    ("taken.png", "already exists"), ("sidecar_taken.png", "already exists"),
])
def test_check_screenshot_path(tmp_path, name, fragment):
    (tmp_path / "taken.png").write_bytes(b"x")
    (tmp_path / "sidecar_taken.json").write_bytes(b"x")
    assert_user_error(lambda: check_screenshot_path(tmp_path / name), "", fragment)
    assert check_screenshot_path(tmp_path / "free.png") == tmp_path / "free.png"
    assert check_screenshot_path(tmp_path / "FREE.PNG") == tmp_path / "FREE.PNG"


# --------------------------------------------------------------------------- saving


def read_png(path):
    with Image.open(path) as image:
        assert image.format == "PNG" and image.mode == "RGB"
        return np.asarray(image)


def test_save_into_new_folder(tmp_path, fixed_now):
    image = small_image()
    folder = tmp_path / "a" / "b"
    data = sidecar_dict(extra={"up": "-y"}, value=0.1 + 0.2)
    png, js = save_screenshot(image, data, folder=folder)
    assert (png, js) == (folder / f"{STEM}.png", folder / f"{STEM}.json")
    assert listing(folder) == [js.name, png.name]
    np.testing.assert_array_equal(read_png(png), to_rgb8(image))
    assert png.read_bytes() == encode_image(image, ".png")
    assert json.loads(js.read_text()) == data
    assert json.loads(js.read_text())["value"] == 0.1 + 0.2  # floats round-trip exactly
    assert oct(png.stat().st_mode & 0o777) == oct(0o666 & ~current_umask())  # ordinary files, not mkstemp's 0600


def current_umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_save_never_overwrites_in_folder_mode(tmp_path, fixed_now):
    precious = b"precious, not ours"
    (tmp_path / f"{STEM}.png").write_bytes(precious)
    (tmp_path / f"{STEM}-2.json").write_bytes(precious)
    png, js = save_screenshot(small_image(), sidecar_dict(), folder=tmp_path)
    assert (png.name, js.name) == (f"{STEM}-3.png", f"{STEM}-3.json")
    assert (tmp_path / f"{STEM}.png").read_bytes() == precious
    assert (tmp_path / f"{STEM}-2.json").read_bytes() == precious
    assert listing(tmp_path) == sorted([f"{STEM}.png", f"{STEM}-2.json", f"{STEM}-3.png", f"{STEM}-3.json"])
    again = save_screenshot(small_image(1), sidecar_dict(), folder=tmp_path)
    assert again[0].name == f"{STEM}-4.png"
    assert png.read_bytes() == encode_image(small_image(), ".png")


def _another_writer_takes(raced: Path, monkeypatch) -> Path:
    """Makes ``raced`` appear (another writer's) the first time the screenshot code
    writes to it, between choosing the name and writing."""
    real = screenshot.write_atomically

    def racing(path, data, overwrite=False):
        if Path(path) == raced and not raced.exists():
            raced.write_bytes(b"the other writer's")
        return real(path, data, overwrite)

    monkeypatch.setattr(screenshot, "write_atomically", racing)
    return raced


@pytest.mark.parametrize("which", ["png", "json"])
def test_save_retries_when_another_writer_takes_the_name(tmp_path, fixed_now, monkeypatch, which):
    """The name is free when chosen but taken by the time it is written (a second
    viewer saving in the same second): the next suffix is used, nothing is replaced,
    and our PNG does not stay behind under the lost name."""
    raced = _another_writer_takes(tmp_path / f"{STEM}.{which}", monkeypatch)
    png, js = save_screenshot(small_image(), sidecar_dict(), folder=tmp_path)
    assert (png.name, js.name) == (f"{STEM}-2.png", f"{STEM}-2.json")
    assert raced.read_bytes() == b"the other writer's"
    assert listing(tmp_path) == sorted([raced.name, png.name, js.name])


def test_explicit_path(tmp_path):
    image = small_image()
    png, js = save_screenshot(image, sidecar_dict(), path=tmp_path / "shot.png")
    assert (png, js) == (tmp_path / "shot.png", tmp_path / "shot.json")
    assert png.read_bytes() == encode_image(image, ".png")
    # Never replaced: the same path again, or a path whose sidecar exists.
    before = {p: p.read_bytes() for p in (png, js)}
    assert_user_error(lambda: save_screenshot(small_image(1), sidecar_dict(), path=png), "shot.png", "already exists")
    (tmp_path / "other.json").write_bytes(b"precious")
    assert_user_error(lambda: save_screenshot(image, sidecar_dict(), path=tmp_path / "other.png"), "other.json",
                      "already exists")
    assert_user_error(lambda: save_screenshot(image, sidecar_dict(), path=tmp_path / "shot.jpg"), "shot.jpg", ".png")
    assert {p: p.read_bytes() for p in (png, js)} == before
    assert listing(tmp_path) == ["other.json", "shot.json", "shot.png"]


def pair_of_shots():
    return [(small_image(0), sidecar_dict(side="left"), "left"), (small_image(1), sidecar_dict(side="right"), "right")]


def test_save_screenshots_names_each_side_with_one_number(tmp_path, fixed_now):
    folder = tmp_path / "shots"
    saved = save_screenshots(pair_of_shots(), folder=folder)
    names = [f"{STEM}-left", f"{STEM}-right"]
    assert [(png.name, js.name) for png, js in saved] == [(f"{n}.png", f"{n}.json") for n in names]
    for (png, js), (image, sidecar, _) in zip(saved, pair_of_shots()):
        assert png.read_bytes() == encode_image(image, ".png")
        assert json.loads(js.read_text()) == sidecar
    # Again in the same second: both sides move on to -2, nothing is replaced.
    again = save_screenshots(pair_of_shots(), folder=folder)
    assert [png.name for png, _ in again] == [f"{STEM}-2-left.png", f"{STEM}-2-right.png"]
    # Any one of the four names taken moves the whole capture on, so its sides keep one number.
    (folder / f"{STEM}-3-right.json").write_bytes(b"precious")
    third = save_screenshots(pair_of_shots(), folder=folder)
    assert [png.name for png, _ in third] == [f"{STEM}-4-left.png", f"{STEM}-4-right.png"]
    assert (folder / f"{STEM}-3-right.json").read_bytes() == b"precious"
    assert saved[0][0].read_bytes() == encode_image(small_image(0), ".png")
    assert len(listing(folder)) == 13


def test_save_screenshots_retries_when_another_writer_takes_a_name(tmp_path, fixed_now, monkeypatch):
    raced = _another_writer_takes(tmp_path / f"{STEM}-right.png", monkeypatch)
    saved = save_screenshots(pair_of_shots(), folder=tmp_path)
    assert [png.name for png, _ in saved] == [f"{STEM}-left.png", f"{STEM}-2-right.png"]
    assert raced.read_bytes() == b"the other writer's"


def test_save_screenshots_to_an_explicit_path(tmp_path):
    saved = save_screenshots(pair_of_shots(), path=tmp_path / "shot.png")
    assert [(png.name, js.name) for png, js in saved] == [("shot-left.png", "shot-left.json"),
                                                          ("shot-right.png", "shot-right.json")]
    (tmp_path / "other-right.json").write_bytes(b"precious")
    before = listing(tmp_path)
    assert_user_error(lambda: save_screenshots(pair_of_shots(), path=tmp_path / "other.png"), "other-right.json",
                      "already exists")
    assert listing(tmp_path) == before  # checked before the left side was written
    assert_user_error(lambda: save_screenshots(pair_of_shots(), path=tmp_path / "shot.jpg"), "shot-left.jpg", ".png")
    with pytest.raises(ValueError):
        save_screenshots(pair_of_shots()[:1] * 2, folder=tmp_path)
    with pytest.raises(ValueError):
        save_screenshots(pair_of_shots(), path=tmp_path / "x.png", folder=tmp_path)


def test_explicit_path_taken_during_the_write(tmp_path, monkeypatch):
    """A sidecar that appears (here: a folder) between the check and the write: error,
    and the PNG just written is removed."""
    real = screenshot.write_atomically

    def racing(path, data, overwrite=False):
        if Path(path).suffix == ".json":
            Path(path).mkdir()
        return real(path, data, overwrite)

    monkeypatch.setattr(screenshot, "write_atomically", racing)
    assert_user_error(lambda: save_screenshot(small_image(), sidecar_dict(), path=tmp_path / "shot.png"),
                      "shot.json", "already exists")
    assert listing(tmp_path) == ["shot.json"]  # only the intruding folder; no PNG, no temporary file


@pytest.mark.parametrize("mode", ["path", "folder"])
def test_png_removed_when_the_sidecar_cannot_be_written(tmp_path, monkeypatch, fixed_now, mode):
    real = screenshot.write_atomically

    def full_disk(path, data, overwrite=False):
        if Path(path).suffix == ".json":
            raise UserError(f"{path}: cannot write: No space left on device")
        return real(path, data, overwrite)

    monkeypatch.setattr(screenshot, "write_atomically", full_disk)
    where = {"path": tmp_path / "shot.png"} if mode == "path" else {"folder": tmp_path}
    message = assert_user_error(lambda: save_screenshot(small_image(), sidecar_dict(), **where), "",
                                "No space left on device", "its PNG was removed")
    assert message.count(".json") == 1  # named once, not once per layer
    assert ".json" in message
    assert listing(tmp_path) == []


def test_unserialisable_sidecar_writes_nothing(tmp_path):
    for bad in ({"x": float("nan")}, {"x": object()}):
        with pytest.raises(UserError, match="JSON"):
            save_screenshot(small_image(), bad, path=tmp_path / "shot.png")
    assert listing(tmp_path) == []


def test_unusable_folder(tmp_path):
    (tmp_path / "file").write_bytes(b"x")
    assert_user_error(lambda: save_screenshot(small_image(), sidecar_dict(), folder=tmp_path / "file"), "file",
                      "not a folder")
    assert_user_error(lambda: save_screenshot(small_image(), sidecar_dict(), folder=tmp_path / "file" / "sub"),
                      "sub", "Not a directory")
    assert listing(tmp_path) == ["file"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        assert_user_error(lambda: save_screenshot(small_image(), sidecar_dict(), folder=folder), "", "ermission")
        assert listing(folder) == []
    finally:
        folder.chmod(0o755)


def test_save_records_the_scene_relative_to_the_sidecar(tmp_path):
    scene = tmp_path / "scenes" / "a.ply"
    data = sidecar_dict(scene={"path": str(scene), "sha256": "0" * 64})
    _, js = save_screenshot(small_image(), data, folder=tmp_path / "shots")
    assert json.loads(js.read_text())["scene"]["relative_path"] == os.path.join("..", "scenes", "a.ply")
    assert data["scene"] == {"path": str(scene), "sha256": "0" * 64}  # the caller's dict is not changed
    _, js = save_screenshot(small_image(), sidecar_dict(), folder=tmp_path / "shots")
    assert "relative_path" not in json.loads(js.read_text())["scene"]  # "demo" has no file


def test_exactly_one_destination(tmp_path):
    with pytest.raises(ValueError):
        save_screenshot(small_image(), {})
    with pytest.raises(ValueError):
        save_screenshot(small_image(), {}, path=tmp_path / "a.png", folder=tmp_path)


@pytest.mark.parametrize("order", ["distance", "per-pixel"])
def test_render_tiled_draws_every_tile_in_the_settings_key(renderer, monkeypatch, order):
    """Each tile's order is the whole image's order by the settings' key
    (``RenderSettings.sort_key``), restricted to what the tile may see."""
    camera = off_centre_camera()
    settings = RenderSettings(order=order, order_k=2 if order == "per-pixel" else 0)
    with DepthSorter(renderer.scene) as sorter:
        exact = exact_order(sorter, camera, settings)
    whole = exact.indices
    assert exact.key == settings.sort_key and exact.request.dilation == settings.cull_dilation(camera)
    drawn = []
    render = renderer.render

    def recording(part, settings_, tile_order=None, **kwargs):
        drawn.append((settings_, tile_order))
        return render(part, settings_, tile_order, **kwargs)

    monkeypatch.setattr(renderer, "render", recording)
    with DepthSorter(renderer.scene) as sorter:
        render_tiled(renderer, sorter, exact, camera, settings, tile=32)
    monkeypatch.undo()
    assert len(drawn) == 4 and all(s == settings for s, _ in drawn)
    for _, tile_order in drawn:
        assert tile_order.key == settings.sort_key and tile_order.request == exact.request
        np.testing.assert_array_equal(tile_order.indices, whole[np.isin(whole, tile_order.indices)])  # a subsequence
        assert 0 < tile_order.count < exact.count
    if order == "distance":  # the premise: the two keys order this view differently
        with DepthSorter(renderer.scene) as sorter:
            depth = sort_indices(sorter, camera, settings.p_min, key="depth")
        assert not np.array_equal(whole, depth)


# --------------------------------------------------------------------------- tiled channels


@pytest.mark.parametrize("settings", [RenderSettings(), RenderSettings(order="per-pixel", supersample=2)],
                         ids=["global", "per-pixel-2x2"])
def test_render_tiled_channels_equal_one_whole_render(renderer, settings, monkeypatch):
    """Every channel of a tiled render (edge tiles cropped) is the whole render's: the
    tiles' normals stay in the whole camera's space, their depths its z."""
    camera = off_centre_camera()
    whole = sorted_channels(renderer, camera, settings)
    sizes = []
    render_channels = renderer.render_channels
    monkeypatch.setattr(renderer, "render_channels", lambda part, *args, **kwargs: sizes.append(
        (part.width, part.height)) or render_channels(part, *args, **kwargs))
    tiled = tiled_channels(renderer, camera, settings, tile=40)
    monkeypatch.undo()
    side = 40 // settings.supersample
    assert set(sizes) == {(side, side)} and len(sizes) == -(-64 // side) * -(-48 // side)  # really tiled
    assert tiled.normal_space == "camera" and tiled.depth.shape == (48, 64) and tiled.normal.shape == (48, 64, 3)
    assert (tiled.alpha > 0.5).mean() > 0.2 and np.ptp(tiled.depth[tiled.alpha > 0.5]) > 0.5  # shows the scene
    for name in CHANNELS:
        a, b = getattr(tiled, name), getattr(whole, name)
        assert a.dtype == np.float32 and a.shape == b.shape, name
        # The rasterizer's rounding differs between tile projections (see above): a few
        # pixels may differ, the rest agree closely.
        close = np.isclose(a, b, rtol=1e-4, atol=1e-4)
        assert close.mean() > 0.995, (name, close.mean())
    # Negative control: the depth of a tile offset off by one pixel would not pass.
    assert np.isclose(tiled.depth, np.roll(whole.depth, 1, axis=1), rtol=1e-4, atol=1e-4).mean() < 0.9


def test_render_tiled_channels_with_one_tile_is_the_plain_render(renderer):
    camera = off_centre_camera(40, 30)
    tiled, whole = tiled_channels(renderer, camera), sorted_channels(renderer, camera)
    for name in CHANNELS:
        np.testing.assert_array_equal(getattr(tiled, name), getattr(whole, name))
    with pytest.raises(UserError, match=f"{MAX_SCREENSHOT_SIDE + 1}x48"):
        tiled_channels(renderer, off_centre_camera(MAX_SCREENSHOT_SIDE + 1, 48))
