"""The float64 reference's accuracy options (maths page sections 6, 7, 10) against
independent evaluations built here from full 3x3 (or 2x2) matrices, with negative
controls that show each comparison would see the fault it names. No GL needed."""

from dataclasses import replace

import numpy as np
import pytest
from testkit import make_scene, random_rotation, random_scene

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.render.reference import ground_truth, render_reference
from raygs_viewer.render.settings import (
    ACCURACY_PRESETS,
    ALPHA_CLAMP,
    GS_DILATION,
    TRANSMITTANCE_CUTOFF,
    RenderSettings,
    apply_preset,
)
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.demo import demo_camera
from raygs_viewer.sort.depth import DepthSorter

# Odd size, fx != fy, off-centre principal point: any axis or half-pixel slip shows.
CAMERA = replace(look_at([0.4, -0.3, -3.0], [0.05, 0.02, 0.0], width=40, height=30),
                 fx=44.0, fy=39.0, cx=19.3, cy=15.8)


#: The stored float32 quaternion is unit only to ~1e-7, so its matrix is orthogonal only to
#: ~1e-7 and Sigma = Rp S^2 Rp^T (built here) and the reference's whitening by Rp^T differ
#: by ~1e-7 relative: the tolerance of comparisons on randomly rotated gaussians.
ROTATION_ATOL = 2e-7


def _quaternion(rotation):
    """Unit quaternion (w, x, y, z) of a rotation matrix (w > 0 branch; fine for tests)."""
    w = np.sqrt(max(1.0 + np.trace(rotation), 1e-12)) / 2
    return np.array([w, (rotation[2, 1] - rotation[1, 2]) / (4 * w),
                     (rotation[0, 2] - rotation[2, 0]) / (4 * w), (rotation[1, 0] - rotation[0, 1]) / (4 * w)])


def _unit(q):
    return np.asarray(q, np.float64) / np.linalg.norm(q)


def _one(position, scales, opacity=0.8, seed=0, color=(0.8, 0.6, 0.4)):
    """One anisotropic gaussian with a random orientation."""
    rotation = random_rotation(np.random.default_rng(seed))
    return make_scene([position], [scales], rotations=[_quaternion(rotation)], opacities=opacity, colors=color)


def _camera_space(scene, camera):
    """mu (3,), Sigma (3, 3), o of gaussian 0 in camera space, from the stored float32 values."""
    rotation = camera.R @ quaternion_to_matrix(scene.rotations.astype(np.float64))[0]
    scales = scene.scales[0].astype(np.float64)
    sigma = rotation @ np.diag(scales ** 2) @ rotation.T
    mu = camera.R @ scene.positions[0].astype(np.float64) + camera.t
    return mu, sigma, float(scene.opacities[0]), rotation, scales


def _divergence(rays, mu, sigma):
    """D = c^2 - (x^T S^-1 mu)^2 / (x^T S^-1 x) per ray, and x^T S^-1 mu (the peak's side);
    ``sigma`` may be (3, 3) or one matrix per ray (..., 3, 3)."""
    inverse = np.linalg.inv(sigma)
    inv_mu = inverse @ mu
    along = rays @ inv_mu if inverse.ndim == 2 else np.einsum("...i,...i->...", rays, inv_mu)
    weight = np.einsum("...i,...ij,...j->...", rays, inverse, rays)
    c2 = mu @ inv_mu if inverse.ndim == 2 else np.einsum("...i,...i->...", mu, inv_mu)
    return c2 - along ** 2 / weight, along, weight, c2


# --- RayGS with the pixel-invariant MIP filter (Eq. 17) ------------------------------------

@pytest.mark.parametrize("modulation", [True, False])
def test_mip_with_zero_variance_is_plain_raygs(modulation):
    scene = random_scene(n=200, seed=4)
    plain = render_reference(scene, CAMERA)
    mip = render_reference(scene, CAMERA, RenderSettings(mip=True, mip_sigma2=0.0, mip_modulation=modulation))
    assert plain[..., 3].max() > 0.5
    np.testing.assert_allclose(mip, plain, rtol=0, atol=1e-12)
    wide = render_reference(scene, CAMERA, RenderSettings(mip=True, mip_sigma2=2.0, mip_modulation=modulation))
    assert np.abs(wide - plain).max() > 0.05  # the filter does change this scene


