"""A scene opened for rendering with its level-of-detail settings, and the per-view
choice applied to a renderer: what ``render``, ``render-path``, ``verify`` and
``evaluate`` share (the window makes the same choice on its sort thread).

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
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.lod_file import Fits, load_lod, lod_index_file
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest

#: The settings that only a streamed SOG takes.
LOD_FIELDS = ("lod", "lod_budget", "lod_distance")


@dataclass(frozen=True, eq=False)
class OpenedScene:
    """scene: what the renderer holds. lod: the per-view choice to make before each
    view is drawn (None: draw the whole scene). note: one line on what was not read
    (the GPU's memory), or ""."""

    scene: Scene
    lod: LodRequest | None = None
    note: str = ""

    @property
    def framed(self) -> np.ndarray:
        """(N, 3) the positions a camera that frames the scene should see: a streamed
        SOG's levels without its environment (which surrounds the scene from afar)."""
        if self.lod is None:
            return self.scene.positions
        start, count = self.lod.lod.environment
        positions = self.scene.positions
        return np.concatenate([positions[:start], positions[start + count:]])


def lod_settings_given(settings: RenderSettings) -> list[str]:
    """The level-of-detail settings that are set, as option names."""
    return ["--" + name.replace("_", "-") for name in LOD_FIELDS if getattr(settings, name) is not None]


def open_scene(path: str, settings: RenderSettings, *, spz_axes: str = "rub", fits: Fits | None = None
               ) -> OpenedScene:
    """The scene file ``path`` for ``settings`` (see the module docstring); ``fits``:
    whether a scene of (count, SH degree) fits the GPU (``render.gl.memory.scene_fits``)."""
    if lod_index_file(path) is None:
        given = lod_settings_given(settings)
        if given:
            raise UserError(f"{path}: not a streamed SOG: {', '.join(given)} "
                            f"appl{'y' if len(given) > 1 else 'ies'} to a lod-meta.json scene")
        return OpenedScene(load_scene(path, spz_axes=spz_axes))
    if settings.lod is not None:
        return OpenedScene(load_scene(path, lod=settings.lod))
    lod = load_lod(path, fits=fits)
    return OpenedScene(lod.scene, LodRequest(lod, None, settings.lod_budget, settings.lod_distance), lod.unread)


def restrict_to_view(renderer, lod: LodRequest | None, camera: Camera) -> LodChoice | None:
    """Restricts ``renderer`` (a GLRenderer) to what ``camera`` draws of ``lod``: called
    once per frame, before its sorts (tiles and both eyes share the frame's choice)."""
    if lod is None:
        return None
    choice = lod.choose(camera)
    renderer.restrict(choice.spans)
    return choice
