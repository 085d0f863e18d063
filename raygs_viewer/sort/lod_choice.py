"""Which level of a streamed SOG each leaf draws for a view: by its distance, under a
budget of gaussians, refining first what is largest on screen (docs/lod.md).

The rule, for a view from camera centre C:

1. **Distance.** Leaf k wants level ``l_k`` = the number of level distances at or
   below ``d_k``, its box's distance from C (0 inside the box): level 0 (the finest)
   nearer than ``D``, level 1 from ``D``, level 2 from ``2 D``, level l from
   ``2^(l-1) D``, the coarsest beyond. ``D`` is the setting ``lod_distance``; by
   default (:func:`automatic_distance`) four times the median leaf's half-diagonal.
2. **What is there.** A leaf draws a level only where that level is read and holds
   gaussians of the leaf; otherwise the nearest coarser such level (a level not read
   yet, or left unread for the GPU's memory: the leaf waits on its coarser level and no
   hole opens), else the nearest finer one (splat-transform files a coarse gaussian
   under the leaf its centre falls in, so a leaf may have none at a coarse level).
3. **View.** A leaf whose bounding sphere, widened by how far its gaussians reach
   (:data:`REACH_SIGMAS` times the largest standard deviation among them, and two
   pixels), lies outside the view draws its coarsest level: none of it can reach a
   pixel, and the per-gaussian cull drops it.
4. **Budget.** When the wanted levels of the leaves in view, with the environment,
   exceed ``budget`` gaussians (the leaves out of view are not counted), every leaf in
   view starts at its coarsest level and steps to finer levels are taken in order of
   priority, ``s_k 2^l`` for the step to level l (``s_k``: the leaf's projected radius in
   pixels), while the total stays within the budget: what is large on screen is refined
   first, and every leaf's coarse steps come before anyone's finest at the same size.
   When the coarsest levels alone exceed the budget, they are drawn, and the choice
   says so.

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
#: How far a leaf's gaussians reach beyond its box, in standard deviations: their support
#: at the default opacity cut-off, sqrt(2 ln(1 / p_min)) with p_min = 1/255 (a gaussian of
#: opacity 1). Fixed rather than the settings' p_min, so that the window, its screenshots
#: (each split side with its own settings) and their sidecars make one choice.
REACH_SIGMAS = math.sqrt(2.0 * math.log(255.0))


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

    def choose(self, camera: Camera) -> "LodChoice":
        """Itself: a choice already made serves every camera of its frame (its tiles, its eyes)."""
        return self

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


def screen_radius(bounds: np.ndarray, camera: Camera, reach: np.ndarray | float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Each box's bounding sphere seen from ``camera``: (in view, (K,) bool: the sphere
    widened by ``reach`` (scene units) and two pixels meets the view; projected radius in
    pixels, (K,) float64; a sphere holding the camera is as large as the image)."""
    centre = 0.5 * (bounds[:, 0] + bounds[:, 1])
    radius = 0.5 * np.linalg.norm(bounds[:, 1] - bounds[:, 0], axis=1)
    mu = centre @ camera.R.T + camera.t
    x, y, z = mu.T
    distance = np.linalg.norm(mu, axis=1)
    # Two pixels at the sphere's distance: what a MIP filter or rounding may add.
    wide = radius + reach + 2.0 * distance / min(camera.fx, camera.fy)
    in_view = z > -wide
    for coordinate, focal, principal, extent in ((x, camera.fx, camera.cx, camera.width),
                                                 (y, camera.fy, camera.cy, camera.height)):
        for a, b in ((focal, principal), (-focal, extent - principal)):
            in_view &= (coordinate * a + z * b) / math.hypot(a, b) > -wide
    size = np.where(distance > radius, camera.fx * radius / np.maximum(distance, 1e-30),
                    float(max(camera.width, camera.height)))
    return in_view, size


