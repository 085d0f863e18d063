"""The gaussians of a ``.spz`` file: the packed arrays decoded into an activated Scene in
the project's axes (:func:`load_spz`), and a Scene quantised into them (:func:`spz_bytes`),
as the owners' ``packGaussians`` does with its default options. The layout, why the axes
flip, and the two conventions of ``spz_axes`` ("rub", the specification's; "rdf",
splat-transform's) are in :mod:`~raygs_viewer.scene.spz_format`; the header and the
compressed streams in :mod:`~raygs_viewer.scene.spz_stream`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import FileAxes, Scene, sh_coefficient_count
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DropTally, build_scene, scene_arrays
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.spz_format import (
    COORDINATE_SYSTEMS,
    DEFAULT_SPZ_AXES,
    RDF,
    Layout,
    axis_flips,
    flip_quaternion_xyz,
    flip_sh,
    spz_axes_system,
)
from raygs_viewer.scene.spz_stream import pack_spz_file, read_spz_file

#: The owners' default: 12 fractional bits, about 0.24 mm for scenes in metres.
DEFAULT_FRACTIONAL_BITS = 12
#: The owners' colour scale: colour byte = DC * 0.15 * 255 + 127.5.
COLOR_SCALE = 0.15
#: What a byte can hold (a writer clamps beyond): log-scales (s / 16 - 10) and the DC
#: colour coefficient ((c / 255 - 0.5) / COLOR_SCALE).
LOG_SCALE_RANGE = (-10.0, 255.0 / 16.0 - 10.0)
DC_LIMIT = 0.5 / COLOR_SCALE
#: Bits the owners' writer keeps of band-1 and of band-2+ SH bytes (PackOptions defaults).
SH1_BITS = 5
SH_REST_BITS = 4
_SQRT1_2 = np.sqrt(0.5)
#: For the smallest-three rotation: the indices (x y z w order) stored, lowest bits
#: first, when index L was the largest (the encoder shifts them in ascending order).
_SMALLEST_THREE_SLOTS = np.array([[i for i in range(3, -1, -1) if i != largest] for largest in range(4)])

SPZ_FORMATS = {1: "spz v1", 2: "spz v2", 3: "spz v3", 4: "spz v4"}


def load_spz(source: SceneSource, report: Reporter, chunk_bytes: int) -> Scene:
    """Read a ``.spz`` file (any version 1-4) into an activated Scene in RDF axes. A file
    that declares no coordinate system is taken to be in ``source.spz_axes`` ("rub" or
    "rdf"); ``Scene.axes`` says which was used."""
    path = shown = source.path
    chunk = max(1, int(chunk_bytes))
    layout, data, declared = read_spz_file(path, shown, report, chunk)
    scene = _decode(data, layout, declared or spz_axes_system(source.spz_axes), shown, report, chunk=chunk)
    return replace(scene, axes=FileAxes(source.spz_axes, COORDINATE_SYSTEMS[declared - 1] if declared else ""))


def _decode(data: np.ndarray, layout: Layout, system: int, shown: str, report: Reporter, *, chunk: int) -> Scene:
    """The gaussians of a .spz's decompressed ``data``, stored in coordinate system
    ``system`` (an index into COORDINATE_SYSTEMS, from 1), converted to RDF; ``chunk``
    bytes of rows between progress reports."""
    n = layout.n
    degree = min(layout.degree, 3)
    k = sh_coefficient_count(degree) - 1
    sections = np.split(data, np.cumsum(layout.sizes)[:-1])
    positions_b, alphas_b, colours_b, scales_b, rotations_b, sh_b = sections
    flips = axis_flips(system, RDF)
    q_flips = flip_quaternion_xyz(flips)
    sh_flips = flip_sh(flips, k)

    report.activating()
    arrays = scene_arrays(n, degree)
    positions, rotations, scales, opacities, sh = arrays
    drops = DropTally(n)
    step = max(1, chunk // max(1, layout.row_bytes))
    for start in range(0, n, step):
        rows = slice(start, min(n, start + step))
        count = rows.stop - start
        if layout.version == 1:
            # float16 may hold NaN or inf (dropped below); numpy would warn on a second line.
            with np.errstate(all="ignore"):
                p = positions_b[6 * start: 6 * rows.stop].view("<f2").reshape(count, 3) * flips
        else:
            raw = positions_b[9 * start: 9 * rows.stop].reshape(count, 3, 3).astype(np.int32)
            fixed = raw[..., 0] | raw[..., 1] << 8 | raw[..., 2] << 16
            p = ((fixed ^ 0x800000) - 0x800000) * 2.0 ** -layout.fractional_bits * flips
        positions[rows] = p
        scales[rows] = np.exp(scales_b[3 * start: 3 * rows.stop].reshape(count, 3) / 16.0 - 10.0)
        opacities[rows] = alphas_b[rows] / 255.0
        sh[rows, 0] = (colours_b[3 * start: 3 * rows.stop].reshape(count, 3) / 255.0 - 0.5) / COLOR_SCALE
        if k:
            rest = sh_b[3 * layout.sh_dim * start: 3 * layout.sh_dim * rows.stop].reshape(count, layout.sh_dim, 3)
            sh[rows, 1:] = (rest[:, :k] - 128.0) / 128.0 * sh_flips[None, :, None]
        width = layout.rotation_bytes
        q = _unpack_rotations(rotations_b[width * start: width * rows.stop].reshape(count, width))
        q[:, :3] *= q_flips
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        rotations[rows] = q[:, [3, 0, 1, 2]]
        if layout.version == 1:
            drops.add(start, {"nan": np.isnan(p).any(axis=1), "infinite position": np.isinf(p).any(axis=1)})
        report.activating()
    report.validating()
    return build_scene(arrays=arrays, sh_degree=degree, drops=drops, report=report, source=shown,
                       format=SPZ_FORMATS[layout.version])


def _unpack_rotations(raw: np.ndarray) -> np.ndarray:
    """(n, 3) or (n, 4) bytes -> (n, 4) float64 quaternions, x y z w, not yet normalised."""
    n = raw.shape[0]
    if raw.shape[1] == 3:
        xyz = raw / 127.5 - 1.0
        w = np.sqrt(np.maximum(0.0, 1.0 - np.sum(xyz * xyz, axis=1)))
        return np.concatenate([xyz, w[:, None]], axis=1)
    word = raw.astype(np.uint32)
    word = word[:, 0] | word[:, 1] << 8 | word[:, 2] << 16 | word[:, 3] << 24
    largest = (word >> 30).astype(np.intp)
    q = np.zeros((n, 4))
    rows = np.arange(n)
    for slot in range(3):
        bits = (word >> (10 * slot)) & 0x3FF
        value = _SQRT1_2 * (bits & 0x1FF) / 511.0
        q[rows, _SMALLEST_THREE_SLOTS[largest, slot]] = np.where(bits >> 9 == 1, -value, value)
    # Three stored components may square-sum past 1 in a corrupt file: the largest is then 0.
    q[rows, largest] = np.sqrt(np.maximum(0.0, 1.0 - np.sum(q * q, axis=1)))
    return q


def spz_bytes(scene: Scene, version: int = 3, spz_axes: str = DEFAULT_SPZ_AXES) -> bytes:
    """The whole ``.spz`` file for a scene: version 2 or 3 (gzip) or 4 (zstd), quantised
    as the owners' ``packGaussians`` does with its default options, in the axes of
    ``spz_axes`` ("rub", the specification's; "rdf", splat-transform's), unmarked.

    Positions use the owners' 12 fractional bits when every coordinate fits the 24-bit
    word (|x| < 2048); otherwise the largest number of fractional bits that fits (the
    header records it, and readers honour it), down to 0 (|x| < 2^23): beyond that,
    and for non-finite positions, a UserError. SH is written as its bytes
    (buckets of 8 for band 1, of 16 for bands 2 and 3, the owners' defaults).
    """
    if version not in (2, 3, 4):
        raise UserError(f"cannot write .spz version {version} (versions 2, 3 and 4 are written)")
    flips = axis_flips(RDF, spz_axes_system(spz_axes))
    n, degree = scene.count, scene.sh_degree
    positions = scene.positions.astype(np.float64)
    if not np.isfinite(positions).all():
        raise UserError("cannot write .spz: the scene has non-finite positions")
    extent = float(np.abs(positions).max()) if n else 0.0
    fractional_bits = next((bits for bits in range(DEFAULT_FRACTIONAL_BITS, -1, -1)
                            if _round_half_away(extent * 2.0 ** bits) <= 0x7FFFFF), None)
    if fractional_bits is None:
        raise UserError(f"cannot write .spz: a coordinate of magnitude {extent:.6g} does not fit its 24-bit "
                        "fixed-point positions (at most 8,388,607)")
    fixed = _round_half_away(positions * flips * 2.0 ** fractional_bits).astype(np.int64) & 0xFFFFFF
    position_bytes = np.stack([fixed & 0xFF, fixed >> 8 & 0xFF, fixed >> 16], axis=-1).astype(np.uint8)
    with np.errstate(divide="ignore"):
        scale_bytes = _to_uint8((np.log(scene.scales.astype(np.float64)) + 10.0) * 16.0)
    alpha_bytes = _to_uint8(scene.opacities.astype(np.float64) * 255.0)
    colour_bytes = _to_uint8(scene.sh[:, 0].astype(np.float64) * (COLOR_SCALE * 255.0) + 127.5)
    q = scene.rotations.astype(np.float64)[:, [1, 2, 3, 0]]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[:, :3] *= flip_quaternion_xyz(flips)
    rotation_bytes = _pack_smallest_three(q) if version >= 3 else _pack_first_three(q)
    k = sh_coefficient_count(degree) - 1
    # float32 is exact here (x * 128 is a power-of-two scaling) and halves the work on
    # the largest array; levels are clipped before the integer bucket arithmetic.
    rest = scene.sh[:, 1:] * (flip_sh(flips, k) * 128.0).astype(np.float32)[None, :, None]
    level = np.clip(_round_half_away(rest), -1024, 1024).astype(np.int16) + 128
    buckets = np.where(np.arange(k) < 3, 1 << (8 - SH1_BITS), 1 << (8 - SH_REST_BITS)).astype(np.int16)[None, :, None]
    sh_bytes = np.clip((level + buckets // 2) // buckets * buckets, 0, 255).astype(np.uint8)
    arrays = [position_bytes, alpha_bytes, colour_bytes, scale_bytes, rotation_bytes, sh_bytes]
    arrays = [np.ascontiguousarray(a).tobytes() for a in arrays]
    return pack_spz_file(version, n, degree, fractional_bits, arrays)


def _round_half_away(x):
    """C's round(): halves away from zero (numpy's round is half to even)."""
    return np.copysign(np.floor(np.abs(x) + 0.5), x)


def _to_uint8(x: np.ndarray) -> np.ndarray:
    return np.clip(_round_half_away(np.nan_to_num(x, nan=0.0)), 0, 255).astype(np.uint8)


def _pack_first_three(q: np.ndarray) -> np.ndarray:
    """Version 2: x y z of the quaternion with w >= 0, each as round(v * 127.5 + 127.5)."""
    q = np.where(q[:, 3:] < 0, -q, q)
    return _to_uint8(q[:, :3] * 127.5 + 127.5)


def _pack_smallest_three(q: np.ndarray) -> np.ndarray:
    n = q.shape[0]
    rows = np.arange(n)
    largest = np.argmax(np.abs(q), axis=1)
    negate = q[rows, largest] < 0
    word = largest.astype(np.uint32) << 30
    for slot in range(3):
        component = q[rows, _SMALLEST_THREE_SLOTS[largest, slot]]
        magnitude = np.minimum(np.floor(511.0 * np.abs(component) / _SQRT1_2 + 0.5), 511).astype(np.uint32)
        sign = ((component < 0) ^ negate).astype(np.uint32)
        word |= (sign << 9 | magnitude) << (10 * slot)
    return word.astype("<u4").view(np.uint8).reshape(n, 4)
