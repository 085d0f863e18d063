"""render_reference_channels against a plain per-pixel loop over the fragments, in every
mode, order and compositing rule, and on the hard cases (a gaussian straddling the
camera plane, a needle, depths from 1e-3 to 1e5 in one image).

The loop takes each fragment's alpha from the reference rendering that gaussian alone
(the colour machinery the other tests check), and computes everything else here from
3x3 matrices: the peak's z on the pixel's ray (with the MIP filters' covariances), the
facing normal, the order (global, by t*, or through a k-buffer kept with a heap), the
front-to-back sums, the median's crossing and INRIA's cut-off."""

import heapq
from dataclasses import replace

import numpy as np
import pytest
from testkit import make_scene, random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.render.channels import MEDIAN_ALPHA
from raygs_viewer.render.reference import global_order, render_reference, render_reference_channels
from raygs_viewer.render.settings import GS_NEAR, TRANSMITTANCE_CUTOFF, RenderSettings


def _fragment_fields(scene, camera, settings, i):
    """alpha, z, key (t* on the unit ray) (H, W) and facing normal (H, W, 3) of gaussian ``i``."""
    alone = replace(settings, transmittance_cutoff=False, order="depth", order_k=0)
    alpha = render_reference(scene, camera, alone, order=np.array([i]))[..., 3]
    rays = camera.pixel_rays()
    unit = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    axes = camera.R @ quaternion_to_matrix(scene.rotations[i:i + 1].astype(np.float64))[0]
    scales2 = scene.scales[i].astype(np.float64) ** 2
    mu = camera.R @ scene.positions[i].astype(np.float64) + camera.t
    sigma_x2 = settings.pixel_variance(camera)

    def peak(filtered2):
        """The ray parameter of the peak on each z = 1 ray, for per-axis variances (..., 3)."""
        inverse = np.einsum("ij,...j,kj->...ik", axes, 1 / filtered2, axes)
        return (np.einsum("...i,...ij,j->...", rays, inverse, mu)
                / np.einsum("...i,...ij,...j->...", rays, inverse, rays))

    if settings.mode == "gs":
        z = np.full(alpha.shape, mu[2])
    elif settings.mode == "raygs-exact-mip":
        inverse = axes @ np.diag(1 / scales2) @ axes.T
        tau = np.maximum((unit @ inverse @ mu) / np.einsum("...i,ij,...j->...", unit, inverse, unit), 0.0)
        z = peak(scales2 + sigma_x2 * tau[..., None] ** 2)
    else:
        z = peak(np.broadcast_to(scales2 + sigma_x2 * (mu @ mu), rays.shape))
    normal = axes[:, int(np.argmin(scene.scales[i]))]
    facing = np.where((rays @ normal > 0)[..., None], -normal, normal)
    return alpha, z, z * np.linalg.norm(rays, axis=-1), facing


def _brute_force(scene, camera, settings):
    """(alpha, depth, median, normal) per pixel from a Python loop over each pixel's fragments."""
    order = global_order(scene, camera, settings)
    fields = [(int(i),) + _fragment_fields(scene, camera, settings, i) for i in order]
    out = {name: np.zeros((camera.height, camera.width) + shape)
           for name, shape in (("alpha", ()), ("depth", ()), ("median", ()), ("normal", (3,)))}
    for v in range(camera.height):
        for u in range(camera.width):
            # Front to back in the global order: what the rasterizer meets first.
            arriving = [(key[v, u], i, alpha[v, u], z[v, u], normal[v, u])
                        for i, alpha, z, key, normal in reversed(fields) if alpha[v, u] > 0]
            if settings.per_pixel and settings.order_k == 0:
                arriving.sort(key=lambda f: (f[0], f[1]))
            elif settings.per_pixel:
                window, composited = [], []
                for fragment in arriving:
                    heapq.heappush(window, (fragment[0], fragment[1], len(composited) + len(window), fragment))
                    if len(window) > settings.order_k:
                        composited.append(heapq.heappop(window)[3])
                arriving = composited + [entry[3] for entry in sorted(window)]
            transmittance, depth, normal, median = 1.0, 0.0, np.zeros(3), 0.0
            found = False
            for _, _, alpha, z, n in arriving:
                after = transmittance * (1 - alpha)
                if settings.transmittance_cutoff and after < TRANSMITTANCE_CUTOFF:
                    break
                depth += transmittance * alpha * z
                normal += transmittance * alpha * n
                if not found and 1 - after >= MEDIAN_ALPHA:
                    median, found = z, True
                transmittance = after
            alpha = 1 - transmittance
            out["alpha"][v, u] = alpha
            out["depth"][v, u] = depth / alpha if alpha > 0 else 0.0
            out["median"][v, u] = median
            length = np.linalg.norm(normal)
            out["normal"][v, u] = normal / length if length > 0 else 0.0
    return out