@pytest.mark.parametrize("modulation", [True, False])
def test_mip_one_gaussian_matches_matrix_evaluation(modulation):
    scene = _one([0.1, -0.05, 0.2], [0.12, 0.02, 0.06], seed=3)
    settings = RenderSettings(mip=True, mip_sigma2=3.0, mip_modulation=modulation, p_min=1e-3)
    image = render_reference(scene, CAMERA, settings)

    mu, sigma, o, _, _ = _camera_space(scene, CAMERA)
    sigma_x2 = settings.mip_sigma2 / (CAMERA.fx * CAMERA.fy)
    filtered = sigma + sigma_x2 * (mu @ mu) * np.eye(3)
    rays = CAMERA.pixel_rays()
    divergence, along, _, c2_hat = _divergence(rays, mu, filtered)
    if modulation:
        c2 = mu @ np.linalg.solve(sigma, mu)
        o *= np.sqrt(np.linalg.det(sigma) * c2 / (np.linalg.det(filtered) * c2_hat))
    assert c2_hat > -2 * np.log(settings.p_min / o)  # drawn
    alpha = o * np.exp(-divergence / 2)
    alpha[(alpha < settings.p_min) | (along <= 0)] = 0

    assert (alpha > 0.01).sum() > 20  # a visible footprint
    np.testing.assert_allclose(image[..., 3], alpha, rtol=0, atol=ROTATION_ATOL)
    np.testing.assert_allclose(image[..., :3], alpha[..., None] * [0.8, 0.6, 0.4], rtol=0, atol=1e-6)
    plain = render_reference(scene, CAMERA, replace(settings, mip=False))
    assert np.abs(plain[..., 3] - alpha).max() > 0.05  # the negative control


# --- RayGS with the exact MIP filter (Appendix A.5) ----------------------------------------

def _exact_mip(scene, camera, settings):
    """The maths page's per-pixel formula with 3x3 matrices, and the GL path's support rule."""
    mu, sigma, o, rotation, scales = _camera_space(scene, camera)
    sigma_x2 = settings.mip_sigma2 / (camera.fx * camera.fy)
    rays = camera.pixel_rays()
    x = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    inverse = np.linalg.inv(sigma)
    tau = np.maximum((x @ inverse @ mu) / np.einsum("...i,ij,...j->...", x, inverse, x), 0.0)
    filtered = sigma + sigma_x2 * tau[..., None, None] ** 2 * np.eye(3)
    divergence, _, weight_hat, _ = _divergence(x, mu, filtered)
    weight = np.einsum("...i,ij,...j->...", x, inverse, x)
    modulation = np.sqrt(np.linalg.det(sigma) * weight / (np.linalg.det(filtered) * weight_hat))
    alpha = o * (modulation if settings.mip_modulation else 1.0) * np.exp(-divergence / 2)
    # What GL draws: the kappa-support of the ellipsoid of scales s^2 + sigma_x^2 tau_max^2.
    kappa = -2 * np.log(settings.p_min / o)
    tau_max = np.linalg.norm(mu) + np.sqrt(kappa) * np.sqrt(scales.max() ** 2 + sigma_x2 * (mu @ mu))
    big = rotation @ np.diag(scales ** 2 + sigma_x2 * tau_max ** 2) @ rotation.T
    divergence_big, along_big, _, c2_big = _divergence(x, mu, big)
    assert c2_big > kappa  # drawn
    alpha[(alpha < settings.p_min) | (divergence_big > kappa) | (along_big <= 0)] = 0
    return alpha


