"""The PLY reader as it was before issue 16 (main at 7db1cbc: ``load_ply`` with its
header parser, plyfile memory map, whole-column gather and float64 activation), frozen as the
reference the chunked reader must match bit for bit. Do not "fix" this file: it is
what "the same Scene as before" means.
"""

from __future__ import annotations

import os
import re

import numpy as np
from plyfile import PlyData, PlyParseError

from raygs_viewer.scene.model import (
    SH_DEGREE_OF_REST_COUNT,
    Scene,
    sh_coefficient_count,
)
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DROP_REASONS, file_error, shown_token

# --- ply_header.py as it was

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


def parse_header(path, shown: str) -> tuple[int, list[PlyElement]]:
    """Validate the PLY header (read from at most 1 MiB): returns (header bytes, elements)."""
    with open(path, "rb") as f:
        head = f.read(HEADER_LIMIT)
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
    for number, raw in enumerate(lines, start=2):
        line = raw.strip()
        if not line:
            continue
        words = line.split()
        keyword = words[0]
        where = f"PLY header line {number}"
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
    return header_bytes, elements


# --- ply_file.py as it was

_REQUIRED = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
_F_REST = re.compile(r"f_rest_(0|[1-9][0-9]*)")


def reference_load_ply(path, shown: str, report: Reporter, chunk_bytes: int) -> Scene:
    """The old ``load_ply``: patch it into ``raygs_viewer.scene.io`` to load files as
    the viewer did before."""
    header_bytes, elements = parse_header(path, shown)
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        raise file_error(shown, "PLY file has no 'vertex' element")
    if vertex.has_list:
        name = next(n for n, t in vertex.properties if t == "list")
        raise file_error(shown, f"vertex property {shown_token(name)} is a list; gaussian properties must be scalars")

    types = dict(vertex.properties)
    for name in _REQUIRED:
        if name not in types:
            raise file_error(shown, f"missing required vertex property {shown_token(name)}")
    rest = {}
    for name in types:
        if name.startswith("f_rest_"):
            m = _F_REST.fullmatch(name)
            if m is None:
                raise file_error(shown, f"bad SH property name {shown_token(name)} (expected f_rest_<index>)")
            rest[int(m.group(1))] = name
    n_rest = len(rest)
    if n_rest not in SH_DEGREE_OF_REST_COUNT:
        raise file_error(shown, f"{n_rest} f_rest_* properties; expected 0, 9, 24 or 45 (SH degree 0..3)")
    missing = sorted(set(range(n_rest)) - set(rest))
    if missing:
        raise file_error(shown, f"f_rest_* indices are not 0..{n_rest - 1} (missing f_rest_{missing[0]})")
    degree = SH_DEGREE_OF_REST_COUNT[n_rest]
    has_filter = "filter_3D" in types
    used = list(_REQUIRED) + [rest[i] for i in range(n_rest)] + (["filter_3D"] if has_filter else [])
    for name in used:
        if types[name] != "float":
            raise file_error(shown, f"property {shown_token(name)} is {types[name]}, expected float")

    # Size check from the header alone, before anything proportional to a count.
    size = os.path.getsize(path)
    needed = header_bytes + sum(e.count * e.min_row_bytes for e in elements)
    if size < needed:
        if vertex.count * vertex.min_row_bytes > size:
            raise file_error(shown, f"truncated: the header declares {vertex.count} gaussians "
                                    f"({vertex.count * vertex.min_row_bytes} bytes) but the file has {size} bytes")
        raise file_error(shown, f"truncated: the header declares {needed} bytes of data and header "
                                f"but the file has {size} bytes")

    n = vertex.count
    if n == 0:
        return _scene_from_columns(shown, np.zeros((0, len(used)), np.float32), degree, has_filter, report)

    with open(path, "rb") as f:
        try:
            ply = PlyData.read(_BoundedReads(f, size), mmap="c")
        except (PlyParseError, ValueError) as exc:
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise file_error(shown, f"cannot read PLY data ({shown_token(detail, 120)[1:-1]})") from None
        data = ply["vertex"].data
        if data.shape != (n,) or list(data.dtype.names) != [p for p, _ in vertex.properties]:
            raise file_error(shown, "PLY header could not be read consistently")
        columns = _gather_chunked(data, [data.dtype.fields[name][1] for name in used], report, chunk_bytes)
        del data, ply
    return _scene_from_columns(shown, columns, degree, has_filter, report)


class _BoundedReads:
    """The open file as plyfile reads it, refusing reads past its end.

    plyfile reads each list of a row with ``stream.read(length * itemsize)``, the length
    taken from the row itself, and a buffered read allocates what it is asked for before
    it finds the file short: 16 GiB for a bogus uint length. Refused here, the read turns
    into plyfile's "early end-of-file" without allocating anything.
    """

    def __init__(self, f, size: int) -> None:
        self._f = f
        self._size = size

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0 or n > self._size - self._f.tell():
            raise ValueError("read past the end of the file")
        return self._f.read(n)

    def __getattr__(self, name):
        return getattr(self._f, name)


