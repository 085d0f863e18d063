"""Section 4's quad contains every ray of the support, and Eq. 16 on it is section 3's D.

Two checks: the construction itself in float64 (written out here, independently of
the shader) over random and extreme gaussians; and the quads the GL preprocessing
pass really produces, read back from the GPU.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from testkit import random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.sh import sh_to_rgb


def quad64(mu, rotation, scales, kappa):
    """Section 4 in float64: returns (w, c2, frame (3x2 in the whitened frame), U, r)."""
    w = rotation.T @ mu / scales
    c2 = w @ w
    m = w / np.sqrt(c2)
    b = np.sqrt(1 - kappa / c2)
    sigma = 1.0 if m[2] >= 0 else -1.0
    h = m + sigma * np.array([0.0, 0.0, 1.0])
    R = (2 * np.outer(h, h) / (h @ h) - np.eye(3)) @ np.diag([sigma, 1.0, sigma])
    frame = R[:, :2]
    Q2 = rotation @ np.diag(scales) @ frame
    B = Q2.T @ Q2
    eigenvalues, eigenvectors = np.linalg.eigh(B)
    u1 = eigenvectors[:, 1]
    U = np.column_stack([[-u1[1], u1[0]], u1])
    return w, c2, frame, U, np.sqrt(kappa) / b, R


def support_rays(w, kappa, rng, count):
    """Whitened directions of rays whose divergence is <= kappa: through a point of the
    ball of radius sqrt(kappa) around w (its surface included)."""
    offsets = rng.normal(size=(count, 3))
    offsets /= np.linalg.norm(offsets, axis=1, keepdims=True)
    radii = np.sqrt(kappa) * np.concatenate([np.ones(count // 4), rng.uniform(0, 1, count - count // 4) ** (1 / 3)])
    return w + offsets * radii[:, None]


log_scale = st.floats(-12.0, 2.0)


@settings(max_examples=300, deadline=None)
@given(
    scales=st.tuples(log_scale, log_scale, log_scale),
    quaternion=st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: sum(v * v for v in q) > 1e-3),
    direction=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda d: sum(v * v for v in d) > 1e-3),
    log_distance=st.floats(-2.0, 4.0),
    opacity=st.floats(0.01, 1.0),
    seed=st.integers(0, 2**31),
)
def test_quad_contains_the_support_float64(scales, quaternion, direction, log_distance, opacity, seed):
    scales = np.exp(np.array(scales))
    q = np.array(quaternion) / np.linalg.norm(quaternion)
    rotation = quaternion_to_matrix(q[None])[0]
    mu = np.array(direction) / np.linalg.norm(direction) * 10.0 ** log_distance
    kappa = -2 * np.log((1 / 255) / opacity)
    w = rotation.T @ mu / scales
    if kappa <= 0 or w @ w <= kappa * (1 + 1e-9):
        return  # skipped gaussians draw no quad
    w, c2, frame, U, r, R = quad64(mu, rotation, scales, kappa)
    np.testing.assert_allclose(R @ [0, 0, 1], w / np.sqrt(c2), atol=1e-12)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    rays = support_rays(w, kappa, np.random.default_rng(seed), 64)
    normal = w / np.sqrt(c2)
    hits = rays * (np.sqrt(c2) / (rays @ normal))[:, None]  # on the plane through w, normal to it
    in_square = (hits - w) @ frame @ U  # quad coordinates z, corners at (+-r, +-r)
    assert np.all(rays @ normal > 0), "support rays meet the plane in front"
    assert np.all(np.abs(in_square) <= r * (1 + 1e-9)), "a support ray misses the quad"
    # Eq. 16 on the quad equals section 3's divergence of the ray.
    r2 = np.einsum("ni,ni->n", in_square, in_square)
    divergence = np.einsum("ni,ni->n", *(np.cross(rays, w),) * 2) / np.einsum("ni,ni->n", rays, rays)
    # The rays themselves are w + (offset of size sqrt(kappa)) in float64: far away (c up to
    # ~1e8) the offset only carries eps * c absolute, so both sides are that uncertain.
    rtol = max(1e-7, 64 * np.finfo(float).eps * np.sqrt(c2 / kappa))
    np.testing.assert_allclose(r2 / (1 + r2 / c2), divergence, rtol=rtol, atol=1e-9 * kappa)
    assert np.all(divergence <= kappa * (1 + 1e-9))


def test_gl_quads_contain_the_support(gl_ctx):
    """The quads the preprocessing shader writes (float32) hold every support ray, and
    their coordinate gives the ray's divergence."""
    scene = random_scene(n=200, seed=7, log_scale=(-5.0, -1.0), anisotropy=3.0)
    camera = look_at([0.2, -0.3, -2.5], [0, 0, 0], width=64, height=48)
    settings_ = RenderSettings()
    renderer = GLRenderer(gl_ctx, scene)
    try:
        renderer.preprocess(camera, renderer.plan(settings_))
        splats = renderer.read_splats().astype(np.float64)
    finally:
        renderer.release()
    rng = np.random.default_rng(0)
    mu_all = (scene.positions - camera.center) @ camera.R.T
    rotations = camera.R @ quaternion_to_matrix(scene.rotations.astype(np.float64))
    offsets = scene.positions.astype(np.float64) - camera.center
    colors = sh_to_rgb(scene.sh.astype(np.float64), scene.sh_degree,
                       offsets / np.linalg.norm(offsets, axis=1, keepdims=True))
    checked = 0
    for i in range(scene.count):
        center, c2 = splats[i, 0:3], splats[i, 3]
        axis0, half, axis1, opacity = splats[i, 4:7], splats[i, 7], splats[i, 8:11], splats[i, 11]
        kappa = float(-2 * np.log(settings_.p_min / scene.opacities[i]))
        w = rotations[i].T @ mu_all[i] / scene.scales[i]
        if kappa <= 0 or w @ w <= kappa:
            assert c2 == 0, "skipped gaussians are flagged"
            continue
        np.testing.assert_allclose(center, mu_all[i], rtol=1e-5, atol=1e-6)
        assert opacity == scene.opacities[i]
        np.testing.assert_allclose(splats[i, 12:15], colors[i], rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(c2, w @ w, rtol=1e-4)
        whitened = support_rays(w, kappa, rng, 32)
        rays = whitened * scene.scales[i] @ rotations[i].T  # back to camera space
        # Solve center + a axis0 + b axis1 = t ray for (a, b, t).
        for ray, y in zip(rays, whitened):
            a, b, t = np.linalg.solve(np.column_stack([axis0, axis1, -ray]), -center)
            assert t > 0
            assert max(abs(a), abs(b)) <= 1 + 1e-3, (i, a, b)
            r2 = half * half * (a * a + b * b)
            divergence = np.sum(np.cross(y, w) ** 2) / (y @ y)
            assert r2 / (1 + r2 / c2) == pytest.approx(divergence, rel=2e-3, abs=2e-3 * kappa)
        checked += 1
    assert checked > 150
