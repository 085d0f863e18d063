"""Opening scenes while the window runs: a path from the panel or files dropped on the
window load in the background; the current scene stays until the new one is on the
GPU, and the panel's lines say how it went. A ``.spz`` opens in the axes of the opener's
``reading`` (a SceneSource); switching them reads the current one again."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import moderngl

from raygs_viewer.errors import UserError, one_line
from raygs_viewer.scene.loader import LoadedScene, SceneLoader
from raygs_viewer.scene.lod_file import Fits
from raygs_viewer.scene.source import SceneSource, is_demo
from raygs_viewer.viewer.state import PanelState


def scene_title(path: str) -> str:
    return "demo scene" if is_demo(path) else Path(path).name


class SceneOpener:
    """``loader`` does the loading; ``panel`` gets the message and error lines;
    ``reading``: how a scene opened later is read (its .spz axes); ``fits()`` says what
    fits the GPU, for a streamed SOG's levels (None: no limit); ``unsaved()``: what
    opening another scene would lose (the shown scene's edits not exported), or None.
    Where something would be lost, the first Open says so and the same Open again goes on."""

    def __init__(self, panel: PanelState, reading: SceneSource = SceneSource.demo(),
                 fits: Callable[[], Fits | None] = lambda: None, unsaved: Callable[[], str | None] = lambda: None):
        self.panel = panel
        self.loader = SceneLoader()
        self.reading = reading
        self.fits = fits
        self.unsaved = unsaved
        self._warned: tuple[str, str] | None = None  # (path, what it would lose) said once

    def open(self, path: str, cameras: str | None = None) -> None:
        """Starts loading ``path`` in the background (with ``cameras``, a cameras.json,
        instead of one found beside it)."""
        path = path.strip()
        if not path:
            self.panel.error = "error: no file given"
            return
        lost = self.unsaved()
        if lost is not None and self._warned != (path, lost):
            self._warned = (path, lost)
            self.panel.error = f"error: not opened: the edits of the scene shown ({lost}) are not exported; " \
                               "export them, or open it again to leave them"
            return
        self._warned = None
        self.panel.error = ""
        self.panel.message = f"loading {path} ..."
        self.loader.start(self.reading.at(path, cameras), fits=self.fits())

    def read_levels(self, source: SceneSource) -> None:
        """Starts reading more levels of the streamed SOG shown (``source``), each a finer
        reading of it (``LoadedScene.refines``)."""
        self.loader.start(source, fits=self.fits(), refines=True)

    def switch_axes(self, loaded: LoadedScene, axes: str) -> None:
        """Reads ``loaded`` again in the .spz axes ``axes`` when it is a .spz (with the
        cameras it has), and opens later ones so."""
        self.reading = self.reading.with_axes(axes)
        if loaded.scene.axes is not None:
            self.open(loaded.path, loaded.cameras_path)
            self.panel.message = f"reading {scene_title(loaded.path)} again in {axes.upper()} axes ..."

    def drop(self, paths: list[str]) -> None:
        """Files dropped on the window: the first is opened."""
        if paths:
            self.open(paths[0])
            if len(paths) > 1:
                self.panel.message = f"{len(paths)} files dropped; opening the first"

    def poll(self, install: Callable[[LoadedScene], None]) -> None:
        """Hands a finished load to ``install`` (which puts it on the GPU or raises,
        leaving the current scene)."""
        result = self.loader.poll()
        if result is None:
            return
        if isinstance(result, UserError):
            self._failed(f"error: {str(result).splitlines()[0]}")
            return
        if result.scene.count == 0:
            # scene.io accepts an empty file, and one whose every gaussian is invalid, as an
            # empty scene; swapping the shown scene for a black window is never what was meant.
            why = "; ".join(result.warnings)
            self._failed(f"error: {result.path}: no gaussians to show" + (f" ({why})" if why else ""))
            return
        try:
            install(result)
        except (UserError, MemoryError, moderngl.Error) as exc:  # e.g. too large for this GPU
            self._failed(f"error: {result.path}: {one_line(exc)}")
            return
        self.panel.error = ""
        self.panel.message = "; ".join(["loaded " + scene_title(result.path)] + list(result.warnings))

    def close(self) -> None:
        self.loader.close()

    def _failed(self, error: str) -> None:
        self.panel.error = error
        self.panel.message = ""
