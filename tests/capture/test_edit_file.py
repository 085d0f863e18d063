"""Edit documents: written atomically and read back as written, strict about what they
hold, and replayed by ``convert --edits`` only on the scene they were made on."""

from __future__ import annotations

import json

import pytest
from testkit import assert_one_line_error, listing, run_cli, write_inria_ply

from raygs_viewer.capture.edit_file import EditDocument, load_edit_document, save_edit_document
from raygs_viewer.capture.sidecar import scene_sha256
from raygs_viewer.errors import UserError
from raygs_viewer.scene.edits import Operation
from raygs_viewer.scene.selection import Box


def document(path, count=30):
    return EditDocument(str(path.resolve()), scene_sha256(path), count,
                        (Operation("select", Box((-0.2, -1, -1), (1, 1, 1))), Operation("delete")))


def test_a_document_reads_back_as_written_and_is_never_clobbered(tmp_path):
    scene = write_inria_ply(tmp_path / "in.ply", n=30)
    doc = document(scene)
    file = save_edit_document(doc, tmp_path / "e.json")
    assert load_edit_document(file) == doc
    file.write_text("mine")
    with pytest.raises(UserError, match="already exists"):
        save_edit_document(doc, file)
    assert file.read_text() == "mine"


@pytest.mark.parametrize("change, words", [
    (lambda d: d.update(format="other"), "not an edits file"),
    (lambda d: d.update(version=9), "version"),
    (lambda d: d["scene"].update(sha256="xyz"), "64 lowercase hex"),
    (lambda d: d["scene"].pop("count"), "count"),
    (lambda d: d["operations"].append({"op": "explode"}), r"'operations\[2\]': unknown operation"),
    (lambda d: d["operations"].append({"op": "crop", "shape": {"kind": "range", "attribute": "opacity",
                                                               "low": 0, "high": 1}}), "crop needs a box"),
    (lambda d: d.update(surprise=1), "surprise"),
])
def test_a_bad_document_is_one_line_naming_what(tmp_path, change, words):
    scene = write_inria_ply(tmp_path / "in.ply", n=30)
    file = save_edit_document(document(scene), tmp_path / "e.json")
    data = json.loads(file.read_text())
    change(data)
    file.write_text(json.dumps(data))
    with pytest.raises(UserError, match=words):
        load_edit_document(file)


def test_convert_refuses_edits_of_another_scene_and_writes_nothing(capsys, tmp_path):
    scene = write_inria_ply(tmp_path / "in.ply", n=30)
    other = write_inria_ply(tmp_path / "other.ply", n=30, seed=1)
    file = save_edit_document(document(scene), tmp_path / "e.json")
    code, out, err = run_cli(capsys, "convert", other, tmp_path / "out.ply", "--edits", file)
    assert "is not the scene these edits were made on" in assert_one_line_error(code, err)
    assert "out.ply" not in listing(tmp_path)
    code, out, err = run_cli(capsys, "convert", scene, tmp_path / "out.ply", "--edits", file)
    assert code == 0, err
    assert "edits " in out and "operations, removed" in out
