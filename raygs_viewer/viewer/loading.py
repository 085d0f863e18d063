"""Opening scenes while the window runs: a path from the panel or files dropped on the
window load in the background; the current scene stays until the new one is on the
GPU, and the panel's lines say how it went. A ``.spz`` opens in the axes of the opener's
``reading`` (a SceneSource); switching them reads the current one again."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from raygs_viewer.errors import UserError
from raygs_viewer.scene.loader import LoadedScene, SceneLoader
from raygs_viewer.scene.lod_file import Fits
from raygs_viewer.scene.source import SceneSource, is_demo
from raygs_viewer.viewer.state import Message, done, failed, note


def scene_title(path: str) -> str:
    return "demo scene" if is_demo(path) else Path(path).name


class SceneOpener:
    """``loader`` does the loading; ``reading``: how a scene opened later is read (its
    .spz axes); ``fits()`` says what fits the GPU, for a streamed SOG's levels (None:
    no limit; a UserError: a limit that cannot be read, said in the panel, then none).
    Each action returns what the panel says of it. Where an Open would lose the edits
    of the scene shown, the first one says so and the same Open again goes on."""

    def __init__(self, reading: SceneSource = SceneSource.demo(), fits: Callable[[], Fits | None] = lambda: None):
        self.loader = SceneLoader()
        self.reading = reading
        self.fits = fits
        self._warned: tuple[str, str] | None = None  # (path, what it would lose) said once

    def open(self, path: str, cameras: str | None = None, unsaved: str | None = None) -> tuple[Message, ...]:
        """Starts loading ``path`` in the background (with ``cameras``, a cameras.json,
        instead of one found beside it); ``unsaved``: what opening another scene would
        lose (the shown scene's edits not exported), or None."""
        path = path.strip()
        if not path:
            return (failed("no file given"),)
        if unsaved is not None and self._warned != (path, unsaved):
            self._warned = (path, unsaved)
            return (failed(f"the edits of the scene shown ({unsaved}) are not exported; export them, or open it "
                           "again to leave them", "not opened"),)
        self._warned = None
        fits, problem = self._fits()
        self.loader.start(self.reading.at(path, cameras), fits=fits)
        return done(f"loading {path} ..."), problem

    def read_levels(self, source: SceneSource) -> Message | None:
        """Starts reading more levels of the streamed SOG shown (``source``), each a finer
        reading of it (``LoadedScene.refines``)."""
        fits, problem = self._fits()
        self.loader.start(source, fits=fits, refines=True)
        return problem

    def switch_axes(self, loaded: LoadedScene, axes: str, unsaved: str | None = None) -> tuple[Message, ...]:
        """Reads ``loaded`` again in the .spz axes ``axes`` when it is a .spz (with the
        cameras it has), and opens later ones so."""
        self.reading = self.reading.with_axes(axes)
        if loaded.scene.axes is None:
            return ()
        return self.open(loaded.path, loaded.cameras_path, unsaved) + (
            note(f"reading {scene_title(loaded.path)} again in {axes.upper()} axes ..."),)

    def drop(self, paths: list[str], unsaved: str | None = None) -> tuple[Message, ...]:
        """Files dropped on the window: the first is opened."""
        if not paths:
            return ()
        said = self.open(paths[0], unsaved=unsaved)
        if len(paths) > 1:
            said += (note(f"{len(paths)} files dropped; opening the first"),)
        return said

    def poll(self) -> LoadedScene | tuple[Message, ...] | None:
        """A finished load to show (:func:`shown_message` says how it went once it is
        shown), what the panel says of one that failed, or None."""
        result = self.loader.poll()
        if result is None:
            return None
        if isinstance(result, UserError):
            return load_failed(str(result).splitlines()[0])
        if result.scene.count == 0:
            # scene.io accepts an empty file, and one whose every gaussian is invalid, as an
            # empty scene; swapping the shown scene for a black window is never what was meant.
            why = "; ".join(result.warnings)
            return load_failed(f"{result.path}: no gaussians to show" + (f" ({why})" if why else ""))
        return result

    def close(self) -> None:
        self.loader.close()

    def _fits(self) -> tuple[Fits | None, Message | None]:
        try:
            return self.fits(), None
        except UserError as exc:
            return None, failed(exc)


def shown_message(loaded: LoadedScene) -> Message:
    """What the panel says of a load the window now shows."""
    return done("; ".join(["loaded " + scene_title(loaded.path)] + list(loaded.warnings)))


def load_failed(why: str) -> tuple[Message, ...]:
    """What the panel says of a load that failed, or that the GPU could not take."""
    return failed(why), note("")
