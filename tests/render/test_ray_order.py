"""The reference's orders (maths page, section 11): the global keys, the exact per-pixel
order by t*, and the k-buffer window, each checked against an independent evaluation."""

import heapq
from dataclasses import replace

import numpy as np
import pytest
from testkit import make_scene, random_rotation, random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.errors import UserError
from raygs_viewer.render.ray_order import Fragments, composite_per_pixel
from raygs_viewer.render.reference import ground_truth, render_reference
from raygs_viewer.render.settings import TRANSMITTANCE_CUTOFF, RenderSettings
from raygs_viewer.scene.sh import sh_to_rgb
from raygs_viewer.sort.cull import Cull
from raygs_viewer.sort.keys import key_values, sort_back_to_front


def _quaternion(rotation):
    w = np.sqrt(max(1.0 + np.trace(rotation), 1e-12)) / 2
    return np.array([w, (rotation[2, 1] - rotation[1, 2]) / (4 * w),
                     (rotation[0, 2] - rotation[2, 0]) / (4 * w), (rotation[1, 0] - rotation[0, 1]) / (4 * w)])


def _camera(width=48, height=36, eye=(0.0, 0.0, -4.0)):
    return look_at(eye, (0.0, 0.0, 0.0), width=width, height=height, fov_y_degrees=50.0)


def needle_and_ball():
    """The maths page's case: a long needle whose centre lies behind a small ball, but
    whose part on the central ray lies in front of it (camera at the origin, +z ahead)."""
    axis = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    # Rotation taking x to the needle's axis (about y by -45 degrees).
    rotation = np.array([[axis[0], 0.0, -axis[2]], [0.0, 1.0, 0.0], [axis[2], 0.0, axis[0]]])
    return make_scene([(0.0, 0.0, 5.0), (3.0, 0.0, 6.0)], [(0.3, 0.3, 0.3), (8.0, 0.08, 0.08)],
                      rotations=[(1, 0, 0, 0), _quaternion(rotation)], opacities=[0.95, 0.95],
                      colors=[(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)])


def crossing_sheets(seed=0):
    """Flat discs that interpenetrate at random angles: per-ray order changes across each."""
    rng = np.random.default_rng(seed)
    n = 12
    rotations = [_quaternion(random_rotation(rng)) for _ in range(n)]
    positions = rng.uniform(-0.4, 0.4, (n, 3))
    scales = np.column_stack([rng.uniform(0.5, 0.9, n), rng.uniform(0.5, 0.9, n), np.full(n, 0.01)])
    return make_scene(positions, scales, rotations=rotations, opacities=rng.uniform(0.5, 0.95, n),
                      colors=rng.uniform(0, 1, (n, 3)))


def _brute_force(scene, camera, settings, pixel):
    """(rgb, alpha) of one pixel, from Sigma = R S^2 R^T in camera space: every gaussian's
    alpha and t* = x^T S^-1 mu / x^T S^-1 x on the unit ray, sorted by (t*, index)."""
    u, v = pixel
    x = np.array([(u + 0.5 - camera.cx) / camera.fx, (v + 0.5 - camera.cy) / camera.fy, 1.0])
    x /= np.linalg.norm(x)
    fragments = []
    for i in range(scene.count):
        rotation = camera.R @ quaternion_to_matrix(scene.rotations[i:i + 1].astype(np.float64))[0]
        inverse = np.linalg.inv(rotation @ np.diag(scene.scales[i].astype(np.float64) ** 2) @ rotation.T)
        mu = camera.R @ scene.positions[i].astype(np.float64) + camera.t
        opacity = float(scene.opacities[i])
        along, weight, c2 = x @ inverse @ mu, x @ inverse @ x, mu @ inverse @ mu
        kappa = -2 * np.log(settings.p_min / opacity)
        alpha = opacity * np.exp(-0.5 * (c2 - along ** 2 / weight))
        if kappa > 0 and c2 > kappa and along > 0 and alpha >= settings.p_min:
            direction = scene.positions[i].astype(np.float64) - camera.center
            color = sh_to_rgb(scene.sh[i:i + 1].astype(np.float64), scene.sh_degree,
                              (direction / np.linalg.norm(direction))[None])[0]
            fragments.append((along / weight, i, alpha, color))
    rgb, transmittance = np.zeros(3), 1.0
    for _, _, alpha, color in sorted(fragments, key=lambda f: (f[0], f[1])):
        rgb += transmittance * alpha * color
        transmittance *= 1 - alpha
    return rgb + transmittance * np.asarray(settings.background), 1 - transmittance


PER_PIXEL = RenderSettings(order="per-pixel", background=(0.1, 0.2, 0.3))


