"""A SOG scene's ``meta.json`` (version 2): its schema, checked field by field into a
:class:`SogMeta`, every fault one line naming the file and the field.

The JSON itself is read by :func:`raygs_viewer.jsonfile.parse_json` with Python's NaN
and Infinity tokens refused (no number here may be other than finite; a codebook's
``null`` is the one stand-in, see :func:`_codebook`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raygs_viewer.errors import finite_number, is_number
from raygs_viewer.jsonfile import parse_json, show_json
from raygs_viewer.scene.reading import file_error

#: The most gaussians a SOG may declare: 32 Mi, far past what a single SOG holds in
#: practice (PlayCanvas advises streamed SOG beyond 1-2 M). It bounds every image at
#: 2^26 + 65536 pixels (under Pillow's own bomb limit), whatever a header claims.
MAX_COUNT = 1 << 25
#: shN palette: 16-bit labels.
MAX_PALETTE = 1 << 16
CODEBOOK_SIZE = 256
# A bad value is shown cut to 30 characters and "...": enough to recognise it, and the
# message stays one short line.
_SHOWN_CHARACTERS = 33


@dataclass(frozen=True)
class SogMeta:
    """What meta.json says: the count, the position bounds (float64, (3,) each), the
    codebooks (float64, 256 entries each), the image names and the SH palette."""

    count: int
    mins: np.ndarray
    maxs: np.ndarray
    means_files: list[str]
    scales_codebook: np.ndarray
    scales_file: str
    quats_file: str
    sh0_codebook: np.ndarray
    sh0_file: str
    bands: int = 0
    palette_count: int = 0
    shn_codebook: np.ndarray | None = None
    #: centroids, then labels
    shn_files: tuple[str, ...] = ()

    @property
    def image_names(self) -> list[str]:
        """Every image it names, in the order it names them."""
        return [*self.means_files, self.scales_file, self.quats_file, self.sh0_file, *self.shn_files]


def parse_meta(shown: str, raw: bytes) -> SogMeta:
    """The meta.json bytes ``raw`` checked against SOG version 2; ``shown`` names the file
    in messages."""
    meta = parse_json(raw, shown, constants=False)
    if not isinstance(meta, dict):
        raise file_error(shown, "not a SOG meta.json (expected a JSON object)")
    _check_version(shown, meta)
    count = whole_number(shown, "count", meta.get("count"), (0, MAX_COUNT), "gaussians")
    means = _section(shown, meta, "means")
    mins = _numbers(shown, means, "means", "mins", 3)
    maxs = _numbers(shown, means, "means", "maxs", 3)
    means_files = _files(shown, means, "means", 2)
    scales = _section(shown, meta, "scales")
    scales_codebook = _codebook(shown, scales, "scales")
    scales_file = _files(shown, scales, "scales", 1)[0]
    quats_file = _files(shown, _section(shown, meta, "quats"), "quats", 1)[0]
    sh0 = _section(shown, meta, "sh0")
    sh0_codebook = _codebook(shown, sh0, "sh0")
    sh0_file = _files(shown, sh0, "sh0", 1)[0]
    palette = {}
    if meta.get("shN") is not None:
        shn = _section(shown, meta, "shN")
        palette["bands"] = whole_number(shown, "shN.bands", shn.get("bands"), (0, 3), "SH bands")
        if palette["bands"]:
            palette["palette_count"] = whole_number(shown, "shN.count", shn.get("count"), (0, MAX_PALETTE),
                                                    "palette entries")
            palette["shn_codebook"] = _codebook(shown, shn, "shN")
            palette["shn_files"] = tuple(_files(shown, shn, "shN", 2)[:2])
    return SogMeta(count, mins, maxs, means_files, scales_codebook, scales_file, quats_file, sh0_codebook, sh0_file,
                   **palette)


def _check_version(shown: str, meta: dict) -> None:
    """Version 2, or a line saying what else the file is (SOG v1, a streamed index)."""
    if "version" not in meta:
        if "means" in meta:
            raise file_error(shown, "SOG version 1 (a meta.json without 'version') is not supported; "
                                    "this reader reads SOG version 2 (re-export it with splat-transform)")
        raise file_error(shown, "not a SOG meta.json (no 'version' and no 'means')")
    version = meta["version"]
    if not is_number(version) or version != 2:
        if "lodLevels" in meta or "tree" in meta:
            raise file_error(shown, "a streamed SOG index, not a SOG meta.json: open it by its folder "
                                    "or as lod-meta.json")
        raise file_error(shown, f"SOG version {show_json(version, _SHOWN_CHARACTERS)} is not supported "
                                "(this reader reads version 2)")


def _section(shown: str, meta: dict, key: str) -> dict:
    value = meta.get(key)
    if not isinstance(value, dict):
        what = "missing" if value is None else f"a {_json_type(value)}, expected an object"
        raise file_error(shown, f"'{key}' is {what}")
    return value


def _json_type(value) -> str:
    names = {dict: "object", list: "list", str: "string", bool: "boolean", int: "number", float: "number"}
    return names.get(type(value), "null")


def whole_number(shown: str, name: str, value, allowed: tuple[int, int], what: str) -> int:
    """The JSON field ``name``'s ``value`` as an int, when it is a whole number within
    ``allowed`` (low, high), counting ``what``; else a one-line error naming the file
    ``shown`` and the field (the SOG meta.json's and the streamed SOG index's fields)."""
    low, high = allowed
    if finite_number(value) is None or value != int(value):
        raise file_error(shown, f"'{name}' is {show_json(value, _SHOWN_CHARACTERS)}, expected a whole number")
    value = int(value)
    if not low <= value <= high:
        raise file_error(shown, f"'{name}' is {value}: expected {low}..{high} {what}")
    return value


def _numbers(shown: str, section: dict, where: str, key: str, length: int) -> np.ndarray:
    value = section.get(key)
    if (not isinstance(value, list) or len(value) != length
            or not all(finite_number(v) is not None for v in value)):
        raise file_error(shown, f"'{where}.{key}' must be a list of {length} finite numbers")
    return np.array(value, dtype=np.float64)


def _codebook(shown: str, section: dict, where: str) -> np.ndarray:
    value = section.get("codebook")
    if not isinstance(value, list) or len(value) != CODEBOOK_SIZE:
        got = f"{len(value)} entries" if isinstance(value, list) else ("missing" if value is None else
                                                                         f"a {_json_type(value)}")
        raise file_error(shown, f"'{where}.codebook' is {got}, expected a list of {CODEBOOK_SIZE} numbers")
    if not all(v is None or finite_number(v) is not None for v in value):
        raise file_error(shown, f"'{where}.codebook' holds something other than finite numbers and null")
    book = np.array([math.nan if v is None else float(v) for v in value], dtype=np.float64)
    if value[0] is None:
        # Old writers stored -Infinity, which JSON writes as null; the engine extrapolates it.
        with np.errstate(all="ignore"):
            book[0] = book[1] + (book[1] - book[255]) / 255.0
    return book


def _files(shown: str, section: dict, where: str, needed: int) -> list[str]:
    value = section.get("files")
    if (not isinstance(value, list) or len(value) < needed
            or not all(isinstance(v, str) and v for v in value[:needed])):
        raise file_error(shown, f"'{where}.files' must list {needed} image file name{'s' if needed > 1 else ''}")
    return value[:needed]
