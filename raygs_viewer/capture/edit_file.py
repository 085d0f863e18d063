"""Edit documents: the edits made of a scene (``scene.edits``), as JSON, written beside an
export and inside a screenshot's sidecar, and replayed by ``convert --edits``.

Layout (version 1)::

    {"format": "raygs-viewer edits", "version": 1,
     "program": {...}, "created": "...",                       # as every document
     "scene": {"path": "/abs/scene.ply" or "demo",
               "sha256": "<64 hex digits>",                     # the source's content hash
               "count": 123456},                                # its gaussians as read
     "operations": [{"op": "select", "how": "set", "shape": {"kind": "box", ...}},
                    {"op": "delete"}, ...]}

A screen shape records its camera (pose and intrinsics) and the size of its image, so
it selects the same gaussians again. Replaying on a scene whose hash differs is refused
in one line: the rows an operation chose would be other gaussians.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.capture.sidecar import SHA256_HEX, document_head
from raygs_viewer.errors import UserError
from raygs_viewer.files import write_atomically
from raygs_viewer.jsonfile import JsonFields, json_text, read_json_file, show_json
from raygs_viewer.scene.edits import Edits, Operation, replay
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.source import SceneSource

EDITS_FORMAT = "raygs-viewer edits"
EDITS_VERSION = 1
#: The most operations a document may hold (a session's clicks, not a data set).
MAX_OPERATIONS = 100_000


@dataclass(frozen=True)
class EditDocument:
    """The edits of the scene at ``scene_path`` (its SHA-256 ``scene_sha256``, ``count``
    gaussians as read): ``operations`` in order."""

    scene_path: str
    scene_sha256: str
    count: int
    operations: tuple[Operation, ...]

    def check_scene(self, sha256: str, count: int, shown: str) -> None:
        """UserError in one line unless the scene ``shown`` (hash ``sha256``, ``count``
        gaussians) is the one these edits were made on."""
        if sha256 != self.scene_sha256:
            raise UserError(f"{shown}: is not the scene these edits were made on (its SHA-256 {sha256[:12]}... "
                            f"differs from the recorded {self.scene_sha256[:12]}...); refusing to replay them")
        if count != self.count:
            raise UserError(f"{shown}: holds {count:,} gaussians, the edits were made on {self.count:,}")

    def replay(self, scene: Scene) -> Edits:
        return replay(scene, list(self.operations))


def edit_document_json(doc: EditDocument) -> dict:
    return {**document_head(EDITS_FORMAT, EDITS_VERSION),
            "scene": {"path": SceneSource(doc.scene_path).recorded_path, "sha256": doc.scene_sha256,
                      "count": int(doc.count)},
            "operations": [operation.to_json() for operation in doc.operations]}


def save_edit_document(doc: EditDocument, file: str | os.PathLike, overwrite: bool = False) -> Path:
    """Writes ``doc`` atomically (an existing file only with ``overwrite``); what it
    writes reads back as ``doc``."""
    file = check_output_path(file, overwrite, (".json",))
    text = json_text(edit_document_json(doc))
    write_atomically(file, text.encode("utf-8"), overwrite)
    return file


def load_edit_document(file: str | os.PathLike) -> EditDocument:
    """The edit document ``file``, validated; any problem is a one-line UserError."""
    file = Path(file)
    return read_edit_json(read_json_file(file, "an edits .json file"), file)


def read_edit_json(data, file) -> EditDocument:
    """The document of parsed JSON ``data`` (``file`` names it in messages: a path, or
    "SHOT.json: 'edits'" for a sidecar's)."""
    if not isinstance(data, dict) or data.get("format") != EDITS_FORMAT:
        got = show_json(data.get("format")) if isinstance(data, dict) else "not a JSON object"
        raise UserError(f"{file}: not an edits file ('format' should be {show_json(EDITS_FORMAT)}, got {got})")
    fields = JsonFields(file, data)
    fields.version(EDITS_VERSION, "edits")
    fields.keys("", data, ("format", "version", "scene", "operations"), ("program", "created"))
    fields.keys("scene", fields.get("scene", dict), ("path", "sha256", "count"))
    sha = fields.get("scene.sha256", str)
    if not SHA256_HEX.fullmatch(sha):
        raise UserError(f"{file}: 'scene.sha256' must be 64 lowercase hex digits, got {show_json(sha)}")
    count = fields.get("scene.count", int)
    entries = fields.get("operations", list)
    if len(entries) > MAX_OPERATIONS:
        raise UserError(f"{file}: 'operations' has {len(entries):,} entries (at most {MAX_OPERATIONS:,})")
    operations = []
    for index, entry in enumerate(entries):
        try:
            operations.append(Operation.from_json(entry))
        except ValueError as exc:
            raise UserError(f"{file}: 'operations[{index}]': {exc}") from None
    return EditDocument(fields.get("scene.path", str), sha, count, tuple(operations))
