"""Writing a render's channels: .npy in the order listed, .exr with named channels
(read back through OpenEXR), one-channel .png pictures with their stated range, the
atomic never-clobbering writes, and the EXR frame folder of render-path."""

from __future__ import annotations

import io

import numpy as np
import OpenEXR
import pytest
from PIL import Image
from testkit import assert_user_error, listing

from raygs_viewer.capture.channel_io import (
    EXR_NAMES,
    PNG_CHANNEL_KEY,
    PNG_DEPTH_RANGE_KEY,
    colour_channels,
    encode_npy,
    encode_picture,
    is_plain_colour,
    picture_view,
    save_channels,
    write_exr,
)
from raygs_viewer.capture.image_io import encode_image
from raygs_viewer.capture.video import ExrFolderSink
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ALPHA_THRESHOLD, ChannelView, automatic_range
from raygs_viewer.render.channels import CHANNELS, ChannelImage

EVERY = ("rgb", "alpha", "depth", "median_depth", "normal")


def hand_made(height=5, width=7, seed=0) -> ChannelImage:
    """Distinct values in every channel (so a swapped or misnamed one shows); the
    top-left pixel uncovered (alpha, depths and normal 0)."""
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(height, width, 3))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    image = ChannelImage(rng.uniform(0, 1, (height, width, 3)).astype(np.float32),
                         rng.uniform(0.1, 1, (height, width)).astype(np.float32),
                         rng.uniform(1, 5, (height, width)).astype(np.float32),
                         rng.uniform(1, 5, (height, width)).astype(np.float32),
                         normal.astype(np.float32))
    for array in (image.alpha, image.depth, image.median_depth, image.normal):
        array[0, 0] = 0
    return image


def read_exr(path) -> tuple[dict, dict[str, np.ndarray]]:
    exr = OpenEXR.File(str(path), separate_channels=True)
    return exr.header(), {name: channel.pixels for name, channel in exr.channels().items()}


def png_of(data: bytes) -> tuple[np.ndarray, dict]:
    with Image.open(io.BytesIO(data)) as image:
        return np.asarray(image.convert("RGB")), dict(image.text)


# --------------------------------------------------------------------------- .npy and .exr


@pytest.mark.parametrize("channels", [EVERY, ("alpha", "depth", "median_depth", "normal"), ("normal", "rgb"),
                                      ("median_depth",)])
def test_npy_holds_the_channels_in_the_order_listed(channels):
    image = hand_made()
    stacked = np.load(io.BytesIO(encode_npy(image, channels)))
    assert stacked.dtype == np.float32 and stacked.shape == (5, 7, sum(3 if c in ("rgb", "normal") else 1
                                                                       for c in channels))
    column = 0
    for name in channels:
        width = 3 if name in ("rgb", "normal") else 1
        np.testing.assert_array_equal(stacked[..., column:column + width], image.channel(name))
        column += width


@pytest.mark.parametrize("channels", [EVERY, ("alpha", "depth", "median_depth", "normal"), ("normal", "depth")])
def test_exr_round_trip_names_order_and_values_equal_the_npy(tmp_path, channels):
    image = hand_made()
    path = write_exr(tmp_path / "g.exr", image, channels)
    header, planes = read_exr(path)
    names = [name for channel in channels for name in EXR_NAMES[channel]]
    assert sorted(planes) == sorted(names)
    # EXR sorts its channels by name; the header keeps the order listed.
    assert header["raygsChannels"] == ",".join(channels)
    stacked = np.load(io.BytesIO(encode_npy(image, channels)))
    for index, name in enumerate(names):
        assert planes[name].dtype == np.float32 and planes[name].shape == (5, 7)
        np.testing.assert_array_equal(planes[name], stacked[..., index])
    assert listing(tmp_path) == ["g.exr"]  # no temporary left


def test_exr_channel_names():
    """The names compositing tools expect, one per value of each channel."""
    assert EXR_NAMES == {"rgb": ("R", "G", "B"), "alpha": ("A",), "depth": ("Z",), "median_depth": ("Z.median",),
                         "normal": ("N.X", "N.Y", "N.Z")}
    assert set(EXR_NAMES) == set(CHANNELS)


