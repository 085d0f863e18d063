"""The float64 reference's geometry outputs (render_reference_channels) on scenes whose
depth, median depth and normal are known in closed form, each with a negative control
that shows the check would see the fault it names. No GL needed."""

from dataclasses import replace

import numpy as np
import pytest
from testkit import make_scene, random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.render import reference
from raygs_viewer.render.reference import render_reference, render_reference_channels
from raygs_viewer.render.settings import RenderSettings

#: Odd sizes with a centred principal point: pixel (CENTRE) looks exactly along +z.
WIDTH, HEIGHT = 31, 21
CENTRE = (10, 15)  # (row, column)


def _axis_camera(width=WIDTH, height=HEIGHT, fov=60.0):
    """At the origin looking along +z with R = I: camera space is world space."""
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width=width, height=height, fov_y_degrees=fov)
    np.testing.assert_array_equal(camera.R, np.eye(3))
    return camera


def _quaternion(rotation):
    """Unit quaternion (w, x, y, z) of a rotation matrix (w > 0 branch; fine for tests)."""
    w = np.sqrt(max(1.0 + np.trace(rotation), 1e-12)) / 2
    return np.array([w, (rotation[2, 1] - rotation[1, 2]) / (4 * w),
                     (rotation[0, 2] - rotation[2, 0]) / (4 * w), (rotation[1, 0] - rotation[0, 1]) / (4 * w)])


def _frame(short, long):
    """A rotation whose y column is the unit ``short`` and x column ``long`` made
    perpendicular to it: scales (a, b, c) with b smallest give ``short`` as the normal."""
    y = np.asarray(short, np.float64) / np.linalg.norm(short)
    x = np.asarray(long, np.float64) - np.dot(long, y) * y
    x /= np.linalg.norm(x)
    return np.column_stack([x, y, np.cross(x, y)])


def _axes(scene, i):
    """(3, 3) the stored rotation of gaussian ``i`` as the reference reads it (float64)."""
    return quaternion_to_matrix(scene.rotations[i:i + 1].astype(np.float64))[0]


def _peak_z(scene, i, rays):
    """z of gaussian ``i``'s peak on each ray (z = 1, camera = world): the ray parameter
    x^T S^-1 mu / x^T S^-1 x, with S^-1 = Rp diag(s^-2) Rp^T built here."""
    rotation = _axes(scene, i)
    inverse = rotation @ np.diag(scene.scales[i].astype(np.float64) ** -2.0) @ rotation.T
    mu = scene.positions[i].astype(np.float64)
    return (rays @ inverse @ mu) / np.einsum("...i,ij,...j->...", rays, inverse, rays)


def _facing(normal, rays):
    return np.where((rays @ normal > 0)[..., None], -normal, normal)


def _tilted_disc(opacity=0.9):
    """A flat gaussian whose normal (its y axis) is almost perpendicular to the view, so
    it faces some pixels' rays with one sign and the others' with the other."""
    rotation = _frame((1.0, 0.0, 0.06), (0.0, 1.0, 0.3))
    return make_scene([(0.1, -0.05, 3.0)], [(0.6, 0.3, 0.9)], rotations=[_quaternion(rotation)],
                      opacities=opacity)


# --- one gaussian --------------------------------------------------------------------------

