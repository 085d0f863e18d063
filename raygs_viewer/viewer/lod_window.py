"""The window's level of detail for a streamed SOG (``lod-meta.json``; docs/lod.md).

Reading. The command line's scene is read before the window opens only up to what the
first picture needs (:func:`first_levels`: the coarsest level, or ``--lod N``'s), so a
bad file still fails before a window opens; the window then reads the levels its
settings want in the background (:meth:`WindowLod.for_frame`), coarsest first, as a
scene opened from the panel is read. Each level read replaces the renderer's scene and
keeps the view (:meth:`WindowLod.refine`). A level only adds rows after those read
before (``scene.lod_file``), so the last order and its choice still name the right
gaussians: they are drawn until the new scene's first sort is done
(``shown_scene.ShownScene``), and a level arriving never blanks the picture.

Each frame the sort thread makes the choice (:func:`lod_request`, from the scene and
the settings ``lod``, ``lod_budget``, ``lod_distance``); the drawn result's orders carry
its rows. Screenshots make the choice for their own camera, as ``render --sidecar`` does,
so the sidecar's settings reproduce them.

Colour by level draws a copy of the scene whose colours say each gaussian's level
(:data:`LEVEL_COLOURS`; the environment grey): the same rows, so orders and choices carry
over, and no shader knows of it.

:class:`WindowLod` holds none of the window: each call is handed the scene shown, the
settings and the loader's state, and returns what to do as a value (:class:`LodFrame`,
:class:`Refined`, :class:`Swap`), which the window applies.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Protocol

import moderngl
import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.memory import scene_fits
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.lod_file import Fits, LodScene, lod_index_file, merged_spans, read_index, span_rows
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.sh import C0
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest
from raygs_viewer.sort.request import SortResult

#: The window's budget of gaussians when the command line gives none (``render`` has no
#: limit): the cull and sort of 4,000,000 took 66-72 ms on 16 cores in docs/lod.md, so
#: about half that keeps the drawn order a few frames old while flying.
DEFAULT_WINDOW_BUDGET = 2_000_000

#: Colour by level: level l is drawn in ``LEVEL_COLOURS[l % 8]`` (0 the finest, red), the
#: environment in :data:`ENVIRONMENT_COLOUR`.
LEVEL_COLOURS = ((0.9, 0.15, 0.1), (0.15, 0.8, 0.2), (0.15, 0.35, 0.95), (0.95, 0.85, 0.1),
                 (0.85, 0.2, 0.85), (0.1, 0.85, 0.85), (0.95, 0.55, 0.1), (0.55, 0.3, 0.9))
ENVIRONMENT_COLOUR = (0.5, 0.5, 0.5)


def first_levels(source: SceneSource, settings: RenderSettings) -> tuple[int, ...] | None:
    """The levels of ``source``'s scene read before the window opens: ``settings.lod``'s,
    else the coarsest; None when it is not a streamed SOG (read it whole)."""
    if source.is_demo or lod_index_file(source.path) is None:
        return None
    if settings.lod is not None:
        return (settings.lod,)
    return (read_index(source.path, source.path).levels - 1,)


def window_settings(settings: RenderSettings, start: RenderSettings, loaded: LoadedScene) -> RenderSettings:
    """``settings`` for a newly opened scene: a streamed SOG's level, budget and distance
    start at the command line's (``start``; the budget at :data:`DEFAULT_WINDOW_BUDGET`
    when it gave none), any other scene takes none of them (its sidecars could not be
    rendered again with them)."""
    if loaded.lod is None:
        return replace(settings, lod=None, lod_budget=None, lod_distance=None)
    budget = DEFAULT_WINDOW_BUDGET if start.lod_budget is None else start.lod_budget
    level = None if start.lod is None else min(start.lod, loaded.lod.levels - 1)  # another scene may have fewer
    return replace(settings, lod=level, lod_budget=budget, lod_distance=start.lod_distance)


def wanted_levels(levels: int, level: int | None) -> list[int]:
    """The levels the setting ``lod`` (``level``) draws from: one, or every level."""
    return list(range(levels)) if level is None else [min(level, levels - 1)]


def row_levels(lod: LodScene) -> np.ndarray:
    """(N,) int64: the level of each row of ``lod.scene``; -1 for the environment (and
    any row no leaf names)."""
    levels = np.full(lod.scene.count, -1, np.int64)
    for level in np.flatnonzero(lod.loaded):
        start, count = lod.rows[:, level].T
        levels[span_rows(merged_spans(np.stack([start, start + count], axis=1)))] = level
    return levels


def tinted_scene(lod: LodScene) -> Scene:
    """``lod.scene`` with each gaussian's colour its level's (SH degree 0)."""
    palette = np.array(LEVEL_COLOURS + (ENVIRONMENT_COLOUR,), np.float64)
    levels = row_levels(lod)
    rgb = palette[np.where(levels < 0, len(LEVEL_COLOURS), levels % len(LEVEL_COLOURS))]
    dc = ((rgb - 0.5) / C0).astype(np.float32)[:, None, :]  # the inverse of colour = 0.5 + C0 dc
    return replace(lod.scene, sh=dc, sh_degree=0)


def extends(old: LodScene, new: LodScene) -> bool:
    """Whether ``new`` holds ``old``'s rows where ``old`` had them (levels read since only
    appended): what keeps an order of ``old`` right for ``new``."""
    count = old.scene.count
    return (new.scene.count >= count and new.environment == old.environment and bool(new.loaded[old.loaded].all())
            and np.array_equal(new.rows[:, old.loaded], old.rows[:, old.loaded])
            and np.array_equal(new.scene.positions[:count], old.scene.positions))


class LoaderState(Protocol):
    """What the level of detail reads of the window's loader (``scene.loader.SceneLoader``)."""

    @property
    def busy(self) -> bool:
        """A load is in progress."""

    @property
    def path(self) -> str:
        """The path of the current load ("" with none)."""


