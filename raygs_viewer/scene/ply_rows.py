"""Some rows of an INRIA PLY written as a PLY of their own, every byte of each row as the
source has it: extra properties, ``filter_3D`` and the source's own rounding all kept.

An exported cut of a PLY must be the source less the gaussians taken away, not the
scene as read written again: the reader fuses a 3D filter into scale and opacity and
turns logits into opacities, and neither goes back to the same bits. So the kept rows
are copied from the file itself (plyfile's structured rows, memory-mapped where the
rows have a fixed size), the header's comments, other elements, format and byte
order kept; only the vertex count changes.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement, PlyParseError

from raygs_viewer.errors import UserError
from raygs_viewer.files import atomic_writer, check_writable_folder
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.ply_file import PLY_FORMAT
from raygs_viewer.scene.spz_format import SpzEncoding
from raygs_viewer.scene.writing import write_scene

LOG_SCALE_COLUMNS = ("scale_0", "scale_1", "scale_2")


class PlyRows:
    """The vertex rows of the PLY at ``path``, as the file stores them. ``count`` rows;
    the file must still hold ``expected`` rows (the count the scene was read with) or
    the file changed since, and a copy would take the wrong rows."""

    def __init__(self, path: str | os.PathLike, expected: int | None = None) -> None:
        self.path = Path(path)
        try:
            self.ply = PlyData.read(str(self.path), mmap="c")
        except (OSError, PlyParseError, ValueError) as exc:
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise UserError(f"{self.path}: cannot read its rows again ({detail})") from None
        names = [element.name for element in self.ply.elements]
        if "vertex" not in names:
            raise UserError(f"{self.path}: PLY file has no 'vertex' element")
        self.vertex = self.ply["vertex"]
        if expected is not None and self.count != expected:
            raise UserError(f"{self.path}: holds {self.count:,} gaussians now, {expected:,} when it was read: "
                            f"it changed since; open it again")

    @property
    def count(self) -> int:
        return int(self.vertex.count)

    def log_scales(self, rows: np.ndarray) -> np.ndarray:
        """(K, 3) float32 the file's log-scales of ``rows`` ((K,) int64)."""
        return np.stack([np.asarray(self.vertex.data[name][rows], np.float32) for name in LOG_SCALE_COLUMNS], axis=1)

    def write(self, rows: np.ndarray, target: str | os.PathLike, overwrite: bool = False) -> Path:
        """Writes the vertex rows ``rows`` ((K,) int64, in that order) as a PLY at
        ``target``, atomically, never over an existing file without ``overwrite``."""
        target = Path(target)
        if target.is_dir():
            raise UserError(f"{target}: is a folder")
        check_writable_folder(target, target.parent)
        if target.exists() and not overwrite:
            raise UserError(f"{target}: already exists (pass --overwrite to replace it)")
        rows = np.asarray(rows, np.int64)
        if rows.size and (rows.min() < 0 or rows.max() >= self.count):
            raise UserError(f"{self.path}: holds {self.count:,} gaussians, fewer than when it was read: "
                            f"it changed since; open it again")
        kept = PlyElement.describe(self.vertex.data[rows], "vertex",
                                   comments=list(self.vertex.comments))
        elements = [kept if element.name == "vertex" else element for element in self.ply.elements]
        out = PlyData(elements, text=self.ply.text, byte_order=self.ply.byte_order,
                      comments=list(self.ply.comments), obj_info=list(self.ply.obj_info))
        with atomic_writer(target, overwrite) as stream:
            out.write(stream)
        return target


def copies_rows(scene: Scene, target: str | os.PathLike) -> bool:
    """Whether ``scene`` written at ``target`` is a copy of its file's own rows: an INRIA
    PLY to a PLY."""
    return scene.format == PLY_FORMAT and Path(target).suffix.lower() == ".ply"


def read_count(scene: Scene) -> int:
    """The rows the file held when ``scene`` was read from it (its gaussians and its drops)."""
    return scene.count + sum(scene.dropped.values())


def write_kept(scene: Scene, path: str, target: str | os.PathLike, overwrite: bool = False, *,
               rows: PlyRows | None = None, spz: SpzEncoding = SpzEncoding()) -> bool:
    """Writes ``scene`` (read from ``path``; a subset keeps its file rows,
    ``Scene.rows``) at ``target`` in the format its suffix names: a PLY read as a PLY by
    copying its own rows (``rows``, read here if not given), anything else from the
    scene. True when the rows were copied."""
    if copies_rows(scene, target):
        (rows or PlyRows(path, scene.count if scene.file_rows is None else None)).write(
            scene.rows_in_file, target, overwrite)
        return True
    write_scene(scene, target, overwrite, spz)
    return False
