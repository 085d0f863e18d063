"""The accuracy options on GL against the float64 reference (every mode, MIP, the
parity switches, supersampling), and the behaviour each option exists for: MIP
removes aliasing, modulation keeps opacity, exact MIP is no worse than Eq. 17, EWA
splatting departs from RayGS near the camera."""


import numpy as np
import pytest
from testkit import assert_differs, assert_matches, make_scene, random_scene, sort_indices

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.render.reference import ground_truth, render_reference
from raygs_viewer.render.settings import ACCURACY_PRESETS, RenderSettings, apply_preset

FRONT = look_at([0.3, -0.2, -3.0], [0, 0, 0], width=96, height=72)
OFFAXIS = Camera(97, 61, 70.0, 55.0, 40.3, 35.7, look_at([1.0, 0.5, -2.5], [0, 0, 0]).R,
                 look_at([1.0, 0.5, -2.5], [0, 0, 0]).t)
INSIDE = look_at([0.1, 0.05, -0.6], [0.2, 0.0, 1.0], width=64, height=48, fov_y_degrees=90)

SWITCHES = {
    "alpha clamp": RenderSettings(alpha_clamp=True),
    "transmittance cut-off": RenderSettings(transmittance_cutoff=True),
    "both parity switches": RenderSettings(alpha_clamp=True, transmittance_cutoff=True),
    "cut-off, 2x2": RenderSettings(transmittance_cutoff=True, alpha_clamp=True, supersample=2),
    "3x3": RenderSettings(supersample=3),
    "MIP sigma^2 0.5": RenderSettings(mip=True, mip_sigma2=0.5),
    "exact MIP, no modulation": RenderSettings(mode="raygs-exact-mip", mip_modulation=False, mip_sigma2=0.5),
    "exact MIP 2x2": RenderSettings(mode="raygs-exact-mip", supersample=2),
    "GS + compensation, grey": RenderSettings(mode="gs", gs_compensation=True, background=(0.5, 0.5, 0.5)),
}
# The narrow blend presets have their own, stated error: test_precision.py.
CASES = {**{name: apply_preset(RenderSettings(), name) for name in ACCURACY_PRESETS
            if apply_preset(RenderSettings(), name).precision == "float32"}, **SWITCHES}


@pytest.fixture(scope="module")
def scene():
    # Small, thin and large gaussians: sub-pixel ones are where the filters act.
    return random_scene(n=400, seed=1, log_scale=(-6.0, -1.5), anisotropy=2.0)


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("camera", [FRONT, OFFAXIS, INSIDE], ids=["front", "offaxis", "inside"])
def test_gl_matches_reference_in_every_mode(gl_render, scene, name, camera):
    """"inside": the camera within the cloud, with gaussians beside and behind it, where
    GS's clamped linearisation and the filters' culling margins matter."""
    settings = CASES[name]
    reference = render_reference(scene, camera, settings)
    assert reference[..., 3].max() > 0.5
    assert_matches(gl_render(scene, camera, settings), reference)


@pytest.mark.parametrize("name", ["GS", "RayGS + MIP", "RayGS exact MIP", "RayGS 2x2 supersampling"])
def test_each_mode_is_its_own(gl_render, scene, name):
    """Negative control: every mode's GL image differs from plain RayGS's reference, so
    the comparisons above would catch a variant that silently rendered plain RayGS."""
    settings = apply_preset(RenderSettings(), name)
    assert_differs(gl_render(scene, FRONT, settings), render_reference(scene, FRONT))


def test_switches_change_the_image(gl_render):
    """The parity switches matter where opaque splats stack: the clamp lets 1 % of the
    layer behind through, and without the clamp the cut-off drops an opaque first layer
    (INRIA's loop stops before adding it)."""
    n = 6
    colors = np.where((np.arange(n) % 2)[:, None] == 0, [1.0, 0.1, 0.1], [0.1, 0.1, 1.0])
    scene = make_scene(np.column_stack([np.zeros(n), np.zeros(n), np.linspace(0.0, 1.0, n)]), [1.5, 1.5, 0.02],
                       opacities=1.0, colors=colors)
    camera = look_at([0, 0, -3.0], [0, 0, 0], width=48, height=36)
    plain = render_reference(scene, camera)
    for settings in (RenderSettings(alpha_clamp=True), RenderSettings(transmittance_cutoff=True)):
        image = gl_render(scene, camera, settings)
        assert_matches(image, render_reference(scene, camera, settings))
        assert_differs(image, plain)


