"""Niantic's ``.spz``: versions 2 and 3 (gzip around a header and packed arrays) and 4.

NOTE: not implemented yet (issue 18): a .spz file is refused in one line.
"""

from __future__ import annotations

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.reading import Reporter, file_error


def load_spz(path, shown: str, report: Reporter, chunk_bytes: int) -> Scene:
    raise file_error(shown, ".spz files are not supported yet")


def spz_bytes(scene: Scene, version: int = 3) -> bytes:
    """The whole ``.spz`` file of ``scene`` (the spz helper replaces this stub)."""
    raise UserError("writing .spz files is not supported yet")