def _exact_mip_without_support(scene, camera, settings):
    """The same formula with neither the support rule nor the p_min cut."""
    mu, sigma, o, _, _ = _camera_space(scene, camera)
    sigma_x2 = settings.mip_sigma2 / (camera.fx * camera.fy)
    rays = camera.pixel_rays()
    x = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    inverse = np.linalg.inv(sigma)
    tau = np.maximum((x @ inverse @ mu) / np.einsum("...i,ij,...j->...", x, inverse, x), 0.0)
    divergence = _divergence(x, mu, sigma + sigma_x2 * tau[..., None, None] ** 2 * np.eye(3))[0]
    return o * np.exp(-divergence / 2)


@pytest.mark.parametrize("modulation", [True, False])
def test_exact_mip_one_gaussian_matches_matrix_evaluation(modulation):
    scene = _one([0.1, -0.05, 0.2], [0.12, 0.02, 0.06], seed=3)
    settings = RenderSettings(mode="raygs-exact-mip", mip_sigma2=3.0, mip_modulation=modulation, p_min=1e-3)
    image = render_reference(scene, CAMERA, settings)
    alpha = _exact_mip(scene, CAMERA, settings)
    assert (alpha > 0.01).sum() > 20
    np.testing.assert_allclose(image[..., 3], alpha, rtol=0, atol=ROTATION_ATOL)
    approx = render_reference(scene, CAMERA, replace(settings, mode="raygs", mip=True))
    assert np.abs(approx[..., 3] - alpha).max() > 1e-3  # the two forms do differ off-centre


def test_exact_mip_support_rule_cuts_far_peaks():
    """Rays whose unfiltered peak lies beyond tau_max get a filter so wide that omega can
    pass p_min far from the gaussian; the GL quad (the big ellipsoid's support) draws
    nothing there, and the reference must agree with GL."""
    camera = Camera(40, 30, 20.0, 20.0, 20.0, 15.0, np.eye(3), np.zeros(3))
    scene = make_scene([[-0.8, -0.047, 2.666]], [[0.0248, 0.927, 0.0283]],
                       rotations=[_unit([-0.5876, 0.5331, 0.6024, -0.0873])], opacities=0.322)
    settings = RenderSettings(mode="raygs-exact-mip", mip_sigma2=1.0, mip_modulation=False)
    image = render_reference(scene, camera, settings)
    alpha = _exact_mip(scene, camera, settings)
    np.testing.assert_allclose(image[..., 3], alpha, rtol=0, atol=ROTATION_ATOL)
    uncut = _exact_mip_without_support(scene, camera, settings)
    bitten = (uncut >= settings.p_min) & (alpha == 0)
    assert bitten.sum() > 5 and uncut[bitten].max() > 0.05, "the rule must bite in this test"


def test_exact_mip_skips_a_gaussian_whose_big_support_holds_the_camera():
    """c^2 > kappa but c_big^2 <= kappa: GL skips it, so the reference must too."""
    camera = Camera(32, 24, 20.0, 20.0, 16.0, 12.0, np.eye(3), np.zeros(3))
    scene = make_scene([[0.0, 0.0, 1.0]], [0.2], opacities=0.8)
    mip_sigma2 = 8.0  # sigma_x^2 = 0.02
    exact = render_reference(scene, camera, RenderSettings(mode="raygs-exact-mip", mip_sigma2=mip_sigma2))
    approx = render_reference(scene, camera, RenderSettings(mip=True, mip_sigma2=mip_sigma2))
    assert exact[..., 3].max() == 0
    assert approx[..., 3].max() > 0.3