def test_exr_records_the_normals_space(tmp_path):
    camera_space = write_exr(tmp_path / "c.exr", hand_made(), ("normal",))
    assert read_exr(camera_space)[0]["raygsNormalSpace"] == "camera"
    world = ChannelImage(*(getattr(hand_made(), c) for c in CHANNELS), normal_space="world")
    assert read_exr(write_exr(tmp_path / "w.exr", world, ("normal", "depth")))[0]["raygsNormalSpace"] == "world"
    assert "raygsNormalSpace" not in read_exr(write_exr(tmp_path / "d.exr", world, ("depth",)))[0]


@pytest.mark.parametrize("suffix", [".exr", ".npy", ".png"])
def test_existing_files_are_kept_unless_overwrite(tmp_path, suffix):
    path = tmp_path / f"taken{suffix}"
    path.write_bytes(b"precious")
    assert_user_error(lambda: save_channels(path, hand_made(), ("depth",)), path, "already exists", "--overwrite")
    assert path.read_bytes() == b"precious" and listing(tmp_path) == [path.name]
    save_channels(path, hand_made(), ("depth",), overwrite=True)
    assert path.read_bytes() != b"precious" and listing(tmp_path) == [path.name]


def test_exr_write_failure_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    def failing(self, name):
        raise RuntimeError(f'Cannot open image file "{name}". No space left on device.')

    monkeypatch.setattr(OpenEXR.File, "write", failing)
    path = tmp_path / "full.exr"
    assert_user_error(lambda: write_exr(path, hand_made(), ("depth",)), path, "cannot write", "No space left")
    assert listing(tmp_path) == []
    missing = tmp_path / "no" / "g.exr"
    assert_user_error(lambda: write_exr(missing, hand_made(), ("depth",)), missing, "cannot write")


# --------------------------------------------------------------------------- .png pictures


def test_depth_picture_uses_the_stated_range(tmp_path):
    """Pixels at the near end of the range are viridis' bright end, at the far end its
    dark end, undefined ones black; the PNG's text states the range."""
    image = hand_made()
    depth = np.full((5, 7), 3.0, np.float32)
    depth[1, :] = 2.0   # near
    depth[2, :] = 6.0   # far
    depth[3, :] = 9.0   # beyond far: clamped
    depth[0, 0] = 0.0   # undefined
    image = ChannelImage(image.rgb, image.alpha, depth, image.median_depth, image.normal)
    data, used = encode_picture(image, ChannelView("depth", (2.0, 6.0)))
    pixels, text = png_of(data)
    assert used == (2.0, 6.0)
    assert text[PNG_CHANNEL_KEY] == "depth" and text[PNG_DEPTH_RANGE_KEY] == "2.0 6.0"
    near, far, middle = pixels[1, 3].astype(int), pixels[2, 3].astype(int), pixels[4, 3].astype(int)
    np.testing.assert_array_equal(near, [253, 231, 37])   # viridis at 1
    np.testing.assert_array_equal(far, [68, 1, 84])       # viridis at 0
    assert near.sum() > middle.sum() > far.sum()
    np.testing.assert_array_equal(pixels[3, 3], far)
    np.testing.assert_array_equal(pixels[0, 0], [0, 0, 0])


def test_automatic_depth_range_is_stated():
    image = hand_made()
    data, used = encode_picture(image, ChannelView("median_depth"))
    assert used == automatic_range(image.median_depth)
    assert png_of(data)[1][PNG_DEPTH_RANGE_KEY] == f"{used[0]!r} {used[1]!r}"
    empty = colour_channels(np.zeros((4, 5, 4), np.float32))
    data, used = encode_picture(empty, ChannelView("depth"))
    assert used is None and png_of(data)[1][PNG_DEPTH_RANGE_KEY] == "none"


def test_normal_and_alpha_pictures():
    image = hand_made()
    pixels, text = png_of(encode_picture(image, ChannelView("normal"))[0])
    assert text == {PNG_CHANNEL_KEY: "normal", "raygs-viewer normal space": "camera",
                    "raygs-viewer alpha threshold": repr(ALPHA_THRESHOLD)}
    np.testing.assert_array_equal(pixels, np.round(np.where(np.any(image.normal != 0, axis=-1, keepdims=True),
                                                            0.5 + 0.5 * image.normal, 0) * 255))
    pixels, text = png_of(encode_picture(image, ChannelView("alpha"))[0])
    assert text == {PNG_CHANNEL_KEY: "alpha"}
    np.testing.assert_array_equal(pixels[..., 1], np.round(image.alpha * 255))