def _gather_chunked(data: np.ndarray, offsets: list[int], report: Reporter, chunk_bytes: int) -> np.ndarray:
    """:func:`_gather_float32` over ``chunk_bytes`` of rows at a time, into one
    preallocated (N, len(offsets)) float32 array.

    ``data`` is usually plyfile's memory map, so gathering a chunk is what pages it
    in from disk: reporting per chunk tracks the actual reading. Chunking also
    bounds the gather's temporaries to a chunk instead of a copy of every column.
    """
    n = data.shape[0]
    out = np.empty((n, len(offsets)), np.float32)
    step = max(1, chunk_bytes // max(1, data.dtype.itemsize))
    for start in range(0, n, step):
        stop = min(n, start + step)
        out[start:stop] = _gather_float32(data[start:stop], offsets)
        report.reading(stop, n)
    return out


def _gather_float32(data: np.ndarray, offsets: list[int]) -> np.ndarray:
    """(N,) structured rows -> (N, len(offsets)) float32 columns at those byte offsets.

    Rows are viewed as float32 words (shifted by the offset's residue mod 4 when a
    non-4-byte property misaligns them) and gathered with one ``np.take`` per residue.
    """
    n, row = data.shape[0], data.dtype.itemsize
    raw = np.ascontiguousarray(data).view(np.uint8).reshape(n, row)
    offs = np.asarray(offsets, dtype=np.intp)
    parts, picks = [], []
    for r in np.unique(offs % 4):
        pick = np.flatnonzero(offs % 4 == r)
        if r == 0 and row % 4 == 0:
            words = raw.view("<f4")
        else:
            words = np.ascontiguousarray(raw[:, r: r + 4 * ((row - r) // 4)]).view("<f4")
        parts.append(np.take(words, (offs[pick] - r) // 4, axis=1))
        picks.append(pick)
    if len(parts) == 1:
        return parts[0].astype(np.float32, copy=False)
    order = np.argsort(np.concatenate(picks))
    return np.take(np.concatenate(parts, axis=1), order, axis=1).astype(np.float32, copy=False)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    """Stable logistic function: exactly 1 at +inf and 0 at -inf, no overflow."""
    e = np.exp(-np.abs(x))
    return np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def _scene_from_columns(shown: str, m: np.ndarray, degree: int, has_filter: bool,
                        report: Reporter) -> Scene:
    """Columns in the order x y z f_dc_0..2 opacity scale_0..2 rot_0..3 f_rest_* [filter_3D]."""
    report.activating()
    n = m.shape[0]
    k = sh_coefficient_count(degree) - 1
    positions = m[:, 0:3]
    dc = m[:, 3:6]
    rest = m[:, 14:14 + 3 * k]
    # The casts too: a signalling NaN (a flipped bit of +-inf) raises "invalid" when widened
    # to float64, and its gaussian is dropped as "nan" without a RuntimeWarning.
    with np.errstate(all="ignore"):
        logit = m[:, 6].astype(np.float64)
        log_scale = m[:, 7:10].astype(np.float64)
        rot = m[:, 10:14].astype(np.float64)
        opacity = _sigmoid(logit)
        scale = np.exp(log_scale)
        if has_filter:
            f2 = np.square(m[:, 14 + 3 * k].astype(np.float64))[:, None]
            fused = np.sqrt(scale * scale + f2)
            opacity = opacity * np.prod(scale / fused, axis=1)
            scale = fused
        norm = np.sqrt(np.sum(rot * rot, axis=1))
        quat = rot / norm[:, None]
        scales32 = scale.astype(np.float32)
        opacity32 = opacity.astype(np.float32)
        quat32 = quat.astype(np.float32)
        sh = np.empty((n, k + 1, 3), dtype=np.float32)
        sh[:, 0, :] = dc
        sh[:, 1:, :] = rest.reshape(n, 3, k).transpose(0, 2, 1)

        report.validating()
        # Cheap prefilter: a row sum is finite unless the row holds a NaN or an inf
        # (or overflows, which only makes the row a candidate for the exact tests).
        suspect = np.flatnonzero(~np.isfinite(m @ np.ones(m.shape[1], dtype=np.float32)))
        nan = np.zeros(n, dtype=bool)
        nan[suspect] = np.isnan(m[suspect]).any(axis=1)
        inf_colour = np.zeros(n, dtype=bool)
        inf_colour[suspect] = np.isinf(m[suspect, 3:6]).any(axis=1) | np.isinf(rest[suspect]).any(axis=1)
        tests = {
            "nan": nan,
            "infinite position": np.isinf(positions).any(axis=1),
            "infinite scale": np.isinf(scales32).any(axis=1),
            "zero scale": (scales32 == 0).any(axis=1),
            "infinite rotation": np.isinf(rot).any(axis=1),
            "zero quaternion": norm == 0,
            "infinite colour": inf_colour,
        }
    positions = np.ascontiguousarray(positions, dtype=np.float32)
    return build_scene(shown, positions, quat32, scales32, opacity32, sh, degree, has_filter, tests, report)


# --- reading.build_scene as it was

def build_scene(shown: str, positions, rotations, scales, opacities, sh, degree: int, fused: bool,
                tests: dict[str, np.ndarray], report: Reporter) -> Scene:
    """Drop invalid gaussians (``tests``: reason -> (N,) bool mask; the first failing
    reason of :data:`DROP_REASONS` wins) and build the Scene."""
    n = positions.shape[0]
    bad = np.zeros(n, dtype=bool)
    dropped: dict[str, int] = {}
    for reason in DROP_REASONS:
        mask = tests.get(reason)
        if mask is None:
            continue
        new = mask & ~bad
        count = int(np.count_nonzero(new))
        if count:
            dropped[reason] = count
            bad |= new
    if dropped:
        keep = ~bad
        positions, rotations, scales, opacities, sh = (
            a[keep] for a in (positions, rotations, scales, opacities, sh))
    return Scene(
        positions=np.ascontiguousarray(positions, dtype=np.float32),
        rotations=np.ascontiguousarray(rotations, dtype=np.float32),
        scales=np.ascontiguousarray(scales, dtype=np.float32),
        opacities=np.ascontiguousarray(opacities, dtype=np.float32),
        sh=np.ascontiguousarray(sh, dtype=np.float32),
        sh_degree=degree,
        filter_fused=fused,
        source=shown,
        dropped=dropped,
    )
