"""Reading the gaussians of an INRIA PLY file: the vertex properties checked against
the header, the rows read a chunk at a time, activated and validated straight into the
Scene's final arrays (section 2 of the maths page; the rules are in
:mod:`raygs_viewer.scene.io`).

Where every element has fixed-size rows (real scenes: one ``vertex`` element) the rows
are read from the file at their known offset into one reused chunk buffer; a file whose
other elements hold lists goes through plyfile's reader instead, which finds where
``vertex`` starts. Either way nothing of the scene's size exists but the final arrays
and one byte a gaussian for the drop tally: a 3M SH-3 scene peaks at about its file size.
"""

from __future__ import annotations

import os
import re

import numpy as np
from plyfile import PlyData, PlyParseError

from raygs_viewer.scene.compressed_ply import load_compressed_ply
from raygs_viewer.scene.model import SH_DEGREE_OF_REST_COUNT, Scene, sh_coefficient_count
from raygs_viewer.scene.ply_header import PLY_TYPES, parse_header
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DropTally, build_scene, file_error, scene_arrays, shown_token
from raygs_viewer.scene.source import SceneSource

_REQUIRED = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
_F_REST = re.compile(r"f_rest_(0|[1-9][0-9]*)")

PLY_FORMAT = "INRIA PLY"


