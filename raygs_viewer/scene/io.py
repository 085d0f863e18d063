"""Loading Gaussian scenes from disk: INRIA PLY and the 32-byte ``.splat`` format.

Everything here follows section 2 of the maths page (``raygs-math.md``). The
public entry points:

- :func:`load_scene` reads a file into an activated, validated :class:`Scene`.
- :func:`dropped_summary` turns ``scene.dropped`` into one line per reason.
- :func:`describe` / :func:`format_description` give the ``info`` statistics.

Bad input raises :class:`UserError` with a one-line message that starts with the
path as given (``scene.ply: property 'scale_0' is double, expected float``).

Decisions (the maths page leaves these open):

- An empty scene (``element vertex 0``, or an empty ``.splat`` file) is valid:
  N = 0, with the SH degree the header declares.
- Invalid gaussians are dropped, not fatal; each is counted under the *first*
  reason that applies, in this order: ``nan`` (a NaN in any used property,
  ``filter_3D`` included), ``infinite position``, ``infinite scale`` (an
  infinite log-scale, or exp(log-scale) or the fused scale overflowing float32),
  ``zero scale`` (an axis whose activated, fused scale is exactly 0 in float32,
  e.g. a log-scale of -inf or below about -103.3), ``negative scale`` (``.splat``
  only, whose scales are linear), ``infinite rotation``, ``zero quaternion``,
  ``infinite colour`` (an infinite SH coefficient: it would render as NaN).
  Tiny but positive scales (float32 subnormals included, real files carry
  log-scales of about -23) are kept unchanged. Opacity logits of +/-inf are
  valid and give opacity exactly 1 / 0.
- Unknown extra vertex properties (any type, lists excepted) and normals are
  ignored; only the properties used must be float32. Other elements (before or
  after ``vertex``) are allowed; their sizes count towards the size check.
"""

from __future__ import annotations

import os
import re
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyParseError

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import (
    SH_DEGREE_OF_REST_COUNT,
    Scene,
    sh_coefficient_count,
)

__all__ = [
    "DROP_REASONS",
    "READ_CHUNK_BYTES",
    "SPLAT_ROW_BYTES",
    "ProgressCallback",
    "describe",
    "dropped_summary",
    "format_description",
    "load_scene",
]

C0 = 0.28209479177387814

#: The 32-byte ``.splat`` row.
SPLAT_ROW_BYTES = 32
_SPLAT_DTYPE = np.dtype([("position", "<f4", (3,)), ("scale", "<f4", (3,)),
                         ("rgba", "u1", (4,)), ("rotation", "u1", (4,))])

#: Every reason a gaussian can be dropped for, in the order they are tested.
DROP_REASONS = (
    "nan",
    "infinite position",
    "infinite scale",
    "zero scale",
    "negative scale",
    "infinite rotation",
    "zero quaternion",
    "infinite colour",
)

_HEADER_LIMIT = 1 << 20  # bytes searched for end_header
# numpy (and so plyfile) cannot shape an array past the largest signed 64-bit integer, not
# even the zero-byte rows of an element without properties, whose count no size check bounds.
_MAX_COUNT = 2**63 - 1

#: Gaussian data is read (PLY: gathered from the memory map) this many bytes at a time,
#: with a progress report and a cancel check after each chunk. A few MiB keeps a
#: progress bar moving on multi-GB files at a negligible per-chunk overhead; tests
#: set it small to get many chunks from a tiny file.
READ_CHUNK_BYTES = 4 << 20

#: ``progress(fraction, stage)``: fraction in [0, 1], never decreasing; stage is a
#: short word ("reading", "activating", "validating", "done").
ProgressCallback = Callable[[float, str], None]

# Where each stage starts, as a fraction of the whole load. Reading dominates on a
# cold file; the rest are vectorised passes over arrays already in memory.
_READ_END = 0.7
_ACTIVATE_AT = 0.72
_VALIDATE_AT = 0.85
_BUILD_AT = 0.93

# PLY scalar type name -> (canonical name, size in bytes, little-endian numpy dtype)
_PLY_TYPES = {}
for _names, _size, _dtype in (
    (("char", "int8"), 1, "i1"), (("uchar", "uint8"), 1, "u1"),
    (("short", "int16"), 2, "<i2"), (("ushort", "uint16"), 2, "<u2"),
    (("int", "int32"), 4, "<i4"), (("uint", "uint32"), 4, "<u4"),
    (("float", "float32"), 4, "<f4"), (("double", "float64"), 8, "<f8"),
):
    for _name in _names:
        _PLY_TYPES[_name] = (_names[0], _size, np.dtype(_dtype))

