"""Strict JSON: the one reader and the one writer of every JSON file the project
touches (screenshot sidecars, camera paths, nerfstudio camera paths, cameras.json,
SOG meta.json, render-path's progress lines).

Reading is in two steps. :func:`parse_json` (or :func:`read_json_file`) turns text
into Python values, and a file that is missing, unreadable or not JSON becomes one
line naming it. :class:`JsonFields` then reads typed fields out of the value by their
dotted names, and every wrong type, non-finite number, missing or unknown field
becomes one line naming the file and the field: ``FILE: 'settings.p_min' must be a
number, got "x"``. What a field must satisfy beyond its JSON type (a range, a
rotation, agreement with another field) is the file format's own check, written
where the format is.

Why not a typed decoder such as msgspec (docs/architecture.md has the measurement):
on a 1,000-keyframe path file, msgspec parses in 0.9 ms where Python's parser takes
1.9 ms, of a whole read with every check of 72 ms; most of that is what no decoder
expresses (rotations, poses, ranges, times in order), so a second layer would remain,
and msgspec's messages ("Expected `int`, got `bool` - at `$.image.width`") would need
translating into ours. Python's parser with this thin layer keeps one way of checking
and one wording, at no cost that matters.

Writing: :func:`json_text` is the one writer (indented, each innermost list of numbers
on one line, NaN and infinities refused since they are not JSON). Python writes a float as
the shortest repr that reads back to the same bits, so poses survive a round trip
exactly. Files are written through :mod:`raygs_viewer.files`.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from raygs_viewer.errors import UserError, finite_number, is_number

#: The JSON types a field may be asked for, as :meth:`JsonFields.get` names them in messages.
_KIND_NAMES = {str: "a string", bool: "true or false", dict: "a JSON object", list: "a JSON array",
               (dict, type(None)): "a JSON object or null"}
# Only a list of numbers broken over lines matches: a JSON string cannot hold a raw
# newline, so nothing inside a string is touched.
_NUMBER_LIST = re.compile(r"\[\n[-+0-9.eE,\s]*?\]")


# --------------------------------------------------------------------------- parsing


def _reject_constant(token: str):
    raise ValueError(f"{token} is not JSON")


def parse_json(text: str | bytes, where, *, constants: bool = True):
    """The value of JSON ``text`` (bytes are UTF-8, a byte-order mark allowed);
    UserError "<where>: not valid JSON (...)" otherwise. ``constants``: accept Python's
    NaN and Infinity tokens (a field check then refuses them by name); False refuses
    them here, as a reader that never checks numbers one by one must."""
    try:
        if isinstance(text, bytes):
            text = text.decode("utf-8-sig")
        if constants:
            return json.loads(text)
        return json.loads(text, parse_constant=_reject_constant)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise UserError(f"{where}: not valid JSON ({' '.join(str(exc).split()) or type(exc).__name__})") from None
    except ValueError as exc:
        if constants:  # an integer of over 4300 digits, which Python refuses to parse
            raise UserError(f"{where}: not valid JSON (a number with too many digits)") from None
        raise UserError(f"{where}: not valid JSON ({' '.join(str(exc).split())})") from None


def read_json_file(path: str | os.PathLike, expected: str):
    """The parsed JSON of the file ``path``; a one-line UserError for a missing,
    unreadable or invalid file (``expected`` names what a folder should have been)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a folder, expected {expected}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    return parse_json(text, path)


# --------------------------------------------------------------------------- messages


def show_json(value, limit: int = 60) -> str:
    """A short one-line rendering of a JSON value for messages (cut to ``limit``)."""
    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def json_key(name: str) -> str:
    """A JSON key from the file as a message shows it: a newline in it would split the one line."""
    return ascii(name)[1:-1]


# --------------------------------------------------------------------------- typed fields


def typed(value, kind, where: str):
    """``value`` checked against a JSON type: int (not bool), float (any finite number,
    returned as a float), str, bool, dict, list or (dict, NoneType); ``where`` starts the
    message ("FILE: 'field'")."""
    if kind is float:
        if not is_number(value):
            raise UserError(f"{where} must be a number, got {show_json(value)}")
        number = finite_number(value)
        if number is None:
            raise UserError(f"{where} must be finite, got {show_json(value)}")
        return number
    if kind is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise UserError(f"{where} must be a whole number, got {show_json(value)}")
        return value
    if not isinstance(value, kind):
        raise UserError(f"{where} must be {_KIND_NAMES.get(kind, getattr(kind, '__name__', kind))}, "
                        f"got {show_json(value)}")
    return value


def nested_numbers(value, depth: int) -> bool:
    """Whether ``value`` is a JSON array of numbers only, nested at most ``depth`` deep:
    numpy would quietly take "1" and true (and the bound keeps a deeply nested file
    from exhausting the stack)."""
    return isinstance(value, list) and depth > 0 and all(
        nested_numbers(v, depth - 1) if isinstance(v, list) else is_number(v) for v in value)