@pytest.mark.parametrize("name", sorted(CASES))
def test_no_nan_in_any_mode(gl_render, name):
    """Hard views for every mode: the camera inside the cloud, gaussians straddling the
    camera plane and behind it."""
    scene = random_scene(n=300, seed=5, spread=1.0, log_scale=(-7.0, -0.5), anisotropy=3.0)
    for camera in (INSIDE, look_at([0, 0, 0], [0, 0, 1], width=40, height=30, fov_y_degrees=120)):
        image = gl_render(scene, camera, CASES[name])
        assert np.all(np.isfinite(image)), name


# -- what each option is for -----------------------------------------------------------

def _far_stripes():
    """High-frequency content seen from far away: rows of small gaussians whose spacing
    falls below a pixel, on a camera 1/4 the size of the one they were made for."""
    xs, ys = np.meshgrid(np.linspace(-1.0, 1.0, 60), np.linspace(-0.6, 0.6, 36))
    positions = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    colors = np.where(((np.arange(xs.size) // 60) % 2)[:, None] == 0, [1.0, 0.9, 0.2], [0.1, 0.2, 1.0])
    scene = make_scene(positions, [0.006, 0.006, 0.006], opacities=0.9, colors=colors)
    camera = look_at([0.05, 0.03, -6.0], [0.05, 0.03, 0.0], width=40, height=30, fov_y_degrees=30)
    return scene, camera


def _rgb_rmse(image, truth):
    return float(np.sqrt(np.mean((np.asarray(image, np.float64)[..., :3] - truth[..., :3]) ** 2)))


def test_mip_reduces_aliasing_far_away(gl_render):
    scene, camera = _far_stripes()
    truth = ground_truth(scene, camera, samples=8)
    errors = {name: _rgb_rmse(gl_render(scene, camera, apply_preset(RenderSettings(), name)), truth)
              for name in ("RayGS", "RayGS + MIP", "RayGS exact MIP", "RayGS 2x2 supersampling")}
    # Plain RayGS samples each pixel at one ray and aliases; the filters integrate.
    assert errors["RayGS + MIP"] < 0.5 * errors["RayGS"], errors
    assert errors["RayGS exact MIP"] < 0.5 * errors["RayGS"], errors
    assert errors["RayGS 2x2 supersampling"] < errors["RayGS"], errors


def test_exact_mip_at_least_as_accurate_as_the_approximation(gl_render):
    """Thin needles spanning a wide cone of rays are where Eq. 17's per-gaussian factor
    is least accurate (the paper, section 5); against the pixel-integrated ground truth
    the per-pixel filter does at least as well."""
    rng = np.random.default_rng(3)
    n = 150
    positions = rng.uniform([-1.0, -0.7, -0.2], [1.0, 0.7, 0.2], (n, 3))
    scales = np.column_stack([np.full(n, 0.35), np.full(n, 0.002), np.full(n, 0.002)])
    angles = rng.uniform(0, np.pi, n)
    rotations = np.column_stack([np.cos(angles / 2), np.zeros(n), np.zeros(n), np.sin(angles / 2)])
    scene = make_scene(positions, scales, rotations, opacities=rng.uniform(0.4, 0.9, n),
                       colors=rng.uniform(0.2, 1.0, (n, 3)))
    camera = look_at([0, 0, -5.0], [0, 0, 0], width=48, height=36, fov_y_degrees=35)
    truth = ground_truth(scene, camera, samples=8)
    approx = _rgb_rmse(gl_render(scene, camera, RenderSettings(mip=True)), truth)
    exact = _rgb_rmse(gl_render(scene, camera, RenderSettings(mode="raygs-exact-mip")), truth)
    plain = _rgb_rmse(gl_render(scene, camera), truth)
    assert exact <= approx * 1.02 and exact < plain, (exact, approx, plain)


def _one_gaussian_alpha(gl_render, scale_px, settings):
    """Summed alpha of one faint round gaussian of ``scale_px`` pixels at the image centre."""
    camera = look_at([0, 0, -4.0], [0, 0, 0], width=96, height=96, fov_y_degrees=40)
    scale = scale_px * 4.0 / camera.fx
    scene = make_scene([[0.0, 0.0, 0.0]], [scale, scale, scale], opacities=0.3)
    return float(gl_render(scene, camera, settings)[..., 3].sum())


@pytest.mark.parametrize("scale_px", [0.7, 4.0])
def test_modulation_keeps_total_opacity(gl_render, scale_px):
    """Dilation alone adds the filter's variance to the footprint, inflating the summed
    opacity by about (s^2 + sigma^2) / s^2; modulation scales opacity so the total stays
    that of the unfiltered gaussian."""
    sigma2 = 0.5
    plain = _one_gaussian_alpha(gl_render, scale_px, RenderSettings(p_min=1e-4))
    dilated = _one_gaussian_alpha(gl_render, scale_px, RenderSettings(p_min=1e-4, mip=True, mip_sigma2=sigma2,
                                                                      mip_modulation=False))
    modulated = _one_gaussian_alpha(gl_render, scale_px, RenderSettings(p_min=1e-4, mip=True, mip_sigma2=sigma2))
    inflation = (scale_px ** 2 + sigma2) / scale_px ** 2
    assert dilated / plain == pytest.approx(inflation, rel=0.03)
    assert modulated / plain == pytest.approx(1.0, abs=0.02)


def test_gs_departs_from_the_reference_near_the_camera(gl_render):
    """Far away the linearised projection is good and GS matches RayGS; near the camera,
    with gaussians large and off-axis on screen, GS's footprints stretch ("spikes") while
    RayGS still matches the float64 reference."""
    rng = np.random.default_rng(11)
    n = 40
    positions = rng.uniform([-0.6, -0.4, -0.1], [0.6, 0.4, 0.1], (n, 3))
    scales = np.exp(rng.uniform(np.log(0.03), np.log(0.15), (n, 3)))
    q = rng.normal(size=(n, 4))
    scene = make_scene(positions, scales, q / np.linalg.norm(q, axis=1, keepdims=True), opacities=0.8,
                       colors=rng.uniform(0.2, 1.0, (n, 3)))
    far = look_at([0, 0, -30.0], [0, 0, 0], width=64, height=48, fov_y_degrees=4)
    near = look_at([0.05, 0.02, -0.45], [0.05, 0.02, 0.0], width=64, height=48, fov_y_degrees=100)
    gs = RenderSettings(mode="gs")
    for camera in (far, near):
        reference = render_reference(scene, camera)
        assert_matches(gl_render(scene, camera), reference)
    far_error = np.abs(gl_render(scene, far, gs) - render_reference(scene, far))
    near_error = np.abs(gl_render(scene, near, gs) - render_reference(scene, near))
    # Far: the 0.3 px^2 dilation softens edges, and that is all (measured: mean 0.007,
    # 0.5 % of pixels off by over 0.1). Near: a quarter of the image is off by over 0.1.
    assert far_error.mean() < 0.01 and (far_error.max(axis=-1) > 0.1).mean() < 0.01
    assert near_error.mean() > 0.03 and (near_error.max(axis=-1) > 0.1).mean() > 0.15


def test_supersampling_is_a_box_filter_of_the_bigger_render(gl_render, scene):
    k = 3
    image = gl_render(scene, FRONT, RenderSettings(supersample=k))
    big = gl_render(scene, FRONT.resized(FRONT.width * k, FRONT.height * k))
    blocks = big.reshape(FRONT.height, k, FRONT.width, k, 4).mean(axis=(1, 3))
    np.testing.assert_allclose(image, blocks, atol=2e-6)
    with pytest.raises(AssertionError):  # the blocks must be the image's own pixels, not shifted
        np.testing.assert_allclose(image[:, 1:], blocks[:, :-1], atol=1e-3)



@pytest.mark.parametrize("settings", [RenderSettings(mip=True, mip_sigma2=4.0, mip_modulation=False),
                                      RenderSettings(mode="raygs-exact-mip", mip_sigma2=4.0, mip_modulation=False),
                                      RenderSettings(mode="gs")], ids=["mip", "exact-mip", "gs"])
def test_culling_keeps_what_a_filter_spreads_into_view(gl_render, settings):
    """Tiny gaussians just outside the image, widened by the filter (or EWA's footprint)
    into it: the culled GL render equals the reference drawing every gaussian in front
    of the camera plane."""
    from raygs_viewer.sort.depth import DepthSorter
    rng = np.random.default_rng(4)
    n = 600
    positions = np.column_stack([rng.uniform(-2.2, 2.2, n), rng.uniform(-1.7, 1.7, n), rng.uniform(-0.3, 0.3, n)])
    scene = make_scene(positions, 0.002, opacities=0.9, colors=rng.uniform(0.2, 1.0, (n, 3)))
    camera = look_at([0, 0, -4.0], [0, 0, 0], width=64, height=48, fov_y_degrees=30)
    everything = sort_indices(DepthSorter(scene), camera, settings.p_min, dilation=None)
    culled = sort_indices(DepthSorter(scene), camera, settings.p_min, dilation=settings.cull_dilation(camera))
    if settings.mode != "gs":
        assert culled.size < everything.size  # the test exercises the cull
    assert_matches(gl_render(scene, camera, settings), render_reference(scene, camera, settings, order=everything))
