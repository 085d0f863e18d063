"""PlayCanvas's compressed PLY: a ``chunk`` element of per-256-gaussian bounds and packed
``vertex`` words, as SuperSplat and splat-transform export it.

Layout (binary little-endian PLY; elements found by name, properties by name):

- ``chunk``, ceil(N / 256) rows of float32: ``min_x min_y min_z max_x max_y max_z``,
  ``min_scale_x .. max_scale_z`` (log-scales), and in files written since SuperSplat
  added them ``min_r min_g min_b max_r max_g max_b`` (older files have 12 columns).
  Gaussian i uses row i // 256.
- ``vertex``, N rows of uint32 words:
  ``packed_position`` x:11 (bits 21-31), y:10 (bits 11-20), z:11 (bits 0-10), each a
  unorm t = q / (2^bits - 1) and the value ``min * (1 - t) + max * t`` of its chunk;
  ``packed_scale`` the same 11-10-11 split of the *log*-scales;
  ``packed_rotation`` smallest three: bits 30-31 the index (in rot_0..rot_3 order, i.e.
  w x y z) of the largest component, dropped and made positive by the writer, then the
  other three in order at bits 20, 10 and 0, 10 bits each, as (t - 0.5) * sqrt(2); the
  largest is sqrt(max(0, 1 - a^2 - b^2 - c^2));
  ``packed_color`` r, g, b, a at bits 24, 16, 8, 0, 8 bits each: r, g, b are unorms of
  the *colour* ``f_dc * C0 + 0.5`` between the chunk's colour bounds (directly the
  colour when the chunk has none), a is the activated opacity sigmoid(logit).
- ``sh`` (optional), N rows of uint8 ``f_rest_0 .. f_rest_{K-1}``, K = 9, 24 or 45 in
  INRIA's channel-major order; byte b is ``(n - 0.5) * 8`` with n = 0 for b = 0,
  1 for b = 255, else (b + 0.5) / 256: the centre of the writer's bin
  ``trunc((v / 8 + 0.5) * 256)`` clamped to 0..255, so the rest lies in [-4, 4].

The axes are the INRIA PLY's: splat-transform reads INRIA and compressed PLY alike as
its ``Transform.PLY`` space, and its writer converts to that space before packing, so
nothing is flipped here. The decoding mirrors splat-transform's (src/lib/readers/
decompress-ply.ts and read-ply.ts ``readCompressedChunked``; its writer is
src/lib/writers/compressed-chunk.ts and write-compressed-ply.ts) in float64, rounded
once to float32: positions and SH come out bit-identical to its decode; scales,
opacities and rotations within a float32 rounding (it stores the log-scale, logit and
raw quaternion as float32 before they are activated). PlayCanvas's engine (src/scene/gsplat/gsplat-compressed-data.js)
decodes the same words alike except the SH bytes, which it maps as b * 8 / 255 - 4
(at most half a step, 1/64, from the bin centres used here). The opacity is the
alpha unorm itself: sigmoid of the logit -log(1 / a - 1) those readers produce.

Sizes and counts are checked from the header before anything proportional to a count
is allocated; rows are read ``chunk_bytes`` at a time between progress reports.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np

from raygs_viewer.scene.model import SH_DEGREE_OF_REST_COUNT, Scene
from raygs_viewer.scene.ply_header import PLY_TYPES, PlyElement
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DropTally, SceneArrays, build_scene, file_error, scene_arrays, shown_token
from raygs_viewer.scene.sh import C0

COMPRESSED_PLY_FORMAT = "PlayCanvas compressed PLY"
#: gaussians per row of the ``chunk`` element
CHUNK_GAUSSIANS = 256

_BOUNDS = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
           "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z")
_COLOUR_BOUNDS = ("min_r", "min_g", "min_b", "max_r", "max_g", "max_b")
_PACKED = ("packed_position", "packed_rotation", "packed_scale", "packed_color")
_F_REST = re.compile(r"f_rest_(0|[1-9][0-9]*)")

def _sh_of_byte() -> np.ndarray:
    """The 256 SH byte values: the centres of splat-transform's writer's bins."""
    n = (np.arange(256) + 0.5) / 256.0
    n[0], n[255] = 0.0, 1.0  # the writer clamps to 0..255, so the end bytes stand for -4 and 4 and beyond
    return ((n - 0.5) * 8.0).astype(np.float32)


_SH_OF_BYTE = _sh_of_byte()

@dataclass(frozen=True)
class _Layout:
    """Where a compressed PLY's values are: its ``vertex`` element, whether its chunks
    carry colour bounds, its ``sh`` element (None without one) and that element's
    f_rest_* names in index order."""

    vertex: PlyElement
    has_colour: bool
    sh: PlyElement | None
    rest_names: list[str]


def load_compressed_ply(path, shown: str, report: Reporter, *, chunk_bytes: int, header_bytes: int,
                        elements: list[PlyElement], refusal: str | None) -> Scene:
    """The Scene of a compressed PLY whose header :func:`parse_header` has read:
    ``header_bytes`` long, its ``elements``, and plyfile's ``refusal`` of it or None."""
    chunk, vertex, sh = _check_elements(shown, elements)
    n = vertex.count
    chunk_types = dict(chunk.properties)
    has_colour = any(name in chunk_types for name in _COLOUR_BOUNDS)
    bound_names = _BOUNDS + (_COLOUR_BOUNDS if has_colour else ())
    for name in bound_names:
        _expect(shown, chunk, chunk_types, name, "float")
    vertex_types = dict(vertex.properties)
    for name in _PACKED:
        _expect(shown, vertex, vertex_types, name, "uint")
    rest_names = _rest_names(shown, sh) if sh is not None else []
    degree = SH_DEGREE_OF_REST_COUNT[len(rest_names)]

    chunks = -(-n // CHUNK_GAUSSIANS)
    if chunk.count != chunks:
        raise file_error(shown, f"compressed PLY: {n} gaussians need ceil({n} / {CHUNK_GAUSSIANS}) = {chunks} "
                                f"'chunk' rows, the header declares {chunk.count}")
    if sh is not None and sh.count != n:
        raise file_error(shown, f"compressed PLY: 'sh' element has {sh.count} rows but 'vertex' has {n}")

    # Size check from the header alone, before anything proportional to a count.
    size = os.path.getsize(path)
    offsets, at = {}, header_bytes
    for element in elements:
        offsets[element.name] = at
        at += element.count * element.min_row_bytes
    if size < at:
        raise file_error(shown, f"truncated: the header declares {n} gaussians in {at} bytes of header "
                                f"and data but the file has {size} bytes")
    if n and refusal is not None:
        raise file_error(shown, f"cannot read PLY data ({refusal})")

    arrays = scene_arrays(n, degree)
    drops = DropTally(n)
    layout = _Layout(vertex, has_colour, sh, rest_names)
    with open(path, "rb") as f:
        bounds_rows = _read_rows(f, shown, chunk, offsets["chunk"], range(0, chunks))
        bounds = np.stack([_field(bounds_rows, chunk, name, "<f4") for name in bound_names], axis=1)
        del bounds_rows
        row_bytes = vertex.min_row_bytes + (sh.min_row_bytes if sh is not None else 0)
        step = max(1, chunk_bytes // max(1, row_bytes))
        for start in range(0, n, step):
            stop = min(n, start + step)
            words = _read_rows(f, shown, vertex, offsets["vertex"], range(start, stop))
            coefficients = _read_rows(f, shown, sh, offsets["sh"], range(start, stop)) if sh is not None else None
            _decode(layout, start, words, bounds[np.arange(start, stop) // CHUNK_GAUSSIANS], coefficients,
                    out=arrays, drops=drops)
            del words, coefficients
            report.reading(stop, n)
    report.activating()
    report.validating()
    return build_scene(arrays=arrays, sh_degree=degree, drops=drops, report=report, source=shown,
                       format=COMPRESSED_PLY_FORMAT)


def _decode(layout: _Layout, start: int, words: np.ndarray, block: np.ndarray, coefficients: np.ndarray | None, *,
            out: SceneArrays, drops: DropTally) -> None:
    """The gaussians from ``start`` on, from their raw vertex rows ``words`` (rows, row
    bytes), their chunks' bounds ``block`` (rows, 12 or 18) and their raw sh rows (None
    without SH), into the scene's arrays ``out``; their drops into ``drops``."""
    stop = start + len(words)
    vertex, has_colour, sh, rest_names = layout.vertex, layout.has_colour, layout.sh, layout.rest_names
    positions, rotations, scales, opacities, sh_out = (a[start:stop] for a in out)
    with np.errstate(all="ignore"):  # non-finite bounds: their gaussians are dropped below
        positions[:] = _unpack_111011(_field(words, vertex, "packed_position", "<u4"), block[:, 0:6])
        log_scales = _unpack_111011(_field(words, vertex, "packed_scale", "<u4"), block[:, 6:12])
        scales[:] = np.exp(log_scales)
        rotations[:] = _unpack_rotation(_field(words, vertex, "packed_rotation", "<u4"))
        colour, alpha = _unpack_colour(_field(words, vertex, "packed_color", "<u4"),
                                       block[:, 12:18] if has_colour else None)
        opacities[:] = alpha
        sh_out[:, 0, :] = (colour - 0.5) / C0
    if coefficients is not None:
        k = len(rest_names) // 3
        rest = np.stack([_field(coefficients, sh, name, "u1") for name in rest_names], axis=1)
        # f_rest_{c * k + j} is coefficient j + 1 of channel c
        sh_out[:, 1:, :] = _SH_OF_BYTE[rest].reshape(stop - start, 3, k).transpose(0, 2, 1)
    dc = sh_out[:, 0, :]  # judged in float32: a finite colour past 3.4e38 is infinite there
    drops.add(start, {
        "nan": np.isnan(positions).any(axis=1) | np.isnan(log_scales).any(axis=1) | np.isnan(dc).any(axis=1),
        "infinite position": np.isinf(positions).any(axis=1),
        "infinite scale": np.isinf(scales).any(axis=1),
        "zero scale": (scales == 0).any(axis=1),
        "infinite colour": np.isinf(dc).any(axis=1),
    })


def _check_elements(shown: str, elements: list[PlyElement]):
    """(chunk, vertex, sh or None) after checking that every element's rows have a fixed
    size (the data of each is then at a known offset)."""
    by_name = {e.name: e for e in elements}
    if "vertex" not in by_name:
        raise file_error(shown, "compressed PLY has no 'vertex' element")
    for element in elements:
        if element.has_list:
            name = next(p for p, t in element.properties if t == "list")
            raise file_error(shown, f"compressed PLY element {shown_token(element.name)} has a list property "
                                    f"{shown_token(name)}")
    return by_name["chunk"], by_name["vertex"], by_name.get("sh")


def _expect(shown: str, element: PlyElement, types: dict, name: str, kind: str) -> None:
    if name not in types:
        raise file_error(shown, f"compressed PLY: {shown_token(element.name)} element has no property "
                                f"{shown_token(name)}")
    if types[name] != kind:
        raise file_error(shown, f"compressed PLY: property {shown_token(name)} is {types[name]}, expected {kind}")


def _rest_names(shown: str, sh: PlyElement) -> list[str]:
    """The ``sh`` element's f_rest_* names in index order (9, 24 or 45 uchar properties)."""
    rest = {}
    for name, kind in sh.properties:
        m = _F_REST.fullmatch(name)
        if m is None:
            raise file_error(shown, f"compressed PLY: 'sh' element has property {shown_token(name)} "
                                    "(expected only f_rest_<index>)")
        if kind != "uchar":
            raise file_error(shown, f"compressed PLY: property {shown_token(name)} is {kind}, expected uchar")
        rest[int(m.group(1))] = name
    if len(rest) not in SH_DEGREE_OF_REST_COUNT or not rest:
        raise file_error(shown, f"compressed PLY: 'sh' element has {len(rest)} f_rest_* properties; "
                                "expected 9, 24 or 45 (SH degree 1..3)")
    missing = sorted(set(range(len(rest))) - set(rest))
    if missing:
        raise file_error(shown, f"compressed PLY: f_rest_* indices are not 0..{len(rest) - 1} "
                                f"(missing f_rest_{missing[0]})")
    return [rest[i] for i in range(len(rest))]


def _read_rows(f, shown: str, element: PlyElement, offset: int, rows: range) -> np.ndarray:
    """The ``rows`` of ``element`` (data at ``offset``) as (rows, row bytes) uint8; ``f``
    is buffered, so a short read means the end of the file."""
    start, stop = rows.start, rows.stop
    row = element.min_row_bytes
    f.seek(offset + start * row)
    data = f.read((stop - start) * row)  # no more than the size check found in the file
    if len(data) != (stop - start) * row:
        raise file_error(shown, "truncated PLY file (the file shrank while reading)")
    return np.frombuffer(data, np.uint8).reshape(stop - start, row)


def _field(rows: np.ndarray, element: PlyElement, name: str, dtype: str) -> np.ndarray:
    """The column ``name`` of raw rows, as its little-endian ``dtype``."""
    at = 0
    for prop, kind in element.properties:
        if prop == name:
            break
        at += PLY_TYPES[kind][1]
    size = np.dtype(dtype).itemsize
    return np.ascontiguousarray(rows[:, at: at + size]).view(dtype)[:, 0]


def _unorm(words: np.ndarray, shift: int, bits: int) -> np.ndarray:
    mask = (1 << bits) - 1
    return ((words >> np.uint32(shift)) & np.uint32(mask)).astype(np.float64) / mask


def _lerp(low: np.ndarray, high: np.ndarray, t: np.ndarray) -> np.ndarray:
    # splat-transform's form, not low + (high - low) * t: the two differ in the last bit.
    return low * (1.0 - t) + high * t


def _unpack_111011(words: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(rows,) words, (rows, 6) min xyz, max xyz -> (rows, 3) float64 between them."""
    bounds = bounds.astype(np.float64)
    t = np.stack([_unorm(words, 21, 11), _unorm(words, 11, 10), _unorm(words, 0, 11)], axis=1)
    return _lerp(bounds[:, 0:3], bounds[:, 3:6], t)


def _unpack_rotation(words: np.ndarray) -> np.ndarray:
    """Smallest-three words -> (rows, 4) unit quaternions w, x, y, z."""
    rows = words.shape[0]
    abc = np.stack([_unorm(words, 20, 10), _unorm(words, 10, 10), _unorm(words, 0, 10)], axis=1)
    abc = (abc - 0.5) * math.sqrt(2.0)
    largest = np.sqrt(np.maximum(0.0, 1.0 - np.sum(abc * abc, axis=1)))
    which = (words >> np.uint32(30)).astype(np.intp)
    q = np.empty((rows, 4), np.float64)
    for slot in range(4):
        mine = which == slot
        q[mine, slot] = largest[mine]
        q[np.ix_(mine, [s for s in range(4) if s != slot])] = abc[mine]
    # A writer's three smallest have a^2 + b^2 + c^2 <= 3/4, so q is a unit vector; only a
    # corrupt word exceeds 1 (the largest is then 0): normalised like the PLY reader's rot_*,
    # its norm sqrt(a^2 + b^2 + c^2) > 1 is never zero.
    return q / np.sqrt(np.sum(q * q, axis=1))[:, None]


def _unpack_colour(words: np.ndarray, bounds: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """8-8-8-8 words -> ((rows, 3) colour f_dc * C0 + 0.5, (rows,) opacity)."""
    t = np.stack([_unorm(words, 24, 8), _unorm(words, 16, 8), _unorm(words, 8, 8)], axis=1)
    colour = t if bounds is None else _lerp(bounds[:, 0:3].astype(np.float64), bounds[:, 3:6].astype(np.float64), t)
    return colour, _unorm(words, 0, 8)
