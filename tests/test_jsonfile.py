"""The one strict JSON reader and writer (raygs_viewer/jsonfile.py): every problem is one
line naming the file and the field, and what is written reads back to the same values."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from testkit import assert_user_error

from raygs_viewer.jsonfile import (
    JsonFields,
    json_key,
    json_line,
    json_text,
    nested_numbers,
    parse_json,
    read_json_file,
    show_json,
    typed,
)

FILE = Path("shot.json")


# --------------------------------------------------------------------------- parsing


@pytest.mark.parametrize("text, detail", [
    ("{", "Expecting property name"),
    ('{"a": 1,}', "Expecting property name"),
    ("[1, 2", "Expecting"),
    ("", "Expecting value"),
    ("1" * 5000, "a number with too many digits"),
    ("[" * 100_000 + "]" * 100_000, "recursion"),
])
def test_text_that_is_not_json_is_one_line_naming_the_file(text, detail):
    assert_user_error(lambda: parse_json(text, FILE), FILE, "shot.json: not valid JSON (", detail)


def test_bytes_are_utf8_with_or_without_a_byte_order_mark():
    assert parse_json(b'\xef\xbb\xbf{"a": "\xc3\xa9"}', FILE) == {"a": "\u00e9"}
    assert_user_error(lambda: parse_json(b'{"a": "\xff"}', FILE), FILE, "shot.json: not valid JSON")


def test_nan_tokens_parse_for_the_field_checks_or_are_refused_at_once():
    assert math.isnan(parse_json('{"x": NaN}', FILE)["x"])
    for token in ("NaN", "Infinity", "-Infinity"):
        assert_user_error(lambda: parse_json(f'{{"x": {token}}}', FILE, constants=False), FILE,
                       "shot.json: not valid JSON", f"{token} is not JSON")


def test_a_file_that_is_missing_a_folder_or_unreadable_is_one_line(tmp_path):
    assert_user_error(lambda: read_json_file(tmp_path / "no.json", "a sidecar"), "no.json", "no.json: no such file")
    assert_user_error(lambda: read_json_file(tmp_path, "a sidecar"), tmp_path, "is a folder, expected a sidecar")
    (tmp_path / "latin1.json").write_bytes(b'{"a": "\xe9"}')
    assert_user_error(lambda: read_json_file(tmp_path / "latin1.json", "x"), "latin1.json", "latin1.json: cannot read")
    (tmp_path / "good.json").write_text('{"a": [1, 2.5]}')
    assert read_json_file(tmp_path / "good.json", "x") == {"a": [1, 2.5]}


# --------------------------------------------------------------------------- typed fields


@pytest.mark.parametrize("value, kind, expected", [
    (3, int, 3), (3, float, 3.0), (2.5, float, 2.5), ("a", str, "a"), (True, bool, True),
    ({}, dict, {}), ([], list, []), (None, (dict, type(None)), None),
])
def test_a_value_of_the_asked_type_comes_back(value, kind, expected):
    result = typed(value, kind, "f: 'x'")
    assert result == expected and type(result) is type(expected)


@pytest.mark.parametrize("value, kind, words", [
    (True, int, "must be a whole number, got true"),   # a bool is not a number in a file
    (1.0, int, "must be a whole number, got 1.0"),
    ("1", float, 'must be a number, got "1"'),
    (False, float, "must be a number, got false"),
    (float("nan"), float, "must be finite, got NaN"),
    (10 ** 400, float, "must be finite"),
    (1, str, "must be a string, got 1"),
    ("yes", bool, 'must be true or false, got "yes"'),
    ([], dict, "must be a JSON object, got []"),
    ({}, list, "must be a JSON array, got {}"),
    (3, (dict, type(None)), "must be a JSON object or null, got 3"),
])
def test_a_value_of_another_type_is_one_line_naming_the_field(value, kind, words):
    assert_user_error(lambda: typed(value, kind, "shot.json: 'image.width'"), FILE, "shot.json: 'image.width' " + words)


def test_fields_are_read_by_their_dotted_names():
    fields = JsonFields(FILE, {"image": {"width": 64, "scale": 1}, "list": [1]})
    assert fields.get("image.width", int) == 64
    assert fields.get("image.scale", float) == 1.0
    assert_user_error(lambda: fields.get("image.height", int), FILE, "shot.json: missing 'image.height'")
    assert_user_error(lambda: fields.get("camera.fx", float), FILE, "shot.json: missing 'camera.fx'")
    assert_user_error(lambda: fields.get("list.x", int), FILE, "shot.json: 'list' must be a JSON object")
    assert_user_error(lambda: fields.get("image.width.x", int), FILE, "shot.json: 'image.width' must be a JSON object")


def test_an_optional_field_absent_or_null_takes_its_default_and_is_checked_when_present():
    fields = JsonFields(FILE, {"path": {"loop": None, "alpha": 0.25, "up": "x"}})
    assert fields.optional("path.loop", bool, False) is False
    assert fields.optional("path.tension", float, 0.5) == 0.5
    assert fields.optional("path.alpha", float, 0.5) == 0.25
    assert fields.optional("extra", dict) is None
    assert_user_error(lambda: fields.optional("path.up", list), FILE, "shot.json: 'path.up' must be a JSON array")


def test_an_array_has_its_shape_and_finite_numbers_only():
    fields = JsonFields(FILE, {"R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [1, 2, 3], "bad": [1, True, 3],
                               "ragged": [[1, 0, 0], [0, 1], [0, 0, 1]], "nan": [1, float("nan"), 3],
                               "huge": [1, 10 ** 400, 3], "short": [1, 2]})
    np.testing.assert_array_equal(fields.array("R", (3, 3)), np.eye(3))
    assert fields.array("t", (3,)).dtype == np.float64
    assert_user_error(lambda: fields.array("bad", (3,)), FILE, "shot.json: 'bad' must be 3 numbers, got [1, true, 3]")
    assert_user_error(lambda: fields.array("ragged", (3, 3)), FILE, "'ragged' must be 3x3 numbers")
    assert_user_error(lambda: fields.array("short", (3,)), FILE, "'short' must be 3 numbers")
    assert_user_error(lambda: fields.array("nan", (3,)), FILE, "'nan' must be finite")
    assert_user_error(lambda: fields.array("huge", (3,)), FILE, "'huge' must be finite")


def test_an_array_entry_is_named_by_its_index():
    fields = JsonFields.entry(FILE, "keyframes[3]", {"fov": "wide"})
    assert_user_error(lambda: fields.get("keyframes[3].fov", float), FILE, "shot.json: 'keyframes[3].fov' must be a number")
    assert_user_error(lambda: JsonFields.entry(FILE, "keyframes[4]", [1]), FILE, "'keyframes[4]' must be a JSON object")


def test_keys_missing_or_unknown_are_one_line_and_a_strange_key_stays_on_it():
    fields = JsonFields(FILE, {})
    fields.keys("image", {"width": 1, "height": 2, "scale": 1}, ("width", "height"), ("scale",))
    assert_user_error(lambda: fields.keys("image", {"width": 1}, ("width", "height")), FILE, "shot.json: missing 'image.height'")
    assert_user_error(lambda: fields.keys("", {"format": 1, "zoom": 2}, ("format",)), FILE,
                   "shot.json: unknown field 'zoom'", "newer raygs-viewer")
    message = assert_user_error(lambda: fields.keys("stereo", {"a\nb": 1}, ()), FILE, "unknown field 'stereo.a\\nb'")
    assert json_key("a\nb\u00e9") == "a\\nb\\xe9" and "\n" not in message


@pytest.mark.parametrize("version, words", [
    (3, "sidecar version 3 was written by a newer raygs-viewer (this one reads version 2)"),
    (0, "'version' 0 is not a sidecar version (expected 2)"),
    (1.0, "'version' must be a whole number"),
])
def test_the_version_is_one_this_program_reads(version, words):
    assert JsonFields(FILE, {"version": 2}).version(2, "sidecar") == 2
    assert JsonFields(FILE, {"version": 1}).version(2, "sidecar") == 1
    assert_user_error(lambda: JsonFields(FILE, {"version": version}).version(2, "sidecar"), FILE, words)


def test_nested_numbers_are_numbers_to_a_bounded_depth():
    assert nested_numbers([[1, 2.5], [3]], 2)
    assert not nested_numbers([[1]], 1)
    assert not nested_numbers([1, "2"], 1) and not nested_numbers([True], 1) and not nested_numbers(1, 1)


def test_values_shown_in_messages_are_short_and_one_line():
    assert show_json("x" * 100) == json.dumps("x" * 100)[:57] + "..."
    assert show_json("x" * 100, limit=30).endswith("...") and len(show_json("x" * 100, limit=30)) == 30
    assert show_json({1, 2}).startswith("{")  # not JSON: its repr
    assert "\n" not in show_json("a\nb")


# --------------------------------------------------------------------------- writing


def test_text_puts_each_innermost_list_of_numbers_on_one_line_and_leaves_strings_alone():
    data = {"R": [[1.0, 0.0, -0.0], [0.1, 1e-300, 2.5e+20]], "name": "[\n1,\n2\n]", "empty": [], "words": ["a", "b"]}
    text = json_text(data)
    assert '"R": [\n    [1.0, 0.0, -0.0],\n    [0.1, 1e-300, 2.5e+20]\n  ]' in text  # a matrix: a line a row
    assert '"name": "[\\n1,\\n2\\n]"' in text
    assert '"words": [\n' in text  # a list of strings keeps the indented layout
    assert text.endswith("}\n") and json.loads(text) == data


@given(st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False, allow_infinity=False)
                    | st.text(), lambda children: st.lists(children) | st.dictionaries(st.text(), children),
                    max_leaves=30))
def test_text_reads_back_to_the_same_values_bit_for_bit(data):
    assert parse_json(json_text(data), FILE) == data
    assert parse_json(json_line({"v": data}), FILE) == {"v": data}


def test_what_json_cannot_hold_is_never_written():
    for value in (float("nan"), float("inf")):
        with pytest.raises(ValueError):
            json_text({"x": value})
        with pytest.raises(ValueError):
            json_line({"x": value})
    with pytest.raises(TypeError):
        json_text({"x": np.float32(1.0)})


def test_a_line_is_one_line():
    line = json_line({"a": [1, 2], "b": "x\ny"})
    assert line.endswith("\n") and line.count("\n") == 1 and json.loads(line) == {"a": [1, 2], "b": "x\ny"}
