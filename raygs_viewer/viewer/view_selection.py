"""Selecting what the view shows rather than what it covers: the gaussians whose share of
some pixel's colour under a drawn shape reaches a weight, or the one a clicked pixel
shows most, weighed on the GPU (``render.gl.weighing``) in the order the view
composites, without the deleted rows, beside the frames: a slice a frame. What is found
is recorded by row (``scene.selection.Rows``), with the shape it was found through.

Each side weighs with its own settings: the split view's pixels right of the divider
with the right side's, in its key's order; a stereo eye with that eye's camera and the
order the eyes share, sorted from their midpoint. A side's order is the view's (the
frame's sort camera and key, its level-of-detail choice, the deleted rows left out),
culled to the rows each slice weighs.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from raygs_viewer.render.gl.weighing import DEFAULT_SLICE_SECONDS, WeighOn, Weighing, start_weighing
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import part_orders
from raygs_viewer.scene.selection import Rows, ScreenShape
from raygs_viewer.errors import UserError
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.state import Message, failed, note


@dataclass(frozen=True, eq=False)
class Side:
    """One side's share of a shape: its pixels ((H, W) bool of the shape's camera) and
    the settings they are drawn with."""

    inside: np.ndarray
    settings: RenderSettings


def sides(frame: Frame, shape: ScreenShape, divider: int | None) -> list[Side]:
    """The shape's pixels by the settings that draw them: all with the frame's, or in the
    split view those from column ``divider`` on with the right side's."""
    inside = shape.pixel_mask()
    if frame.right is None or divider is None:
        return [Side(inside, frame.settings)]
    right = np.zeros_like(inside)
    right[:, divider:] = inside[:, divider:]
    left = inside & ~right
    return [Side(mask, settings) for mask, settings in ((left, frame.settings), (right, frame.right)) if mask.any()]


class ShownWeighing:
    """A selection of what the view shows, being weighed: one weighing a side, stepped a
    slice a frame (:meth:`step`), then :meth:`rows`. ``how`` and ``min_weight`` say what
    to select (None: the click's top gaussian). The edit tool drops it when another scene,
    or a streamed SOG's next level, is shown."""

    def __init__(self, weighings: list[Weighing], shape: ScreenShape, *, min_weight: float | None, how: str):
        self.weighings, self.shape, self.min_weight, self.how = weighings, shape, min_weight, how
        self.started = time.perf_counter()
        self.slices = 0
        self._next = 0

    @property
    def progress(self) -> float:
        """The share weighed so far (0..1)."""
        return (self._next + (self.weighings[self._next].progress if self._next < len(self.weighings) else 0.0)) \
            / max(1, len(self.weighings))

    @property
    def where(self) -> str:
        return self.weighings[0].where if self.weighings else "GPU"

    def step(self) -> bool:
        """One slice of the side under way; True once every side is weighed."""
        if self._next < len(self.weighings):
            self.slices += 1
            if self.weighings[self._next].step():
                self._next += 1
        return self._next >= len(self.weighings)

    def rows(self) -> Rows | None:
        """What the finished weighing selects: the gaussians of at least ``min_weight``
        somewhere, or the one shown most (None: no gaussian shows there)."""
        weights = self.weighings[0].weights
        for weighing in self.weighings[1:]:
            weights = np.maximum(weights, weighing.weights)
        if self.min_weight is None:
            top = int(np.argmax(weights)) if weights.size else 0
            return Rows((top,), "top", self.shape) if weights.size and weights[top] > 0 else None
        return Rows(tuple(np.flatnonzero((weights >= self.min_weight) & (weights > 0)).tolist()), "visible",
                    self.shape, self.min_weight)

    def release(self) -> None:
        for weighing in self.weighings:
            weighing.release()


def start_shown_weighing(scene, frame: Frame, shape: ScreenShape, *, divider: int | None, min_weight: float | None,
                         how: str, weigh_on: WeighOn = "auto",
                         slice_seconds: float = DEFAULT_SLICE_SECONDS) -> ShownWeighing:
    """The weighing of ``shape`` (drawn on ``frame``'s view, or one stereo eye) of
    ``scene`` (the window's ``SceneView``: its renderer, direct sorter, deleted rows and
    the orders drawn). UserError where it cannot run."""
    weighings = []
    try:
        for side in sides(frame, shape, divider):
            weighings.append(start_weighing(scene.renderer, shape.camera, side.settings,
                                            view_sort(scene, frame, side.settings), side.inside, weigh_on=weigh_on,
                                            slice_seconds=slice_seconds))
    except BaseException:
        for weighing in weighings:
            weighing.release()
        raise
    return ShownWeighing(weighings, shape, min_weight=min_weight, how=how)


def view_sort(scene, frame: Frame, settings: RenderSettings):
    """The view's order for ``settings`` culled for a camera (a part of the view, or of an
    eye), in the view's own sequence (``render.sorting.part_orders``): the order the frame
    drew where it answers the frame's sort, else that sort made now (sorted from the
    frame's camera, the stereo midpoint, by ``settings``' key, of the level-of-detail
    choice drawn, without the deleted rows)."""
    drawn = scene.orders.get(settings.sort_key)
    if drawn is None or drawn.request != frame.sort:
        drawn = scene.sorter.sort(frame.sort).orders[settings.sort_key]
    return part_orders(scene.sorter, frame.camera, settings, drawn, levels=drawn.choice or frame.lod,
                       deleted=scene.deleted)


def advance(weighing: ShownWeighing, select: Callable[[Rows, str], Message | None]) -> tuple[bool, Message | None]:
    """One slice of ``weighing``: (whether it has ended, what to say). Once finished, what
    ``select`` (rows, how) said of the rows it found, with how long it took and on what."""
    try:
        if not weighing.step():
            return False, None
        rows = weighing.rows()
    except UserError as exc:
        return True, failed(exc, "nothing selected")
    if rows is None:
        return True, note("nothing selected: no gaussian shows at that pixel")
    said = select(rows, weighing.how)
    if said is None:
        return True, None
    took = time.perf_counter() - weighing.started
    return True, note(f"{said.text} (weighed in {took:.2f} s, {weighing.slices} slices, {weighing.where})")

