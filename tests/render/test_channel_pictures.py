"""Channel pictures (render/channel_pictures.py): the automatic range's sample grid, the
colour map's direction, undefined pixels, the alpha threshold's mask, and the view's
checks. The GPU twin of these
pictures is held to them in tests/render/test_gl_geometry.py."""

import numpy as np
import pytest

from raygs_viewer.errors import UserError
from raygs_viewer.render.channels import ChannelImage
from raygs_viewer.render.channel_pictures import (
    ALPHA_THRESHOLD,
    AUTO_SAMPLES,
    ChannelView,
    automatic_range,
    channel_picture,
    color_table,
    depth_picture,
    depth_samples,
    sample_step,
)


def test_the_automatic_range_samples_a_regular_grid_of_bounded_size():
    assert sample_step(48, 64) == 1  # small images: every pixel
    for height, width in ((720, 1280), (2160, 3840), (1, 100_000)):
        step = sample_step(height, width)
        samples = depth_samples(np.ones((height, width), np.float32))
        assert samples.size <= AUTO_SAMPLES * 1.1 and samples.shape == (-(-height // step), -(-width // step))
    depth = np.random.default_rng(0).uniform(1.0, 5.0, (720, 1280)).astype(np.float32)
    step = sample_step(720, 1280)
    near, far = automatic_range(depth)
    assert (near, far) == pytest.approx(tuple(np.percentile(depth[::step, ::step], (1, 99))))


def test_depth_pictures_are_bright_near_dark_far_and_black_where_undefined():
    depth = np.array([[1.0, 2.0, 0.0]], np.float32)
    picture, used = depth_picture(depth, (1.0, 2.0))
    table = color_table()
    assert used == (1.0, 2.0)
    np.testing.assert_array_equal(picture[0, 0], table[-1])  # near: the bright end
    np.testing.assert_array_equal(picture[0, 1], table[0])   # far: the dark end
    np.testing.assert_array_equal(picture[0, 2], 0.0)        # no depth: black
    assert table[-1].sum() > table[0].sum()
    picture, used = depth_picture(np.zeros((2, 2), np.float32), None)
    assert used is None and not picture.any()


@pytest.mark.parametrize("view", [dict(channel="height"), dict(channel="depth", depth_range=(2.0, 1.0)),
                                  dict(channel="depth", depth_range=(0.0, float("inf"))),
                                  dict(channel="normal", normal_space="object"),
                                  dict(channel="depth", alpha_threshold=-0.1),
                                  dict(channel="depth", alpha_threshold=1.5),
                                  dict(channel="depth", alpha_threshold=float("nan"))])
def test_a_bad_view_is_a_user_error(view):
    with pytest.raises(UserError):
        ChannelView(**view)


def test_the_alpha_threshold_masks_faint_pixels_of_the_geometry_pictures():
    # Alpha 0.02 (haze), exactly the threshold, opaque, none; the haze is nearest.
    alpha = np.array([[0.02, 0.25, 0.9, 0.0]], np.float32)
    depth = np.array([[1.0, 2.0, 3.0, 0.0]], np.float32)
    normal = np.zeros((1, 4, 3), np.float32)
    normal[0, :3, 2] = -1.0
    image = ChannelImage(np.full((1, 4, 3), 0.5, np.float32), alpha, depth, depth, normal)
    for channel in ("depth", "median_depth", "normal"):
        masked, _ = channel_picture(image, ChannelView(channel, alpha_threshold=0.25))
        unmasked, _ = channel_picture(image, ChannelView(channel, alpha_threshold=0.0))
        assert not masked[0, 0].any() and unmasked[0, 0].any()  # below it: black, as undefined
        assert masked[0, 1].any() and masked[0, 2].any()        # at it and above: painted
        assert not masked[0, 3].any() and not unmasked[0, 3].any()
    # The automatic range ignores the masked depth (0.25 keeps 2 and 3, 0 spans 1 to 3).
    assert channel_picture(image, ChannelView("depth", alpha_threshold=0.25))[1] == pytest.approx(
        tuple(np.percentile([2.0, 3.0], (1, 99))))
    assert channel_picture(image, ChannelView("depth", alpha_threshold=0.0))[1][0] < 1.1
    # The colour and alpha pictures show every pixel whatever the threshold.
    for channel in ("rgb", "alpha"):
        np.testing.assert_array_equal(channel_picture(image, ChannelView(channel, alpha_threshold=1.0))[0],
                                      channel_picture(image, ChannelView(channel, alpha_threshold=0.0))[0])
    assert ChannelView("depth").alpha_threshold == ALPHA_THRESHOLD > 0  # masked unless switched off
