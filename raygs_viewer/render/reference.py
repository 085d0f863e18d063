"""The float64 reference renderer: the oracle of the tests, the CPU baseline of benchmarks.

Per pixel and per gaussian it evaluates the maths page directly, in every render mode
of :class:`RenderSettings` (the per-fragment maths: :mod:`raygs_viewer.render.reference_models`):

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

:func:`render_reference_channels` also gives the geometry outputs of
:mod:`raygs_viewer.render.channels` (depth, median depth, normal) from the very same
fragments, colour computed exactly as :func:`render_reference` computes it. The median
needs the fragments front to back: where colour composites back to front, a band's
fragments are kept and the geometry accumulated over them in reverse (the same sums).

Memory: the image is rendered in horizontal bands of about BAND_SAMPLES samples
(pixel rays and per-gaussian temporaries exist for one band at a time), so
:func:`ground_truth` at 16 x 16 samples per pixel stays bounded.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.channels import ChannelImage, finish
from raygs_viewer.render.ray_order import Fragments, GeometrySums, composite_per_pixel, composite_per_pixel_geometry
from raygs_viewer.render.reference_models import MODELS, CameraGaussians, peak_z
from raygs_viewer.render.settings import ALPHA_CLAMP, TRANSMITTANCE_CUTOFF, RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.depth import DepthSorter

#: Samples (pixels of the rendered, supersampled image) per band: bounds peak memory
#: to a few hundred MB even when one gaussian covers a whole band.
BAND_SAMPLES = 1 << 20
#: Per-pixel order, and any order with the geometry outputs, keeps a band's fragments
#: (tens per sample in real scenes) at once: its bands hold this many times fewer samples.
PER_PIXEL_BAND_DIVISOR = 16
#: Values per sample a band carries: RGBA, then with geometry depth_sum, normal_sum (3),
#: median * found and found (:meth:`GeometrySums.stacked`).
COLOR_VALUES, GEOMETRY_VALUES = 4, 10


def render_reference(scene: Scene, camera: Camera, settings: RenderSettings = RenderSettings(),
                     order: np.ndarray | str | None = None, *, color_origin: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 4) float64 image: RGB composited over the background, and accumulated alpha.

    ``order``: the global order (indices, back to front), by default the sorter's for
    this camera with ``settings.sort_key``, culled with the settings' filter dilation;
    or the name of an order mode (one of ORDERS), short for ``settings`` with that
    ``order``. Every field of ``settings`` is honoured; with ``supersample`` k the image
    is the k x k block mean of the image rendered with ``camera.resized(k W, k H)``.
    Per-pixel order composites each pixel by t* (:mod:`raygs_viewer.render.ray_order`);
    its window (``order_k``) is fed in the global order. ``color_origin``: the world
    point SH colour is seen from (None: the camera's centre), as ``GLRenderer.render``'s.
    """
    settings, order = _settings_and_order(scene, camera, settings, order)
    return _render(scene, camera, settings, order, samples=settings.supersample, band_samples=BAND_SAMPLES,
                   color_origin=color_origin)


def render_reference_channels(scene: Scene, camera: Camera, settings: RenderSettings = RenderSettings(),
                              order: np.ndarray | str | None = None) -> ChannelImage:
    """Every channel (:class:`ChannelImage`, camera-space normals), arguments as
    :func:`render_reference`, whose rgb and alpha it returns bit for bit (as float32).

    Per fragment z is its peak's camera-space z (t* on the unit ray times that ray's z;
    in "gs" mode the centre's z) and n the gaussian's shortest axis facing the sample's
    ray; the sums run in the order the fragments are composited (a pixel's stopping
    fragment under the cut-off adds nothing), per sample, then average over the
    supersampling block before :func:`raygs_viewer.render.channels.finish`."""
    settings, order = _settings_and_order(scene, camera, settings, order)
    values = _render(scene, camera, settings, order, samples=settings.supersample, band_samples=BAND_SAMPLES,
                     geometry=True)
    return finish(values[..., :4], values[..., 4:8], values[..., 8:10])


def global_order(scene: Scene, camera: Camera, settings: RenderSettings) -> np.ndarray:
    """(M,) uint32 back to front: the sorter's order for ``camera`` with the settings'
    key, culled with their filter dilation (what the GL path draws)."""
    with DepthSorter(scene) as sorter:
        return exact_order(sorter, camera, settings).indices


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
    return _render(scene, camera, exact, global_order(scene, camera, exact), samples=samples,
                   band_samples=band_samples)


def _settings_and_order(scene: Scene, camera: Camera, settings: RenderSettings, order):
    """The settings and the explicit global order ``order`` stands for (see render_reference)."""
    if isinstance(order, str):
        settings, order = replace(settings, order=order), None
    if order is None:
        order = global_order(scene, camera, settings)
    return settings, order


# --- the render loop shared by every mode ------------------------------------------------

