"""The float64 reference renderer: the oracle of the tests, the CPU baseline of benchmarks.

Per pixel and per gaussian it evaluates section 3 of the maths page directly:
the opacity a pixel sees is ``o * exp(-D/2)`` with D the ray's divergence, zero
where that is below p_min, where the peak lies behind the camera (the
rasterizer draws only the part of the quad in front of it) or where the
gaussian is skipped (kappa <= 0, or the camera inside the support, c^2 <= kappa).
Gaussians are composited back to front in the sorter's order, like the GL path.

D is computed in the gaussian's whitened frame (y = S^-1 Rp^T x, w = S^-1 Rp^T mu)
as |y x w|^2 / |y|^2, which equals c^2 - (x^T S^-1 mu)^2 / (x^T S^-1 x) exactly
but does not cancel catastrophically when c^2 is huge.
"""

from __future__ import annotations

import math

import numpy as np

from raygs_viewer.camera import Camera
from raygs_viewer.scene import Scene, quaternion_to_matrix
from raygs_viewer.settings import RenderSettings
from raygs_viewer.sh import sh_to_rgb
from raygs_viewer.sorting import DepthSorter


def render_reference(scene: Scene, camera: Camera, settings: RenderSettings = RenderSettings(),
                     order: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 4) float64 image: RGB composited over the background, and accumulated alpha.

    ``order`` (indices, back to front) defaults to the sorter's order for this camera.
    """
    if order is None:
        order = DepthSorter(scene).order(camera, settings.p_min)
    order = np.asarray(order, dtype=np.int64)
    scene = scene.with_sh_degree(settings.effective_sh_degree(scene.sh_degree))
    height, width = camera.height, camera.width
    image = np.zeros((height, width, 4))
    image[..., :3] = settings.background
    if order.size == 0:
        return image

    positions = scene.positions[order].astype(np.float64)
    scales = scene.scales[order].astype(np.float64)
    opacities = scene.opacities[order].astype(np.float64)
    center = camera.center
    offsets = positions - center  # world-space vectors camera -> centre
    directions = offsets / np.linalg.norm(offsets, axis=1, keepdims=True).clip(1e-300)
    colors = sh_to_rgb(scene.sh[order].astype(np.float64), scene.sh_degree, directions)
    # Whitening maps camera-space vectors into each gaussian's frame: S^-1 Rq^T R^T.
    whiten = quaternion_to_matrix(scene.rotations[order].astype(np.float64)).transpose(0, 2, 1)
    whiten = whiten @ camera.R.T / scales[:, :, None]
    mu = offsets @ camera.R.T
    w = np.einsum("nij,nj->ni", whiten, mu)
    c2 = np.einsum("ni,ni->n", w, w)
    with np.errstate(divide="ignore"):
        kappa = -2.0 * np.log(settings.p_min / opacities)
    drawn = (kappa > 0) & (c2 > kappa)

    rays = camera.pixel_rays()
    radius = np.sqrt(np.maximum(kappa, 0.0)) * scales.max(axis=1)
    for i in np.flatnonzero(drawn):
        rows, cols = _pixel_bounds(camera, mu[i], radius[i])
        if rows.start >= rows.stop or cols.start >= cols.stop:
            continue
        y = rays[rows, cols] @ whiten[i].T
        along = y @ w[i]
        divergence = np.einsum("hwi,hwi->hw", *(np.cross(y, w[i]),) * 2) / np.einsum("hwi,hwi->hw", y, y)
        alpha = opacities[i] * np.exp(-0.5 * divergence)
        alpha[(alpha < settings.p_min) | (along <= 0)] = 0.0
        block = image[rows, cols]
        block[..., :3] = alpha[..., None] * colors[i] + (1 - alpha[..., None]) * block[..., :3]
        block[..., 3] = alpha + (1 - alpha) * block[..., 3]
        image[rows, cols] = block
    return image


def _pixel_bounds(camera: Camera, mu: np.ndarray, radius: float) -> tuple[slice, slice]:
    """Rows and columns that can see a peak inside the sphere (mu, radius); the whole
    image when the sphere reaches the camera plane. Only an optimisation: the
    per-pixel test above decides coverage."""
    x, y, z = mu
    if z - radius <= 1e-9 * max(1.0, abs(z)):
        return slice(0, camera.height), slice(0, camera.width)
    # x'/z' over the box around the sphere is extreme at the box's corners.
    def span(coordinate: float, focal: float, principal: float, size: int) -> slice:
        ratios = [(coordinate + sx * radius) / (z + sz * radius) for sx in (-1, 1) for sz in (-1, 1)]
        low = math.floor(focal * min(ratios) + principal - 0.5) - 1
        high = math.ceil(focal * max(ratios) + principal - 0.5) + 2
        return slice(int(min(max(low, 0), size)), int(min(max(high, 0), size)))
    return span(y, camera.fy, camera.cy, camera.height), span(x, camera.fx, camera.cx, camera.width)