def test_exact_mip_equals_approximation_through_the_centre():
    """Where the ray points at mu, tau = |mu| and both forms use the same filter and the
    same modulation factor (Eq. 17 is the exact form at that ray)."""
    camera = Camera(21, 17, 30.0, 25.0, 10.3, 8.1, np.eye(3), np.zeros(3))
    u, v, depth = 13, 6, 2.5
    centre = depth * np.array([(u + 0.5 - camera.cx) / camera.fx, (v + 0.5 - camera.cy) / camera.fy, 1.0])
    scene = _one(centre, [0.01, 0.004, 0.02], seed=5)  # sub-pixel: the filter dominates
    # The stored centre is float32: aim the camera's pixel exactly at it.
    stored = scene.positions[0].astype(np.float64)
    camera = replace(camera, cx=u + 0.5 - camera.fx * stored[0] / stored[2],
                     cy=v + 0.5 - camera.fy * stored[1] / stored[2])
    for modulation in (True, False):
        exact = render_reference(scene, camera, RenderSettings(mode="raygs-exact-mip", mip_sigma2=0.5,
                                                               mip_modulation=modulation))
        approx = render_reference(scene, camera, RenderSettings(mip=True, mip_sigma2=0.5,
                                                                mip_modulation=modulation))
        assert exact[v, u, 3] == pytest.approx(approx[v, u, 3], rel=1e-9)
        if modulation:
            plain = render_reference(scene, camera)
            assert abs(plain[v, u, 3] - exact[v, u, 3]) > 0.05  # the filter matters at that pixel


@pytest.mark.parametrize("mode", ["raygs", "raygs-exact-mip", "gs"])
def test_a_gaussian_behind_the_camera_draws_nothing(mode):
    """Rays whose line meets it do so behind the camera (the peak's side test); GL's quad
    there lies behind the camera too. Drawn in front, the same gaussian shows."""
    camera = Camera(32, 24, 20.0, 20.0, 16.0, 12.0, np.eye(3), np.zeros(3))
    settings = RenderSettings(mode=mode, mip_sigma2=1.0, mip_modulation=False)
    behind = make_scene([[0.02, 0.01, -0.5]], [0.1], opacities=0.8)
    assert render_reference(behind, camera, settings, order=np.array([0]))[..., 3].max() == 0
    ahead = make_scene([[0.02, 0.01, 0.5]], [0.1], opacities=0.8)
    assert render_reference(ahead, camera, settings, order=np.array([0]))[..., 3].max() > 0.5


@pytest.mark.parametrize("mode", ["raygs", "raygs-exact-mip"])
def test_default_order_keeps_what_only_the_filter_makes_visible(mode):
    """Tiny gaussians 3 px outside the left border: their own support is culled, but the
    10 px wide MIP filter reaches into the image, so the default order must keep them.
    (A long focal length keeps sigma_x^2 |mu|^2 small enough that the camera stays
    outside the filtered support.)"""
    camera = Camera(32, 24, 60.0, 60.0, 16.0, 12.0, np.eye(3), np.zeros(3))
    positions = [[2.0 * (-3.0 - camera.cx) / camera.fx, 2.0 * (v - camera.cy) / camera.fy, 2.0] for v in (4, 12, 20)]
    scene = make_scene(positions, [0.002], opacities=0.8)
    settings = RenderSettings(mode=mode, mip=True, mip_sigma2=100.0, mip_modulation=False)
    everything = render_reference(scene, camera, settings, order=np.arange(3))
    assert everything[..., 3].max() > 0.5
    np.testing.assert_allclose(render_reference(scene, camera, settings), everything, rtol=0, atol=1e-12)
    assert render_reference(scene, camera, replace(settings, mip=False, mode="raygs"))[..., 3].max() == 0


# --- the opacity modulation ------------------------------------------------------------------

def test_modulation_keeps_a_large_gaussians_total_opacity():
    camera = Camera(64, 48, 60.0, 60.0, 32.0, 24.0, np.eye(3), np.zeros(3))
    scene = _one([0.0, 0.0, 3.0], [0.5, 0.4, 0.45], opacity=0.6, seed=1)  # ~8 px wide
    base = RenderSettings(p_min=1e-5, mip_sigma2=4.0)
    plain = render_reference(scene, camera, base)[..., 3].sum()
    for mode in ("raygs", "raygs-exact-mip"):
        filtered = replace(base, mode=mode, mip=True)
        modulated = render_reference(scene, camera, filtered)[..., 3].sum()
        dilated = render_reference(scene, camera, replace(filtered, mip_modulation=False))[..., 3].sum()
        assert modulated == pytest.approx(plain, rel=0.01), mode
        assert dilated > 1.03 * plain, mode