@pytest.mark.parametrize("make", [needle_and_ball, crossing_sheets])
def test_per_pixel_matches_a_brute_force_evaluation(make):
    scene = make()
    camera = (look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width=40, height=30, fov_y_degrees=60.0)
              if make is needle_and_ball else _camera(40, 30))
    image = render_reference(scene, camera, PER_PIXEL)
    for pixel in [(20, 15), (3, 4), (31, 22), (12, 25), (27, 9)]:
        rgb, alpha = _brute_force(scene, camera, PER_PIXEL, pixel)
        # The stored float32 quaternions are unit to ~1e-7 (test_reference.py's ROTATION_ATOL).
        np.testing.assert_allclose(image[pixel[1], pixel[0], :3], rgb, atol=2e-7)
        np.testing.assert_allclose(image[pixel[1], pixel[0], 3], alpha, atol=2e-7)


def test_the_needle_in_front_of_the_ball_needs_per_pixel_order():
    scene = needle_and_ball()
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width=41, height=31, fov_y_degrees=60.0)
    centre = (15, 20)
    per_pixel = render_reference(scene, camera, order="per-pixel")[centre]
    assert per_pixel[2] > per_pixel[0]  # blue: the needle is met first
    for key in ("depth", "distance"):
        wrong = render_reference(scene, camera, order=key)[centre]
        assert wrong[0] > wrong[2], key  # red: both global keys put the ball in front
        np.testing.assert_allclose(wrong[3], per_pixel[3], atol=1e-12)
    # A window of one already swaps the two at this pixel: the needle arrives second.
    windowed = render_reference(scene, camera, RenderSettings(order="per-pixel", order_k=1))[centre]
    np.testing.assert_array_equal(windowed, per_pixel)


@pytest.mark.parametrize("settings", [RenderSettings(), RenderSettings(mip=True),
                                      RenderSettings(mode="raygs-exact-mip"), RenderSettings(supersample=2),
                                      RenderSettings(alpha_clamp=True)], ids=str)
def test_accumulated_alpha_does_not_depend_on_the_order(settings):
    scene, camera = random_scene(200, seed=3), _camera()
    alphas = [render_reference(scene, camera, replace(settings, order=order, order_k=k))[..., 3]
              for order, k in (("depth", 0), ("distance", 0), ("per-pixel", 0), ("per-pixel", 3))]
    colors = [render_reference(scene, camera, replace(settings, order=order))[..., :3] for order in ("depth", "per-pixel")]
    for alpha in alphas[1:]:
        np.testing.assert_allclose(alpha, alphas[0], atol=1e-12)
    assert np.abs(colors[0] - colors[1]).max() > 1e-3  # the orders do differ in colour


def test_a_wide_window_is_the_exact_order_bit_for_bit_and_a_narrow_one_is_not():
    scene, camera = crossing_sheets(), _camera()
    exact = render_reference(scene, camera, PER_PIXEL)
    np.testing.assert_array_equal(render_reference(scene, camera, replace(PER_PIXEL, order_k=16)), exact)
    assert np.abs(render_reference(scene, camera, replace(PER_PIXEL, order_k=1)) - exact).max() > 1e-3


def _window_by_heap(stream, k):
    """The k-buffer on one pixel's (key, index, alpha, color) stream, with a heap."""
    window, out = [], []
    for fragment in stream:
        heapq.heappush(window, fragment)
        if len(window) > k:
            out.append(heapq.heappop(window))
    return out + sorted(window)


@pytest.mark.parametrize("k", [1, 2, 5])
def test_the_window_matches_a_heap_per_pixel(k):
    rng = np.random.default_rng(k)
    pixels, count = 7, 200
    fragments = Fragments(pixel=rng.integers(0, pixels, count), key=rng.integers(0, 20, count).astype(float),
                          index=rng.permutation(count), rank=rng.permutation(count),
                          alpha=rng.uniform(0.05, 0.9, count), color=rng.uniform(0, 1, (count, 3)))
    image = composite_per_pixel(fragments, pixels, (0.2, 0.3, 0.4), window=k)
    for p in range(pixels):
        mine = np.flatnonzero(fragments.pixel == p)
        arrival = mine[np.argsort(-fragments.rank[mine])]
        stream = [(fragments.key[i], fragments.index[i], i) for i in arrival]
        rgb, transmittance = np.zeros(3), 1.0
        for _, _, i in _window_by_heap(stream, k):
            rgb += transmittance * fragments.alpha[i] * fragments.color[i]
            transmittance *= 1 - fragments.alpha[i]
        np.testing.assert_allclose(image[p, :3], rgb + transmittance * np.array([0.2, 0.3, 0.4]), atol=1e-12)