@dataclass(frozen=True)
class _Pass:
    """One reference render, decided once: the model of the settings' mode over the
    rendered (supersampled) camera, the gaussians in camera space, each ordered
    gaussian's index in the scene (per-pixel ties), and whether the geometry sums are
    composited beside colour."""

    model: object
    gaussians: CameraGaussians
    camera: Camera
    settings: RenderSettings
    scene_index: np.ndarray
    geometry: bool


def _render(scene: Scene, camera: Camera, settings: RenderSettings, order, *, samples: int,
            band_samples: int, geometry: bool = False, color_origin: np.ndarray | None = None) -> np.ndarray:
    """(H, W, COLOR_VALUES) or, with ``geometry``, (H, W, GEOMETRY_VALUES): ``render_reference``
    with an explicit sample count per axis (``settings.supersample`` is ignored), so ground
    truth can go past the settings' limit, in bands of about ``band_samples`` samples.
    Where the render's :class:`_Pass` is made."""
    order = np.asarray(order, dtype=np.int64)
    scene = scene.with_sh_degree(settings.effective_sh_degree(scene.sh_degree))
    height, width = camera.height, camera.width
    values = GEOMETRY_VALUES if geometry else COLOR_VALUES
    image = np.zeros((height, width, values))
    image[..., :3] = settings.background
    if order.size == 0:
        return image

    # Only the intrinsics change with supersampling: fx, cx scale by k, so sample i of
    # pixel u sits at u + (i + 0.5) / k. Every pixel-unit quantity (MIP variance, GS
    # dilation and clamping) refers to this rendered camera.
    rendered = camera if samples == 1 else camera.resized(samples * width, samples * height)
    gaussians = CameraGaussians.of(scene, order, camera, color_origin)
    render = _Pass(MODELS[settings.mode](gaussians, rendered, settings), gaussians, rendered, settings, order,
                   geometry)

    # Bands of whole output rows, so each band's block mean is complete. Per-pixel order
    # and geometry hold every fragment of a band at once: smaller bands.
    if settings.per_pixel or geometry:
        band_samples = max(1, band_samples // PER_PIXEL_BAND_DIVISOR)
    rows_per_band = max(1, band_samples // (samples * samples * width))
    for top in range(0, height, rows_per_band):
        bottom = min(height, top + rows_per_band)
        band = _composite(render, top * samples, bottom * samples)
        if samples > 1:
            # Every accumulator, geometry's included, is averaged over the block.
            band = band.reshape(bottom - top, samples, width, samples, values).mean(axis=(1, 3))
        image[top:bottom] = band
    return image


def band_rays(camera: Camera, top: int, bottom: int) -> np.ndarray:
    """(bottom - top, W, 3) rays (z = 1) of rows top..bottom-1: ``camera.pixel_rays()[top:bottom]``
    computed for those rows only (the same numbers, bit for bit)."""
    u = (np.arange(camera.width) + 0.5 - camera.cx) / camera.fx
    v = (np.arange(top, bottom) + 0.5 - camera.cy) / camera.fy
    rays = np.empty((bottom - top, camera.width, 3))
    rays[..., 0] = u[None, :]
    rays[..., 1] = v[:, None]
    rays[..., 2] = 1.0
    return rays


def _facing(normal: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """(..., 3): the unit ``normal`` (3,) at each of ``rays`` (..., 3), negated where it
    points along the ray (n . ray > 0) so that it faces the camera."""
    return np.where((rays @ normal > 0)[..., None], -normal, normal)


def _composite(render: _Pass, top: int, bottom: int) -> np.ndarray:
    """(bottom - top, W, COLOR_VALUES or GEOMETRY_VALUES) of rows top..bottom-1 of the
    rendered camera's image."""
    model, gaussians, camera, settings, geometry = (render.model, render.gaussians, render.camera, render.settings,
                                                    render.geometry)
    rays = band_rays(camera, top, bottom)
    # Only gaussians whose pixel box meets the band.
    boxes = model.boxes
    meets = np.flatnonzero((boxes[:, 0] < bottom) & (boxes[:, 1] > top)
                           & (boxes[:, 0] < boxes[:, 1]) & (boxes[:, 2] < boxes[:, 3]))
    if settings.per_pixel:
        return _composite_per_pixel(render, rays, meets, top, bottom)

    def fragments(sequence):
        """(index, rows, cols, alpha, z) per gaussian box, rows relative to the band;
        z (the peak's, or None without geometry) as the model gives it."""
        for j in sequence:
            r0, r1, c0, c1 = boxes[j]
            r0, r1 = max(r0, top), min(r1, bottom)
            rows, cols = slice(r0, r1), slice(c0, c1)
            i = model.drawn[j]
            block = rays[r0 - top:r1 - top, cols]
            alpha, z = model.fragment(i, block, rows, cols) if geometry else (model.alpha(i, block, rows, cols), None)
            if settings.alpha_clamp:  # after the p_min test, as INRIA does
                np.minimum(alpha, ALPHA_CLAMP, out=alpha)
            yield i, slice(r0 - top, r1 - top), cols, alpha, z

    colors, normals = gaussians.colors, gaussians.normals
    band = np.zeros((bottom - top, camera.width, 4))
    sums = GeometrySums(band.shape[:2]) if geometry else None
    if not settings.transmittance_cutoff:
        # Back to front, "over" blending of premultiplied fragments, as the GL path does.
        band[..., :3] = settings.background
        kept = []
        for fragment in fragments(meets):
            i, rows, cols, alpha, _ = fragment
            block = band[rows, cols]
            block[..., :3] = alpha[..., None] * colors[i] + (1 - alpha[..., None]) * block[..., :3]
            block[..., 3] = alpha + (1 - alpha) * block[..., 3]
            if geometry:
                kept.append(fragment)
        if geometry:
            _accumulate_front_to_back(sums, reversed(kept), rays, normals)
        return _with_geometry(band, sums)

    # Front to back with INRIA's rule: a fragment that would take the transmittance
    # below the cut-off ends the pixel, itself not drawn.
    color = np.zeros((bottom - top, camera.width, 3))
    transmittance = np.ones((bottom - top, camera.width))
    done = np.zeros((bottom - top, camera.width), dtype=bool)
    for i, rows, cols, alpha, z in fragments(meets[::-1]):
        t, finished = transmittance[rows, cols], done[rows, cols]  # views, updated in place
        active = (alpha > 0) & ~finished
        after = t * (1 - alpha)
        stop = active & (after < TRANSMITTANCE_CUTOFF)
        finished |= stop
        take = active & ~stop
        weight = np.where(take, t * alpha, 0.0)
        color[rows, cols] += weight[..., None] * colors[i]
        if geometry:
            sums.add((rows, cols), weight, np.where(take, 1 - after, 0.0), z, _facing(normals[i], rays[rows, cols]))
        t[take] = after[take]
    band[..., :3] = color + transmittance[..., None] * np.asarray(settings.background)
    band[..., 3] = 1 - transmittance
    return _with_geometry(band, sums)


def _accumulate_front_to_back(sums: GeometrySums, fragments, rays: np.ndarray, normals: np.ndarray) -> None:
    """Adds (index, rows, cols, alpha, z) fragments, given front to back, to ``sums``."""
    transmittance = np.ones(rays.shape[:2])
    for i, rows, cols, alpha, z in fragments:
        t = transmittance[rows, cols]  # a view, updated in place
        after = t * (1 - alpha)
        sums.add((rows, cols), t * alpha, 1 - after, z, _facing(normals[i], rays[rows, cols]))
        t[...] = after


def _with_geometry(band: np.ndarray, sums: GeometrySums | None) -> np.ndarray:
    return band if sums is None else np.concatenate((band, sums.stacked()), axis=-1)


def _composite_per_pixel(render: _Pass, rays: np.ndarray, meets: np.ndarray, top: int, bottom: int) -> np.ndarray:
    """(bottom - top, W, COLOR_VALUES or GEOMETRY_VALUES): the band composited per pixel by
    t* (exactly, or through the settings' window), from every fragment with alpha > 0 of
    the gaussians ``meets``."""
    model, gaussians, settings, scene_index = render.model, render.gaussians, render.settings, render.scene_index
    boxes, geometry = model.boxes, render.geometry
    height, width = bottom - top, rays.shape[1]
    columns = np.arange(width)
    parts = []
    for j in meets:
        r0, r1, c0, c1 = boxes[j]
        r0, r1 = max(r0, top), min(r1, bottom)
        i = model.drawn[j]
        block = rays[r0 - top:r1 - top, c0:c1]
        alpha, key = model.alpha(i, block, slice(r0, r1), slice(c0, c1), key=True)
        if settings.alpha_clamp:
            np.minimum(alpha, ALPHA_CLAMP, out=alpha)
        rows, cols = np.nonzero(alpha > 0)
        if rows.size == 0:
            continue
        count = rows.size
        part = ((rows + (r0 - top)) * width + columns[c0:c1][cols], key[rows, cols],
                np.full(count, scene_index[i], np.int64), np.full(count, i, np.int64),
                alpha[rows, cols], np.broadcast_to(gaussians.colors[i], (count, 3)))
        if geometry:
            hit = block[rows, cols]
            part += (peak_z(key[rows, cols], hit), _facing(gaussians.normals[i], hit))
        parts.append(part)
    cutoff = TRANSMITTANCE_CUTOFF if settings.transmittance_cutoff else None
    composite = composite_per_pixel_geometry if geometry else composite_per_pixel
    image = composite(Fragments.concatenate(parts), height * width, settings.background,
                      window=settings.order_k, cutoff=cutoff)
    return image.reshape(height, width, -1)
