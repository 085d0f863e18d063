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

from raygs_viewer.capture.edit_file import EditDocument, save_edit_document
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.scene.edits import Edits
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.ply_rows import write_kept
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.writing import WRITE_SUFFIXES
from raygs_viewer.viewer.state import Message, done, failed, note


def edit_document_path(target: str | os.PathLike) -> Path:
    """Where an export's edit document is written: ``NAME.edits.json`` beside it."""
    target = Path(target)
    return target.with_name(f"{target.stem}.edits.json")


def edit_document(loaded: LoadedScene, edits: Edits) -> EditDocument:
    """The document of ``edits`` of the scene ``loaded``: the file (its sha256) and the
    operations, in order."""
    return EditDocument(SceneSource(loaded.path).recorded_path, loaded.content_sha256, edits.count,
                        tuple(edits.operations))


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
    there; ``exported``: the edits' generation last written (None: never). Each action
    returns what the panel says of it."""

    def __init__(self) -> None:
        self.file = ""
        self.confirm_replace: str | None = None
        self.existing: tuple[str, ...] = ()
        self.exported: int | None = None  # the edits' generation last written
        self.writing: Writing | None = None
        self._close_asked: str | None = None

    def unsaved(self, edits: Edits | None) -> str | None:
        """What another scene opened now, or the window closed, would lose of ``edits``:
        "N deleted" where the deletions changed since the last export (or none was made),
        else None."""
        if edits is None or not edits.edited or self.exported == edits.generation:
            return None
        return f"{int(edits.deleted.sum()):,} deleted"

    def may_close(self, edits: Edits | None) -> Message | None:
        """Why the window, asked to close, may not (None: it may): not at the first ask
        while deletions are not exported (the same ask again closes)."""
        lost = self.unsaved(edits)
        if lost is None or self._close_asked == lost:
            return None
        self._close_asked = lost
        return failed(f"the edits of the scene shown ({lost}) are not exported; export them, or close again "
                      "to leave them", "not closed")

    def export(self, edits: Edits, loaded: LoadedScene, replace: bool = False) -> tuple[Message, ...]:
        """Writes the gaussians of ``loaded`` not deleted by ``edits`` at :attr:`file`, and
        the edit document beside it; an existing file waits for a confirmation (``replace``)."""
        target = Path(self.file.strip() or "")
        try:
            if not self.file.strip():
                raise UserError("name the file to export to")
            if target.suffix.lower() not in WRITE_SUFFIXES:
                raise UserError(f"{target}: the export must end in {', '.join(WRITE_SUFFIXES)}")
            source = loaded.source
            if not source.is_demo and Path(source.path).resolve() == target.resolve():
                raise UserError(f"{target}: is the scene shown; export to another file")
            document = edit_document_path(target)
            existing = tuple(str(path) for path in (target, document) if path.exists())
            if existing and not replace:
                self.confirm_replace, self.existing = str(target), existing
                return ()
            if self.writing is not None:
                raise UserError(f"{self.writing.target} is still being written")
            kept = ~edits.deleted
            if not kept.any():
                raise UserError("every gaussian is deleted: nothing to export")
            writing = Writing(target, document, int(kept.sum()), edits.generation)
            writing.thread = threading.Thread(target=self._write, name="export", args=(
                writing, loaded.scene.rows(kept), source.path, edit_document(loaded, edits), replace))
        except UserError as exc:
            return (failed(exc, "not exported"),)
        finally:
            if replace:
                self.confirm_replace = None
        self.writing = writing
        writing.thread.start()
        return (done(f"exporting {writing.count:,} gaussians to {target} ..."),)

    @staticmethod
    def _write(writing: Writing, rows: Scene, source: str, document: EditDocument, replace: bool) -> None:
        try:
            write_kept(rows, source, writing.target, replace)
            save_edit_document(document, writing.document, replace)
        except UserError as exc:
            writing.failure = one_line(exc)
        except Exception as exc:  # a failure no check foresaw: said in the panel, never a dead thread
            writing.failure = f"{type(exc).__name__}: {one_line(exc)}"

    def poll(self) -> Message | None:
        """How a finished export went (each frame: a cheap check); None while none has finished."""
        writing = self.writing
        if writing is None or writing.thread.is_alive():
            return None
        self.writing = None
        if writing.failure is not None:
            return failed(writing.failure, "not exported")
        self.exported = writing.generation
        return note(f"exported {writing.count:,} gaussians to {writing.target} (+ {writing.document.name})")

    def wait(self) -> Message | None:
        """Waits for an export under way to finish, then says how it went."""
        if self.writing is not None:
            self.writing.thread.join()
        return self.poll()
