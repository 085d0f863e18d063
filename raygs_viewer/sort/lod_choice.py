"""Which level of a streamed SOG each leaf draws for a view: by its distance, under a
budget of gaussians, refining first what is largest on screen (docs/lod.md).

The rule, for a view from camera centre C:

1. **Distance.** Leaf k wants level ``l_k`` = the number of level distances at or
   below ``d_k``, its box's distance from C (0 inside the box): level 0 (the finest)
   nearer than ``D``, level 1 from ``D``, level 2 from ``2 D``, level l from
   ``2^(l-1) D``, the coarsest beyond. ``D`` is the setting ``lod_distance``; by
   default (:func:`automatic_distance`) four times the median leaf's half-diagonal.
2. **Readiness.** A level not read yet (or left unread: the GPU's memory) is replaced by
   the finest read level coarser than it: a leaf waits on its coarser level, never
   opening a hole.
3. **View.** A leaf whose bounding sphere lies outside the view draws its coarsest
   level: only the tails of its gaussians can reach the image (the box holds their
   centres and one standard deviation), and the per-gaussian cull drops the rest.
4. **Budget.** When the wanted levels of the leaves in view, with the environment,
   exceed ``budget`` gaussians (the leaves out of view are not counted), every leaf in
   view starts at its coarsest level and
   steps to finer levels are taken in order of priority, ``s_k 2^l`` for the step to
   level l (``s_k``: the leaf's projected radius in pixels), while the total stays within
   the budget: what is large on screen is refined first, and every leaf's coarse steps
   come before anyone's finest at the same size. When the coarsest levels alone exceed
   the budget, they are drawn, and the choice says so.

``level`` (``--lod N``) instead draws one level everywhere (waiting on coarser ones as
in 2), with no budget and whatever the view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.lod_file import LodScene

#: The default distance in leaf sizes: level 1 begins four half-diagonals away.
AUTOMATIC_DISTANCE_LEAVES = 4.0


@dataclass(frozen=True)
class LodChoice:
    """What a view draws of a :class:`LodScene`.

    levels:  (K,) int64: the level each leaf draws.
    wanted:  (K,) int64: the level its distance asks for (before readiness and budget).
    spans:   (S, 2) int64 ascending [start, stop) rows of the LodScene's scene: the
             chosen levels' rows and the environment (what the sort culls and sorts).
    count:   gaussians in ``spans``.
    over_budget: the coarsest levels alone exceed the budget (they are drawn anyway).
    """

    levels: np.ndarray
    wanted: np.ndarray
    spans: np.ndarray
    count: int
    over_budget: bool = False

    def per_level(self, levels: int) -> np.ndarray:
        """(L,) int64: how many leaves draw each level."""
        return np.bincount(self.levels[self.levels >= 0], minlength=levels)


def automatic_distance(lod: LodScene) -> float:
    """The default first level distance: :data:`AUTOMATIC_DISTANCE_LEAVES` times the median
    leaf's half-diagonal (a scene-sized unit whatever the scene's scale)."""
    if lod.index.leaves == 0:
        return 1.0
    half = 0.5 * np.linalg.norm(lod.index.bounds[:, 1] - lod.index.bounds[:, 0], axis=1)
    return float(max(AUTOMATIC_DISTANCE_LEAVES * np.median(half), 1e-6))


def level_distances(lod: LodScene, distance: float | None) -> np.ndarray:
    """(L - 1,) float64: where each level from 1 on begins (``distance`` None: automatic)."""
    first = automatic_distance(lod) if distance is None else float(distance)
    return first * 2.0 ** np.arange(lod.levels - 1)


def box_distances(bounds: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(K,) distance from ``centre`` to each box ((K, 2, 3) min, max); 0 inside."""
    outside = np.maximum(np.maximum(bounds[:, 0] - centre, centre - bounds[:, 1]), 0.0)
    return np.linalg.norm(outside, axis=1)