_REQUIRED = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
_F_REST = re.compile(r"f_rest_(0|[1-9][0-9]*)")


# --------------------------------------------------------------------------- helpers


def _shown(text: str, limit: int = 60) -> str:
    """A header token made safe for a one-line message (quoted, ASCII, clipped)."""
    if len(text) > limit:
        text = text[:limit] + "..."
    return ascii(text)


def _error(path, message: str) -> UserError:
    line = f"{path}: {message}"
    return UserError(" ".join(line.splitlines()))


def _os_error(path, exc: OSError) -> UserError:
    if isinstance(exc, FileNotFoundError):
        return _error(path, "no such file")
    if isinstance(exc, IsADirectoryError):
        return _error(path, "is a directory, expected a .ply or .splat file")
    if isinstance(exc, PermissionError):
        return _error(path, "permission denied")
    return _error(path, f"cannot read: {exc.strerror or exc}")


class _Reporter:
    """Forwards progress to the caller's callback and turns a set cancel event into
    ``UserError("loading cancelled")``: every progress point is also a cancel point."""

    def __init__(self, progress: ProgressCallback | None, cancel: threading.Event | None) -> None:
        self.progress = progress
        self.cancel = cancel
        self.last = 0.0

    def __call__(self, fraction: float, stage: str) -> None:
        if self.cancel is not None and self.cancel.is_set():
            raise UserError("loading cancelled")
        if self.progress is not None:
            # Clamped so a caller's bar never runs backwards, whatever the stage maths says.
            self.last = min(1.0, max(self.last, float(fraction)))
            self.progress(self.last, stage)


# --------------------------------------------------------------------------- entry point


def load_scene(path: str | os.PathLike, *, progress: ProgressCallback | None = None,
               cancel: threading.Event | None = None) -> Scene:
    """Read an INRIA PLY or a ``.splat`` file into an activated :class:`Scene`.

    The format is chosen by the extension ``.splat`` (32-byte rows), otherwise by
    the PLY magic ``ply`` at the start of the file. Raises :class:`UserError`
    for anything that is not a readable scene file. Invalid gaussians are
    dropped and counted in ``scene.dropped`` (see the module docstring).

    ``progress(fraction, stage)`` is called from the loading thread: first with
    0.0, then after every :data:`READ_CHUNK_BYTES` of gaussian data and at each
    later stage, with a non-decreasing fraction; the last call is ``(1.0, "done")``.
    When ``cancel`` is set, loading stops at the next progress point (whether or
    not a callback is given) with ``UserError("loading cancelled")``.
    """
    report = _Reporter(progress, cancel)
    scene = _load(path, report)
    report(1.0, "done")
    return scene


def _load(path: str | os.PathLike, report: _Reporter) -> Scene:
    shown = os.fspath(path)
    report(0.0, "reading")
    if not os.path.exists(path):
        raise _error(shown, "no such file")
    if os.path.isdir(path):
        raise _error(shown, "is a directory, expected a .ply or .splat file")
    if not os.path.isfile(path):
        raise _error(shown, "not a regular file")
    try:
        if Path(path).suffix.lower() == ".splat":
            return _load_splat(path, shown, report)
        with open(path, "rb") as f:
            magic = f.read(4)
        if magic[:3] == b"ply" and magic[3:4] in (b"\n", b"\r"):
            return _load_ply(path, shown, report)
        if Path(path).suffix.lower() == ".ply" or magic[:3] == b"ply":
            what = "empty file" if not magic else "does not start with the 'ply' magic line"
            raise _error(shown, f"not a PLY file ({what})")
        raise _error(shown, "unrecognised file format: expected a PLY file (starting with 'ply') "
                            "or a .splat file")
    except OSError as exc:
        raise _os_error(shown, exc) from None
    except MemoryError:
        raise _error(shown, "not enough memory to load this scene") from None


# --------------------------------------------------------------------------- PLY header


class _Element:
    """One ``element`` of a PLY header."""

    def __init__(self, name: str, count: int) -> None:
        self.name = name
        self.count = count
        self.properties: list[tuple[str, str]] = []  # (name, canonical type or "list")
        self.has_list = False
        #: bytes per row; with list properties, the size when every list is empty
        self.min_row_bytes = 0