@dataclass(frozen=True)
class Swap:
    """Put ``scene`` on the GPU; ``keep``: its rows hold the shown scene's where they were,
    so the last order is drawn until its first sort (``shown_scene.ShownScene``)."""

    scene: Scene
    keep: bool


@dataclass(frozen=True)
class Refined:
    """What a finer reading of the scene shown asks of the window: ``swap`` (None: the
    scene on the GPU stays; the load's last word: the hash, what was left unread), then
    ``loaded`` and ``settings`` are the window's."""

    loaded: LoadedScene
    settings: RenderSettings
    swap: Swap | None = None


@dataclass(frozen=True)
class LodFrame:
    """A frame's level of detail: the request the sort thread makes the choice by (None:
    not a streamed SOG), and the levels to start reading (None: nothing to read)."""

    request: LodRequest | None
    read: SceneSource | None = None


def refines(current: LoadedScene | None, loaded: LoadedScene) -> bool:
    """Whether ``loaded`` is a finer reading of the scene shown (``current``)."""
    return (loaded.refines and loaded.lod is not None and current is not None and current.lod is not None
            and loaded.path == current.path)


def reading(loaded: LoadedScene, loader: LoaderState) -> bool:
    """Whether levels of the scene shown (``loaded``) are being read."""
    return loaded.lod is not None and loader.busy and loader.path == loaded.path


def lod_request(loaded: LoadedScene, settings: RenderSettings) -> LodRequest | None:
    """The choice to make for a view of the scene shown with ``settings``."""
    lod = loaded.lod
    if lod is None:
        return None
    return LodRequest(lod, settings.lod, settings.lod_budget, settings.lod_distance)


def window_fits(ctx: moderngl.Context) -> Callable[[], Fits | None]:
    """What says whether a scene fits this window's GPU (``render.gl.memory.scene_fits``);
    a UserError where ``RAYGS_GPU_MEMORY`` is not a size."""
    return lambda: scene_fits(ctx)[0]


class WindowLod:
    """The level of detail of the scene the window shows: it is handed the scene, the
    settings and the loader's state at each call and returns what the window is to do
    (:class:`LodFrame`, :class:`Refined`, :class:`Swap`), which the window applies.

    ``choice``: the choice the last frame drew (None: not a streamed SOG, or no sort yet);
    ``tint``: colour by level is on (the window sets it once the tinted scene is shown)."""

    def __init__(self) -> None:
        self.choice: LodChoice | None = None
        self.tint = False
        self._asked: LodScene | None = None  # the scene whose missing levels are being read

    # -- scenes ----------------------------------------------------------------------------
    def installed(self) -> None:
        """A new scene is shown, in its own colours (its settings: :func:`window_settings`)."""
        self.tint, self.choice, self._asked = False, None, None

    def refine(self, current: LoadedScene, loaded: LoadedScene, settings: RenderSettings, start: RenderSettings,
               loader: LoaderState) -> Refined | None:
        """How to show the levels of ``loaded`` (:func:`refines` ``current``) in the view as
        it is: the scene drawn (tinted while colour by level is on), the SH degree
        followed when it is each scene's own (``start``: the command line's settings);
        None while a reading has not yet caught up with the levels shown."""
        if loaded.scene is current.scene:  # the load's last word: the hash, what was left unread
            return Refined(loaded, settings)
        if loader.busy and not loaded.lod.loaded[current.lod.loaded].all():
            return None
        swap = Swap(self._drawn_scene(loaded.lod), keep=extends(current.lod, loaded.lod))
        if start.sh_degree is None and settings.sh_degree == current.scene.sh_degree:
            settings = replace(settings, sh_degree=loaded.scene.sh_degree)
        return Refined(loaded, settings, swap)

    def tint_swap(self, on: bool, lod: LodScene | None) -> Swap | None:
        """The swap that turns colour by level on or off (the same rows), None when there
        is nothing to do; the window sets :attr:`tint` once it is shown."""
        if on == self.tint or lod is None:
            return None
        return Swap(tinted_scene(lod) if on else lod.scene, keep=True)

    def check_screenshot(self) -> None:
        """UserError while colour by level is on: a sidecar re-renders the scene's colours."""
        if self.tint:
            raise UserError("screenshots save the scene's own colours; turn off colour by level "
                            "(Level of detail section) first")

    # -- frames ----------------------------------------------------------------------------
    def for_frame(self, loaded: LoadedScene, settings: RenderSettings, loader: LoaderState) -> LodFrame:
        """The frame's request (:func:`lod_request`), and the levels to start reading: those
        the settings want that are not read (once per scene; never over a load under way,
        nor past the GPU's memory, which the reading is told)."""
        lod = loaded.lod
        if self._asked is lod and loader.path != loaded.path:
            self._asked = None  # another file's load took the loader over (and failed): read again
        read = None
        if lod is not None and not lod.unread and self._asked is not lod and not loader.busy:
            level = settings.lod
            wanted = wanted_levels(lod.levels, level)
            if not lod.loaded[wanted].all():
                self._asked = lod
                done = set(np.flatnonzero(lod.loaded).tolist())
                levels = None if level is None else tuple(sorted(done | set(wanted)))
                read = SceneSource(loaded.path, loaded.cameras_path, levels=levels)
        return LodFrame(lod_request(loaded, settings), read)

    def shown(self, result: SortResult | None) -> None:
        """Notes the choice of the sort result the frame draws."""
        self.choice = None if result is None else result.choice

    def _drawn_scene(self, lod: LodScene) -> Scene:
        return tinted_scene(lod) if self.tint else lod.scene