def screen_radius(bounds: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Each box's bounding sphere seen from ``camera``: (in view, (K,) bool; projected
    radius in pixels, (K,) float64; a sphere holding the camera is as large as the image)."""
    centre = 0.5 * (bounds[:, 0] + bounds[:, 1])
    radius = 0.5 * np.linalg.norm(bounds[:, 1] - bounds[:, 0], axis=1)
    mu = centre @ camera.R.T + camera.t
    x, y, z = mu.T
    in_view = z > -radius
    for coordinate, focal, principal, extent in ((x, camera.fx, camera.cx, camera.width),
                                                 (y, camera.fy, camera.cy, camera.height)):
        for a, b in ((focal, principal), (-focal, extent - principal)):
            in_view &= (coordinate * a + z * b) / math.hypot(a, b) > -radius
    distance = np.linalg.norm(mu, axis=1)
    size = np.where(distance > radius, camera.fx * radius / np.maximum(distance, 1e-30),
                    float(max(camera.width, camera.height)))
    return in_view, size


def choose(lod: LodScene, camera: Camera, *, level: int | None = None, budget: int | None = None,
           distance: float | None = None) -> LodChoice:
    """What ``camera`` draws of ``lod`` (see the module docstring for the rule)."""
    leaves, levels = lod.index.leaves, lod.levels
    loaded = np.flatnonzero(lod.loaded)
    if loaded.size == 0:  # nothing read yet: nothing but the environment
        empty = np.full(leaves, -1, np.int64)
        spans = lod.spans(empty)
        return LodChoice(empty, empty, spans, int((spans[:, 1] - spans[:, 0]).sum()))
    finest, coarsest = int(loaded[0]), int(loaded[-1])
    if level is not None:
        wanted = np.full(leaves, min(int(level), levels - 1), np.int64)
    else:
        d = box_distances(lod.index.bounds, camera.center)
        wanted = np.searchsorted(level_distances(lod, distance), d, side="right").astype(np.int64)
    ready = _ready_levels(lod.loaded)
    target = ready[np.maximum(wanted, finest)]
    counts = lod.rows[:, :, 1]
    over = False
    if level is None:
        in_view, size = screen_radius(lod.index.bounds, camera)
        target[~in_view] = coarsest
        if budget is not None:
            target, over = _within_budget(lod, in_view, size, target, counts, coarsest, int(budget))
    spans = lod.spans(target)
    return LodChoice(target, wanted, spans, int((spans[:, 1] - spans[:, 0]).sum()), over)


def _ready_levels(loaded: np.ndarray) -> np.ndarray:
    """(L,) int64: for each level, the finest read level at or coarser than it (a level
    coarser than every read one maps to the coarsest read)."""
    levels = loaded.shape[0]
    ready = np.empty(levels, np.int64)
    nearest = int(np.flatnonzero(loaded)[-1])
    for level in range(levels - 1, -1, -1):
        if loaded[level]:
            nearest = level
        ready[level] = nearest
    return ready


def _within_budget(lod: LodScene, in_view: np.ndarray, size: np.ndarray, target: np.ndarray, counts: np.ndarray,
                   coarsest: int, budget: int) -> tuple[np.ndarray, bool]:
    """``target`` coarsened until the leaves in view and the environment fit ``budget``."""
    leaves = np.arange(target.shape[0])
    environment = lod.environment[1]
    wanted_total = environment + int(counts[leaves[in_view], target[in_view]].sum())
    if wanted_total <= budget:
        return target, False
    chosen = target.copy()
    chosen[in_view] = coarsest
    base = environment + int(counts[leaves[in_view], coarsest].sum())
    if base >= budget:
        return chosen, base > budget
    # Every step of every leaf in view, from the coarsest level to its target: the
    # step to level l costs the difference of the two levels' counts.
    ready = np.flatnonzero(lod.loaded)
    step_leaf, step_level = [], []
    for level in ready[ready < coarsest]:
        takes = in_view & (target <= level)
        step_leaf.append(leaves[takes])
        step_level.append(np.full(int(takes.sum()), level, np.int64))
    step_leaf = np.concatenate(step_leaf) if step_leaf else np.zeros(0, np.int64)
    step_level = np.concatenate(step_level) if step_level else np.zeros(0, np.int64)
    coarser = _next_coarser(lod.loaded)[step_level]
    cost = counts[step_leaf, step_level] - counts[step_leaf, coarser]
    priority = size[step_leaf] * 2.0 ** step_level
    # A leaf's steps come coarse to fine (a tie of sizes 0 keeps that by the level).
    order = np.lexsort((-step_level, step_leaf, -priority))
    taken = np.cumsum(cost[order]) <= budget - base
    stop = int(np.argmin(taken)) if not taken.all() else taken.size
    accepted = order[:stop]
    np.minimum.at(chosen, step_leaf[accepted], step_level[accepted])
    return chosen, False


def _next_coarser(loaded: np.ndarray) -> np.ndarray:
    """(L,) int64: for each read level, the next coarser read level (itself for the coarsest)."""
    levels = loaded.shape[0]
    out = np.arange(levels)
    nearest = None
    for level in range(levels - 1, -1, -1):
        out[level] = level if nearest is None else nearest
        if loaded[level]:
            nearest = level
    return out


@dataclass(frozen=True, eq=False)
class LodRequest:
    """A choice to make for every view the sort thread sorts (``BackgroundSorter.request``):
    the scene and the settings of :func:`choose`. ``key`` is what makes two requests
    the same choice (the scene by identity: a newly read level is a new LodScene)."""

    lod: LodScene
    level: int | None = None
    budget: int | None = None
    distance: float | None = None

    def choose(self, camera: Camera) -> LodChoice:
        return choose(self.lod, camera, level=self.level, budget=self.budget, distance=self.distance)

    @property
    def key(self) -> tuple:
        return (id(self.lod), self.level, self.budget, self.distance)