def test_dilation_without_modulation_inflates_a_subpixel_gaussian():
    # The gaussian (~0.05 px) sits on pixel (11, 9)'s ray, so the sampled sums are stable.
    camera = Camera(24, 20, 40.0, 40.0, 11.5, 9.5, np.eye(3), np.zeros(3))
    scene = _one([0.0, 0.0, 4.0], [0.005, 0.004, 0.006], opacity=0.8, seed=2)
    truth = ground_truth(scene, camera, samples=16)[..., 3].sum()  # the integral over the image
    for mode in ("raygs", "raygs-exact-mip"):
        filtered = RenderSettings(mode=mode, mip=True, mip_sigma2=0.1)
        modulated = render_reference(scene, camera, filtered)[..., 3].sum()
        dilated = render_reference(scene, camera, replace(filtered, mip_modulation=False))[..., 3].sum()
        assert 0.5 < modulated / truth < 2.0, mode
        assert dilated / truth > 10.0, mode


# --- GS (EWA splatting) ----------------------------------------------------------------------

def _splat(scene, camera, compensation=False, p_min=1 / 255):
    """INRIA's 2D gaussian, built by hand: alpha per pixel and the compensation factor."""
    mu, sigma, o, _, _ = _camera_space(scene, camera)
    x, y, z = mu
    fx, fy, w, h = camera.fx, camera.fy, camera.width, camera.height
    limit_x = (-camera.cx / fx - 0.15 * w / fx, (w - camera.cx) / fx + 0.15 * w / fx)
    limit_y = (-camera.cy / fy - 0.15 * h / fy, (h - camera.cy) / fy + 0.15 * h / fy)
    tx, ty = np.clip(x / z, *limit_x) * z, np.clip(y / z, *limit_y) * z
    jacobian = np.array([[fx / z, 0, -fx * tx / z ** 2], [0, fy / z, -fy * ty / z ** 2]])
    projected = jacobian @ sigma @ jacobian.T
    dilated = projected + GS_DILATION * np.eye(2)
    factor = np.sqrt(np.linalg.det(projected) / np.linalg.det(dilated))
    if compensation:
        o *= factor
    centre = np.array([fx * x / z + camera.cx, fy * y / z + camera.cy])
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    d = np.stack([cols - centre[0], rows - centre[1]], axis=-1)
    alpha = o * np.exp(-0.5 * np.einsum("...i,ij,...j->...", d, np.linalg.inv(dilated), d))
    alpha[alpha < p_min] = 0
    return alpha, factor


# On screen; centre off screen, where INRIA's clamp of the Jacobian's ray applies.
GS_CASES = {"on-screen": ([0.1, -0.05, 0.2], [0.05, 0.01, 0.2]), "clamped": ([2.2, 0.3, 0.4], [0.3, 0.05, 0.5])}


@pytest.mark.parametrize("case", sorted(GS_CASES))
def test_gs_one_gaussian_matches_hand_built_splat(case):
    scene = _one(*GS_CASES[case], seed=3)
    image = render_reference(scene, CAMERA, RenderSettings(mode="gs"))
    alpha, _ = _splat(scene, CAMERA)
    assert (alpha > 0.01).sum() > 10
    np.testing.assert_allclose(image[..., 3], alpha, rtol=0, atol=ROTATION_ATOL)
    np.testing.assert_allclose(image[..., :3], alpha[..., None] * [0.8, 0.6, 0.4], rtol=0, atol=1e-6)
    raygs = render_reference(scene, CAMERA)
    assert np.abs(raygs[..., 3] - alpha).max() > 0.01  # GS is not RayGS here