def test_one_gaussian_depth_is_its_peak_z_normal_its_facing_shortest_axis_median_where_half():
    scene, camera = _tilted_disc(), _axis_camera()
    image = render_reference_channels(scene, camera)
    rays = camera.pixel_rays()
    z = _peak_z(scene, 0, rays)
    covered = image.alpha > 0
    half = image.alpha >= 0.5
    assert covered.sum() > 60 and (~covered).sum() > 60 and half.sum() > 20 and (covered & ~half).sum() > 20

    np.testing.assert_allclose(image.depth[covered], z[covered], rtol=1e-6)
    assert np.all(image.depth[~covered] == 0)
    np.testing.assert_allclose(image.median_depth, np.where(half, z, 0.0), rtol=1e-6)

    normal = _axes(scene, 0)[:, 1]  # the y scale is the shortest
    expected = _facing(normal, rays)
    sides = np.sign(rays @ normal)[covered]
    assert (sides > 0).sum() > 10 and (sides < 0).sum() > 10  # the flip is exercised both ways
    np.testing.assert_allclose(image.normal[covered], expected[covered], atol=1e-6)
    assert np.all(image.normal[~covered] == 0)

    # Negative controls: the distance along the unit ray is not z, an unflipped normal
    # and the longest axis are wrong, and alpha reaches 0.5 only where the median is set.
    distance = z * np.linalg.norm(rays, axis=-1)
    assert np.abs(distance - image.depth)[covered].max() > 1e-2
    assert np.abs(image.normal - normal)[covered].max() > 1.0
    assert np.abs(image.normal - _facing(_axes(scene, 0)[:, 2], rays))[covered].max() > 1.0
    assert np.all(image.median_depth[covered & ~half] == 0)


def test_gs_depth_is_the_centre_z_and_raygs_depth_is_not():
    scene, camera = _tilted_disc(), _axis_camera()
    gs = render_reference_channels(scene, camera, RenderSettings(mode="gs"))
    covered = gs.alpha > 0
    assert covered.sum() > 60
    np.testing.assert_allclose(gs.depth[covered], np.float32(3.0), rtol=1e-7)
    np.testing.assert_allclose(gs.median_depth[gs.alpha >= 0.5], np.float32(3.0), rtol=1e-7)
    raygs = render_reference_channels(scene, camera)
    assert np.abs(raygs.depth - 3.0)[raygs.alpha > 0].max() > 0.05


def test_world_normals_are_the_axis_in_world_space_facing_the_world_ray():
    scene = _tilted_disc()
    camera = look_at((0.8, -0.5, -1.0), (0.1, -0.05, 3.0), width=WIDTH, height=HEIGHT)
    image = render_reference_channels(scene, camera)
    world = image.in_space("world", camera)
    covered = image.alpha > 0
    assert covered.sum() > 60 and world.normal_space == "world"
    normal = _axes(scene, 0)[:, 1]
    world_rays = camera.pixel_rays() @ camera.R  # R^T x per ray
    np.testing.assert_allclose(world.normal[covered], _facing(normal, world_rays)[covered], atol=1e-6)
    np.testing.assert_allclose(world.in_space("camera", camera).normal, image.normal, atol=1e-6)


# --- the median's crossing, and the cut-off ----------------------------------------------

def _stacked(opacities, scales=((0.2, 0.2, 0.2), (0.2, 0.2, 0.2))):
    """Two gaussians on the optical axis, at z 4 and 6: the centre pixel sees each at its
    peak (D = 0 exactly), so there its alphas are exactly the opacities."""
    return make_scene([(0.0, 0.0, 4.0), (0.0, 0.0, 6.0)], scales, opacities=opacities,
                      colors=[(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)])


ORDERS = [RenderSettings(), RenderSettings(transmittance_cutoff=True), RenderSettings(order="distance"),
          RenderSettings(order="per-pixel"), RenderSettings(order="per-pixel", order_k=1, transmittance_cutoff=True)]


@pytest.mark.parametrize("settings", ORDERS, ids=str)
@pytest.mark.parametrize("opacities, median", [((0.3, 0.4), 6.0), ((0.5, 0.4), 4.0), ((0.45, 0.05), 0.0)],
                         ids=["second-reaches", "exactly-half", "never"])
def test_the_median_is_the_first_fragment_bringing_alpha_to_one_half(settings, opacities, median):
    scene, camera = _stacked(opacities), _axis_camera()
    first, second = (float(o) for o in scene.opacities)
    alone = render_reference(scene, camera, order=np.array([0]))
    assert alone[CENTRE + (3,)] == first  # exactly: "exactly-half" is 0.5 itself
    image = render_reference_channels(scene, camera, settings)
    alpha = 1 - (1 - first) * (1 - second)
    np.testing.assert_allclose(image.alpha[CENTRE], alpha, rtol=1e-7)
    np.testing.assert_allclose(image.depth[CENTRE], (first * 4 + (1 - first) * second * 6) / alpha, rtol=1e-6)
    assert image.median_depth[CENTRE] == median
    # Isotropic scales tie: the first minimum, x, is the normal; x . (0, 0, 1) = 0 is not flipped.
    np.testing.assert_allclose(image.normal[CENTRE], (1.0, 0.0, 0.0), atol=1e-7)