def _parse_header(path, shown: str) -> tuple[int, list[_Element]]:
    """Validate the PLY header (read from at most 1 MiB): returns (header bytes, elements)."""
    with open(path, "rb") as f:
        head = f.read(_HEADER_LIMIT)
    nl = b"\r\n" if head.startswith(b"ply\r\n") else head[3:4]
    marker = nl + b"end_header" + nl
    end = head.find(marker)
    if end < 0:
        raise _error(shown, "PLY header has no 'end_header' line in the first 1 MiB "
                            "(truncated or garbage header)")
    header_bytes = end + len(marker)
    try:
        text = head[:end].decode("ascii")
    except UnicodeDecodeError:
        raise _error(shown, "PLY header is not ASCII text (garbage header)") from None
    lines = text.split(nl.decode("ascii"))[1:]  # after "ply"

    fmt = None
    elements: list[_Element] = []
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
                raise _error(shown, f"{where}: unexpected 'format' line")
            if len(words) != 3:
                raise _error(shown, f"{where}: expected 'format <type> 1.0'")
            fmt = words[1]
            if fmt == "ascii":
                raise _error(shown, "ASCII PLY is not supported (need binary_little_endian)")
            if fmt == "binary_big_endian":
                raise _error(shown, "big-endian PLY is not supported (need binary_little_endian)")
            if fmt != "binary_little_endian":
                raise _error(shown, f"{where}: unknown PLY format {_shown(fmt)}")
            if words[2] != "1.0":
                raise _error(shown, f"{where}: unsupported PLY version {_shown(words[2])} (expected 1.0)")
            continue
        if fmt is None:
            raise _error(shown, f"{where}: expected a 'format' line, got {_shown(keyword)}")
        if keyword == "element":
            if len(words) != 3:
                raise _error(shown, f"{where}: expected 'element <name> <count>'")
            name = words[1]
            if not words[2].isdigit():
                raise _error(shown, f"{where}: element {_shown(name)} has a bad count {_shown(words[2])}")
            if int(words[2]) > _MAX_COUNT:
                raise _error(shown, f"{where}: element {_shown(name)} count {_shown(words[2], 30)} is too large")
            if any(e.name == name for e in elements):
                raise _error(shown, f"{where}: duplicate element {_shown(name)}")
            elements.append(_Element(name, int(words[2])))
            continue
        if keyword == "property":
            if not elements:
                raise _error(shown, f"{where}: 'property' before any 'element'")
            element = elements[-1]
            if len(words) >= 2 and words[1] == "list":
                if len(words) != 5:
                    raise _error(shown, f"{where}: expected 'property list <count type> <type> <name>'")
                types, name = words[2:4], words[4]
            elif len(words) == 3:
                types, name = words[1:2], words[2]
            else:
                raise _error(shown, f"{where}: expected 'property <type> <name>'")
            for t in types:
                if t not in _PLY_TYPES:
                    raise _error(shown, f"{where}: unknown property type {_shown(t)}")
            if any(p == name for p, _ in element.properties):
                raise _error(shown, f"element {_shown(element.name)} has duplicate property {_shown(name)}")
            if len(types) == 2:
                element.has_list = True
                element.min_row_bytes += _PLY_TYPES[types[0]][1]
                element.properties.append((name, "list"))
            else:
                element.properties.append((name, _PLY_TYPES[types[0]][0]))
                element.min_row_bytes += _PLY_TYPES[types[0]][1]
            continue
        raise _error(shown, f"{where}: unexpected {_shown(keyword)} (garbage header)")
    if fmt is None:
        raise _error(shown, "PLY header has no 'format' line")
    return header_bytes, elements


# --------------------------------------------------------------------------- PLY data


