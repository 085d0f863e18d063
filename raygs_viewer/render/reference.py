"""The float64 reference renderer: the oracle of the tests, the CPU baseline of benchmarks.

Per pixel and per gaussian it evaluates the maths page directly, in every render mode
of :class:`RenderSettings`:

- "raygs" (section 3): the opacity a pixel sees is ``o * exp(-D/2)`` with D the ray's
  divergence, zero where that is below p_min, where the peak lies behind the camera
  (the rasterizer draws only the part of the quad in front of it) or where the
  gaussian is skipped (kappa <= 0, or the camera inside the support, c^2 <= kappa).
  With ``mip`` on, the pixel-invariant MIP filter of Eq. 17 first widens the scales
  (and, with ``mip_modulation``, lowers the opacity) per gaussian (section 6).
- "raygs-exact-mip" (section 6, Appendix A.5): the filter's width follows each ray's
  distance to its peak, so scales and modulation are per pixel.
- "gs" (section 7): EWA splatting, the linearised projection INRIA trains with.

Gaussians are composited back to front in the sorter's order, like the GL path, or
front to back with INRIA's transmittance cut-off (section 10). Supersampling renders
k x k samples per pixel with a k-times larger camera and averages them (a box filter).

D is computed in the gaussian's whitened frame (y = S^-1 Rp^T x, w = S^-1 Rp^T mu)
as |y x w|^2 / |y|^2, which equals c^2 - (x^T S^-1 mu)^2 / (x^T S^-1 x) exactly
but does not cancel catastrophically when c^2 is huge.

Memory: the image is rendered in horizontal bands of about BAND_SAMPLES samples
(pixel rays and per-gaussian temporaries exist for one band at a time), so
:func:`ground_truth` at 16 x 16 samples per pixel stays bounded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.render.ray_order import Fragments, composite_per_pixel
from raygs_viewer.render.settings import (
    ALPHA_CLAMP,
    GS_DILATION,
    GS_NEAR,
    TRANSMITTANCE_CUTOFF,
    RenderSettings,
)
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.sh import sh_to_rgb
from raygs_viewer.sort.depth import DepthSorter

#: Samples (pixels of the rendered, supersampled image) per band: bounds peak memory
#: to a few hundred MB even when one gaussian covers a whole band.
BAND_SAMPLES = 1 << 20
#: Per-pixel order keeps a band's fragments (tens per sample in real scenes) at once:
#: its bands hold this many times fewer samples.
PER_PIXEL_BAND_DIVISOR = 16


def render_reference(scene: Scene, camera: Camera, settings: RenderSettings = RenderSettings(),
                     order: np.ndarray | str | None = None) -> np.ndarray:
    """(H, W, 4) float64 image: RGB composited over the background, and accumulated alpha.

    ``order``: the global order (indices, back to front), by default the sorter's for
    this camera with ``settings.sort_key``, culled with the settings' filter dilation;
    or the name of an order mode (one of ORDERS), short for ``settings`` with that
    ``order``. Every field of ``settings`` is honoured; with ``supersample`` k the image
    is the k x k block mean of the image rendered with ``camera.resized(k W, k H)``.
    Per-pixel order composites each pixel by t* (:mod:`raygs_viewer.render.ray_order`);
    its window (``order_k``) is fed in the global order.
    """
    if isinstance(order, str):
        settings, order = replace(settings, order=order), None
    if order is None:
        order = global_order(scene, camera, settings)
    return _render(scene, camera, settings, order, settings.supersample, BAND_SAMPLES)


def global_order(scene: Scene, camera: Camera, settings: RenderSettings) -> np.ndarray:
    """(M,) uint32 back to front: the sorter's order for ``camera`` with the settings'
    key, culled with their filter dilation (what the GL path draws)."""
    return DepthSorter(scene).order(camera, settings.p_min, dilation=settings.cull_dilation(camera),
                                    key=settings.sort_key)


def ground_truth(scene: Scene, camera: Camera, settings: RenderSettings = RenderSettings(),
                 samples: int = 8, *, order: str | None = None, band_samples: int = BAND_SAMPLES) -> np.ndarray:
    """(H, W, 4) float64: exact RayGS (no MIP filter, no alpha clamp, no cut-off)
    integrated over each pixel's area with ``samples`` x ``samples`` samples (a box
    filter); p_min, background and SH degree come from ``settings``, and the order mode
    from ``order`` (default ``settings.order``; "per-pixel" is always exact here, every
    ray composited by t*). ``samples`` may exceed the renderers' MAX_SUPERSAMPLE; memory
    stays about one band's (``band_samples`` samples, :data:`BAND_SAMPLES` unless given)."""
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ValueError(f"samples must be a whole number >= 1, got {samples!r}")
    exact = replace(settings, mode="raygs", mip=False, supersample=1, alpha_clamp=False,
                    transmittance_cutoff=False, order=order or settings.order, order_k=0)
    return _render(scene, camera, exact, global_order(scene, camera, exact), samples, band_samples)