def _assert_matches_brute_force(scene, camera, settings):
    image = render_reference_channels(scene, camera, settings)
    expected = _brute_force(scene, camera, settings)
    for name in ("alpha", "depth", "median_depth", "normal", "rgb"):
        assert np.all(np.isfinite(getattr(image, name))), name
    np.testing.assert_allclose(image.alpha, expected["alpha"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(image.depth, expected["depth"], rtol=2e-6, atol=1e-12)
    np.testing.assert_allclose(image.median_depth, expected["median"], rtol=2e-6, atol=1e-12)
    np.testing.assert_allclose(image.normal, expected["normal"], atol=2e-6)
    return image, expected


def _camera():
    return look_at((0.3, -0.2, -2.6), (0.0, 0.0, 0.0), width=24, height=16, fov_y_degrees=50.0)


@pytest.mark.parametrize("settings", [
    RenderSettings(), RenderSettings(mip=True, mip_sigma2=2.0), RenderSettings(mode="raygs-exact-mip", mip_sigma2=2.0),
    RenderSettings(mode="gs"), RenderSettings(alpha_clamp=True, transmittance_cutoff=True),
    RenderSettings(order="distance"), RenderSettings(order="per-pixel"),
    RenderSettings(order="per-pixel", order_k=2, transmittance_cutoff=True),
], ids=str)
def test_a_random_scene_matches_a_per_pixel_loop(settings):
    # Few, large, opaque gaussians: many pixels see several and cross one half.
    scene = random_scene(20, seed=5, degree=0, spread=0.6, log_scale=(-2.2, -1.0), anisotropy=1.5)
    scene = replace(scene, opacities=np.clip(scene.opacities * 1.6, 0, 0.999).astype(np.float32))
    image, expected = _assert_matches_brute_force(scene, _camera(), settings)
    assert (expected["median"] > 0).mean() > 0.2 and ((expected["alpha"] > 0) & (expected["median"] == 0)).any()
    # The loop is strict enough to see the order: depth in another order differs.
    other = replace(settings, order="depth" if settings.per_pixel or settings.mode == "gs" else "per-pixel",
                    order_k=0)
    other = replace(other, order="distance") if other == settings else other
    assert np.abs(render_reference_channels(scene, _camera(), other).depth - image.depth).max() > 1e-3


def test_the_cutoff_case_stops_pixels():
    # At the centre the second stops the pixel (T = 0.03 would fall to 1.5e-6).
    scene = make_scene([(0.0, 0.0, 3.0), (0.0, 0.0, 3.5), (0.0, 0.0, 4.0)], 0.3, opacities=[0.97, 0.99995, 0.5])
    camera = _origin_camera(25, 17, 60.0)
    settings = RenderSettings(transmittance_cutoff=True)
    image, _ = _assert_matches_brute_force(scene, camera, settings)
    uncut = render_reference_channels(scene, camera, replace(settings, transmittance_cutoff=False))
    assert np.abs(uncut.depth - image.depth).max() > 1e-2


# --- hard cases ----------------------------------------------------------------------------

def _origin_camera(width=24, height=16, fov=90.0):
    return look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width=width, height=height, fov_y_degrees=fov)


@pytest.mark.parametrize("centre_z", [0.01, 0.0, -0.01])
@pytest.mark.parametrize("mode", ["raygs", "raygs-exact-mip", "gs"])
def test_a_gaussian_straddling_the_camera_plane(centre_z, mode):
    # A slab 0.3 thin in x, 2.0 in y and z, beside the camera (c^2 = 44 > kappa even for
    # exact MIP's widened support) and reaching 6 units either side of z = 0; plus one
    # gaussian in front of it so some pixels see two.
    tilt = np.radians(10.0)
    scene = make_scene([(2.0, 0.1, centre_z), (1.2, 0.0, 2.0)], [(0.3, 2.0, 2.0), (0.5, 0.5, 0.2)],
                       rotations=[(np.cos(tilt), 0.0, np.sin(tilt), 0.0), (1, 0, 0, 0)], opacities=[0.9, 0.7])
    settings = RenderSettings(mode=mode)
    camera = _origin_camera()
    image, _ = _assert_matches_brute_force(scene, camera, settings)
    covered = image.alpha > 0
    assert covered.sum() > 20 and np.all(image.depth[covered] > 0)
    # RayGS draws the part in front of the camera; GS skips a centre nearer than GS_NEAR.
    straddling = render_reference(scene, camera, settings, order=np.array([0]))[..., 3]
    assert (straddling.max() > 0.3) == (mode != "gs")


def test_a_needle():
    # Scales (1e-4, 1e-4, 1) along the world y axis through the central column's rays:
    # the tie between x and y picks x, the normal; x . ray = 0 there, so it is not flipped.
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    scene = make_scene([(0.0, 0.0, 3.0)], [(1e-4, 1e-4, 1.0)], rotations=[(c, s, 0.0, 0.0)], opacities=0.9)
    camera = _origin_camera(25, 17, 60.0)
    # (Exact MIP's modulation would dim so thin a needle below p_min: without it, it widens
    # to about 0.2 px.)
    for settings in (RenderSettings(), RenderSettings(order="per-pixel"),
                     RenderSettings(mode="raygs-exact-mip", mip_modulation=False)):
        image, _ = _assert_matches_brute_force(scene, camera, settings)
        covered = image.alpha > 0
        assert covered[:, 12].all() and (settings.mip_active or covered.sum() == covered[:, 12].sum())
        # (The filter's isotropic widening moves exact MIP's peaks a little towards the camera.)
        np.testing.assert_allclose(image.depth[:, 12], 3.0, rtol=1e-2 if settings.mip_active else 1e-6)
        np.testing.assert_allclose(image.normal[:, 12], np.broadcast_to([1.0, 0.0, 0.0], (camera.height, 3)),
                                   atol=1e-6)
        assert (image.median_depth[:, 12] == image.depth[:, 12]).sum() >= 3


def test_depths_from_a_thousandth_to_a_hundred_thousand_in_one_image():
    # Each gaussian spans about 0.1 of the view at its own depth.
    depths = np.array([1e-3, 1.0, 1e5])
    positions = [(-0.4 * z, 0.0, z) for z in depths[:1]] + [(0.0, 0.0, depths[1]), (0.4 * depths[2], 0.0, depths[2])]
    scene = make_scene(positions, [(0.08 * z, 0.05 * z, 0.02 * z) for z in depths], opacities=0.95)
    camera = _origin_camera(32, 16, 60.0)
    for settings in (RenderSettings(), RenderSettings(mode="gs"), RenderSettings(order="per-pixel")):
        image, _ = _assert_matches_brute_force(scene, camera, settings)
        seen = image.median_depth[image.median_depth > 0]
        for z in depths:
            # GS skips centres nearer than GS_NEAR (its projection is undefined at z = 0).
            visible = settings.mode != "gs" or z > GS_NEAR
            assert np.any(np.abs(seen / z - 1) < 1e-2) == visible, (settings, z)