def test_per_pixel_cutoff_ends_a_pixel_at_the_fragment_that_would_pass_it():
    # Five fragments at one pixel, given in scrambled order; sorted by key the
    # transmittance falls to 0.15^4 = 5.1e-4, and the 5th (blue) would take it below 1e-4.
    fragments = Fragments(pixel=np.zeros(5, np.int64), key=np.array([3.0, 1.0, 4.0, 0.0, 2.0]),
                          index=np.arange(5), rank=np.arange(5), alpha=np.full(5, 0.85), color=np.eye(5)[:, :3])
    image = composite_per_pixel(fragments, 1, (0.0, 0.0, 0.0), cutoff=TRANSMITTANCE_CUTOFF)
    np.testing.assert_allclose(image[0, 3], 1 - 0.15 ** 4, rtol=1e-12)
    # By key: black (index 3), green (1), black (4), red (0); blue (2) is never drawn.
    np.testing.assert_allclose(image[0, :3], [0.15 ** 3 * 0.85, 0.15 * 0.85, 0.0], rtol=1e-12, atol=1e-15)
    uncut = composite_per_pixel(fragments, 1, (0.0, 0.0, 0.0))
    assert uncut[0, 2] > 1e-4 and uncut[0, 3] > image[0, 3]


def test_distance_is_invariant_when_the_camera_turns_in_place_and_depth_is_not():
    scene = random_scene(400, seed=5, spread=1.0)
    camera = _camera(eye=(0.0, 0.0, -6.0))
    turned = replace(camera, R=random_rotation(np.random.default_rng(1)) @ camera.R)
    turned = replace(turned, t=-turned.R @ camera.center)
    np.testing.assert_allclose(turned.center, camera.center, atol=1e-12)
    scale = Cull(scene).coordinate_scale

    def back_to_front(view, key):
        return sort_back_to_front(key_values(scene.positions, view, key, scale), "float")

    same = [back_to_front(view, "distance") for view in (camera, turned)]
    np.testing.assert_array_equal(same[0], same[1])
    depth = [back_to_front(view, "depth") for view in (camera, turned)]
    assert not np.array_equal(depth[0], depth[1])
    distance = np.linalg.norm(scene.positions[same[0]] - camera.center, axis=1)
    assert np.all(np.diff(distance) <= 1e-5)  # back to front: farthest first


def test_ground_truth_takes_the_order():
    scene = needle_and_ball()
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width=21, height=15, fov_y_degrees=60.0)
    depth = ground_truth(scene, camera, samples=2)
    per_pixel = ground_truth(scene, camera, samples=2, order="per-pixel")
    assert np.abs(depth - per_pixel).max() > 0.1
    np.testing.assert_array_equal(per_pixel, ground_truth(scene, camera, PER_PIXEL.__class__(order="per-pixel",
                                                                                              order_k=3), samples=2))
    np.testing.assert_allclose(depth[..., 3], per_pixel[..., 3], atol=1e-12)


def test_per_pixel_needs_a_raygs_mode():
    with pytest.raises(UserError, match="RayGS mode"):
        RenderSettings(mode="gs", order="per-pixel")
    with pytest.raises(UserError, match="order K"):
        RenderSettings(order="per-pixel", order_k=17)
    with pytest.raises(UserError, match="order must be"):
        RenderSettings(order="nearest")


def test_mip_orders_by_the_filtered_gaussians():
    # Without modulation the pixel-invariant filter is plain RayGS on the widened scales
    # s^2 + sigma_x^2 |mu|^2: the same t*, so the same per-pixel image.
    scene, camera = crossing_sheets(seed=2), _camera()
    settings = replace(PER_PIXEL, mip=True, mip_sigma2=4.0, mip_modulation=False)
    distance2 = np.sum((scene.positions.astype(np.float64) - camera.center) ** 2, axis=1)
    widened = np.sqrt(scene.scales.astype(np.float64) ** 2 + settings.pixel_variance(camera) * distance2[:, None])
    filtered = replace(scene, scales=widened.astype(np.float32))
    np.testing.assert_allclose(render_reference(scene, camera, settings),
                               render_reference(filtered, camera, replace(settings, mip=False)), atol=2e-6)


def test_exact_mip_without_a_filter_orders_as_plain_raygs():
    scene, camera = crossing_sheets(seed=4), _camera()
    exact = render_reference(scene, camera, replace(PER_PIXEL, mode="raygs-exact-mip", mip_sigma2=0.0))
    np.testing.assert_allclose(exact, render_reference(scene, camera, PER_PIXEL), atol=1e-12)
    assert np.abs(exact - render_reference(scene, camera, replace(PER_PIXEL, order="depth"))).max() > 1e-2