class JsonFields:
    """Typed access to the dotted fields of a parsed JSON object, with errors naming the
    file (``path``) and the field."""

    def __init__(self, path, data: dict):
        self.path, self.data = path, data

    @classmethod
    def entry(cls, path, name: str, value) -> "JsonFields":
        """Fields of ``value``, one entry of an array, named ``name`` ("keyframes[3]")
        in messages: "keyframes[3].fov"."""
        fields = cls(path, {name: value})
        fields.get(name, dict)
        return fields

    def get(self, dotted: str, kind):
        """The field ``dotted`` ("image.width") checked by :func:`typed`; UserError when
        it, or an object on its way, is missing or not an object."""
        value = self.data
        for depth, key in enumerate(dotted.split(".")):
            if not isinstance(value, dict):
                parent = ".".join(dotted.split(".")[:depth])
                raise UserError(f"{self.path}: '{parent}' must be a JSON object")
            if key not in value:
                raise UserError(f"{self.path}: missing '{dotted}'")
            value = value[key]
        return typed(value, kind, f"{self.path}: '{dotted}'")

    def optional(self, dotted: str, kind, default=None):
        """:meth:`get`, or ``default`` when the field is absent or null (a file written
        before the field existed)."""
        parent, _, key = dotted.rpartition(".")
        section = self.get(parent, dict) if parent else self.data
        if section.get(key) is None:
            return default
        return self.get(dotted, kind)

    def choice(self, dotted: str, choices: tuple[str, ...], default: str) -> str:
        """:meth:`optional` for a string that must be one of ``choices``."""
        value = self.optional(dotted, str, default)
        if value not in choices:
            raise UserError(f"{self.path}: '{dotted}' must be {' or '.join(map(show_json, choices))}, "
                            f"got {show_json(value)}")
        return value

    def array(self, dotted: str, shape: tuple[int, ...]) -> np.ndarray:
        """The field as a float64 array of ``shape``: nested arrays of finite numbers."""
        value = self.get(dotted, list)
        where = f"{self.path}: '{dotted}'"
        what = "3x3 numbers" if shape == (3, 3) else f"{shape[0]} numbers"

        def numbers(v, depth):
            if depth == len(shape):
                return is_number(v)
            return isinstance(v, list) and len(v) == shape[depth] and all(numbers(x, depth + 1) for x in v)

        if not numbers(value, 0):
            raise UserError(f"{where} must be {what}, got {show_json(value)}")
        try:
            array = np.array(value, dtype=np.float64)
        except OverflowError:  # an integer beyond float range
            raise UserError(f"{where} must be finite, got {show_json(value)}") from None
        if not np.all(np.isfinite(array)):
            raise UserError(f"{where} must be finite, got {show_json(value)}")
        return array

    def keys(self, where: str, entry: dict, required: tuple[str, ...], optional: tuple[str, ...] = ()) -> None:
        """UserError for a ``required`` key missing from ``entry`` (the object at dotted
        ``where``, "" for the top) or a key that is neither required nor ``optional``: a
        newer program's field cannot be honoured."""
        prefix = f"{where}." if where else ""
        for key in required:
            if key not in entry:
                raise UserError(f"{self.path}: missing '{prefix}{key}'")
        for key in entry:
            if key not in required and key not in optional:
                raise UserError(f"{self.path}: unknown field '{prefix}{json_key(key)}' "
                                f"(it may come from a newer raygs-viewer)")

    def version(self, newest: int, what: str) -> int:
        """The file's "version": a whole number from 1 to ``newest``; ``what`` names the
        kind of file in messages ("sidecar")."""
        version = self.get("version", int)
        if version > newest:
            raise UserError(f"{self.path}: {what} version {version} was written by a newer raygs-viewer "
                            f"(this one reads version {newest}); update raygs-viewer")
        if version < 1:
            raise UserError(f"{self.path}: 'version' {version} is not a {what} version (expected {newest})")
        return version


# --------------------------------------------------------------------------- writing


def json_text(data) -> str:
    """``data`` as indented JSON with each innermost list of numbers on one line (a 3x3
    matrix: a line a row), ending in a newline. Non-finite numbers and values JSON cannot hold are
    a ValueError or TypeError (nothing invalid is ever written)."""
    text = json.dumps(data, indent=2, allow_nan=False)
    return _NUMBER_LIST.sub(lambda m: "[" + " ".join(m.group(0)[1:-1].split()) + "]", text) + "\n"


def json_line(record: dict) -> str:
    """``record`` as one line of JSON with its newline (a stream of records, one a line)."""
    return json.dumps(record, allow_nan=False) + "\n"
