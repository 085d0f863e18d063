"""The reference renderer's per-fragment maths (float64), one model per render mode of
:class:`RenderSettings`: what opacity, and at what camera-space z, each gaussian has at
each sample ray (see :mod:`raygs_viewer.render.reference` for the modes and the maths
page sections they follow), and which pixels each gaussian can reach.

D is computed in the gaussian's whitened frame (y = S^-1 Rp^T x, w = S^-1 Rp^T mu)
as |y x w|^2 / |y|^2, which equals c^2 - (x^T S^-1 mu)^2 / (x^T S^-1 x) exactly
but does not cancel catastrophically when c^2 is huge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.render.settings import GS_DILATION, GS_NEAR, RenderSettings
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.sh import sh_to_rgb


@dataclass
class CameraGaussians:
    """The ordered gaussians in camera space (float64): mu (N, 3) centres, rotation
    (N, 3, 3) = Rp^T (camera space -> the gaussian's axes), scales s (N, 3), opacities o
    (N,), colours (N, 3) for the view, and normals (N, 3): each one's shortest axis in
    camera space (not yet turned to face a ray)."""

    mu: np.ndarray
    rotation: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    colors: np.ndarray
    normals: np.ndarray

    @classmethod
    def of(cls, scene: Scene, order: np.ndarray, camera: Camera,
           color_origin: np.ndarray | None = None) -> "CameraGaussians":
        """``color_origin``: the world point SH colour is seen from (None: the camera's
        centre; stereo and headset eyes see it from their midpoint, as the GL path does)."""
        positions = scene.positions[order].astype(np.float64)
        offsets = positions - camera.center  # world-space vectors camera -> centre
        seen = offsets if color_origin is None else positions - np.asarray(color_origin, np.float64)
        directions = seen / np.linalg.norm(seen, axis=1, keepdims=True).clip(1e-300)
        colors = sh_to_rgb(scene.sh[order].astype(np.float64), scene.sh_degree, directions)
        rotation = quaternion_to_matrix(scene.rotations[order].astype(np.float64)).transpose(0, 2, 1)
        rotation = rotation @ camera.R.T
        # Row a of Rp^T R^T is axis a of the gaussian in camera space. The shortest axis
        # is chosen on the stored float32 scales (first minimum on ties), as the GL path does.
        shortest = np.argmin(scene.scales[order], axis=1)
        normals = rotation[np.arange(len(order)), shortest]
        return cls(offsets @ camera.R.T, rotation, scene.scales[order].astype(np.float64),
                   scene.opacities[order].astype(np.float64), colors, normals)


def ray_length(rays: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...i,...i->...", rays, rays))


def peak_z(key: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """The camera-space z of the peak points t* = ``key`` (along the unit rays) on
    ``rays`` (..., 3) written with z = 1: t* times the unit ray's z, 1 / |ray|."""
    return key / ray_length(rays)


def _whitened_divergence(y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """D = |y x w|^2 / |y|^2 for rays y (..., 3) and a centre w (3,) or (..., 3) in a
    whitened frame; it does not depend on the rays' length."""
    y0, y1, y2 = y[..., 0], y[..., 1], y[..., 2]
    w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
    # The cross product written out (np.cross's own arithmetic, without its overhead).
    cross = np.stack((y1 * w2 - y2 * w1, y2 * w0 - y0 * w2, y0 * w1 - y1 * w0), axis=-1)
    return np.einsum("...i,...i->...", cross, cross) / np.einsum("...i,...i->...", y, y)


# --- RayGS, plain and with the pixel-invariant MIP filter (sections 3, 6) ---------------

class RayGS:
    """Per gaussian: the whitening S^-1 Rp^T, w = S^-1 Rp^T mu, c^2, kappa. With MIP the
    scales are s^2 + sigma_x^2 |mu|^2 (Eq. 17: the filter at the centre's distance) and,
    with modulation, the opacity scaled so the gaussian's total opacity is kept."""

    def __init__(self, g: CameraGaussians, camera: Camera, settings: RenderSettings):
        self.p_min = settings.p_min
        scales, opacities = g.scales, g.opacities
        if settings.mip:  # only reached in "raygs" mode
            sigma2 = settings.pixel_variance(camera)
            distance2 = np.einsum("ni,ni->n", g.mu, g.mu)
            filtered = np.sqrt(scales ** 2 + sigma2 * distance2[:, None])
            if settings.mip_modulation:
                # o * sqrt(|S| c^2 / (|S^| c^^2)) = o * prod(s / s^) * c / c^, as per-axis
                # ratios (each <= 1) so tiny scales cannot underflow a product.
                local = np.einsum("nij,nj->ni", g.rotation, g.mu)  # Rp^T mu
                c = np.linalg.norm(local / scales, axis=1)
                c_hat = np.linalg.norm(local / filtered, axis=1)
                # mu = 0: both vanish and the filter does nothing there (limit 1).
                ratio = np.divide(c, c_hat, out=np.ones_like(c), where=c_hat > 0)
                opacities = opacities * np.prod(scales / filtered, axis=1) * ratio
            scales = filtered
        self.opacities = opacities
        self.whiten = g.rotation / scales[:, :, None]
        self.w = np.einsum("nij,nj->ni", self.whiten, g.mu)
        c2 = np.einsum("ni,ni->n", self.w, self.w)
        with np.errstate(divide="ignore"):
            self.kappa = -2.0 * np.log(settings.p_min / opacities)
        self.drawn = np.flatnonzero((self.kappa > 0) & (c2 > self.kappa))
        self.boxes = support_boxes(camera, g, scales, self.kappa, self.drawn)

    def alpha(self, i: int, rays: np.ndarray, rows: slice, cols: slice, key: bool = False):
        """The opacity gaussian ``i`` has at each of ``rays``; with ``key``, also t* (its
        peak's distance along each unit ray: (y.w) / (y.y) for the ray of length |x|)."""
        y = rays @ self.whiten[i].T
        along = y @ self.w[i]
        alpha = self.opacities[i] * np.exp(-0.5 * _whitened_divergence(y, self.w[i]))
        alpha[(alpha < self.p_min) | (along <= 0)] = 0.0
        if key:
            return alpha, along / np.einsum("...i,...i->...", y, y) * ray_length(rays)
        return alpha

    def fragment(self, i: int, rays: np.ndarray, rows: slice, cols: slice) -> tuple[np.ndarray, np.ndarray]:
        """The opacity, and the camera-space z of the peak point, gaussian ``i`` has at
        each of ``rays`` (z = 1): t* on the unit ray times its z, 1 / |ray|."""
        alpha, key = self.alpha(i, rays, rows, cols, key=True)
        return alpha, peak_z(key, rays)


# --- RayGS with the exact, pixel-dependent MIP filter (Appendix A.5) ---------------------

class ExactMip:
    """Per pixel ray x (unit), in the gaussian's axes x' = Rp^T x: the peak's distance
    tau = (sum x'mu'/s^2) / (sum x'^2/s^2), the filtered scales s^2 + sigma_x^2 tau^2,
    D with them, and the per-pixel modulation root.

    Which pixels are drawn follows the GL path exactly: a quad bounds the kappa-support
    of a "big" ellipsoid whose scales hold every tau the support can reach, so a pixel
    is nonzero only where its ray meets that support (D_big <= kappa, peak in front)."""

    def __init__(self, g: CameraGaussians, camera: Camera, settings: RenderSettings):
        self.p_min, self.modulation = settings.p_min, settings.mip_modulation
        self.sigma2 = settings.pixel_variance(camera)
        self.g = g
        self.local = np.einsum("nij,nj->ni", g.rotation, g.mu)  # mu' = Rp^T mu
        with np.errstate(divide="ignore"):
            self.kappa = -2.0 * np.log(settings.p_min / g.opacities)  # the unmodulated o
        distance = np.linalg.norm(g.mu, axis=1)
        root_kappa = np.sqrt(np.maximum(self.kappa, 0.0))
        # The farthest peak inside the support: |mu| plus the support's radius, itself
        # measured with the filter at distance |mu|.
        tau_max = distance + root_kappa * np.sqrt(g.scales.max(axis=1) ** 2 + self.sigma2 * distance ** 2)
        self.big = np.sqrt(g.scales ** 2 + self.sigma2 * (tau_max ** 2)[:, None])
        self.w_big = self.local / self.big
        c2_big = np.einsum("ni,ni->n", self.w_big, self.w_big)
        self.drawn = np.flatnonzero((self.kappa > 0) & (c2_big > self.kappa))
        self.boxes = support_boxes(camera, g, self.big, self.kappa, self.drawn)

    def alpha(self, i: int, rays: np.ndarray, rows: slice, cols: slice, key: bool = False):
        """As :meth:`RayGS.alpha`; t* is the peak of this pixel's filtered gaussian."""
        s2 = self.g.scales[i] ** 2
        mu = self.local[i]
        x = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
        x = x @ self.g.rotation[i].T  # x' = Rp^T x
        along = x @ (mu / s2)
        weight = (x * x) @ (1 / s2)  # x^T Sigma^-1 x
        # tau <= 0: the peak is behind the camera; no filter there (tau = 0).
        tau = np.maximum(along / weight, 0.0)
        filtered2 = s2 + self.sigma2 * (tau ** 2)[..., None]
        filtered = np.sqrt(filtered2)
        divergence = _whitened_divergence(x / filtered, mu / filtered)
        alpha = self.g.opacities[i] * np.exp(-0.5 * divergence)
        if self.modulation:
            # sqrt(|S| x^T S^-1 x / (|S^| x^T S^^-1 x)), the determinants as per-axis ratios.
            weight_hat = (x * x / filtered2).sum(axis=-1)
            alpha *= np.sqrt(np.prod(s2 / filtered2, axis=-1) * (weight / weight_hat))
        # The GL quad covers the kappa-support of the big ellipsoid, in front of the camera.
        y_big = x / self.big[i]
        outside = ((_whitened_divergence(y_big, self.w_big[i]) > self.kappa[i])
                   | (y_big @ self.w_big[i] <= 0))
        alpha[(alpha < self.p_min) | outside] = 0.0
        if key:
            return alpha, (x * mu / filtered2).sum(axis=-1) / (x * x / filtered2).sum(axis=-1)
        return alpha

    def fragment(self, i: int, rays: np.ndarray, rows: slice, cols: slice) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`RayGS.fragment`, with this pixel's t*."""
        alpha, key = self.alpha(i, rays, rows, cols, key=True)
        return alpha, peak_z(key, rays)


# --- EWA splatting (section 7) -----------------------------------------------------------

class Splat:
    """INRIA's EWA splat: Sigma2 = J Sigma J^T at the centre, J the pinhole's Jacobian
    along a ray clamped to 15% beyond the image (as INRIA does, so off-screen centres do
    not blow up), plus GS_DILATION px^2; a 2D gaussian around the projected centre."""

    def __init__(self, g: CameraGaussians, camera: Camera, settings: RenderSettings):
        self.p_min = settings.p_min
        fx, fy, cx, cy, width, height = camera.fx, camera.fy, camera.cx, camera.cy, camera.width, camera.height
        x, y, z = g.mu.T
        self.z = z
        front = z > GS_NEAR  # the linearisation is undefined at z = 0
        z = np.where(front, z, 1.0)  # placeholders for skipped gaussians: no warnings
        rp = g.rotation.transpose(0, 2, 1)
        covariance = (rp * g.scales[:, None, :] ** 2) @ g.rotation  # Rp diag(s^2) Rp^T
        tx = np.clip(x / z, -cx / fx - 0.15 * width / fx, (width - cx) / fx + 0.15 * width / fx) * z
        ty = np.clip(y / z, -cy / fy - 0.15 * height / fy, (height - cy) / fy + 0.15 * height / fy) * z
        jacobian = np.zeros((len(z), 2, 3))
        jacobian[:, 0, 0] = fx / z
        jacobian[:, 0, 2] = -fx * tx / z ** 2
        jacobian[:, 1, 1] = fy / z
        jacobian[:, 1, 2] = -fy * ty / z ** 2
        sigma2 = jacobian @ covariance @ jacobian.transpose(0, 2, 1)
        self.a = sigma2[:, 0, 0] + GS_DILATION
        self.b = 0.5 * (sigma2[:, 0, 1] + sigma2[:, 1, 0])
        self.c = sigma2[:, 1, 1] + GS_DILATION
        self.det = self.a * self.c - self.b * self.b
        opacities = g.opacities
        if settings.gs_compensation:
            # Mip-Splatting: keep the splat's integral when the dilation widens it.
            det_undilated = sigma2[:, 0, 0] * sigma2[:, 1, 1] - self.b * self.b
            opacities = opacities * np.sqrt(np.maximum(det_undilated, 0.0) / self.det)
        self.opacities = opacities
        with np.errstate(divide="ignore"):
            kappa = -2.0 * np.log(settings.p_min / opacities)
        self.drawn = np.flatnonzero(front & (kappa > 0))
        self.u = fx * x / z + cx  # continuous pixel coordinates: pixel i spans [i, i+1)
        self.v = fy * y / z + cy
        # The kappa ellipse's bounding box; the per-pixel test decides coverage.
        kappa = np.maximum(kappa, 0.0)
        half_u, half_v = np.sqrt(kappa * self.a), np.sqrt(kappa * self.c)
        self.boxes = np.zeros((len(self.drawn), 4), np.int64)
        for k, (centre, half, size) in enumerate(((self.v, half_v, height), (self.u, half_u, width))):
            low = np.floor(np.clip(centre - half - 0.5, -1.0, size + 1.0)[self.drawn])
            high = np.ceil(np.clip(centre + half - 0.5, -1.0, size + 1.0)[self.drawn]) + 1
            self.boxes[:, 2 * k] = np.clip(low, 0, size)
            self.boxes[:, 2 * k + 1] = np.clip(high, 0, size)

    def alpha(self, i: int, rays: np.ndarray, rows: slice, cols: slice) -> np.ndarray:
        du = (np.arange(cols.start, cols.stop) + 0.5 - self.u[i])[None, :]
        dv = (np.arange(rows.start, rows.stop) + 0.5 - self.v[i])[:, None]
        # d^T Sigma2d^-1 d with the 2x2 inverse written out.
        power = (self.c[i] * du * du - 2 * self.b[i] * du * dv + self.a[i] * dv * dv) / self.det[i]
        alpha = self.opacities[i] * np.exp(-0.5 * power)
        alpha[alpha < self.p_min] = 0.0
        return alpha

    def fragment(self, i: int, rays: np.ndarray, rows: slice, cols: slice) -> tuple[np.ndarray, float]:
        """The opacity, and the z of the gaussian's centre (what the 3DGS renderer
        blends as depth), the same at every ray."""
        return self.alpha(i, rays, rows, cols), self.z[i]


MODELS = {"raygs": RayGS, "raygs-exact-mip": ExactMip, "gs": Splat}


# --- pixel bounds --------------------------------------------------------------------------

def support_boxes(camera: Camera, gaussians: CameraGaussians, scales: np.ndarray, kappa: np.ndarray,
                  drawn: np.ndarray) -> np.ndarray:
    """(len(drawn), 4) int64 rows start, stop, columns start, stop per drawn gaussian:
    pixels whose ray can meet its kappa-ellipsoid (p - mu)^T Sigma^-1 (p - mu) <= kappa,
    Sigma = Rp diag(scales^2) Rp^T (``gaussians``' camera-space centres mu and rotations
    Rp^T; ``scales`` (N, 3) the ones the model draws). A ray meets it exactly where
    D <= kappa (D is the least Mahalanobis distance^2 along the ray's line).

    The bounding sphere's box (:func:`_pixel_bounds`) is intersected with the ellipsoid's
    own projected box, which is much tighter for needles and pancakes (the reference's
    cost is the pixels it visits). Only an optimisation: the per-pixel test decides."""
    mu, rotation = gaussians.mu, gaussians.rotation
    boxes = np.zeros((len(drawn), 4), np.int64)
    radius = np.sqrt(np.maximum(kappa, 0.0)) * scales.max(axis=1)
    for k, i in enumerate(drawn):
        rows, cols = _pixel_bounds(camera, mu[i], radius[i])
        boxes[k] = rows.start, rows.stop, cols.start, cols.stop
    if len(drawn) == 0:
        return boxes
    rp = rotation[drawn].transpose(0, 2, 1)
    sigma = (rp * (scales[drawn] ** 2)[:, None, :]) @ rotation[drawn]
    kappa, (x, y, z) = kappa[drawn], mu[drawn].T
    # The plane through the camera {p_axis = a p_z} meets the ellipsoid iff
    # (mu_axis - a mu_z)^2 <= kappa n^T Sigma n with n = (e_axis - a e_z): a quadratic
    # A a^2 - 2 B a + C <= 0 whose roots bound the ray slopes a that can meet it. With
    # A > 0 the ellipsoid lies wholly in front of the camera plane and the set is the
    # interval between the roots; otherwise the sphere's box stands.
    a_zz = z * z - kappa * sigma[:, 2, 2]
    for k, (coordinate, focal, principal, size) in enumerate(((y, camera.fy, camera.cy, camera.height),
                                                               (x, camera.fx, camera.cx, camera.width))):
        axis = 1 - k
        b = coordinate * z - kappa * sigma[:, axis, 2]
        c = coordinate * coordinate - kappa * sigma[:, axis, axis]
        with np.errstate(invalid="ignore", divide="ignore"):
            root = np.sqrt(b * b - a_zz * c)
            low, high = (b - root) / a_zz, (b + root) / a_zz
        usable = (z > 0) & (a_zz > 0) & np.isfinite(low) & np.isfinite(high)
        # Slopes -> pixel centres, with a relative margin for rounding and the same
        # whole-pixel padding as the sphere's box.
        margin = 1e-6 * (np.abs(low) + np.abs(high) + 1.0)
        low = np.where(usable, focal * (low - margin) + principal - 0.5, -np.inf)
        high = np.where(usable, focal * (high + margin) + principal - 0.5, np.inf)
        start = np.floor(np.clip(low, -2.0, size + 2.0)) - 1
        stop = np.ceil(np.clip(high, -2.0, size + 2.0)) + 2
        boxes[:, 2 * k] = np.maximum(boxes[:, 2 * k], np.clip(start, 0, size).astype(np.int64))
        boxes[:, 2 * k + 1] = np.minimum(boxes[:, 2 * k + 1], np.clip(stop, 0, size).astype(np.int64))
    return boxes


def _pixel_bounds(camera: Camera, mu: np.ndarray, radius: float) -> tuple[slice, slice]:
    """Rows and columns that can see a peak inside the sphere (mu, radius); the whole
    image when the sphere reaches the camera plane. Only an optimisation: the
    per-pixel test decides coverage."""
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
