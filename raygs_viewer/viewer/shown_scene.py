"""The scene the window shows: as read, on the GPU with its sorters, and its level of detail.

A scene opened replaces the renderer and the sorters whole. A streamed SOG's next level
and colour by level replace them too, keeping the rows (a level only adds rows after
those read before; the tinted copy has the same rows), so the last sort result still
names the right gaussians: it is drawn until the new sorter's first, and a level
arriving never blanks the picture.

What to do about the levels (which to read, which scene to show, whether the last
order stays right) is ``lod_window.WindowLod``'s decision, made from what it is handed
and returned as a value; :class:`ShownScene` carries out what it says of the GPU and
the reading, and the window takes the scene as read and the settings from it.
"""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass, replace
from typing import Callable

import moderngl

from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.scene.lod_file import LodScene
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import SortResult
from raygs_viewer.sort.worker import BackgroundSorter, InlineSorter
from raygs_viewer.viewer.lod_window import LoaderState, Refined, WindowLod


@dataclass(frozen=True)
class Swapped:
    """The GPU's copy of the scene was replaced: what was drawn of the one before is
    stale; ``kept``: the result drawn on until the new sorter's first, as it was (None:
    none)."""

    kept: SortResult | None


class ShownScene:
    """``renderer`` (made by ``renderer_factory(ctx, scene, general=)``) draws the scene
    (None before :meth:`open`); ``sorter`` (made by
    ``sorter_factory(direct_sorter)``) sorts the frames' requests without waiting;
    ``direct_sorter`` sorts on the caller's thread and returns the order (screenshots,
    picks and selections sort with it; with the CPU sort, ``sorter`` runs the same
    DepthSorter on its thread).
    ``sort``: "cpu" or "gpu", what ``sort_for(count)`` says for the scene's size when
    it is opened (or :meth:`resort` is asked). With "gpu": ``sorter`` is an InlineSorter of a GpuSorter that sorts in the
    frame, and ``direct_sorter`` another GpuSorter: the frames' orders stay on the GPU,
    and no screenshot's sorts reuse the buffer of the order the window draws. Neither
    waits for the GPU after a sort (a frame's draw waits for it on the GPU itself);
    the frames' sorts are timed by :attr:`sort_timer`'s queries instead.
    ``fallback``: the last result of the scene before a swap that kept the rows, drawn
    until the new sorter's first (:meth:`shown`). ``lod``: its level of detail.

    Each action that replaces the GPU's copy returns :class:`Swapped`: what the window
    keeps of the scene before is then stale."""

    def __init__(self, ctx: moderngl.Context, *, general: bool, renderer_factory: Callable[..., GLRenderer],
                 sorter_factory: Callable[..., BackgroundSorter], sort_for: Callable[[int], str] = lambda count: "cpu"):
        self.ctx, self.general, self.sort_for, self.sort = ctx, general, sort_for, "cpu"
        self.renderer_factory, self.sorter_factory = renderer_factory, sorter_factory
        self.renderer: GLRenderer | None = None
        self.sorter: BackgroundSorter | InlineSorter | None = None
        self.direct_sorter: DepthSorter | GpuSorter | None = None
        self.fallback: SortResult | None = None
        self.lod = WindowLod()
        self._sort_timer: GpuTimer | None = None  # made with the first GPU sorter, kept for the window
        # What releases the scene's renderer and closes its sorters, each made with them.
        self._renderer_made, self._sorters_made = ExitStack(), ExitStack()

    @property
    def sort_timer(self) -> GpuTimer | None:
        """The GPU time of the frames' sorts while they run on the GPU (read frames
        late: ``GpuTimer.frame``); None while the CPU sorts."""
        return self._sort_timer if self.sort == "gpu" else None

    # -- scenes ----------------------------------------------------------------------------
    def open(self, scene: Scene) -> Swapped:
        """Shows a scene opened (not a finer reading of the one shown: :meth:`refine`), in
        its own colours, sorted as ``sort_for`` its size says; a UserError (too large for
        this GPU) changes nothing."""
        sort, self.sort = self.sort, self.sort_for(scene.count)
        try:
            swapped = self._swap(scene, keep=False)
        except BaseException:
            self.sort = sort
            raise
        self.lod.installed()
        return swapped

    def refine(self, current: LoadedScene, loaded: LoadedScene, settings: RenderSettings, start: RenderSettings,
               loader: LoaderState) -> tuple[Refined | None, Swapped | None]:
        """Shows the levels of ``loaded``, a finer reading of the scene shown (``current``;
        ``lod_window.refines``), in the view as it is (``WindowLod.refine``, with the
        ``loader``'s state); returns the scene as read and the settings now (``start``:
        the command line's; None when nothing changes), and the swap where there was one.
        A UserError (the GPU's memory) leaves the scene shown."""
        refined = self.lod.refine(current, loaded, settings, start, loader)
        if refined is None or refined.swap is None:
            return refined, None
        return refined, self._swap(refined.swap.scene, refined.swap.keep)

    def resort(self) -> Swapped | str | None:
        """Sorts the scene shown as ``sort_for`` says now ("cpu", "gpu"), from the next
        frame on: new sorters, the renderer and its buffers kept (None: nothing to do).
        Where they cannot be made (the GPU sort cannot hold this scene) the sorters stay
        and the one line says why."""
        sort = None if self.renderer is None else self.sort_for(self.renderer.scene.count)
        if sort is None or sort == self.sort:
            return None
        previous, self.sort = self.sort, sort
        try:
            sorters = self._sorters(self.renderer.scene)
        except UserError as exc:
            self.sort = previous
            return one_line(exc)
        *sorters, sorters_made = sorters
        self._sorters_made.close()
        self._sorters_made = sorters_made
        self.direct_sorter, self.sorter = sorters
        self.fallback = None
        return Swapped(None)

    def set_tint(self, on: bool, lod: LodScene | None) -> Swapped | str | None:
        """Colour by level on or off for the levels ``lod``: the renderer gets the tinted
        copy, or the scene (None: nothing to do). Where that fails (a UserError,
        MemoryError or moderngl.Error) it stays as it was and the one line says why."""
        swap = self.lod.tint_swap(on, lod)
        if swap is None:
            return None
        try:
            swapped = self._swap(swap.scene, swap.keep)
        except (UserError, MemoryError, moderngl.Error) as exc:
            return one_line(exc)
        self.lod.tint = on
        return swapped

    # -- frames ----------------------------------------------------------------------------
    def shown(self, result: SortResult | None) -> SortResult | None:
        """The result a frame draws: ``result`` (the sorter's newest), else the fallback,
        which the new sorter's first result ends; its choice is the one drawn."""
        if result is not None:
            self.fallback = None
        else:
            result = self.fallback
        self.lod.shown(result)
        return result

    def close(self) -> None:
        """Releases the renderer and closes the sorters (a CPU direct sorter on the sort
        thread that runs it)."""
        self._sorters_made.close()
        self._renderer_made.close()

    def _swap(self, scene: Scene, keep: bool) -> Swapped:
        """``scene`` on the GPU with its own sorters; a UserError (too large for this GPU)
        changes nothing. ``keep``: ``scene`` holds the rows of the scene shown where they
        were, so the last result (the sorter's newest, else the fallback) becomes the
        fallback, as serial 0, which no request has (so its draw is never taken for a new
        one's)."""
        last = (None if self.sorter is None else self.sorter.latest()) or self.fallback
        with ExitStack() as made:
            renderer = self.renderer_factory(self.ctx, scene, general=self.general)
            made.callback(renderer.release)
            *sorters, sorters_made = self._sorters(scene)
            renderer_made = made.pop_all()
        self.close()
        self._renderer_made, self._sorters_made = renderer_made, sorters_made
        self.renderer, (self.direct_sorter, self.sorter) = renderer, sorters
        # A GPU order lives in its sorter's buffers, gone with it; the new sorter answers
        # in the same frame anyway.
        kept = last if keep and self.sort == "cpu" else None
        self.fallback = None if kept is None else replace(kept, serial=0)
        return Swapped(kept)

    def _sorters(self, scene: Scene) -> tuple[DepthSorter | GpuSorter, BackgroundSorter | InlineSorter, ExitStack]:
        """(direct sorter, the frames' sorter, what closes both) of ``scene`` (see the
        class docstring)."""
        with ExitStack() as made:
            if self.sort == "gpu":
                if self._sort_timer is None:
                    self._sort_timer = GpuTimer(self.ctx)
                direct = GpuSorter(self.ctx, scene, finish=False)
                made.callback(direct.close)
                frames = InlineSorter(GpuSorter(self.ctx, scene, finish=False, timer=self._sort_timer))
            else:  # the sort thread runs the direct sorter too, and closes it
                direct = DepthSorter(scene)
                frames = self.sorter_factory(direct)
            made.callback(frames.close)
            return direct, frames, made.pop_all()