def test_gs_clamps_the_jacobian_for_off_screen_centres():
    """The "clamped" case's centre lies beyond 15% past the right edge, so the clamp
    changes its footprint (which the test above matches)."""
    scene = _one(*GS_CASES["clamped"], seed=3)
    mu = _camera_space(scene, CAMERA)[0]
    assert mu[0] / mu[2] > (1.15 * CAMERA.width - CAMERA.cx) / CAMERA.fx
    alpha, _ = _splat(scene, CAMERA)
    unclamped = _splat(scene, replace(CAMERA, width=1000))[0]  # a clamp limit far to the right
    assert np.abs(unclamped[:, :CAMERA.width] - alpha).max() > 0.01


def test_gs_compensation_scales_opacity_by_the_determinant_ratio():
    scene = _one([0.1, -0.05, 0.2], [0.02, 0.004, 0.05], seed=3)
    plain = render_reference(scene, CAMERA, RenderSettings(mode="gs", p_min=1e-6))
    compensated = render_reference(scene, CAMERA, RenderSettings(mode="gs", gs_compensation=True, p_min=1e-6))
    _, factor = _splat(scene, CAMERA)
    assert factor < 0.8  # thin enough for the dilation to matter
    both = (plain[..., 3] > 0) & (compensated[..., 3] > 0)
    assert both.sum() > 10
    np.testing.assert_allclose(compensated[..., 3][both] / plain[..., 3][both], factor, rtol=1e-10)
    np.testing.assert_allclose(compensated[..., 3], _splat(scene, CAMERA, True, 1e-6)[0], rtol=0, atol=ROTATION_ATOL)


def test_gs_agrees_with_raygs_far_away_and_not_near():
    camera = Camera(64, 48, 1000.0, 1000.0, 32.0, 24.0, np.eye(3), np.zeros(3))
    far = _one([0.05, -0.03, 1000.0], [8.0, 3.0, 5.0], seed=6)  # ~5 px wide at 1000 units
    gs = render_reference(far, camera, RenderSettings(mode="gs"))
    raygs = render_reference(far, camera)
    assert raygs[..., 3].max() > 0.5
    assert np.abs(gs - raygs).max() < 0.01
    wide = Camera(64, 48, 30.0, 30.0, 32.0, 24.0, np.eye(3), np.zeros(3))
    near = _one([0.35, 0.1, 0.3], [0.05, 0.02, 0.25], seed=6)  # off-axis, close, elongated
    gs = render_reference(near, wide, RenderSettings(mode="gs"))
    raygs = render_reference(near, wide)
    assert np.abs(gs - raygs).max() > 0.2


def test_gs_skips_gaussians_at_the_camera_plane():
    camera = Camera(32, 24, 20.0, 20.0, 16.0, 12.0, np.eye(3), np.zeros(3))
    scene = make_scene([[0.0, 0.0, 0.005]], [[0.001, 0.001, 0.001]], opacities=0.9)
    assert render_reference(scene, camera)[..., 3].max() > 0.5  # RayGS draws it
    assert render_reference(scene, camera, RenderSettings(mode="gs"))[..., 3].max() == 0


# --- parity switches: transmittance cut-off, alpha clamp (section 10) -----------------------

def _stack(opacity=0.95, count=6):
    """Gaussians on the ray of pixel (4, 4), one behind the other, distinct colours."""
    camera = Camera(9, 9, 10.0, 10.0, 4.5, 4.5, np.eye(3), np.zeros(3))
    colors = np.random.default_rng(0).uniform(0.1, 0.9, (count, 3))
    scene = make_scene([[0.0, 0.0, 1.0 + k] for k in range(count)], [0.05], opacities=opacity, colors=colors)
    return scene, camera


