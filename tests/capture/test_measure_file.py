"""Measurement files: the exact JSON round trip, the scale, saving that never clobbers,
strict loading (every problem one line naming the field) and the scene hash warning."""

from __future__ import annotations

import json

import numpy as np
import pytest
from testkit import assert_user_error, delete_field, listing, set_field, write_case

from raygs_viewer.capture.measure_file import (
    MEASURE_FORMAT,
    SCENE_UNIT,
    MeasureDocument,
    MeasureScale,
    Measurement,
    convert,
    load_measure_document,
    measure_document_json,
    measure_scene_mismatch,
    save_measure_document,
)
from raygs_viewer.capture.sidecar import demo_sha256
from raygs_viewer.errors import UserError

SHA = "ab" * 32


def document(scale=True) -> MeasureDocument:
    rng = np.random.default_rng(3)
    measurements = tuple(Measurement(rng.normal(size=3) * 10 ** rng.uniform(-3, 3, 3), rng.normal(size=3))
                         for _ in range(3))
    return MeasureDocument(measurements, MeasureScale(0.1 + 1 / 3, "m", 1) if scale else None, "demo", SHA)


def test_round_trip_is_exact(tmp_path):
    doc = document()
    saved = save_measure_document(doc, tmp_path / "m.json")
    loaded = load_measure_document(saved)
    assert len(loaded.measurements) == 3 and loaded.source == saved
    for a, b in zip(doc.measurements, loaded.measurements):
        np.testing.assert_array_equal(a.a, b.a)
        np.testing.assert_array_equal(a.b, b.b)
    assert loaded.scale == doc.scale
    assert (loaded.scene_path, loaded.scene_sha256) == ("demo", SHA)
    data = json.loads(saved.read_text())
    assert data["format"] == MEASURE_FORMAT and data["version"] == 1
    assert data["scale"] == {"factor": 0.1 + 1 / 3, "unit": "m", "reference": 1}
    # An empty list and no scale are a valid file too.
    empty = load_measure_document(save_measure_document(MeasureDocument(), tmp_path / "empty.json"))
    assert empty.measurements == () and empty.scale is None and empty.scene_path is None


def test_saving_never_clobbers_and_leaves_no_partial_file(tmp_path):
    path = tmp_path / "m.json"
    path.write_text("mine")
    assert_user_error(lambda: save_measure_document(document(), path), path, "already exists")
    assert path.read_text() == "mine" and listing(tmp_path) == ["m.json"]
    save_measure_document(document(), path, overwrite=True)
    assert load_measure_document(path).scale.unit == "m"
    assert_user_error(lambda: save_measure_document(document(), tmp_path / "m.txt"), "m.txt", ".json")


def test_scale_converts_every_distance():
    m = Measurement([0, 0, 0], [3, 4, 0])
    assert m.distance == 5.0
    scale = MeasureScale.from_length(m, 1.2, " m ")
    assert scale.unit == "m" and scale.factor == pytest.approx(0.24)
    assert convert(m.distance, scale) == (pytest.approx(1.2), "m")
    assert convert(10.0, scale) == (pytest.approx(2.4), "m")
    assert convert(10.0, None) == (10.0, SCENE_UNIT)
    for length in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(UserError, match="known length"):
            MeasureScale.from_length(m, length, "m")
    with pytest.raises(UserError, match="no length"):
        MeasureScale.from_length(Measurement([1, 1, 1], [1, 1, 1]), 1.0, "m")
    for unit in ("", "  ", "a\nb", "x" * 33):
        with pytest.raises(UserError, match="one line"):
            MeasureScale(1.0, unit)
    with pytest.raises(UserError):
        Measurement([0, 0, float("nan")], [0, 0, 0])


def valid_data() -> dict:
    return measure_document_json(document())


MALFORMED = {
    "not json": ("{", "not valid JSON"),
    "no file": (None, "no such file"),
    "array": ("[]", "not a measurements file"),
    "other format": (set_field("format", "raygs-viewer camera path"), "not a measurements file"),
    "newer version": (set_field("version", 2), "newer raygs-viewer"),
    "unknown field": (set_field("colour", 1), "unknown field 'colour'"),
    "no measurements": (delete_field("measurements"), "missing 'measurements'"),
    "measurements not a list": (set_field("measurements", {}), "'measurements' must be a JSON array"),
    "point too short": (set_field("measurements.0.a", [1, 2]), "'measurements[0].a' must be 3 numbers"),
    "point not numbers": (set_field("measurements.1.b", [1, "2", 3]), "'measurements[1].b' must be 3 numbers"),
    "point nan": (set_field("measurements.2.a", [1, float("nan"), 3]), "'measurements[2].a' must be finite"),
    "measurement extra key": (set_field("measurements.0.c", [1, 2, 3]), "unknown field 'measurements[0].c'"),
    "measurement missing b": (delete_field("measurements.0.b"), "missing 'measurements[0].b'"),
    "factor zero": (set_field("scale.factor", 0), "'scale.factor' must be a positive number"),
    "factor string": (set_field("scale.factor", "1"), "'scale.factor' must be a number"),
    "unit empty": (set_field("scale.unit", ""), "'scale.unit' must be one line"),
    "unit two lines": (set_field("scale.unit", "m\nft"), "'scale.unit' must be one line"),
    "reference out of range": (set_field("scale.reference", 3), "'scale.reference' must be the index"),
    "reference not int": (set_field("scale.reference", 0.5), "'scale.reference' must be a whole number"),
    "scale extra key": (set_field("scale.offset", 1), "unknown field 'scale.offset'"),
    "relative scene": (set_field("scene.path", "scene.ply"), "'scene.path' must be"),
    "bad sha": (set_field("scene.sha256", "xyz"), "'scene.sha256' must be 64"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_file_is_one_line_user_error(tmp_path, case):
    change, fragment = MALFORMED[case]
    path = write_case(tmp_path / "m.json", change, valid_data)
    assert_user_error(lambda: load_measure_document(path), path, fragment)


def test_the_valid_file_behind_the_cases_loads_and_optional_fields_may_go(tmp_path):
    assert len(load_measure_document(write_case(tmp_path / "a.json", lambda d: None, valid_data)).measurements) == 3

    def strip(data):
        for key in ("program", "created", "scene", "scale"):
            del data[key]
    loaded = load_measure_document(write_case(tmp_path / "b.json", strip, valid_data))
    assert loaded.scale is None and loaded.scene_sha256 is None


def test_scene_mismatch_warns_only_for_another_recorded_scene():
    doc = MeasureDocument(scene_path="demo", scene_sha256=demo_sha256())
    assert measure_scene_mismatch(doc, "demo") is None
    assert measure_scene_mismatch(MeasureDocument(scene_path="demo"), "demo") is None  # no hash: never checked
    other = MeasureDocument(scene_path="/data/room.ply", scene_sha256=SHA)
    warning = measure_scene_mismatch(other, "demo")
    assert "measured on /data/room.ply, not on the demo scene" in warning and "\n" not in warning
