"""A scene opened for rendering with its level-of-detail settings: what ``render``,
``render-path``, ``verify`` and ``evaluate`` share. The per-view choice travels in each
view's sort request (``SortRequest.levels``); the window makes it on its sort thread.

For a streamed SOG, ``settings.lod`` N reads level N alone (and the environment) into
an ordinary Scene; otherwise every level that fits is read (``lod_file.load_lod``) and
each view draws the levels ``sort.lod_choice.choose`` picks under ``settings.lod_budget``
and ``settings.lod_distance``. Other scenes take none of the three settings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.demo import demo_scene
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.lod_file import Fits, LodScene, level_scene, load_lod, lod_index_file, span_rows
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest

#: The settings that only a streamed SOG takes.
LOD_FIELDS = ("lod", "lod_budget", "lod_distance")


@dataclass(frozen=True, eq=False)
class OpenedScene:
    """scene: what the renderer holds. lod: the per-view choice to make before each
    view is drawn (None: draw the whole scene). note: one line on what was not read
    (the GPU's memory), or "". deleted: the rows every sort leaves out (deleted in the
    window: a screenshot's edits; None: none)."""

    scene: Scene
    lod: LodRequest | None = None
    note: str = ""
    environment: int = 0
    deleted: DeletedRows | None = None

    @property
    def framed(self) -> np.ndarray:
        """(N, 3) the positions a camera that frames the scene should see: a streamed
        SOG's levels without its environment (its first rows, which surround the scene
        from afar)."""
        return self.scene.positions[self.environment:]

    def drawn(self, camera: Camera) -> tuple[Scene, LodChoice | None]:
        """What ``camera`` draws as a Scene of its own (the reference renderer's input: the
        level-of-detail choice's rows, without the deleted ones, in scene order), and the
        choice (None: the whole scene)."""
        choice = None if self.lod is None else self.lod.choose(camera)
        if self.deleted is None:
            return (self.scene if choice is None else self.lod.lod.subset(choice.spans)), choice
        rows = np.arange(self.scene.count) if choice is None else span_rows(choice.spans)
        return self.scene.rows(rows[~self.deleted.mask[rows]]), choice


def lod_settings_given(settings: RenderSettings) -> list[str]:
    """The level-of-detail settings that are set, as option names."""
    return ["--" + name.replace("_", "-") for name in LOD_FIELDS if getattr(settings, name) is not None]


def refuse_lod_settings(what: str, settings: RenderSettings) -> None:
    """UserError when ``settings`` set a level-of-detail option for ``what``, a scene
    that is not a streamed SOG (the option would silently do nothing)."""
    given = lod_settings_given(settings)
    if given:
        raise UserError(f"{what}: not a streamed SOG: {', '.join(given)} "
                        f"appl{'y' if len(given) > 1 else 'ies'} to a lod-meta.json scene")


def open_scene(source: SceneSource, settings: RenderSettings, *, fits: Fits | None = None) -> OpenedScene:
    """The demo or the scene file of ``source`` for ``settings`` (see the module
    docstring); ``fits``: whether a scene of (count, SH degree) fits the GPU
    (``render.gl.memory.scene_fits``); ``source.levels``: the levels to read for the
    choice (a sidecar's: those read when it was taken), None for every level that fits."""
    if source.is_demo:
        refuse_lod_settings("the demo scene", settings)
        return OpenedScene(demo_scene())
    if lod_index_file(source.path) is None:
        refuse_lod_settings(source.path, settings)
        return OpenedScene(load_scene(source))
    return for_settings(load_lod(source.path, levels=levels_to_read(settings, source.levels), fits=fits), settings)


def levels_to_read(settings: RenderSettings, recorded: tuple[int, ...] | None = None) -> tuple[int, ...] | None:
    """The levels of a streamed SOG that ``settings`` need read: the one level they set,
    else those ``recorded``, else None (all that fit)."""
    return recorded if settings.lod is None else (settings.lod,)


def for_settings(lod: LodScene, settings: RenderSettings) -> OpenedScene:
    """A streamed SOG read with :func:`levels_to_read` opened for ``settings``: level
    ``settings.lod`` as a scene of its own, or every level read with the choice to make."""
    if settings.lod is not None:
        return OpenedScene(level_scene(lod, settings.lod), environment=lod.environment[1])
    return OpenedScene(lod.scene, LodRequest(lod, None, settings.lod_budget, settings.lod_distance), lod.unread,
                       lod.environment[1])
