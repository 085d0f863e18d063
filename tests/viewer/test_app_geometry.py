"""The window's view mode (the Geometry section): what the frame shows in each channel,
the alpha threshold masking faint pixels, the depth range automatic or set and the range
in use, normals in camera or world space, both sides of the split view and both stereo
eyes, and screenshots of it."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from appkit import PANEL_HEIGHT, click_choice, headless, right_image, window_image
from PIL import Image
from testkit import gaussian_columns, write_ply

from raygs_viewer.camera.stereo import StereoRig, custom_preset, eye_cameras
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.capture.sidecar import load_sidecar
from raygs_viewer.render.channel_pictures import ALPHA_THRESHOLD, ChannelView, channel_picture
from raygs_viewer.render.gl.stereo_frame import stereo_order
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.viewer.state import StereoPreview

W, H = 64, 48
PANEL_NARROW = 380  # the panel (360 wide) and a sliver of view: a small scene image to draw
EYE = custom_preset(40, 30, 90.0, 72.0)
# The window's picture and a headless one of the same view and order: float32 rounding
# of the same passes (a depth's colour-map entry may round to its neighbour).
PICTURE_TOLERANCE = 0.02


def small(open_viewer, **options):
    options.setdefault("hide_panel", True)
    viewer, drive = open_viewer(width=W, height=H, **options)
    drive.settle()
    return viewer, drive


def expected_picture(viewer, view: ChannelView, camera=None, settings=None, order=None, color_origin=None):
    """(picture, range used): channel_picture of render_channels of the view."""
    camera, settings = camera or viewer.camera, settings or viewer.settings
    if order is None:
        order = exact_order(viewer.scene.direct_sorter, camera, settings)
    channels = viewer.scene.renderer.render_channels(camera, settings, order, color_origin=color_origin)
    return channel_picture(channels.in_space(view.normal_space, camera), view)


def assert_picture(shown: np.ndarray, expected: np.ndarray) -> None:
    assert shown.shape[:2] == expected.shape[:2]
    np.testing.assert_array_equal(shown[..., 3], 1.0)  # a picture is opaque
    difference = np.abs(shown[..., :3] - expected)
    assert np.mean(difference > PICTURE_TOLERANCE) < 0.005, difference.max()


def test_each_view_mode_shows_the_channel_picture(open_viewer):
    viewer, drive = small(open_viewer)
    colour = window_image(viewer).copy()
    for channel in ("depth", "median_depth", "normal", "alpha"):
        viewer.view_mode.channel = channel
        drive.frames(2)
        expected, used = expected_picture(viewer, ChannelView(channel))
        assert_picture(window_image(viewer), expected)
        assert np.abs(window_image(viewer)[..., :3] - colour[..., :3]).max() > 0.2  # not the colour any more
        if channel in ("depth", "median_depth"):
            assert viewer.drawer.view_range == pytest.approx(used, rel=1e-4)
        else:
            assert viewer.drawer.view_range is None
    viewer.view_mode.channel = "rgb"
    drive.frames(2)
    np.testing.assert_array_equal(window_image(viewer), colour)


def test_normals_in_world_space_differ_from_camera_space(open_viewer):
    viewer, drive = small(open_viewer)
    viewer.view.navigator.look(150, 0)  # turned well away from the world's axes
    viewer.view_mode.channel = "normal"
    drive.settle()
    camera_space = window_image(viewer).copy()
    viewer.view_mode.normal_space = "world"
    drive.frames(2)
    expected, _ = expected_picture(viewer, ChannelView("normal", normal_space="world"))
    assert_picture(window_image(viewer), expected)
    assert np.abs(window_image(viewer) - camera_space).max() > 0.2


def test_a_set_depth_range_is_used_and_a_bad_one_is_a_standing_error(open_viewer):
    viewer, drive = small(open_viewer)
    mode = viewer.view_mode
    mode.channel, mode.automatic, mode.near, mode.far = "depth", False, 3.5, 5.0
    drive.frames(2)
    assert viewer.drawer.view_range == (3.5, 5.0)
    expected, _ = expected_picture(viewer, ChannelView("depth", (3.5, 5.0)))
    assert_picture(window_image(viewer), expected)
    mode.far = 2.0  # not above near: the automatic range meanwhile, and the panel says why
    drive.frames(2)
    assert viewer.panel.error.startswith("error: depth range") and "\n" not in viewer.panel.error
    automatic, used = expected_picture(viewer, ChannelView("depth"))
    assert viewer.drawer.view_range == pytest.approx(used, rel=1e-4)
    mode.far = 6.0
    drive.frames(2)
    assert viewer.panel.error == "" and viewer.drawer.view_range == (3.5, 6.0)


def test_the_panel_switches_the_view_and_states_the_range_in_use(open_viewer, tmp_path):
    # A few gaussians: the view fills the window under the panel, drawn per pixel each frame.
    few = write_ply(tmp_path / "few.ply", gaussian_columns(n=40, seed=3))
    viewer, drive = open_viewer(str(few), width=PANEL_NARROW, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.reveal("show")
    click_choice(drive, "show", "median depth")
    drive.frames(2)
    assert viewer.view_mode.channel == "median_depth"
    near, far = viewer.drawer.view_range
    assert f"range in use: {near:.4g} to {far:.4g} units" in drive.panel.labels()
    drive.reveal("automatic range")
    drive.click("automatic range")
    drive.frames(2)
    assert not viewer.view_mode.automatic
    assert viewer.drawer.view_range == (viewer.view_mode.near, viewer.view_mode.far)
    assert "on" not in drive.panel.labels()  # the sides matter only in the split view
    viewer.split.on = True
    drive.frames(2)
    drive.reveal("on")
    click_choice(drive, "on", "right side (B)")
    drive.frames(2)
    assert viewer.view_mode.side == "right"
    assert viewer.drawer.view is None and viewer.drawer.right_view is not None


def test_both_sides_of_the_split_view_show_it_in_one_range(open_viewer):
    viewer, drive = small(open_viewer)
    viewer.split.on, viewer.split.preset = True, "GS"
    viewer.view_mode.channel = "depth"
    drive.settle()
    left, used = expected_picture(viewer, ChannelView("depth"))
    right_settings = viewer.right_settings()
    # The right side keeps the left's automatic range, so one colour is one depth.
    right, right_used = expected_picture(viewer, ChannelView("depth", used), settings=right_settings)
    assert right_used == pytest.approx(used)
    assert_picture(window_image(viewer), left)
    assert_picture(right_image(viewer), right)
    assert np.abs(right_image(viewer) - window_image(viewer)).max() > 0.05  # GS's depths differ


@pytest.mark.parametrize("side", ["left", "right"])
def test_one_side_of_the_split_view_shows_it_and_the_other_the_colour(open_viewer, side):
    viewer, drive = small(open_viewer)
    viewer.split.on, viewer.split.preset = True, "GS"
    viewer.view_mode.channel, viewer.view_mode.side = "depth", side
    drive.settle()
    settings = viewer.settings if side == "left" else viewer.right_settings()
    picture, used = expected_picture(viewer, ChannelView("depth"), settings=settings)
    depth_side, colour_side = (window_image, right_image) if side == "left" else (right_image, window_image)
    assert_picture(depth_side(viewer), picture)
    colour_settings = viewer.right_settings() if side == "left" else viewer.settings
    np.testing.assert_allclose(colour_side(viewer), headless(viewer, colour_settings), atol=1e-6)
    assert viewer.drawer.view_range == pytest.approx(used, rel=1e-4)
    # Each side's screenshot is what it shows, and its sidecar says so.
    viewer.save_screenshot()
    views = {png.stem.rsplit("-", 1)[1]: load_sidecar(sidecar).channel_view for png, sidecar in viewer.captures.saved}
    assert views[side] == ChannelView("depth", viewer.drawer.view_range)
    assert views["left" if side == "right" else "right"] is None


def test_both_stereo_eyes_show_it(open_viewer):
    stereo = StereoPreview.of(EYE, on=True, layout="sbs", rig=StereoRig(ipd=0.2))
    viewer, drive = open_viewer(hide_panel=True, width=2 * EYE.width, height=EYE.height, stereo=stereo)
    viewer.view_mode.channel = "depth"
    drive.settle()
    camera, rig = viewer.camera, viewer.stereo.view().rig
    order = stereo_order(viewer.scene.direct_sorter, camera, viewer.settings, rig)
    left_eye, right_eye = eye_cameras(camera, rig)
    left, used = expected_picture(viewer, ChannelView("depth"), left_eye, order=order, color_origin=camera.center)
    right, _ = expected_picture(viewer, ChannelView("depth", used), right_eye, order=order,
                                color_origin=camera.center)
    shown_left, shown_right = viewer.drawer.stereo.read_eyes()
    assert_picture(shown_left, left)
    assert_picture(shown_right, right)
    assert viewer.drawer.view_range == pytest.approx(used, rel=1e-4)


def test_a_screenshot_saves_the_picture_shown_and_records_the_view(open_viewer):
    viewer, drive = small(open_viewer)
    viewer.view_mode.channel = "depth"
    drive.frames(2)
    png, sidecar = viewer.save_screenshot()
    saved = np.asarray(Image.open(png).convert("RGB")).astype(int)
    shown = to_rgb8(window_image(viewer)[..., :3]).astype(int)
    assert np.mean(np.abs(saved - shown) > 4) < 0.005
    near, far = viewer.drawer.view_range
    view = json.loads(sidecar.read_text())["channel_view"]
    assert view == {"channel": "depth", "depth_range": [near, far], "normal_space": "camera",
                    "alpha_threshold": ALPHA_THRESHOLD}
    # What `render --sidecar` reads back to draw the same picture.
    assert load_sidecar(sidecar).channel_view == ChannelView("depth", (near, far))


def test_a_masked_depth_screenshot_renders_again_to_the_bit(open_viewer, tmp_path):
    import glfw  # late: imgui must be imported before it (see raygs_viewer.viewer.window)

    from raygs_viewer.cli.main import main
    viewer, drive = small(open_viewer)
    viewer.view_mode.channel, viewer.view_mode.alpha_threshold = "depth", 0.3
    drive.frames(2)
    near, far = viewer.drawer.view_range
    expected, _ = expected_picture(viewer, ChannelView("depth", (near, far), alpha_threshold=0.3))
    assert_picture(window_image(viewer), expected)
    unmasked, _ = expected_picture(viewer, ChannelView("depth", (near, far), alpha_threshold=0.0))
    assert (unmasked.any(axis=-1) & ~expected.any(axis=-1)).mean() > 0.02  # the threshold masks pixels here
    png, sidecar = viewer.save_screenshot()
    assert json.loads(sidecar.read_text())["channel_view"]["alpha_threshold"] == 0.3
    out = tmp_path / "again.png"
    assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
    np.testing.assert_array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(png)))
    glfw.make_context_current(viewer.window.handle)


def test_the_panel_sets_the_alpha_threshold(open_viewer):
    viewer, drive = open_viewer(width=PANEL_NARROW, height=PANEL_HEIGHT)
    drive.frames(2)
    assert "mask below alpha" not in drive.panel.labels()  # the colour view has no mask
    drive.reveal("show")
    click_choice(drive, "show", "depth")
    drive.frames(2)
    assert viewer.view_mode.alpha_threshold == ALPHA_THRESHOLD and viewer.drawer.view == ChannelView("depth")
    drive.reveal("mask below alpha")
    drive.click_left_end("mask below alpha")  # 0: the mask off
    drive.frames(2)
    assert viewer.view_mode.alpha_threshold == 0.0 and viewer.drawer.view.alpha_threshold == 0.0
    x0, y0, x1, y1 = drive.panel.rect("mask below alpha")  # the slider's frame (160 wide), then its label
    drive.click_at(x0 + 80, (y0 + y1) / 2)  # the frame's middle: about half
    drive.frames(2)
    assert 0.3 < viewer.view_mode.alpha_threshold < 0.7
    assert viewer.drawer.view.alpha_threshold == viewer.view_mode.alpha_threshold
    click_choice(drive, "show", "normal")
    drive.frames(2)
    assert "mask below alpha" in drive.panel.labels()
    click_choice(drive, "show", "alpha")
    drive.frames(2)
    assert "mask below alpha" not in drive.panel.labels()  # the alpha picture shows every value


def test_a_split_screenshot_saves_each_side_in_the_range_shown(open_viewer):
    viewer, drive = small(open_viewer)
    viewer.split.on = True
    viewer.view_mode.channel = "median_depth"
    drive.settle()
    saved = viewer.save_screenshot() and viewer.captures.saved
    assert [png.stem.rsplit("-", 1)[1] for png, _ in saved] == ["left", "right"]
    for (png, sidecar), shown in zip(saved, (window_image(viewer), right_image(viewer))):
        image = np.asarray(Image.open(png).convert("RGB")).astype(int)
        assert np.mean(np.abs(image - to_rgb8(shown[..., :3]).astype(int)) > 4) < 0.005
        assert json.loads(sidecar.read_text())["channel_view"]["depth_range"] == list(viewer.drawer.view_range)


def test_the_colour_view_draws_without_a_view_argument(open_viewer, monkeypatch):
    """Colour is the renderer's plain path: no channel view reaches render_into."""
    viewer, drive = small(open_viewer)
    calls = []
    render_into = viewer.scene.renderer.render_into

    def recording(*args, **kwargs):
        calls.append(kwargs.get("view"))
        return render_into(*args, **kwargs)

    monkeypatch.setattr(viewer.scene.renderer, "render_into", recording)
    viewer.settings = replace(viewer.settings, p_min=viewer.settings.p_min * 1.01)  # something to draw
    drive.frames(2)
    viewer.view_mode.channel = "alpha"
    drive.frames(2)
    assert calls[0] is None and calls[-1] == ChannelView("alpha")
