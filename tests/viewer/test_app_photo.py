"""The window's Photo view: at a training camera of an INRIA model folder made on the fly,
the photo, |render - photo| through magma, the split, the PSNR; leaving the camera, a
missing photo, screenshots."""

from __future__ import annotations

import numpy as np
import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, presented, split_expected, text_past_the_panel, window_image
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from matplotlib import colormaps
from datasets_kit import write_dataset
from testkit import random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.photos.compare import resize_picture
from raygs_viewer.photos.dataset import load_photo, open_dataset
from raygs_viewer.photos.metrics import psnr
from raygs_viewer.photos.evaluate import evaluate, evaluation_settings, render_view
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.io import load_scene
from raygs_viewer.sort.depth import DepthSorter

SIZE = (48, 32)  # the cameras' and, for exact pixels, the window's


@pytest.fixture
def model(tmp_path, gl_render):
    """An INRIA model folder: a small scene, two training cameras, and as their photos
    the renders with noise (view_001's deleted where a test needs it missing)."""
    scene = random_scene(n=80, seed=3, degree=0)
    cameras = [look_at(eye, (0, 0, 0), width=SIZE[0], height=SIZE[1], fov_y_degrees=50)
               for eye in ((0.3, -0.2, -4.0), (-1.5, 0.4, -3.6))]
    rng = np.random.default_rng(0)
    photos = [np.clip(gl_render(scene, c)[..., :3] + rng.normal(0, 0.05, (SIZE[1], SIZE[0], 3)), 0, 1)
              for c in cameras]
    root = write_dataset(tmp_path / "data", "inria", cameras, photos, scene=scene)
    return root


def scene_of(model) -> str:
    return str(model / "point_cloud" / "iteration_7000" / "point_cloud.ply")


def the_photo(model, index: int) -> np.ndarray:
    dataset = open_dataset(model)
    return load_photo(dataset.views[index], dataset.background)


def at_camera(drive, key=imgui.Key.n) -> None:
    drive.tap(key)
    drive.frames(8)  # the flight (0.6 s at 0.1 s a frame) lands
    drive.settle()
    drive.frames(1)


def shown_render(viewer) -> np.ndarray:
    return np.clip(window_image(viewer)[..., :3], 0.0, 1.0)


def magma(render: np.ndarray, photo: np.ndarray, vmax: float) -> np.ndarray:
    """(H, W, 3) uint8: mean |render - photo| over RGB through matplotlib's magma, 0..vmax."""
    error = np.abs(render - photo).mean(axis=2)
    return to_rgb8(colormaps["magma"](np.rint(np.clip(error / vmax, 0, 1) * 255).astype(int)))


def test_photo_view_shows_the_photo_difference_and_split_with_the_psnr(open_viewer, model):
    viewer, drive = open_viewer(scene_of(model), hide_panel=True, width=SIZE[0], height=SIZE[1])
    at_camera(drive)
    assert viewer.photo.at == 0 and (viewer.camera.width, viewer.camera.height) == SIZE
    photo, render = the_photo(model, 0), shown_render(viewer)

    viewer.photo.choose("photo")
    drive.frames(1)
    np.testing.assert_array_equal(presented(viewer), to_rgb8(photo))
    assert viewer.photo.psnr == psnr(render, photo)
    assert f"PSNR {psnr(render, photo):.2f} dB at 48x32" in viewer.photo.status
    assert 15 < viewer.photo.psnr < 40  # noise of 0.05: about 26 dB

    viewer.photo.choose("difference")
    drive.frames(1)
    np.testing.assert_array_equal(presented(viewer), magma(render, photo, viewer.photo.heat_max))

    viewer.photo.choose("split")
    viewer.photo.fraction = 0.25
    drive.frames(1)
    np.testing.assert_array_equal(presented(viewer), split_expected(photo, render, 12))

    viewer.photo.choose("render")
    drive.frames(1)
    np.testing.assert_array_equal(presented(viewer), to_rgb8(render))
    assert viewer.photo.psnr == psnr(render, photo)  # still measured, the render shown


def test_moving_away_returns_to_the_render_and_says_so(open_viewer, model):
    viewer, drive = open_viewer(scene_of(model), hide_panel=True, width=SIZE[0], height=SIZE[1])
    at_camera(drive)
    viewer.photo.choose("difference")
    drive.frames(1)
    assert viewer.photo.showing
    drive.tap(imgui.Key.w)
    drive.settle()
    assert viewer.photo.at is None and not viewer.photo.showing
    assert "left the training camera" in viewer.panel.message
    np.testing.assert_array_equal(presented(viewer), to_rgb8(shown_render(viewer)))
    # The chosen view comes back at the next training camera.
    at_camera(drive)
    assert viewer.photo.at == 1
    np.testing.assert_array_equal(presented(viewer),
                                  magma(shown_render(viewer), the_photo(model, 1), viewer.photo.heat_max))


