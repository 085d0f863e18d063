"""The Edit section's export: the gaussians not deleted, in their order, written to a
scene file (a PLY's own rows byte for byte), and the edit document beside it as
``NAME.edits.json``. An existing file waits for a confirmation; the scene shown is never
a target; both files are written atomically.

The files are written on a thread of their own (a SOG of a million gaussians takes tens
of seconds), from the rows and the document as they were at the click, so the window
goes on and later edits do not reach the files; the panel says when they are written.
The thread is not a daemon: a window closed meanwhile exits once they are complete."""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass, field
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

    def deleted_count(self) -> int: ...


@dataclass
class Writing:
    """An export under way: its files, what it writes, the edits' generation it was made
    from, and what went wrong (None: nothing, or not finished)."""

    target: Path
    document: Path
    count: int
    generation: int
    thread: threading.Thread = field(init=False)
    failure: str | None = None


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
        self.writing: Writing | None = None
        self._close_asked: str | None = None

    def unsaved(self) -> str | None:
        """What another scene opened now, or the window closed, would lose: "N deleted"
        where the deletions changed since the last export (or none was made), else None."""
        edits = self.tool.edits
        if edits is None or not edits.edited or self.exported == edits.generation:
            return None
        return f"{self.tool.deleted_count():,} deleted"

    def may_close(self) -> bool:
        """Whether the window, asked to close, may: not at the first ask while deletions
        are not exported (the panel says so, and the same ask again closes)."""
        lost = self.unsaved()
        if lost is None or self._close_asked == lost:
            return True
        self._close_asked = lost
        self.tool.host.window.keep_open()
        self.tool.host.panel.error = (f"error: not closed: the edits of the scene shown ({lost}) are not exported; "
                                      "export them, or close again to leave them")
        return False

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
            if self.writing is not None:
                raise UserError(f"{self.writing.target} is still being written")
            kept = tool.edits.kept
            if not kept.any():
                raise UserError("every gaussian is deleted: nothing to export")
            writing = Writing(target, document, int(kept.sum()), tool.edits.generation)
            writing.thread = threading.Thread(target=self._write, name="export", args=(
                writing, tool.scene.rows(kept), source.path, tool.document(), replace))
        except UserError as exc:
            panel.error = f"error: not exported: {one_line(exc)}"
            return None
        finally:
            if replace:
                self.confirm_replace = None
        self.writing = writing
        writing.thread.start()
        panel.note(f"exporting {writing.count:,} gaussians to {target} ...")
        panel.error = ""
        return target

    @staticmethod
    def _write(writing: Writing, rows: Scene, source: str, document: EditDocument, replace: bool) -> None:
        try:
            write_kept(rows, source, writing.target, replace)
            save_edit_document(document, writing.document, replace)
        except UserError as exc:
            writing.failure = one_line(exc)
        except Exception as exc:  # a failure no check foresaw: said in the panel, never a dead thread
            writing.failure = f"{type(exc).__name__}: {one_line(exc)}"

    def poll(self) -> None:
        """Says in the panel how a finished export went (each frame: a cheap check)."""
        writing = self.writing
        if writing is None or writing.thread.is_alive():
            return
        self.writing, panel = None, self.tool.host.panel
        if writing.failure is not None:
            panel.error = f"error: not exported: {writing.failure}"
            return
        self.exported = writing.generation
        panel.note(f"exported {writing.count:,} gaussians to {writing.target} (+ {writing.document.name})")

    def wait(self) -> None:
        """Waits for an export under way to finish, then says how it went."""
        if self.writing is not None:
            self.writing.thread.join()
        self.poll()