def test_a_picture_of_colour_is_the_png_render_always_wrote():
    rgba = np.random.default_rng(1).uniform(-0.2, 1.2, (6, 8, 4)).astype(np.float32)
    pixels, _ = png_of(encode_picture(colour_channels(rgba), picture_view(("rgb",), ".png"))[0])
    assert np.array_equal(pixels, png_of(encode_image(rgba, ".png"))[0])


def test_picture_view_choices():
    assert picture_view(("rgb", "alpha"), ".png") == ChannelView("rgb")
    assert picture_view(("depth",), ".PNG", (1.0, 2.0)) == ChannelView("depth", (1.0, 2.0))
    assert picture_view(("normal",), ".png", None, "world") == ChannelView("normal", None, "world")
    assert picture_view(("depth",), ".png", None, "camera", 0.0) == ChannelView("depth", alpha_threshold=0.0)
    assert picture_view(("depth",), ".npy") is None
    assert picture_view(EVERY, ".exr") is None and picture_view(EVERY, ".npy") is None
    for channels in (("depth", "normal"), ("alpha", "rgb"), ("rgb", "alpha", "depth")):
        with pytest.raises(UserError, match="a .png shows one channel"):
            picture_view(channels, ".png")
    with pytest.raises(UserError, match="--depth-range"):
        picture_view(("depth",), ".exr", (1.0, 2.0))
    with pytest.raises(UserError, match="--depth-range is for a picture of depth"):
        picture_view(("normal",), ".png", (1.0, 2.0))


def test_only_the_default_channels_to_png_or_npy_keep_the_old_path():
    assert is_plain_colour(("rgb", "alpha"), ".png") and is_plain_colour(("rgb", "alpha"), ".NPY")
    assert not is_plain_colour(("rgb", "alpha"), ".exr")
    assert not is_plain_colour(("alpha", "rgb"), ".npy") and not is_plain_colour(("rgb",), ".png")


def test_colour_channels_keep_the_render_and_cost_no_geometry_memory():
    rgba = np.random.default_rng(2).uniform(0, 1, (3, 4, 4))
    image = colour_channels(rgba)
    np.testing.assert_array_equal(image.stack(("rgb", "alpha")), rgba.astype(np.float32))
    assert image.depth.strides == (0, 0) and image.normal.strides == (0, 0, 0) and not image.depth.any()


# --------------------------------------------------------------------------- render-path's EXR frames


def test_exr_folder_sink_writes_a_numbered_exr_per_frame(tmp_path):
    folder = tmp_path / "frames"
    sink = ExrFolderSink(folder, 7, 5, ("depth", "normal"), frames=3)
    images = [hand_made(seed=seed) for seed in range(3)]
    for image in images:
        sink.write(image)
    assert sink.finish() == folder
    assert listing(folder) == ["frame_00000.exr", "frame_00001.exr", "frame_00002.exr"]
    for image, name in zip(images, listing(folder)):
        header, planes = read_exr(folder / name)
        assert sorted(planes) == ["N.X", "N.Y", "N.Z", "Z"] and header["raygsChannels"] == "depth,normal"
        np.testing.assert_array_equal(planes["Z"], image.depth)
    with pytest.raises(ValueError, match="ChannelImage"):
        ExrFolderSink(tmp_path / "other", 7, 5, ("depth",)).write(hand_made(height=4))
    # Written again over it with fewer frames: the stale EXR goes, other files stay.
    (folder / "notes.txt").write_text("mine")
    (folder / "frame_00009.png").write_bytes(b"a PNG frame of another render")
    again = ExrFolderSink(folder, 7, 5, ("depth",), overwrite=True, frames=1)
    again.write(images[0])
    again.finish()
    assert listing(folder) == ["frame_00000.exr", "frame_00009.png", "notes.txt"]