@pytest.mark.parametrize("settings", [RenderSettings(transmittance_cutoff=True),
                                      RenderSettings(transmittance_cutoff=True, order="per-pixel")], ids=str)
def test_the_fragment_that_stops_a_pixel_adds_to_no_output(settings):
    # At the centre: 0.4 leaves T = 0.6; the second would take it to 3e-5 < 1e-4 and so is
    # not drawn. Without the cut-off it would set the median, pull the depth to 6 and
    # turn the normal to its own shortest axis, z, flipped to face the ray: (0, 0, -1).
    scene, camera = _stacked((0.4, 0.99995), scales=((0.2, 0.2, 0.2), (0.3, 0.3, 0.1))), _axis_camera()
    cut = render_reference_channels(scene, camera, settings)
    np.testing.assert_allclose(cut.alpha[CENTRE], 0.4, rtol=1e-6)
    np.testing.assert_allclose(cut.depth[CENTRE], 4.0, rtol=1e-7)
    assert cut.median_depth[CENTRE] == 0
    np.testing.assert_allclose(cut.normal[CENTRE], (1.0, 0.0, 0.0), atol=1e-7)
    uncut = render_reference_channels(scene, camera, replace(settings, transmittance_cutoff=False))
    assert uncut.median_depth[CENTRE] == 6.0 and uncut.depth[CENTRE] > 5.0
    assert uncut.normal[CENTRE][2] < -0.8


def test_per_pixel_order_takes_the_nearer_peak_first_where_centres_say_otherwise():
    # A long needle whose centre lies behind a ball but which crosses the central ray in
    # front of it (tests/render/test_ray_order.py's case).
    axis = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    rotation = np.array([[axis[0], 0.0, -axis[2]], [0.0, 1.0, 0.0], [axis[2], 0.0, axis[0]]])
    scene = make_scene([(0.0, 0.0, 5.0), (3.0, 0.0, 6.0)], [(0.3, 0.3, 0.3), (8.0, 0.08, 0.08)],
                       rotations=[(1, 0, 0, 0), _quaternion(rotation)], opacities=[0.95, 0.95])
    camera = _axis_camera(41, 31)
    centre = (15, 20)
    needle_z = _peak_z(scene, 1, camera.pixel_rays())[centre]
    assert needle_z < 4.0  # its peak on this ray is in front of the ball's
    per_pixel = render_reference_channels(scene, camera, order="per-pixel")
    np.testing.assert_allclose(per_pixel.median_depth[centre], needle_z, rtol=1e-6)
    by_depth = render_reference_channels(scene, camera, order="depth")
    np.testing.assert_allclose(by_depth.median_depth[centre], 5.0, rtol=1e-7)
    np.testing.assert_allclose(by_depth.alpha, per_pixel.alpha, atol=1e-7)
    assert per_pixel.depth[centre] < by_depth.depth[centre] - 0.3


# --- supersampling ------------------------------------------------------------------------------

def _block_mean(values, k):
    h, w = values.shape[0] // k, values.shape[1] // k
    return values.reshape(h, k, w, k, *values.shape[2:]).astype(np.float64).mean(axis=(1, 3))


@pytest.mark.parametrize("settings", [RenderSettings(supersample=2), RenderSettings(supersample=3, order="per-pixel")],
                         ids=str)
