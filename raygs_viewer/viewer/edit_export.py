"""The Edit section's export: the gaussians not deleted, in their order, written to a
scene file (a PLY's own rows byte for byte), and the edit document beside it as
``NAME.edits.json``. An existing file waits for a confirmation; the scene shown is never
a target; both files are written atomically."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Protocol

from raygs_viewer.capture.edit_file import EditDocument, save_edit_document
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.scene.edits import Edits
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.ply_rows import write_kept
from raygs_viewer.scene.writing import WRITE_SUFFIXES


def edit_document_path(target: str | os.PathLike) -> Path:
    """Where an export's edit document is written: ``NAME.edits.json`` beside it."""
    target = Path(target)
    return target.with_name(f"{target.stem}.edits.json")


class Edited(Protocol):
    """What the export reads of the edit tool: the window, the scene, its edits and their document."""

    host: object
    edits: Edits

    @property
    def scene(self) -> Scene: ...

    def document(self) -> EditDocument: ...


class EditExport:
    """``file``: the target the panel names; ``confirm_replace``: a target waiting for a
    yes (None: none) because the files ``existing`` (it, its edit document, or both) are
    there; ``exported``: the edits' generation last written (None: never)."""

    def __init__(self, tool: Edited) -> None:
        self.tool = tool
        self.file = ""
        self.confirm_replace: str | None = None
        self.existing: tuple[str, ...] = ()
        self.exported: int | None = None  # the edits' generation last written

    def export(self, replace: bool = False) -> Path | None:
        """Writes the gaussians not deleted at :attr:`file`, and the edit document beside
        it; an existing file waits for a confirmation (``replace``)."""
        tool, panel = self.tool, self.tool.host.panel
        target = Path(self.file.strip() or "")
        try:
            if not self.file.strip():
                raise UserError("name the file to export to")
            if target.suffix.lower() not in WRITE_SUFFIXES:
                raise UserError(f"{target}: the export must end in {', '.join(WRITE_SUFFIXES)}")
            source = tool.host.loaded.source
            if not source.is_demo and Path(source.path).resolve() == target.resolve():
                raise UserError(f"{target}: is the scene shown; export to another file")
            document = edit_document_path(target)
            existing = tuple(str(path) for path in (target, document) if path.exists())
            if existing and not replace:
                self.confirm_replace, self.existing = str(target), existing
                return None
            kept = tool.edits.kept
            if not kept.any():
                raise UserError("every gaussian is deleted: nothing to export")
            write_kept(tool.scene.rows(kept), source.path, target, replace)
            save_edit_document(tool.document(), document, replace)
        except UserError as exc:
            panel.error = f"error: not exported: {one_line(exc)}"
            return None
        finally:
            if replace:
                self.confirm_replace = None
        self.exported = tool.edits.generation
        panel.note(f"exported {int(kept.sum()):,} gaussians to {target} (+ {document.name})")
        panel.error = ""
        return target