def load_ply(source: SceneSource, report: Reporter, chunk_bytes: int) -> Scene:
    """The Scene of a PLY file, validated from its header before anything the size of
    its count is allocated; ``chunk_bytes`` of rows are read between progress reports."""
    path = shown = source.path
    header_bytes, elements, refusal = parse_header(path, shown)
    if any(e.name == "chunk" for e in elements):  # PlayCanvas's packed layout, not INRIA's
        return load_compressed_ply(path, shown, report, chunk_bytes=chunk_bytes, header_bytes=header_bytes,
                                   elements=elements, refusal=refusal)
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
    if n and refusal is not None:
        raise file_error(shown, f"cannot read PLY data ({refusal})")
    target = _Target(n, degree, has_filter)
    if n and not any(e.has_list for e in elements):
        # Every row has a fixed size: the vertex data sits at a known offset and is read
        # straight from the file, a chunk at a time, into the final arrays.
        offset = header_bytes
        for element in elements[: elements.index(vertex)]:
            offset += element.count * element.min_row_bytes
        offsets = _property_offsets(vertex, used)
        for start, raw in _file_chunks(path, shown, offset, n, row_bytes=vertex.min_row_bytes, chunk_bytes=chunk_bytes):
            target.add(start, _gather_float32(raw, offsets))
            report.reading(start + raw.shape[0], n)
    elif n:
        with open(path, "rb") as f:
            try:
                ply = PlyData.read(_BoundedReads(f, size), mmap="c")
            except (PlyParseError, ValueError) as exc:
                detail = " ".join(str(exc).split()) or type(exc).__name__
                raise file_error(shown, f"cannot read PLY data ({shown_token(detail, 120)[1:-1]})") from None
            data = ply["vertex"].data
            if data.shape != (n,) or list(data.dtype.names) != [p for p, _ in vertex.properties]:
                raise file_error(shown, "PLY header could not be read consistently")
            offsets = [data.dtype.fields[name][1] for name in used]
            step = max(1, chunk_bytes // max(1, data.dtype.itemsize))
            for start in range(0, n, step):
                rows = np.ascontiguousarray(data[start: start + step])
                target.add(start, _gather_float32(rows.view(np.uint8).reshape(rows.shape[0], -1), offsets))
                report.reading(start + rows.shape[0], n)
            del data, ply
    report.activating()
    report.validating()
    return target.build(shown, report)


def _property_offsets(vertex, used: list[str]) -> list[int]:
    """Byte offsets within a vertex row of the ``used`` properties (the row packs every
    property of the header, in order, each of its type's size)."""
    offsets, at = {}, 0
    for name, kind in vertex.properties:
        offsets[name] = at
        at += PLY_TYPES[kind][1]
    return [offsets[name] for name in used]


def _file_chunks(path, shown: str, offset: int, n: int, *, row_bytes: int, chunk_bytes: int):
    """Yields (first row, (rows, row_bytes) uint8) for the ``n`` rows at ``offset``, about
    ``chunk_bytes`` at a time, read into one reused buffer (each chunk is only valid
    until the next one is read)."""
    step = max(1, chunk_bytes // row_bytes)
    buffer = np.empty((min(step, n), row_bytes), np.uint8)
    with open(path, "rb", buffering=0) as f:
        f.seek(offset)
        for start in range(0, n, step):
            rows = min(step, n - start)
            view = memoryview(buffer[:rows]).cast("B")
            done = 0
            while done < len(view):
                got = f.readinto(view[done:])
                if not got:
                    raise file_error(shown, "truncated PLY file (the file shrank while reading)")
                done += got
            yield start, buffer[:rows]


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


def _gather_float32(raw: np.ndarray, offsets: list[int]) -> np.ndarray:
    """(N, row bytes) uint8 rows -> (N, len(offsets)) float32 columns at those byte offsets.

    Rows are viewed as float32 words (shifted by the offset's residue mod 4 when a
    non-4-byte property misaligns them) and gathered with one ``np.take`` per residue.
    """
    row = raw.shape[1]
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


class _Target:
    """The Scene's final float32 arrays, filled a chunk of rows at a time with activated
    values, and the invalid gaussians found on the way.

    Activations are computed in float64 per chunk and rounded once to float32, so the
    result does not depend on how the rows are chunked; nothing is held for the whole
    scene but the final arrays and the drop tally (one byte a gaussian).
    """

    def __init__(self, n: int, degree: int, has_filter: bool) -> None:
        self.k = sh_coefficient_count(degree) - 1
        self.degree = degree
        self.has_filter = has_filter
        self.arrays = scene_arrays(n, degree)
        self.drops = DropTally(n)

    def add(self, start: int, m: np.ndarray) -> None:
        """Rows ``start..`` from ``m``: (rows, columns) float32 in the order x y z
        f_dc_0..2 opacity scale_0..2 rot_0..3 f_rest_* [filter_3D]."""
        k = self.k
        rows = m.shape[0]
        stop = start + rows
        positions, scales = self.arrays.positions[start:stop], self.arrays.scales[start:stop]
        rest = m[:, 14:14 + 3 * k]
        positions[:] = m[:, 0:3]
        sh = self.arrays.sh[start:stop]
        sh[:, 0, :] = m[:, 3:6]
        sh[:, 1:, :] = rest.reshape(rows, 3, k).transpose(0, 2, 1)
        # The casts too: a signalling NaN (a flipped bit of +-inf) raises "invalid" when widened
        # to float64, and its gaussian is dropped as "nan" without a RuntimeWarning.
        with np.errstate(all="ignore"):
            logit = m[:, 6].astype(np.float64)
            log_scale = m[:, 7:10].astype(np.float64)
            rot = m[:, 10:14].astype(np.float64)
            opacity = _sigmoid(logit)
            scale = np.exp(log_scale)
            if self.has_filter:
                f2 = np.square(m[:, 14 + 3 * k].astype(np.float64))[:, None]
                fused = np.sqrt(scale * scale + f2)
                opacity = opacity * np.prod(scale / fused, axis=1)
                scale = fused
            norm = np.sqrt(np.sum(rot * rot, axis=1))
            scales[:] = scale
            self.arrays.opacities[start:stop] = opacity
            self.arrays.rotations[start:stop] = rot / norm[:, None]

            # Cheap prefilter: a row sum is finite unless the row holds a NaN or an inf
            # (or overflows, which only makes the row a candidate for the exact tests).
            # numpy's own sum, not a BLAS product: OpenBLAS threads stall on a busy machine
            # (the hash and the sort run beside a load), and this pass runs per chunk.
            suspect = np.flatnonzero(~np.isfinite(np.add.reduce(m, axis=1)))
            nan = np.zeros(rows, dtype=bool)
            nan[suspect] = np.isnan(m[suspect]).any(axis=1)
            inf_colour = np.zeros(rows, dtype=bool)
            inf_colour[suspect] = np.isinf(m[suspect, 3:6]).any(axis=1) | np.isinf(rest[suspect]).any(axis=1)
            self.drops.add(start, {
                "nan": nan,
                "infinite position": np.isinf(positions).any(axis=1),
                "infinite scale": np.isinf(scales).any(axis=1),
                "zero scale": (scales == 0).any(axis=1),
                "infinite rotation": np.isinf(rot).any(axis=1),
                "zero quaternion": norm == 0,
                "infinite colour": inf_colour,
            })

    def build(self, shown: str, report: Reporter) -> Scene:
        return build_scene(arrays=self.arrays, sh_degree=self.degree, filter_fused=self.has_filter,
                           drops=self.drops, report=report, source=shown, format=PLY_FORMAT)
