"""SceneSource (scene/source.py): what to read, checked once, with the demo and the wording
of a failed read in one place."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import testkit
from testkit import write_inria_ply

import raygs_viewer.scene.io as io
from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import SCENE_FILES, load_scene
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.source import DEMO, SceneSource, is_demo

LOD_FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "lod-small"


def test_a_source_keeps_its_paths_as_strings_and_its_levels_as_a_tuple(tmp_path):
    source = SceneSource(tmp_path / "s.ply", tmp_path / "cameras.json", "rdf", [2, 1])
    assert source == SceneSource(str(tmp_path / "s.ply"), str(tmp_path / "cameras.json"), "rdf", (2, 1))
    assert isinstance(source.path, str) and isinstance(source.cameras, str) and source.levels == (2, 1)
    assert SceneSource("s.ply") == SceneSource("s.ply", None, "rub", None)  # the specification's axes


@pytest.mark.parametrize("axes", ["RDF", "up", ""])
def test_a_bad_axes_name_fails_when_the_source_is_made_even_for_the_demo(axes):
    for path in ("demo", "absent.ply"):
        testkit.assert_user_error(lambda: SceneSource(path, spz_axes=axes), repr(axes), "rub or rdf")
    testkit.assert_user_error(lambda: SceneSource.demo().with_axes(axes), repr(axes), "rub or rdf")


def test_the_demo_is_one_comparison():
    assert SceneSource.demo() == SceneSource(DEMO) and SceneSource.demo().is_demo
    assert SceneSource.demo("views.json").cameras == "views.json"
    assert not SceneSource("demo.ply").is_demo and not SceneSource("./demo").is_demo
    assert is_demo("demo") and is_demo(Path("demo")) and not is_demo(None) and not is_demo("DEMO")


def test_a_document_records_the_demo_or_an_absolute_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert SceneSource.demo().recorded_path == "demo"
    assert SceneSource("sub/../s.ply").recorded_path == os.path.join(str(tmp_path), "s.ply")


def test_another_scene_is_read_the_same_way_with_its_own_cameras_and_every_level():
    source = SceneSource("a.spz", "a.json", "rdf", (3,))
    assert source.at("b.spz") == SceneSource("b.spz", None, "rdf")
    assert source.at("b.spz", "b.json").cameras == "b.json"
    assert source.with_axes("rub") == SceneSource("a.spz", "a.json", "rub", (3,))
    assert source.with_axes(FileAxes("rub", "RDF")).spz_axes == "rub"  # the convention it was read with
    assert source.with_axes(None) is source
    assert source.with_levels(None).levels is None


@pytest.mark.parametrize("exc,words", [
    (FileNotFoundError(2, "No such file or directory"), "no such file"),
    (IsADirectoryError(21, "Is a directory"), f"is a directory, expected a scene file ({SCENE_FILES})"),
    (PermissionError(13, "Permission denied"), "permission denied"),
    (OSError(5, "Input/output error"), "cannot read: Input/output error"),
    (OSError("odd"), "cannot read: odd"),
    (MemoryError(), "not enough memory to load this scene"),
])
def test_a_failed_read_is_one_line_naming_the_path(exc, words):
    assert str(SceneSource("scenes/a b.ply").read_error(exc)) == f"scenes/a b.ply: {words}"


def test_load_scene_and_load_now_word_a_failed_read_alike(tmp_path, monkeypatch):
    """The reader table's failure and the loader's (here: a streamed SOG's reader, which
    load_scene does not run) come out in the same words."""
    scene = write_inria_ply(tmp_path / "s.ply", n=5)

    def unreadable(source, report, chunk_bytes):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(io, "FORMATS", tuple(row._replace(read=unreadable) for row in io.FORMATS))
    testkit.assert_user_error(lambda: load_scene(scene), f"{scene}: permission denied")

    def unreadable_levels(path, **kwargs):
        raise PermissionError(13, "Permission denied")

    index = str(LOD_FIXTURE / "scene" / "lod-meta.json")
    with pytest.raises(UserError) as caught:
        load_now(SceneSource(index), read_lod=unreadable_levels)
    assert str(caught.value) == f"{index}: permission denied"


def test_every_reader_takes_the_source_it_is_handed(tmp_path, monkeypatch):
    scene = write_inria_ply(tmp_path / "s.ply", n=5)
    seen = []

    def spy(real):
        def read(source, report, chunk_bytes):
            seen.append(source)
            return real(source, report, chunk_bytes)
        return read

    monkeypatch.setattr(io, "FORMATS", tuple(row._replace(read=spy(row.read)) for row in io.FORMATS))
    source = SceneSource(scene, spz_axes="rdf")
    assert load_scene(source).count == 5
    assert seen == [source] and seen[0] is source