# --- the render loop shared by every mode ------------------------------------------------

def _render(scene: Scene, camera: Camera, settings: RenderSettings, order, samples: int,
            band_samples: int) -> np.ndarray:
    """``render_reference`` with an explicit sample count per axis (``settings.supersample``
    is ignored), so ground truth can go past the settings' limit, in bands of about
    ``band_samples`` samples."""
    order = np.asarray(order, dtype=np.int64)
    scene = scene.with_sh_degree(settings.effective_sh_degree(scene.sh_degree))
    height, width = camera.height, camera.width
    image = np.zeros((height, width, 4))
    image[..., :3] = settings.background
    if order.size == 0:
        return image

    # Only the intrinsics change with supersampling: fx, cx scale by k, so sample i of
    # pixel u sits at u + (i + 0.5) / k. Every pixel-unit quantity (MIP variance, GS
    # dilation and clamping) refers to this rendered camera.
    rendered = camera if samples == 1 else camera.resized(samples * width, samples * height)
    gaussians = _Gaussians.of(scene, order, camera)
    model = _MODELS[settings.mode](gaussians, rendered, settings)

    # Bands of whole output rows, so each band's block mean is complete. Per-pixel order
    # holds every fragment of a band at once: smaller bands.
    if settings.per_pixel:
        band_samples = max(1, band_samples // PER_PIXEL_BAND_DIVISOR)
    rows_per_band = max(1, band_samples // (samples * samples * width))
    for top in range(0, height, rows_per_band):
        bottom = min(height, top + rows_per_band)
        band = _composite(model, gaussians.colors, rendered, settings, top * samples, bottom * samples, order)
        if samples > 1:
            band = band.reshape(bottom - top, samples, width, samples, 4).mean(axis=(1, 3))
        image[top:bottom] = band
    return image


@dataclass
class _Gaussians:
    """The ordered gaussians in camera space (float64): mu centres, rotation = Rp^T
    (camera space -> the gaussian's axes), scales s, opacities o, colours for the view."""

    mu: np.ndarray
    rotation: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    colors: np.ndarray

    @classmethod
    def of(cls, scene: Scene, order: np.ndarray, camera: Camera) -> "_Gaussians":
        positions = scene.positions[order].astype(np.float64)
        offsets = positions - camera.center  # world-space vectors camera -> centre
        directions = offsets / np.linalg.norm(offsets, axis=1, keepdims=True).clip(1e-300)
        colors = sh_to_rgb(scene.sh[order].astype(np.float64), scene.sh_degree, directions)
        rotation = quaternion_to_matrix(scene.rotations[order].astype(np.float64)).transpose(0, 2, 1)
        rotation = rotation @ camera.R.T
        return cls(offsets @ camera.R.T, rotation, scene.scales[order].astype(np.float64),
                   scene.opacities[order].astype(np.float64), colors)


def _band_rays(camera: Camera, top: int, bottom: int) -> np.ndarray:
    """(bottom - top, W, 3) rays (z = 1) of rows top..bottom-1: ``camera.pixel_rays()[top:bottom]``
    computed for those rows only (the same numbers, bit for bit)."""
    u = (np.arange(camera.width) + 0.5 - camera.cx) / camera.fx
    v = (np.arange(top, bottom) + 0.5 - camera.cy) / camera.fy
    rays = np.empty((bottom - top, camera.width, 3))
    rays[..., 0] = u[None, :]
    rays[..., 1] = v[:, None]
    rays[..., 2] = 1.0
    return rays


def _composite(model, colors: np.ndarray, camera: Camera, settings: RenderSettings,
               top: int, bottom: int, scene_index: np.ndarray) -> np.ndarray:
    """(bottom - top, W, 4) RGBA of rows top..bottom-1 of ``camera``'s image;
    ``scene_index``: each ordered gaussian's index in the scene (per-pixel ties)."""
    rays = _band_rays(camera, top, bottom)
    # Only gaussians whose pixel box meets the band.
    boxes = model.boxes
    meets = np.flatnonzero((boxes[:, 0] < bottom) & (boxes[:, 1] > top)
                           & (boxes[:, 0] < boxes[:, 1]) & (boxes[:, 2] < boxes[:, 3]))

    def fragments(sequence):
        """(index, rows, cols, alpha) per gaussian box, rows relative to the band."""
        for j in sequence:
            r0, r1, c0, c1 = boxes[j]
            r0, r1 = max(r0, top), min(r1, bottom)
            rows, cols = slice(r0, r1), slice(c0, c1)
            i = model.drawn[j]
            alpha = model.alpha(i, rays[r0 - top:r1 - top, cols], rows, cols)
            if settings.alpha_clamp:  # after the p_min test, as INRIA does
                np.minimum(alpha, ALPHA_CLAMP, out=alpha)
            yield i, slice(r0 - top, r1 - top), cols, alpha

    band = np.zeros((bottom - top, camera.width, 4))
    if settings.per_pixel:
        return _composite_per_pixel(model, colors, rays, boxes, meets, settings, top, bottom, scene_index)
    if not settings.transmittance_cutoff:
        # Back to front, "over" blending of premultiplied fragments, as the GL path does.
        band[..., :3] = settings.background
        for i, rows, cols, alpha in fragments(meets):
            block = band[rows, cols]
            block[..., :3] = alpha[..., None] * colors[i] + (1 - alpha[..., None]) * block[..., :3]
            block[..., 3] = alpha + (1 - alpha) * block[..., 3]
        return band

    # Front to back with INRIA's rule: a fragment that would take the transmittance
    # below the cut-off ends the pixel, itself not drawn.
    color = np.zeros((bottom - top, camera.width, 3))
    transmittance = np.ones((bottom - top, camera.width))
    done = np.zeros((bottom - top, camera.width), dtype=bool)
    for i, rows, cols, alpha in fragments(meets[::-1]):
        t, finished = transmittance[rows, cols], done[rows, cols]  # views, updated in place
        active = (alpha > 0) & ~finished
        after = t * (1 - alpha)
        stop = active & (after < TRANSMITTANCE_CUTOFF)
        finished |= stop
        take = active & ~stop
        color[rows, cols] += np.where(take, t * alpha, 0.0)[..., None] * colors[i]
        t[take] = after[take]
    band[..., :3] = color + transmittance[..., None] * np.asarray(settings.background)
    band[..., 3] = 1 - transmittance
    return band


def _composite_per_pixel(model, colors: np.ndarray, rays: np.ndarray, boxes: np.ndarray, meets: np.ndarray,
                         settings: RenderSettings, top: int, bottom: int, scene_index: np.ndarray) -> np.ndarray:
    """(bottom - top, W, 4): the band composited per pixel by t* (exactly, or through the
    settings' window), from every fragment with alpha > 0."""
    height, width = bottom - top, rays.shape[1]
    columns = np.arange(width)
    parts = []
    for j in meets:
        r0, r1, c0, c1 = boxes[j]
        r0, r1 = max(r0, top), min(r1, bottom)
        i = model.drawn[j]
        alpha, key = model.alpha(i, rays[r0 - top:r1 - top, c0:c1], slice(r0, r1), slice(c0, c1), key=True)
        if settings.alpha_clamp:
            np.minimum(alpha, ALPHA_CLAMP, out=alpha)
        rows, cols = np.nonzero(alpha > 0)
        if rows.size == 0:
            continue
        count = rows.size
        parts.append(((rows + (r0 - top)) * width + columns[c0:c1][cols], key[rows, cols],
                      np.full(count, scene_index[i], np.int64), np.full(count, i, np.int64),
                      alpha[rows, cols], np.broadcast_to(colors[i], (count, 3))))
    cutoff = TRANSMITTANCE_CUTOFF if settings.transmittance_cutoff else None
    image = composite_per_pixel(Fragments.concatenate(parts), height * width, settings.background,
                                window=settings.order_k, cutoff=cutoff)
    return image.reshape(height, width, 4)


def _ray_length(rays: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("...i,...i->...", rays, rays))


def _whitened_divergence(y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """D = |y x w|^2 / |y|^2 for rays y (..., 3) and a centre w (3,) or (..., 3) in a
    whitened frame; it does not depend on the rays' length."""
    y0, y1, y2 = y[..., 0], y[..., 1], y[..., 2]
    w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
    # The cross product written out (np.cross's own arithmetic, without its overhead).
    cross = np.stack((y1 * w2 - y2 * w1, y2 * w0 - y0 * w2, y0 * w1 - y1 * w0), axis=-1)
    return np.einsum("...i,...i->...", cross, cross) / np.einsum("...i,...i->...", y, y)


# --- RayGS, plain and with the pixel-invariant MIP filter (sections 3, 6) ---------------

class _RayGS:
    """Per gaussian: the whitening S^-1 Rp^T, w = S^-1 Rp^T mu, c^2, kappa. With MIP the
    scales are s^2 + sigma_x^2 |mu|^2 (Eq. 17: the filter at the centre's distance) and,
    with modulation, the opacity scaled so the gaussian's total opacity is kept."""

    def __init__(self, g: _Gaussians, camera: Camera, settings: RenderSettings):
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
        self.boxes = _support_boxes(camera, g.mu, g.rotation, scales, self.kappa, self.drawn)

    def alpha(self, i: int, rays: np.ndarray, rows: slice, cols: slice, key: bool = False):
        """The opacity gaussian ``i`` has at each of ``rays``; with ``key``, also t* (its
        peak's distance along each unit ray: (y.w) / (y.y) for the ray of length |x|)."""
        y = rays @ self.whiten[i].T
        along = y @ self.w[i]
        alpha = self.opacities[i] * np.exp(-0.5 * _whitened_divergence(y, self.w[i]))
        alpha[(alpha < self.p_min) | (along <= 0)] = 0.0
        if key:
            return alpha, along / np.einsum("...i,...i->...", y, y) * _ray_length(rays)
        return alpha


# --- RayGS with the exact, pixel-dependent MIP filter (Appendix A.5) ---------------------

class _ExactMip:
    """Per pixel ray x (unit), in the gaussian's axes x' = Rp^T x: the peak's distance
    tau = (sum x'mu'/s^2) / (sum x'^2/s^2), the filtered scales s^2 + sigma_x^2 tau^2,
    D with them, and the per-pixel modulation root.

    Which pixels are drawn follows the GL path exactly: a quad bounds the kappa-support
    of a "big" ellipsoid whose scales hold every tau the support can reach, so a pixel
    is nonzero only where its ray meets that support (D_big <= kappa, peak in front)."""

    def __init__(self, g: _Gaussians, camera: Camera, settings: RenderSettings):
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
        self.boxes = _support_boxes(camera, g.mu, g.rotation, self.big, self.kappa, self.drawn)

    def alpha(self, i: int, rays: np.ndarray, rows: slice, cols: slice, key: bool = False):
        """As :meth:`_RayGS.alpha`; t* is the peak of this pixel's filtered gaussian."""
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


# --- EWA splatting (section 7) -----------------------------------------------------------

class _Splat:
    """INRIA's EWA splat: Sigma2 = J Sigma J^T at the centre, J the pinhole's Jacobian
    along a ray clamped to 15% beyond the image (as INRIA does, so off-screen centres do
    not blow up), plus GS_DILATION px^2; a 2D gaussian around the projected centre."""

    def __init__(self, g: _Gaussians, camera: Camera, settings: RenderSettings):
        self.p_min = settings.p_min
        fx, fy, cx, cy, width, height = camera.fx, camera.fy, camera.cx, camera.cy, camera.width, camera.height
        x, y, z = g.mu.T
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


_MODELS = {"raygs": _RayGS, "raygs-exact-mip": _ExactMip, "gs": _Splat}


# --- pixel bounds --------------------------------------------------------------------------

def _support_boxes(camera: Camera, mu: np.ndarray, rotation: np.ndarray, scales: np.ndarray,
                   kappa: np.ndarray, drawn: np.ndarray) -> np.ndarray:
    """(len(drawn), 4) int64 rows start, stop, columns start, stop per drawn gaussian:
    pixels whose ray can meet its kappa-ellipsoid (p - mu)^T Sigma^-1 (p - mu) <= kappa,
    Sigma = Rp diag(scales^2) Rp^T (``rotation`` is Rp^T). A ray meets it exactly where
    D <= kappa (D is the least Mahalanobis distance^2 along the ray's line).

    The bounding sphere's box (:func:`_pixel_bounds`) is intersected with the ellipsoid's
    own projected box, which is much tighter for needles and pancakes (the reference's
    cost is the pixels it visits). Only an optimisation: the per-pixel test decides."""
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