def _load_ply(path, shown: str, report: _Reporter) -> Scene:
    header_bytes, elements = _parse_header(path, shown)
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        raise _error(shown, "PLY file has no 'vertex' element")
    if vertex.has_list:
        name = next(n for n, t in vertex.properties if t == "list")
        raise _error(shown, f"vertex property {_shown(name)} is a list; gaussian properties must be scalars")

    types = dict(vertex.properties)
    for name in _REQUIRED:
        if name not in types:
            raise _error(shown, f"missing required vertex property {_shown(name)}")
    rest = {}
    for name in types:
        if name.startswith("f_rest_"):
            m = _F_REST.fullmatch(name)
            if m is None:
                raise _error(shown, f"bad SH property name {_shown(name)} (expected f_rest_<index>)")
            rest[int(m.group(1))] = name
    n_rest = len(rest)
    if n_rest not in SH_DEGREE_OF_REST_COUNT:
        raise _error(shown, f"{n_rest} f_rest_* properties; expected 0, 9, 24 or 45 (SH degree 0..3)")
    missing = sorted(set(range(n_rest)) - set(rest))
    if missing:
        raise _error(shown, f"f_rest_* indices are not 0..{n_rest - 1} (missing f_rest_{missing[0]})")
    degree = SH_DEGREE_OF_REST_COUNT[n_rest]
    has_filter = "filter_3D" in types
    used = list(_REQUIRED) + [rest[i] for i in range(n_rest)] + (["filter_3D"] if has_filter else [])
    for name in used:
        if types[name] != "float":
            raise _error(shown, f"property {_shown(name)} is {types[name]}, expected float")

    # Size check from the header alone, before anything proportional to a count.
    size = os.path.getsize(path)
    needed = header_bytes + sum(e.count * e.min_row_bytes for e in elements)
    if size < needed:
        if vertex.count * vertex.min_row_bytes > size:
            raise _error(shown, f"truncated: the header declares {vertex.count} gaussians "
                                f"({vertex.count * vertex.min_row_bytes} bytes) but the file has {size} bytes")
        raise _error(shown, f"truncated: the header declares {needed} bytes of data and header "
                            f"but the file has {size} bytes")

    n = vertex.count
    if n == 0:
        return _scene_from_columns(shown, np.zeros((0, len(used)), np.float32), degree, has_filter, report)

    with open(path, "rb") as f:
        try:
            ply = PlyData.read(_BoundedReads(f, size), mmap="c")
        except (PlyParseError, ValueError) as exc:
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise _error(shown, f"cannot read PLY data ({_shown(detail, 120)[1:-1]})") from None
        data = ply["vertex"].data
        if data.shape != (n,) or list(data.dtype.names) != [p for p, _ in vertex.properties]:
            raise _error(shown, "PLY header could not be read consistently")
        columns = _gather_chunked(data, [data.dtype.fields[name][1] for name in used], report)
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


def _gather_chunked(data: np.ndarray, offsets: list[int], report: _Reporter) -> np.ndarray:
    """:func:`_gather_float32` over READ_CHUNK_BYTES of rows at a time, into one
    preallocated (N, len(offsets)) float32 array.

    ``data`` is usually plyfile's memory map, so gathering a chunk is what pages it
    in from disk: reporting per chunk tracks the actual reading. Chunking also
    bounds the gather's temporaries to a chunk instead of a copy of every column.
    """
    n = data.shape[0]
    out = np.empty((n, len(offsets)), np.float32)
    step = max(1, READ_CHUNK_BYTES // max(1, data.dtype.itemsize))
    for start in range(0, n, step):
        stop = min(n, start + step)
        out[start:stop] = _gather_float32(data[start:stop], offsets)
        report(_READ_END * stop / n, "reading")
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
                        report: _Reporter) -> Scene:
    """Columns in the order x y z f_dc_0..2 opacity scale_0..2 rot_0..3 f_rest_* [filter_3D]."""
    report(_ACTIVATE_AT, "activating")
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

        report(_VALIDATE_AT, "validating")
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
    return _finish(shown, positions, quat32, scales32, opacity32, sh, degree, has_filter, tests, report)


def _finish(shown, positions, rotations, scales, opacities, sh, degree, fused, tests,
            report: _Reporter) -> Scene:
    """Drop invalid gaussians (first failing reason wins) and build the Scene."""
    report(_BUILD_AT, "validating")
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


# --------------------------------------------------------------------------- .splat


def _load_splat(path, shown: str, report: _Reporter) -> Scene:
    """The 32-byte ``.splat`` rows: float32 position xyz, float32 *linear* scale xyz,
    RGBA uint8 (colour -> SH DC via (c/255 - 0.5)/C0, opacity a/255), quaternion
    as 4 uint8 ``q*128+128`` in order w, x, y, z (normalised here). SH degree 0."""
    size = os.path.getsize(path)
    if size % SPLAT_ROW_BYTES:
        raise _error(shown, f"not a .splat file: size {size} bytes is not a multiple of {SPLAT_ROW_BYTES}")
    n = size // SPLAT_ROW_BYTES
    rows = np.empty(n, dtype=_SPLAT_DTYPE)
    # Read straight into the rows' memory, a chunk at a time: the same footprint as
    # one np.fromfile, with progress and cancel points in between.
    buffer = memoryview(rows.view(np.uint8))
    done = 0
    with open(path, "rb") as f:
        while done < size:
            got = f.readinto(buffer[done: min(size, done + max(1, READ_CHUNK_BYTES))])
            if not got:
                raise _error(shown, "truncated .splat file (the file shrank while reading)")
            done += got
            report(_READ_END * done / size, "reading")
    del buffer
    report(_ACTIVATE_AT, "activating")
    positions = rows["position"].astype(np.float32)
    scale = rows["scale"].astype(np.float32)
    rgba = rows["rgba"].astype(np.float64)
    q = (rows["rotation"].astype(np.float64) - 128.0) / 128.0
    with np.errstate(all="ignore"):
        norm = np.sqrt(np.sum(q * q, axis=1))
        quat = (q / norm[:, None]).astype(np.float32)
    sh = ((rgba[:, None, :3] / 255.0 - 0.5) / C0).astype(np.float32)
    opacity = (rgba[:, 3] / 255.0).astype(np.float32)
    report(_VALIDATE_AT, "validating")
    tests = {
        "nan": np.isnan(positions).any(axis=1) | np.isnan(scale).any(axis=1),
        "infinite position": np.isinf(positions).any(axis=1),
        "infinite scale": np.isinf(scale).any(axis=1),
        "zero scale": (scale == 0).any(axis=1),
        "negative scale": (scale < 0).any(axis=1),
        "zero quaternion": norm == 0,
    }
    return _finish(shown, positions, quat, scale, opacity, sh, 0, False, tests, report)


