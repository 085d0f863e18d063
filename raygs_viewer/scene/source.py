"""What to read as a scene, as one value: the file (or the built-in demo), the training
cameras to show with it, the axes a ``.spz`` that declares none is taken to store, and a
streamed SOG's levels to read. The command line, the window and a document's recorded
scene make one; :func:`~raygs_viewer.scene.io.load_scene`, its readers and
:func:`~raygs_viewer.scene.loader.load_now` take it.

The options are checked here, once, when the value is made (a bad axes name fails even
for the demo, before anything is read), and an OSError or MemoryError of a read becomes
its one-line UserError here (:meth:`SceneSource.read_error`), whichever reader hit it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.reading import file_error
from raygs_viewer.scene.spz_format import DEFAULT_SPZ_AXES, spz_axes_system

__all__ = ["DEMO", "SCENE_FILES", "SceneSource", "is_demo"]

#: The scene "path" that means the built-in demo scene.
DEMO = "demo"

#: The files a source names, in words (help texts and errors); a .ply is INRIA's layout
#: or PlayCanvas's compressed one.
SCENE_FILES = ".ply, .splat, .spz, .sog, a SOG meta.json or a streamed SOG's lod-meta.json"


def is_demo(name: str | os.PathLike | None) -> bool:
    """Whether a scene name (an argument, a document's recorded path) means the demo."""
    return name is not None and os.fspath(name) == DEMO


@dataclass(frozen=True)
class SceneSource:
    """path: the scene file (or folder) as given, or :data:`DEMO`. cameras: an explicit
    cameras.json (None: the one found beside the file; the demo's own views). spz_axes:
    the convention ("rub" or "rdf", ``spz_format.SPZ_AXES``) of a ``.spz`` that declares
    no axes; other formats ignore it. levels: a streamed SOG's levels to read (None:
    every level that fits); other scenes ignore it. Paths are kept as strings."""

    path: str
    cameras: str | None = None
    spz_axes: str = DEFAULT_SPZ_AXES
    levels: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", os.fspath(self.path))
        if self.cameras is not None:
            object.__setattr__(self, "cameras", os.fspath(self.cameras))
        if self.levels is not None:
            object.__setattr__(self, "levels", tuple(self.levels))
        spz_axes_system(self.spz_axes)

    @classmethod
    def demo(cls, cameras: str | os.PathLike | None = None) -> SceneSource:
        """The built-in demo scene (with ``cameras`` instead of its own views)."""
        return cls(DEMO, cameras)

    @property
    def is_demo(self) -> bool:
        return is_demo(self.path)

    @property
    def recorded_path(self) -> str:
        """The scene as a sidecar or a path file records it: "demo", or the absolute path
        (the reader of the document may run in another folder)."""
        return DEMO if self.is_demo else os.path.abspath(self.path)

    def at(self, path: str | os.PathLike, cameras: str | os.PathLike | None = None) -> SceneSource:
        """Another scene read the same way (the same ``.spz`` axes): ``cameras`` its own,
        every level of a streamed SOG."""
        return SceneSource(path, cameras, self.spz_axes)

    def with_axes(self, axes: str | FileAxes | None) -> SceneSource:
        """This scene read in the ``.spz`` axes ``axes``: "rub" or "rdf", or those a
        scene was read in (``Scene.axes``, a document's record); None: as it is."""
        if axes is None:
            return self
        return replace(self, spz_axes=axes if isinstance(axes, str) else axes.assumed)

    def with_levels(self, levels: tuple[int, ...] | None) -> SceneSource:
        """This scene with a streamed SOG's ``levels`` to read (None: all that fit)."""
        return replace(self, levels=levels)

    def read_error(self, exc: OSError | MemoryError) -> UserError:
        """The one-line UserError of a read of this scene that failed with ``exc``."""
        if isinstance(exc, MemoryError):
            return file_error(self.path, "not enough memory to load this scene")
        if isinstance(exc, FileNotFoundError):
            return file_error(self.path, "no such file")
        if isinstance(exc, IsADirectoryError):
            return file_error(self.path, f"is a directory, expected a scene file ({SCENE_FILES})")
        if isinstance(exc, PermissionError):
            return file_error(self.path, "permission denied")
        return file_error(self.path, f"cannot read: {exc.strerror or exc}")
