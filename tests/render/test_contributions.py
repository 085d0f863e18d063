"""Each gaussian's share of the colour of the pixels asked about (``render.contributions``):
at one pixel the weights and the gaussians' colours recompose the float64 reference's
pixel in every compositing order, over several pixels a gaussian's weight is its largest
at any of them, a gaussian in front takes the weight of one it hides, and a shape too
large to weigh is refused in one line. No GL needed."""

from dataclasses import replace

import numpy as np
import pytest
from testkit import COMPOSITING_SETUPS, make_scene, random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.errors import UserError
from raygs_viewer.render import contributions
from raygs_viewer.render.contributions import cropped, max_weights
from raygs_viewer.render.reference import global_order, render_reference
from raygs_viewer.render.reference_models import CameraGaussians
from raygs_viewer.render.settings import RenderSettings

# Odd size, fx != fy, an off-centre principal point: a slip of the crop shows.
CAMERA = replace(look_at([0.3, -0.2, -3.0], [0.0, 0.05, 0.0], width=26, height=19), fx=30.0, fy=27.0, cx=12.7, cy=9.1)
SETTINGS = COMPOSITING_SETUPS


@pytest.fixture(scope="module")
def scene():
    return random_scene(n=90, seed=4, degree=2, spread=0.8, log_scale=(-2.6, -1.4))


def one_pixel(u, v, camera=CAMERA):
    inside = np.zeros((camera.height, camera.width), bool)
    inside[v, u] = True
    return inside


def busy_pixels(image, count=4):
    """(u, v) of ``count`` pixels the scene covers well (alpha > 0.6), spread over the image."""
    v, u = np.nonzero(image[..., 3] > 0.6)
    picks = np.linspace(0, u.size - 1, count).astype(int)
    return list(zip(u[picks], v[picks]))


@pytest.mark.parametrize("name", SETTINGS)
def test_the_weights_at_a_pixel_recompose_the_reference_pixel(scene, name):
    settings = replace(SETTINGS[name], background=(0.2, 0.3, 0.5))
    order = global_order(scene, CAMERA, settings)
    image = render_reference(scene, CAMERA, settings, order)
    colors = CameraGaussians.of(scene.with_sh_degree(scene.sh_degree), np.arange(scene.count), CAMERA).colors
    for u, v in busy_pixels(image):
        weights = max_weights(scene, CAMERA, settings, order, one_pixel(u, v))
        assert np.count_nonzero(weights) >= 2  # layered: the order matters
        alpha = weights.sum()
        recomposed = weights @ colors + (1 - alpha) * np.asarray(settings.background)
        np.testing.assert_allclose(recomposed, image[v, u, :3], atol=1e-9, err_msg=f"{name} at {(u, v)}")
        assert alpha == pytest.approx(image[v, u, 3], abs=1e-9)


@pytest.mark.parametrize("name", ["global", "per pixel k=2", "ewa"])
def test_over_several_pixels_a_gaussian_weighs_its_largest_at_any(scene, name, monkeypatch):
    settings = SETTINGS[name]
    order = global_order(scene, CAMERA, settings)
    block = [(u, v) for v in range(6, 13) for u in range(9, 16)] + [(3, 2)]  # a far pixel widens the box
    each = np.array([max_weights(scene, CAMERA, settings, order, one_pixel(u, v)) for u, v in block])
    # A hole where some gaussian weighs more than anywhere else: the result must leave it out.
    strict = [(g, int(np.argmax(each[:, g]))) for g in range(scene.count)
              if np.sort(each[:, g])[-1] > np.sort(each[:, g])[-2] + 1e-6]
    gaussian, hole = strict[0]
    inside = np.zeros((CAMERA.height, CAMERA.width), bool)
    for k, (u, v) in enumerate(block):
        inside[v, u] = k != hole
    truth = np.delete(each, hole, axis=0).max(axis=0)
    assert truth[gaussian] < each[hole, gaussian]
    np.testing.assert_allclose(max_weights(scene, CAMERA, settings, order, inside), truth, rtol=1e-12, atol=1e-15)
    monkeypatch.setattr(contributions, "BAND_SAMPLES", 16 * 2 * 13)  # two rows a band
    np.testing.assert_allclose(max_weights(scene, CAMERA, settings, order, inside), truth, rtol=1e-12, atol=1e-15)


def test_a_gaussian_in_front_takes_the_weight_of_one_it_hides():
    # On the camera's axis: a wide opaque gaussian at z = 2, a small one behind it at z = 4.
    camera = look_at([0.0, 0.0, -3.0], [0.0, 0.0, 0.0], width=21, height=21)
    scene = make_scene([[0, 0, -1.0], [0, 0, 1.0]], [[0.4, 0.4, 0.4], [0.1, 0.1, 0.1]], opacities=[0.98, 0.9])
    centre = one_pixel(10, 10, camera)
    order = global_order(scene, camera, RenderSettings())
    weights = max_weights(scene, camera, RenderSettings(), order, centre)
    assert weights[0] == pytest.approx(0.98 * np.exp(0), rel=1e-3)
    assert weights[1] == pytest.approx((1 - weights[0]) * 0.9, rel=1e-3)
    front_left_out = order[order != 0]  # as the window's order leaves out a deleted gaussian
    weights = max_weights(scene, camera, RenderSettings(), front_left_out, centre)
    assert weights[0] == 0 and weights[1] == pytest.approx(0.9, rel=1e-3)


def test_the_crop_is_the_part_of_the_image_it_names():
    crop = cropped(CAMERA, slice(4, 11), slice(7, 20))
    assert (crop.width, crop.height) == (13, 7)
    np.testing.assert_array_equal(crop.pixel_rays(), CAMERA.pixel_rays()[4:11, 7:20])


def test_a_shape_over_too_many_fragments_is_refused_in_one_line(scene, monkeypatch):
    order = global_order(scene, CAMERA, RenderSettings())
    monkeypatch.setattr(contributions, "MAX_FRAGMENTS", 50)
    inside = np.ones((CAMERA.height, CAMERA.width), bool)
    with pytest.raises(UserError, match=r"^the shape covers [\d,]+ fragments of [\d,]+ gaussians .*'through'$"):
        max_weights(scene, CAMERA, RenderSettings(), order, inside)
    with pytest.raises(ValueError, match="inside is"):
        max_weights(scene, CAMERA, RenderSettings(), order, inside[1:])
    assert not max_weights(scene, CAMERA, RenderSettings(), order, ~inside).any()


@pytest.mark.parametrize("order", ["depth", "per-pixel"])
def test_the_cut_off_ends_a_pixel_and_what_follows_it_weighs_nothing(order):
    # Four gaussians of opacity 0.95 on the axis: T falls to 5e-2, 2.5e-3, 1.25e-4, then
    # 6.25e-6, below the cut-off (1e-4): the fourth is not drawn.
    camera = look_at([0.0, 0.0, -3.0], [0.0, 0.0, 0.0], width=21, height=21)
    scene = make_scene([[0, 0, z] for z in (-1.0, -0.5, 0.0, 0.5)], 0.2, opacities=0.95)
    settings = RenderSettings(transmittance_cutoff=True, order=order)
    order = global_order(scene, camera, settings)
    weights = max_weights(scene, camera, settings, order, one_pixel(10, 10, camera))
    np.testing.assert_allclose(weights, [0.95, 0.05 * 0.95, 0.0025 * 0.95, 0], rtol=1e-6, atol=1e-12)
    image = render_reference(scene, camera, settings, order)
    assert weights.sum() == pytest.approx(image[10, 10, 3], abs=1e-12)