def usable_levels(lod: LodScene) -> np.ndarray:
    """(K, L) int64: the level leaf k draws when level l is asked for: l where it is read
    and holds gaussians of the leaf, else the nearest coarser such level (a leaf waits on
    its coarser level), else the nearest finer one (a leaf whose coarse gaussians lie in
    its neighbours' boxes still draws its own); -1 where the leaf has none read."""
    available = lod.loaded[None, :] & (lod.rows[:, :, 1] > 0)
    leaves, levels = available.shape
    coarser, finer = np.full((leaves, levels), -1), np.full((leaves, levels), -1)
    nearest = np.full(leaves, -1)
    for level in range(levels - 1, -1, -1):
        nearest = np.where(available[:, level], level, nearest)
        coarser[:, level] = nearest
    nearest = np.full(leaves, -1)
    for level in range(levels):
        nearest = np.where(available[:, level], level, nearest)
        finer[:, level] = nearest
    return np.where(coarser >= 0, coarser, finer)


def choose(lod: LodScene, camera: Camera, *, level: int | None = None, budget: int | None = None,
           distance: float | None = None) -> LodChoice:
    """What ``camera`` draws of ``lod`` (see the module docstring for the rule)."""
    leaves, levels = lod.index.leaves, lod.levels
    if level is not None:
        wanted = np.full(leaves, min(int(level), levels - 1), np.int64)
    else:
        d = box_distances(lod.index.bounds, camera.center)
        wanted = np.searchsorted(level_distances(lod, distance), d, side="right").astype(np.int64)
    usable = usable_levels(lod)
    every = np.arange(leaves)
    over = False
    if level is None:
        in_view, size = screen_radius(lod.index.bounds, camera, REACH_SIGMAS * lod.leaf_scales)
        target = usable[every, np.where(in_view, wanted, levels - 1)]
        if budget is not None:
            target, over = _within_budget(lod, target, int(budget), usable=usable, in_view=in_view, size=size)
    else:
        target = usable[every, wanted]
    spans = lod.spans(target)
    return LodChoice(target, wanted, spans, int((spans[:, 1] - spans[:, 0]).sum()), over)


def _within_budget(lod: LodScene, target: np.ndarray, budget: int, *, usable: np.ndarray, in_view: np.ndarray,
                   size: np.ndarray) -> tuple[np.ndarray, bool]:
    """``target`` coarsened until the leaves in view and the environment fit ``budget``
    (``usable``: :func:`usable_levels`; ``in_view``, ``size``: :func:`screen_radius`'s)."""
    leaves, levels = usable.shape
    counts = lod.rows[:, :, 1]
    every = np.arange(leaves)

    def counted(chosen: np.ndarray) -> int:
        drawn = in_view & (chosen >= 0)
        return lod.environment[1] + int(counts[every[drawn], chosen[drawn]].sum())

    if counted(target) <= budget:
        return target, False
    base_level = usable[:, levels - 1]  # each leaf's coarsest level with gaussians
    chosen = np.where(in_view, base_level, target)
    base = counted(chosen)
    if base >= budget:
        return chosen, base > budget
    # Every step of every leaf in view, from its coarsest level towards its target: the
    # step to level l (one the leaf has) costs the difference from the next coarser one.
    level = np.arange(levels)
    steps = ((usable == level) & in_view[:, None] & (level >= target[:, None]) & (level < base_level[:, None]))
    step_leaf, step_level = np.nonzero(steps)
    coarser = usable[step_leaf, step_level + 1]
    cost = counts[step_leaf, step_level] - counts[step_leaf, coarser]
    priority = size[step_leaf] * 2.0 ** step_level
    # A leaf's steps come coarse to fine (a tie of sizes 0 keeps that by the level).
    order = np.lexsort((-step_level, step_leaf, -priority))
    taken = np.cumsum(cost[order]) <= budget - base
    stop = int(np.argmin(taken)) if not taken.all() else taken.size
    accepted = order[:stop]
    np.minimum.at(chosen, step_leaf[accepted], step_level[accepted])
    return chosen, False


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
        # The scene itself, compared by identity: an id() could be reused by the next
        # reading once this one is freed, and a newly read level would look unchanged.
        return (self.lod, self.level, self.budget, self.distance)
