"""The header of a binary little-endian PLY file, validated before any data is read.

Everything a header can get wrong is a one-line UserError naming the file and, where
there is one, the header line; see :mod:`raygs_viewer.scene.io` for what is accepted.
"""

from __future__ import annotations

import numpy as np

from raygs_viewer.scene.reading import file_error, shown_token

HEADER_LIMIT = 1 << 20  # bytes searched for end_header
# numpy (and so plyfile) cannot shape an array past the largest signed 64-bit integer, not
# even the zero-byte rows of an element without properties, whose count no size check bounds.
MAX_COUNT = 2**63 - 1

#: PLY scalar type name -> (canonical name, size in bytes, little-endian numpy dtype)
PLY_TYPES: dict[str, tuple[str, int, np.dtype]] = {}
for _names, _size, _dtype in (
    (("char", "int8"), 1, "i1"), (("uchar", "uint8"), 1, "u1"),
    (("short", "int16"), 2, "<i2"), (("ushort", "uint16"), 2, "<u2"),
    (("int", "int32"), 4, "<i4"), (("uint", "uint32"), 4, "<u4"),
    (("float", "float32"), 4, "<f4"), (("double", "float64"), 8, "<f8"),
):
    for _name in _names:
        PLY_TYPES[_name] = (_names[0], _size, np.dtype(_dtype))


class PlyElement:
    """One ``element`` of a PLY header."""

    def __init__(self, name: str, count: int) -> None:
        self.name = name
        self.count = count
        self.properties: list[tuple[str, str]] = []  # (name, canonical type or "list")
        self.has_list = False
        #: bytes per row; with list properties, the size when every list is empty
        self.min_row_bytes = 0


def parse_header(path, shown: str) -> tuple[int, list[PlyElement], str | None]:
    """Validate the PLY header (read from at most 1 MiB, starting with the ``ply`` magic
    line): returns (header bytes, elements, refusal).

    ``refusal`` is None, or why plyfile, which read the data of every PLY file before
    issue 16, refused this header (an empty line, ``obj_info`` after an element) though
    the rules here accept it. Such a file failed to load unless it held no gaussians
    (their data was never read then); the reader keeps it that way.
    """
    with open(path, "rb") as f:
        head = f.read(HEADER_LIMIT)
    if head[:3] != b"ply" or head[3:4] not in (b"\n", b"\r"):
        what = "empty file" if not head else "does not start with the 'ply' magic line"
        raise file_error(shown, f"not a PLY file ({what})")
    nl = b"\r\n" if head.startswith(b"ply\r\n") else head[3:4]
    marker = nl + b"end_header" + nl
    end = head.find(marker)
    if end < 0:
        raise file_error(shown, "PLY header has no 'end_header' line in the first 1 MiB "
                                "(truncated or garbage header)")
    header_bytes = end + len(marker)
    try:
        text = head[:end].decode("ascii")
    except UnicodeDecodeError:
        raise file_error(shown, "PLY header is not ASCII text (garbage header)") from None
    lines = text.split(nl.decode("ascii"))[1:]  # after "ply"

    fmt = None
    elements: list[PlyElement] = []
    refusal = None
    for number, raw in enumerate(lines, start=2):
        where = f"PLY header line {number}"
        if not raw and refusal is None:
            refusal = f"{where}: empty line (a PLY header has none)"
        line = raw.strip()
        if not line:
            continue
        words = line.split()
        keyword = words[0]
        if keyword == "obj_info" and elements and refusal is None:
            refusal = f"{where}: 'obj_info' after an element (it belongs before them)"
        if keyword in ("comment", "obj_info"):
            continue
        if keyword == "format":
            if fmt is not None or elements:
                raise file_error(shown, f"{where}: unexpected 'format' line")
            if len(words) != 3:
                raise file_error(shown, f"{where}: expected 'format <type> 1.0'")
            fmt = words[1]
            if fmt == "ascii":
                raise file_error(shown, "ASCII PLY is not supported (need binary_little_endian)")
            if fmt == "binary_big_endian":
                raise file_error(shown, "big-endian PLY is not supported (need binary_little_endian)")
            if fmt != "binary_little_endian":
                raise file_error(shown, f"{where}: unknown PLY format {shown_token(fmt)}")
            if words[2] != "1.0":
                raise file_error(shown, f"{where}: unsupported PLY version {shown_token(words[2])} (expected 1.0)")
            continue
        if fmt is None:
            raise file_error(shown, f"{where}: expected a 'format' line, got {shown_token(keyword)}")
        if keyword == "element":
            if len(words) != 3:
                raise file_error(shown, f"{where}: expected 'element <name> <count>'")
            name = words[1]
            if not words[2].isdigit():
                raise file_error(shown, f"{where}: element {shown_token(name)} has a bad count {shown_token(words[2])}")
            if int(words[2]) > MAX_COUNT:
                raise file_error(shown, f"{where}: element {shown_token(name)} count "
                                        f"{shown_token(words[2], 30)} is too large")
            if any(e.name == name for e in elements):
                raise file_error(shown, f"{where}: duplicate element {shown_token(name)}")
            elements.append(PlyElement(name, int(words[2])))
            continue
        if keyword == "property":
            if not elements:
                raise file_error(shown, f"{where}: 'property' before any 'element'")
            element = elements[-1]
            if len(words) >= 2 and words[1] == "list":
                if len(words) != 5:
                    raise file_error(shown, f"{where}: expected 'property list <count type> <type> <name>'")
                types, name = words[2:4], words[4]
            elif len(words) == 3:
                types, name = words[1:2], words[2]
            else:
                raise file_error(shown, f"{where}: expected 'property <type> <name>'")
            for t in types:
                if t not in PLY_TYPES:
                    raise file_error(shown, f"{where}: unknown property type {shown_token(t)}")
            if any(p == name for p, _ in element.properties):
                raise file_error(shown, f"element {shown_token(element.name)} has duplicate property "
                                        f"{shown_token(name)}")
            if len(types) == 2:
                element.has_list = True
                element.min_row_bytes += PLY_TYPES[types[0]][1]
                element.properties.append((name, "list"))
            else:
                element.properties.append((name, PLY_TYPES[types[0]][0]))
                element.min_row_bytes += PLY_TYPES[types[0]][1]
            continue
        raise file_error(shown, f"{where}: unexpected {shown_token(keyword)} (garbage header)")
    if fmt is None:
        raise file_error(shown, "PLY header has no 'format' line")
    return header_bytes, elements, refusal