def test_supersampling_averages_every_accumulator_over_the_block(settings):
    k = settings.supersample
    camera = look_at((0.3, -0.2, -2.5), (0.0, 0.0, 0.0), width=14, height=10, fov_y_degrees=40.0)
    fine = camera.resized(k * camera.width, k * camera.height)
    single = replace(settings, supersample=1)

    scene = random_scene(40, seed=7, degree=0, log_scale=(-2.5, -1.2))
    image = render_reference_channels(scene, camera, settings)
    samples = render_reference_channels(scene, fine, single)
    alpha = _block_mean(samples.alpha, k)
    assert (alpha > 0.5).mean() > 0.2 and (samples.median_depth > 0).mean() < 0.95
    found = _block_mean(samples.median_depth > 0, k)
    assert ((found > 0) & (found < 1)).sum() > 3  # pixels where only some samples have a median
    np.testing.assert_allclose(image.alpha, alpha, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(image.rgb, _block_mean(samples.rgb, k), rtol=1e-6, atol=1e-7)
    covered = alpha > 0
    np.testing.assert_allclose(image.depth[covered],
                               (_block_mean(samples.alpha * samples.depth, k) / np.where(covered, alpha, 1))[covered],
                               rtol=2e-6)
    median = _block_mean(samples.median_depth, k) / np.where(found > 0, found, 1)
    np.testing.assert_allclose(image.median_depth, median, rtol=2e-6)
    # Negative control: the mean of the finished depths is not the depth of the means.
    assert np.abs(_block_mean(samples.depth, k) - image.depth).max() > 1e-2

    # With one fragment per sample its normal_sum is alpha n: the block's normal is the
    # direction of the mean of alpha n.
    disc = _tilted_disc()
    image = render_reference_channels(disc, camera, settings)
    samples = render_reference_channels(disc, fine, single)
    mean = _block_mean(samples.alpha[..., None] * samples.normal, k)
    length = np.linalg.norm(mean, axis=-1, keepdims=True)
    covered = length[..., 0] > 0
    assert covered.sum() > 20
    np.testing.assert_allclose(image.normal[covered], (mean / np.where(length > 0, length, 1))[covered], atol=1e-6)


# --- colour is render_reference's, bit for bit ------------------------------------------------

SETTINGS = [RenderSettings(), RenderSettings(mip=True, mip_modulation=True), RenderSettings(mode="raygs-exact-mip"),
            RenderSettings(mode="gs", gs_compensation=True),
            RenderSettings(alpha_clamp=True, transmittance_cutoff=True),
            RenderSettings(supersample=2, background=(0.2, 0.3, 0.4)), RenderSettings(order="distance"),
            RenderSettings(order="per-pixel", transmittance_cutoff=True), RenderSettings(order="per-pixel", order_k=2)]


@pytest.mark.parametrize("settings", SETTINGS, ids=str)
def test_colour_and_alpha_are_render_reference_bit_for_bit(settings, monkeypatch):
    scene = random_scene(120, seed=11, degree=1)
    camera = look_at((0.4, -0.3, -3.0), (0.0, 0.0, 0.0), width=23, height=17, fov_y_degrees=45.0)
    image = render_reference_channels(scene, camera, settings)
    color = render_reference(scene, camera, settings)
    assert color[..., 3].max() > 0.5
    np.testing.assert_array_equal(image.rgb, color[..., :3].astype(np.float32))
    np.testing.assert_array_equal(image.alpha, color[..., 3].astype(np.float32))
    # Bands of two output rows (the geometry bands are smaller still): the same image.
    monkeypatch.setattr(reference, "BAND_SAMPLES",
                        2 * camera.width * settings.supersample ** 2 * reference.PER_PIXEL_BAND_DIVISOR)
    banded = render_reference_channels(scene, camera, settings)
    np.testing.assert_array_equal(banded.rgb, image.rgb)
    for name in ("alpha", "depth", "median_depth", "normal"):
        np.testing.assert_allclose(getattr(banded, name), getattr(image, name), rtol=1e-6, atol=1e-7)


def test_an_empty_order_gives_the_background_and_no_geometry():
    scene, camera = _stacked((0.3, 0.4)), _axis_camera()
    image = render_reference_channels(scene, camera, RenderSettings(background=(0.1, 0.2, 0.3)),
                                      order=np.zeros(0, np.int64))
    np.testing.assert_allclose(image.rgb, np.broadcast_to(np.float32([0.1, 0.2, 0.3]), image.rgb.shape))
    for name in ("alpha", "depth", "median_depth", "normal"):
        assert not getattr(image, name).any()