def test_missing_photo_is_one_line_and_screenshots_refuse_the_photo(open_viewer, model):
    (model.parent / "source" / "images" / "view_001.png").unlink()
    viewer, drive = open_viewer(scene_of(model), hide_panel=True, width=SIZE[0], height=SIZE[1])
    at_camera(drive)
    viewer.photo.choose("photo")
    drive.frames(1)
    viewer.captures.request()
    drive.frames(1)
    assert "screenshots save renders" in viewer.panel.error and "\n" not in viewer.panel.error
    assert viewer.captures.last is None
    at_camera(drive)
    assert viewer.photo.at == 1 and not viewer.photo.showing
    assert "view_001" in viewer.photo.status and "\n" not in viewer.photo.status
    np.testing.assert_array_equal(presented(viewer), to_rgb8(shown_render(viewer)))


def test_panel_chooses_the_photo_and_shows_the_psnr_at_the_window_size(open_viewer, model):
    viewer, drive = open_viewer(scene_of(model), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.reveal("###training")
    drive.click("###training")
    drive.reveal("photo##photo")
    drive.click("photo##photo")
    assert viewer.photo.mode == "photo"
    assert "at a training camera (N / P) the window compares with its photo" in drive.panel
    assert text_past_the_panel(drive) == []  # the radio row and the hint fit the panel
    drive.move_mouse(PANEL_WIDTH - 2, PANEL_HEIGHT - 2)  # off the panel: N reaches the window
    at_camera(drive)
    width, height = viewer.camera.width, viewer.camera.height
    assert (width, height) != SIZE  # letterboxed into the window: the photo is resampled
    photo = resize_picture(the_photo(model, 0), width, height)
    value = psnr(shown_render(viewer), photo)
    assert viewer.photo.psnr == value
    status = [label for label in drive.panel.labels("text_wrapped") if "PSNR" in label]
    assert status == [f"view_000: PSNR {value:.2f} dB at {width}x{height} (the window's size; the camera's is 48x32)"]


def test_images_option_names_the_photos_folder(open_viewer, model, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    (model.parent / "source" / "images").rename(elsewhere)
    viewer, drive = open_viewer(scene_of(model), hide_panel=True, width=SIZE[0], height=SIZE[1],
                                images=str(elsewhere))
    at_camera(drive)
    viewer.photo.choose("photo")
    drive.frames(1)
    dataset = open_dataset(model, elsewhere)
    np.testing.assert_array_equal(presented(viewer), to_rgb8(load_photo(dataset.views[0], dataset.background)))


def test_at_the_cameras_size_the_panel_measures_the_psnr_evaluate_reports(open_viewer, model, gl_ctx):
    """The window at another size than the camera's measures another PSNR; "at the
    camera's size" renders the camera as `evaluate` does and gets evaluate's number,
    and shows that render scaled into the view."""
    dataset = open_dataset(model)
    with gl_ctx:
        renderer = GLRenderer(gl_ctx, load_scene(scene_of(model)))
        try:
            score = evaluate(dataset, dataset.views, renderer, RenderSettings()).scores[0]
            with DepthSorter(renderer.scene) as sorter:
                render = render_view(renderer, sorter, dataset.views[0], evaluation_settings(RenderSettings(), dataset))
        finally:
            renderer.release()
    viewer, drive = open_viewer(scene_of(model), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.reveal("###training")
    drive.click("###training")
    drive.reveal("at the camera's size##photo")
    drive.click("at the camera's size##photo")
    assert viewer.photo.at_camera_size
    drive.move_mouse(PANEL_WIDTH - 2, PANEL_HEIGHT - 2)  # off the panel: N reaches the window
    at_camera(drive)
    assert (viewer.camera.width, viewer.camera.height) != SIZE  # the window renders at its own size
    np.testing.assert_array_equal(viewer.photo.render, render)
    assert viewer.photo.psnr == score.psnr
    status = [label for label in drive.panel.labels("text_wrapped") if "PSNR" in label]
    assert status == [f"view_000: PSNR {score.psnr:.2f} dB at 48x32 (the camera's size, as evaluate measures)"]
    # Shown: the camera-size render scaled into the view (10 times the camera's size: each
    # texel a 10 x 10 block, no pixel centre near a texel's edge).
    import glfw
    glfw.set_window_size(viewer.window.handle, SIZE[0] * 10, SIZE[1] * 10)
    drive.frames(2)
    assert viewer.viewport == (0, 0, SIZE[0] * 10, SIZE[1] * 10) and viewer.photo.psnr == score.psnr
    np.testing.assert_array_equal(presented(viewer), np.repeat(np.repeat(to_rgb8(render), 10, 0), 10, 1))
    # At the window's size the same view measures another PSNR: the toggle is what agrees.
    viewer.photo.set_camera_size(False)
    drive.frames(1)
    assert viewer.photo.psnr != score.psnr