@pytest.mark.parametrize("mode", ["raygs", "gs"])
def test_transmittance_cutoff_stops_a_pixel_before_1e4(mode):
    scene, camera = _stack()
    background = (0.2, 0.3, 0.5)
    settings = RenderSettings(mode=mode, transmittance_cutoff=True, background=background)
    pixel = render_reference(scene, camera, settings)[4, 4]
    # Front to back, alpha = o exactly at the centre: T = 0.05^k; the 4th would end at
    # 6.25e-6 < 1e-4, so exactly the three front ones contribute.
    o = scene.opacities.astype(np.float64)
    colors = scene.sh[:, 0].astype(np.float64) * 0.28209479177387814 + 0.5
    t, color = 1.0, np.zeros(3)
    for k in range(3):
        color += t * o[k] * colors[k]
        t *= 1 - o[k]
    assert t >= TRANSMITTANCE_CUTOFF and t * (1 - o[3]) < TRANSMITTANCE_CUTOFF
    np.testing.assert_allclose(pixel[3], 1 - t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pixel[:3], color + t * np.asarray(background), rtol=0, atol=1e-12)
    uncut = render_reference(scene, camera, replace(settings, transmittance_cutoff=False))[4, 4]
    assert 1 - uncut[3] < TRANSMITTANCE_CUTOFF  # without the cut-off T goes below 1e-4


def test_transmittance_cutoff_matches_back_to_front_when_it_never_triggers():
    scene = random_scene(n=200, seed=7)
    plain = render_reference(scene, CAMERA)
    cut = render_reference(scene, CAMERA, RenderSettings(transmittance_cutoff=True))
    assert 1 - plain[..., 3].max() > TRANSMITTANCE_CUTOFF  # T never reaches the cut-off
    np.testing.assert_allclose(cut, plain, rtol=0, atol=1e-12)


@pytest.mark.parametrize("mode", ["raygs", "raygs-exact-mip", "gs"])
def test_alpha_clamp(mode):
    scene, camera = _stack(opacity=1.0, count=1)
    settings = RenderSettings(mode=mode, mip_modulation=False)  # exact MIP: alpha = o at the centre
    clamped = render_reference(scene, camera, replace(settings, alpha_clamp=True))
    unclamped = render_reference(scene, camera, settings)
    assert clamped[4, 4, 3] == ALPHA_CLAMP
    assert unclamped[4, 4, 3] > ALPHA_CLAMP
    assert clamped[..., 3].max() == ALPHA_CLAMP
    low = unclamped[..., 3] < ALPHA_CLAMP  # below the clamp nothing changes
    np.testing.assert_array_equal(clamped[..., 3][low], unclamped[..., 3][low])


# --- supersampling and ground truth ------------------------------------------------------

def test_resized_camera_puts_samples_inside_each_pixel():
    k = 3
    fine = CAMERA.resized(k * CAMERA.width, k * CAMERA.height)
    u = np.arange(CAMERA.width)[:, None] + (np.arange(k)[None, :] + 0.5) / k  # (W, k) sample positions
    expected = (u - CAMERA.cx) / CAMERA.fx
    np.testing.assert_allclose(fine.pixel_rays()[0, :, 0], expected.ravel(), rtol=0, atol=1e-14)


@pytest.mark.parametrize("settings", [RenderSettings(supersample=2),
                                      RenderSettings(supersample=3, mip=True, mip_sigma2=1.0),
                                      RenderSettings(supersample=2, mode="raygs-exact-mip"),
                                      RenderSettings(supersample=2, mode="gs", transmittance_cutoff=True)])
def test_supersampling_is_the_block_mean_of_a_larger_render(settings):
    scene = random_scene(n=150, seed=8)
    camera = replace(CAMERA, width=24, height=18, cx=11.3, cy=9.6)
    k = settings.supersample
    image = render_reference(scene, camera, settings)
    order = exact_order(DepthSorter(scene), camera, settings).indices
    fine = render_reference(scene, camera.resized(k * camera.width, k * camera.height),
                            replace(settings, supersample=1), order=order)
    blocks = fine.reshape(camera.height, k, camera.width, k, 4).mean(axis=(1, 3))
    np.testing.assert_allclose(image, blocks, rtol=0, atol=1e-12)
    single = render_reference(scene, camera, replace(settings, supersample=1))
    assert np.abs(single - image).max() > 0.01  # supersampling does change the image