# --------------------------------------------------------------------------- reporting


def dropped_summary(scene: Scene) -> list[str]:
    """One line per drop reason, e.g. ``dropped 3 gaussians: nan`` (no ``warning:``
    prefix: the caller adds it). Empty when nothing was dropped."""
    lines = []
    for reason, count in scene.dropped.items():
        noun = "gaussian" if count == 1 else "gaussians"
        lines.append(f"dropped {count} {noun}: {reason}")
    return lines


def _stats(values: np.ndarray, *names: str) -> dict[str, float] | None:
    if values.size == 0:
        return None
    v = values.astype(np.float64, copy=False)
    funcs = {"min": np.min, "median": np.median, "mean": np.mean, "max": np.max}
    return {name: float(funcs[name](v)) for name in names}


def describe(scene: Scene) -> dict:
    """JSON-serialisable statistics of a scene (for ``raygs-viewer info``).

    Keys: source, count, sh_degree, filter_fused, bbox ({min, max} of positions,
    or None when empty), opacity ({min, median, mean, max} or None), scale
    ({min, median, max} over all axes, plus median_anisotropy = median of each
    gaussian's max/min scale ratio; None when empty), dropped ({total, by_reason}).
    """
    n = scene.count
    if n:
        bbox = {"min": [float(v) for v in scene.positions.min(axis=0)],
                "max": [float(v) for v in scene.positions.max(axis=0)]}
        s = scene.scales.astype(np.float64)
        scale = _stats(s, "min", "median", "max")
        scale["median_anisotropy"] = float(np.median(s.max(axis=1) / s.min(axis=1)))
    else:
        bbox = None
        scale = None
    return {
        "source": scene.source,
        "count": n,
        "sh_degree": scene.sh_degree,
        "filter_fused": bool(scene.filter_fused),
        "bbox": bbox,
        "opacity": _stats(scene.opacities, "min", "median", "mean", "max"),
        "scale": scale,
        "dropped": {"total": int(sum(scene.dropped.values())),
                    "by_reason": {k: int(v) for k, v in scene.dropped.items()}},
    }


def format_description(info: dict) -> str:
    """Human-readable multi-line text of :func:`describe`'s dict."""

    def g(v: float) -> str:
        return f"{v:.4g}"

    lines = [
        f"source:       {info['source']}",
        f"gaussians:    {info['count']}",
        f"SH degree:    {info['sh_degree']}",
        f"3D filter:    {'fused at load' if info['filter_fused'] else 'none'}",
    ]
    bbox = info.get("bbox")
    if bbox:
        lo, hi = bbox["min"], bbox["max"]
        size = [h - l for l, h in zip(lo, hi)]
        lines.append(f"bounds:       min ({', '.join(map(g, lo))})  max ({', '.join(map(g, hi))})"
                     f"  size ({', '.join(map(g, size))})")
    else:
        lines.append("bounds:       (empty scene)")
    o = info.get("opacity")
    if o:
        lines.append(f"opacity:      min {g(o['min'])}  median {g(o['median'])}  "
                     f"mean {g(o['mean'])}  max {g(o['max'])}")
    s = info.get("scale")
    if s:
        lines.append(f"scale:        min {g(s['min'])}  median {g(s['median'])}  max {g(s['max'])}  "
                     f"median max/min ratio {g(s['median_anisotropy'])}")
    d = info.get("dropped") or {"total": 0, "by_reason": {}}
    if d["total"]:
        reasons = ", ".join(f"{r}: {c}" for r, c in d["by_reason"].items())
        lines.append(f"dropped:      {d['total']} invalid ({reasons})")
    else:
        lines.append("dropped:      none")
    return "\n".join(lines)
