"""Selecting what the view shows rather than what it covers: the gaussians whose share of
some pixel's colour under a drawn shape reaches a weight, or the one a clicked pixel
shows most, weighed in float64 (``render.contributions.max_weights``) in the order the
view composites, without the deleted rows. What is found is recorded by row
(``scene.selection.Rows``), with the shape it was found through.
"""

from __future__ import annotations

import numpy as np

from raygs_viewer.render.contributions import bounds, cropped, max_weights
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.selection import Rows, ScreenShape
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.viewer.frame import Frame


def weights_under(scene: Scene, sorter, frame: Frame, shape: ScreenShape, deleted: DeletedRows | None) -> np.ndarray:
    """(N,) float64: each of ``scene``'s gaussians' largest weight over the pixels of
    ``shape`` (drawn on ``frame``'s camera), with ``frame``'s settings and level of
    detail, ``deleted`` left out, in the order ``sorter`` (the window's exact sorter) sorts.
    The order is sorted for the shape's bounding box only: the view's order (a sort
    depends on the pose alone), culled to what can reach those pixels."""
    inside = shape.pixel_mask()
    if not inside.any():
        return np.zeros(scene.count)
    order = exact_order(sorter, cropped(shape.camera, *bounds(inside)), frame.settings,
                        levels=frame.lod, deleted=deleted)
    indices = order.indices.read() if order.on_device else order.indices  # a GPU sort's, fetched
    return max_weights(scene, shape.camera, frame.settings, indices, inside)


def shown_rows(scene: Scene, sorter, frame: Frame, shape: ScreenShape, *, deleted: DeletedRows | None,
               min_weight: float | None) -> Rows | None:
    """The gaussians ``shape`` shows with a weight of at least ``min_weight`` somewhere, or
    with ``min_weight`` None the one it shows most (None where it shows none)."""
    weights = weights_under(scene, sorter, frame, shape, deleted)
    if min_weight is None:
        top = int(np.argmax(weights)) if weights.size else 0
        return Rows((top,), "top", shape) if weights.size and weights[top] > 0 else None
    return Rows(tuple(np.flatnonzero((weights >= min_weight) & (weights > 0)).tolist()), "visible", shape,
                min_weight)