def test_ground_truth_is_exact_supersampled_raygs():
    scene = random_scene(n=150, seed=9)
    camera = replace(CAMERA, width=24, height=18, cx=11.3, cy=9.6)
    settings = RenderSettings(p_min=2e-3, background=(0.1, 0.2, 0.3), sh_degree=1)
    truth = ground_truth(scene, camera, settings, samples=3)
    np.testing.assert_allclose(truth, render_reference(scene, camera, replace(settings, supersample=3)),
                               rtol=0, atol=1e-12)
    # It ignores the accuracy switches: mode, MIP, clamp and cut-off (which do change
    # these images when rendered).
    switched = replace(settings, mode="gs", mip=True, alpha_clamp=True, transmittance_cutoff=True)
    np.testing.assert_allclose(ground_truth(scene, camera, switched, samples=3), truth, rtol=0, atol=1e-12)
    for switch, (stack, stack_camera) in (({"alpha_clamp": True}, _stack(opacity=1.0, count=1)),
                                          ({"transmittance_cutoff": True}, _stack()),
                                          ({"mip": True}, _stack())):
        exact = ground_truth(stack, stack_camera, settings, samples=1)
        np.testing.assert_allclose(ground_truth(stack, stack_camera, replace(settings, **switch), samples=1),
                                   exact, rtol=0, atol=1e-12)
        changed = render_reference(stack, stack_camera, replace(settings, **switch))
        assert np.abs(changed - exact).max() > 1e-5, switch  # the cut-off moves T by ~1e-4


def test_ground_truth_bands_equal_the_whole_image():
    scene = random_scene(n=150, seed=10)
    camera = replace(CAMERA, width=24, height=18, cx=11.3, cy=9.6)
    whole = ground_truth(scene, camera, samples=6)
    bands = 5 * 36 * camera.width  # 5 rows a band, a short last one
    np.testing.assert_allclose(ground_truth(scene, camera, samples=6, band_samples=bands), whole, rtol=0, atol=1e-14)
    bands = 1  # one row a band
    np.testing.assert_allclose(ground_truth(scene, camera, samples=6, band_samples=bands), whole, rtol=0, atol=1e-14)


def test_ground_truth_converges():
    scene = random_scene(n=200, seed=11, log_scale=(-5.0, -3.0))  # small gaussians alias
    camera = replace(CAMERA, width=32, height=24, cx=15.7, cy=12.2)
    truth = ground_truth(scene, camera, samples=16)
    near = np.abs(ground_truth(scene, camera, samples=8) - truth).max()
    coarse = np.abs(ground_truth(scene, camera, samples=1) - truth).max()
    assert near < 0.02 and coarse > 0.1 and coarse > 10 * near, (near, coarse)


def test_ground_truth_rejects_a_bad_sample_count():
    scene = random_scene(n=5)
    for samples in (0, -1, 2.0, True):
        with pytest.raises(ValueError):
            ground_truth(scene, CAMERA, samples=samples)


# --- robustness --------------------------------------------------------------------------

ALL_SETTINGS = {name: apply_preset(RenderSettings(), name) for name in ACCURACY_PRESETS} | {
    f"{mode}, parity switches": RenderSettings(mode=mode, alpha_clamp=True, transmittance_cutoff=True, mip_sigma2=2.0)
    for mode in ("raygs", "raygs-exact-mip", "gs")}


@pytest.mark.parametrize("name", sorted(ALL_SETTINGS))
def test_no_nan_in_any_mode(name, demo):
    settings = ALL_SETTINGS[name]
    views = [
        (random_scene(n=300, seed=12, anisotropy=3.0), CAMERA),
        (random_scene(n=300, seed=12, anisotropy=3.0),
         look_at([0.1, 0.05, -0.3], [0.2, 0.0, 1.0], width=32, height=24, fov_y_degrees=100)),
        (demo, demo_camera(48, 36)),
    ]
    for scene, camera in views:
        image = render_reference(scene, camera, settings)
        assert np.all(np.isfinite(image))
        assert image[..., 3].min() >= 0 and image[..., 3].max() <= 1 + 1e-12
        assert image[..., 3].max() > 0.3
