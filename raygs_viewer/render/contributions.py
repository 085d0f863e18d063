"""How much each gaussian shows through a set of pixels: its largest weight T alpha (the
share of a pixel's colour it gives, T the transmittance in front of it) over those
pixels, in float64 by the reference renderer's maths. What "select what the view shows"
and "select what this pixel shows most" select by.

A pixel's colour is ``sum_g w_g c_g + (1 - sum_g w_g) background``, with the weights of
its fragments composited in the order the settings composite them: the global order
(back to front, or front to back with INRIA's cut-off, whose stopping fragment and those
after it weigh 0) or each ray's own (exactly by t*, or through the k-buffer's window).
Only the pixels asked about are composited (their bounding box), so a brush stroke
costs the fragments under it, not the view's; the caller may sort the order for that
box alone (:func:`cropped`: a conservative cull keeps every gaussian reaching it).

A pixel's ray is its centre's: supersampling's sub-samples are not weighed (the weights
are those of the 1 x 1 sample image, which ``supersample`` 1 draws).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterator

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.ray_order import Fragments, largest_weights
from raygs_viewer.render.reference import PER_PIXEL_BAND_DIVISOR, BAND_SAMPLES, band_rays
from raygs_viewer.render.reference_models import MODELS, CameraGaussians
from raygs_viewer.render.settings import ALPHA_CLAMP, TRANSMITTANCE_CUTOFF, RenderSettings
from raygs_viewer.scene.model import Scene

#: The most fragments (a gaussian's pixels under the shape) weighed for one selection:
#: 14 million took 0.9 s in the global order and 3.7 s in a per-ray one on this sandbox (docs/editing.md).
MAX_FRAGMENTS = 20_000_000


def cropped(camera: Camera, rows: slice, cols: slice) -> Camera:
    """The part ``rows`` x ``cols`` of ``camera``'s image as a camera of its own: the same
    pose and focal lengths, the principal point moved (to cull an order for that part)."""
    return replace(camera, width=cols.stop - cols.start, height=rows.stop - rows.start,
                   cx=camera.cx - cols.start, cy=camera.cy - rows.start)


def bounds(inside: np.ndarray) -> tuple[slice, slice]:
    """(rows, cols): the bounding box of the True pixels of ``inside`` ((H, W) bool, some True)."""
    row_span, col_span = np.flatnonzero(inside.any(axis=1)), np.flatnonzero(inside.any(axis=0))
    return slice(int(row_span[0]), int(row_span[-1]) + 1), slice(int(col_span[0]), int(col_span[-1]) + 1)


def max_weights(scene: Scene, camera: Camera, settings: RenderSettings, order: np.ndarray,
                inside: np.ndarray) -> np.ndarray:
    """(N,) float64 for the scene's N gaussians: each one's largest weight over the
    pixels of ``camera`` where ``inside`` ((H, W) bool) holds, drawn with ``settings`` in
    the global ``order`` ((M,) scene rows, back to front, as ``reference.global_order``
    gives; rows left out of it, such as deleted ones, weigh 0). UserError past
    :data:`MAX_FRAGMENTS` fragments."""
    weights = np.zeros(scene.count)
    for _ in weigh_bands(scene, camera, settings, order, inside, weights=weights):
        pass
    return weights


def weigh_bands(scene: Scene, camera: Camera, settings: RenderSettings, order: np.ndarray, inside: np.ndarray, *,
                weights: np.ndarray) -> Iterator[tuple[int, int]]:
    """:func:`max_weights` a band of pixel rows at a time: raises ``weights`` ((N,)
    float64, zeros to begin with) band by band, yielding (rows weighed, rows to weigh)
    after each (a caller may stop between bands)."""
    inside = np.asarray(inside, bool)
    if inside.shape != (camera.height, camera.width):
        raise ValueError(f"inside is {inside.shape}, the camera's image is {(camera.height, camera.width)}")
    order = np.asarray(order, np.int64)
    if order.size == 0 or not inside.any():
        return
    rows, cols = bounds(inside)
    settings = replace(settings, supersample=1)
    scene = scene.with_sh_degree(settings.effective_sh_degree(scene.sh_degree))
    # The model is the whole camera's (EWA clamps its Jacobian to the image's extent);
    # only the boxes' parts inside the bounding box are composited.
    model = MODELS[settings.mode](CameraGaussians.of(scene, order, camera), camera, settings)
    boxes = model.boxes.copy()
    np.clip(boxes[:, :2], rows.start, rows.stop, out=boxes[:, :2])
    np.clip(boxes[:, 2:], cols.start, cols.stop, out=boxes[:, 2:])
    areas = np.maximum(boxes[:, 1] - boxes[:, 0], 0) * np.maximum(boxes[:, 3] - boxes[:, 2], 0)
    fragments = int(areas.sum())
    if fragments > MAX_FRAGMENTS:
        raise UserError(f"the shape covers {fragments:,} fragments of {np.count_nonzero(areas):,} gaussians "
                        f"(at most {MAX_FRAGMENTS:,} are weighed): draw a smaller one, or select 'through'")
    width = cols.stop - cols.start
    band_rows = max(1, BAND_SAMPLES // PER_PIXEL_BAND_DIVISOR // width)
    weighing = _Weighing(model, boxes, camera=camera, settings=settings, order=order, cols=cols)
    for top in range(rows.start, rows.stop, band_rows):
        bottom = min(rows.stop, top + band_rows)
        counted = inside[top:bottom, cols]
        if settings.per_pixel:
            band = weighing.band_fragments(top, bottom)
            np.maximum(weights, largest_weights(band, counted.size, counted.reshape(-1), scene.count,
                                                window=settings.order_k, cutoff=weighing.cutoff), out=weights)
        else:
            weighing.global_weights(weights, top, bottom, counted)
        yield bottom - rows.start, rows.stop - rows.start


@dataclass(frozen=True)
class _Weighing:
    """One weighing, decided once: the settings' model of the whole camera, its pixel
    boxes clipped to the pixels asked about, the global order (scene rows, back to front)
    and the columns of the part weighed."""

    model: object
    boxes: np.ndarray
    camera: Camera
    settings: RenderSettings
    order: np.ndarray
    cols: slice

    @property
    def cutoff(self) -> float | None:
        return TRANSMITTANCE_CUTOFF if self.settings.transmittance_cutoff else None

    def fragment_alpha(self, i: int, rays: np.ndarray, rows: slice, cols: slice, *, key: bool = False):
        """Gaussian ``i``'s alpha (and t* with ``key``) over ``rows`` x ``cols`` (``rays``:
        theirs), clamped as the settings clamp it."""
        if key:
            found = self.model.alpha(i, rays, rows, cols, key=True)
        else:
            found = self.model.alpha(i, rays, rows, cols), None
        if self.settings.alpha_clamp:  # after the p_min test, as INRIA does
            np.minimum(found[0], ALPHA_CLAMP, out=found[0])
        return found

    def global_weights(self, weights: np.ndarray, top: int, bottom: int, counted: np.ndarray) -> None:
        """Raises ``weights`` to each gaussian's largest weight over the ``counted`` pixels of
        rows top..bottom-1, composited front to back in the global order (the same
        weights as back to front; with the cut-off, INRIA's rule ends a pixel at the
        fragment that would take it below, which itself weighs 0)."""
        model, boxes, order, cols, cutoff = self.model, self.boxes, self.order, self.cols, self.cutoff
        rays = band_rays(self.camera, top, bottom)
        transmittance = np.ones(counted.shape)
        done = np.zeros(counted.shape, bool)
        for j in _meeting(boxes, top, bottom)[::-1]:
            r0, r1, c0, c1 = boxes[j]
            r0, r1 = max(r0, top), min(r1, bottom)
            i = model.drawn[j]
            alpha, _ = self.fragment_alpha(i, rays[r0 - top:r1 - top, c0:c1], slice(r0, r1), slice(c0, c1))
            part = (slice(r0 - top, r1 - top), slice(c0 - cols.start, c1 - cols.start))
            t = transmittance[part]  # a view, updated in place
            after = t * (1 - alpha)
            take = alpha > 0
            if cutoff is not None:
                finished = done[part]
                take &= ~finished
                stop = take & (after < cutoff)
                finished |= stop
                take &= ~stop
            weight = np.where(take & counted[part], t * alpha, 0.0)
            if weight.size:
                weights[order[i]] = max(weights[order[i]], float(weight.max()))
            t[take] = after[take]

    def band_fragments(self, top: int, bottom: int) -> Fragments:
        """The fragments (alpha > 0) of rows top..bottom-1 for a per-ray order: pixels flat
        in that part, t*, the scene row, the rank in the order."""
        model, boxes, order, cols = self.model, self.boxes, self.order, self.cols
        rays = band_rays(self.camera, top, bottom)
        width, parts = cols.stop - cols.start, []
        for j in _meeting(boxes, top, bottom):
            r0, r1, c0, c1 = boxes[j]
            r0, r1 = max(r0, top), min(r1, bottom)
            i = model.drawn[j]
            alpha, key = self.fragment_alpha(i, rays[r0 - top:r1 - top, c0:c1], slice(r0, r1), slice(c0, c1),
                                             key=True)
            hit_rows, hit_cols = np.nonzero(alpha > 0)
            if hit_rows.size == 0:
                continue
            count = hit_rows.size
            parts.append(((hit_rows + (r0 - top)) * width + (c0 - cols.start) + hit_cols, key[hit_rows, hit_cols],
                          np.full(count, order[i], np.int64), np.full(count, i, np.int64),
                          alpha[hit_rows, hit_cols], np.zeros((count, 3))))
        return Fragments.concatenate(parts)


def _meeting(boxes: np.ndarray, top: int, bottom: int) -> np.ndarray:
    """The boxes (indices, back to front) that meet rows top..bottom-1 and are not empty."""
    return np.flatnonzero((boxes[:, 0] < bottom) & (boxes[:, 1] > top)
                          & (boxes[:, 0] < boxes[:, 1]) & (boxes[:, 2] < boxes[:, 3]))
