"""Niantic's ``.spz``: reading versions 1 to 4, writing versions 2, 3 and 4.

Mirrors the owners' reference code, nianticlabs/spz (``src/cc/load-spz.cc``,
``src/cc/splat-utils.h``, ``src/cc/splat-types.h``, ``extensions/README.md`` and the
README's "File Format" section, read at commit 21715c3); nothing is copied from it.

Layout
------
Versions 1-3: one gzip stream holding a 16-byte header, then the packed arrays::

    u32 magic 0x5053474e ("NGSP"), u32 version, u32 numPoints,
    u8 shDegree, u8 fractionalBits, u8 flags (1: antialiased, 2: extensions), u8 reserved

Version 4: no gzip; a 32-byte plaintext header (the same first 15 bytes, then
u8 numStreams, u32 tocByteOffset, 12 reserved bytes), optional extension records in
``[32, tocByteOffset)``, a table of contents of numStreams x (u64 compressed size,
u64 uncompressed size) at tocByteOffset, then one zstd stream per non-empty array,
back to back up to the end of the file.

The arrays, in this order (the streams of version 4 in the same order)::

    positions  N x 3 x 24-bit signed fixed point, value * 2^-fractionalBits
               (version 1: N x 3 float16)
    alphas     N x u8: opacity a/255 (the owners store sigmoid(logit) * 255)
    colours    N x 3 u8: SH DC = (c/255 - 0.5) / 0.15 (the owners' colour scale 0.15)
    scales     N x 3 u8: log-scale = s/16 - 10
    rotations  versions 1-2: N x 3 u8, quaternion x y z = r/127.5 - 1, w = sqrt(1 - |xyz|^2) >= 0;
               versions 3-4: N x u32 little-endian "smallest three": bits 30-31 the index
               (in x y z w order) of the largest component, which is positive and rebuilt
               from the unit norm; the other three in index order from bit 29 down,
               10 bits each: a sign bit, then 9 bits of |q_i| / sqrt(1/2) * 511
    sh         N x ((d+1)^2 - 1) x 3 u8 (coefficient-major, colour fastest):
               coefficient = (b - 128) / 128. The owners' writer rounds band 1 to
               buckets of 8 (5 bits) and bands 2-4 to buckets of 16 (4 bits).

Axes: ``.spz`` stores right-up-back (RUB, OpenGL / three.js) axes; the project's
scenes are in INRIA PLY's right-down-front (RDF). The conversion is the owners'
``coordinateConverter`` between two systems of the same family: a diagonal flip
F = diag(fx, fy, fz) (RUB <-> RDF: (1, -1, -1)), applied to positions (p' = F p), to
the quaternion's vector part (x, y, z) *= (fy fz, fx fz, fx fy) (the rotation
F R F, w unchanged), and to each SH coefficient by the parity of its basis function
under F (``_SH_PARITY``: e.g. k=1, proportional to y, flips with fy; k=3, proportional
to x, does not flip). The same converter applied twice is the identity, so writing
uses it too. An ``SPZ_ADOBE_coordinate_system`` extension (type 0xADBE0003) naming a
standard-family system other than RUB is honoured the same way; one of the rotated
family (which needs a 90-degree SH rotation) is refused in one line.

Decisions:

- Version 1 (float16 positions, never released by the owners) is read; versions
  above 4 are refused naming the version. An "NGSP" file that is not gzip must be
  version 4 or later, as in the owners' loader.
- SH degree 4 (allowed by the owners since version 4) is read and truncated to
  degree 3, the project's maximum (bands are orthogonal: the degree-3 part is exact).
- The antialiased flag (trained with Mip-Splatting's 2D filter) is read but the
  Scene has no field for it; the writer writes 0.
- An empty scene (numPoints 0) is valid, as for PLY (the owners' loader refuses it).
- Hostile files: numPoints is bounded before anything is allocated, by an absolute
  cap (:data:`MAX_POINTS`) and by what the compressed bytes can possibly expand to
  (deflate's ratio limit 1032:1; for zstd the owners' bound of 1024 x the file size
  over 9 bytes per point). The data is then stream-decompressed into a buffer of
  exactly the size the header implies: a stream that ends early or runs longer is an
  error. Extension records are bounded by :data:`MAX_EXTENSION_BYTES`. Bytes after
  the end of the gzip stream are ignored, as the owners' loader does.
"""

from __future__ import annotations

import gzip
import io
import os
import struct
import zlib
from dataclasses import dataclass

import numpy as np
import zstandard

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DropTally, build_scene, file_error, scene_arrays

SPZ_MAGIC = 0x5053474E
GZIP_MAGIC = b"\x1f\x8b"
LATEST_VERSION = 4
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
#: More gaussians than any shared scene holds (the largest are a few tens of millions);
#: a header declaring more is corrupt or hostile.
MAX_POINTS = 100_000_000
#: Extension records (a coordinate system, camera limits) are a few dozen bytes.
MAX_EXTENSION_BYTES = 1 << 20
#: Deflate cannot expand more than 1032:1 (a 258-byte match coded in 2 bits).
_GZIP_MAX_RATIO = 1032
#: The owners' v4 sanity bound: numPoints * 9 <= file size * 1024.
_ZSTD_MAX_RATIO = 1024
_ZSTD_MIN_BYTES_PER_POINT = 9
_FLAG_ANTIALIASED = 0x1
_FLAG_EXTENSIONS = 0x2
_EXT_COORDINATE_SYSTEM = 0xADBE0003
_LEGACY_HEADER = struct.Struct("<IIIBBBB")
_NGSP_HEADER = struct.Struct("<IIIBBBBI12x")
_SQRT1_2 = np.sqrt(0.5)
#: The owners' coordinate systems: 1..8 the standard family, bits of (value - 1) say
#: x right (bit 0), y up (bit 1), z front (bit 2); 9..16 the rotated family.
_SYSTEMS = ("LDB", "RDB", "LUB", "RUB", "LDF", "RDF", "LUF", "RUF",
            "LFD", "RFD", "LFU", "RFU", "LBD", "RBD", "LBU", "RBU")
_RUB, _RDF = 4, 6
#: Which of x, y, z each SH basis function k = 1..15 (INRIA's order, ``scene/sh.py``)
#: is odd in: flipping an axis negates the coefficient once per odd axis.
_SH_PARITY = np.array([
    (0, 1, 0), (0, 0, 1), (1, 0, 0),                                    # -y, z, -x
    (1, 1, 0), (0, 1, 1), (0, 0, 0), (1, 0, 1), (0, 0, 0),              # xy, yz, 3z^2-1, xz, x^2-y^2
    (0, 1, 0), (1, 1, 1), (0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 0, 1), (1, 0, 0),
])
#: For the smallest-three rotation: the indices (x y z w order) stored, lowest bits
#: first, when index L was the largest (the encoder shifts them in ascending order).
_SMALLEST_THREE_SLOTS = np.array([[i for i in range(3, -1, -1) if i != largest] for largest in range(4)])

SPZ_FORMATS = {1: "spz v1", 2: "spz v2", 3: "spz v3", 4: "spz v4"}


@dataclass(frozen=True)
class _Layout:
    """The packed arrays' byte sizes for a header."""

    version: int
    n: int
    degree: int
    fractional_bits: int
    flags: int

    @property
    def position_bytes(self) -> int:
        return 6 if self.version == 1 else 9

    @property
    def rotation_bytes(self) -> int:
        return 4 if self.version >= 3 else 3

    @property
    def sh_dim(self) -> int:
        return sh_coefficient_count(self.degree) - 1

    @property
    def sizes(self) -> list[int]:
        """Bytes of positions, alphas, colours, scales, rotations, sh (the file's order)."""
        n = self.n
        return [n * self.position_bytes, n, 3 * n, 3 * n, n * self.rotation_bytes, 3 * n * self.sh_dim]

    @property
    def row_bytes(self) -> int:
        return self.position_bytes + 7 + self.rotation_bytes + 3 * self.sh_dim


# =============================================================================== reading


def load_spz(path, shown: str, report: Reporter, chunk_bytes: int) -> Scene:
    """Read a ``.spz`` file (any version 1-4) into an activated Scene in RDF axes."""
    size = os.path.getsize(path)
    chunk = max(1, int(chunk_bytes))
    with open(path, "rb") as f:
        magic = f.read(4)
        f.seek(0)
        if magic[:2] == GZIP_MAGIC:
            layout, data, extensions = _read_gzip(f, size, shown, report, chunk)
        elif len(magic) == 4 and struct.unpack("<I", magic)[0] == SPZ_MAGIC:
            layout, data, extensions = _read_ngsp(f, size, shown, report, chunk)
        else:
            what = "an empty file" if not magic else "starts with neither gzip's 1f 8b nor 'NGSP'"
            raise file_error(shown, f"not a .spz file ({what})")
    system = _coordinate_system(extensions, shown)
    return _decode(data, layout, system, shown, report, chunk)


def _check_header(shown: str, version: int, n: int, degree: int, fractional_bits: int) -> None:
    if version < 1 or version > LATEST_VERSION:
        raise file_error(shown, f"unsupported .spz version {version} (this viewer reads versions 1 to "
                                f"{LATEST_VERSION})")
    if n > MAX_POINTS:
        raise file_error(shown, f"corrupt .spz header: {n:,} gaussians declared (at most {MAX_POINTS:,} "
                                "are accepted)")
    if degree > 4:
        raise file_error(shown, f"corrupt .spz header: SH degree {degree} (expected 0 to 4)")
    # The 24-bit word has a sign bit; more fractional bits than 23 would leave no
    # integer part at all (and the owners' writer always uses 12).
    if version > 1 and fractional_bits > 23:
        raise file_error(shown, f"corrupt .spz header: {fractional_bits} fractional bits (expected 0 to 23)")


def _read_gzip(f, size: int, shown: str, report: Reporter, chunk: int):
    inflater = _Inflater(f, shown, chunk)
    head = inflater.read_exactly(_LEGACY_HEADER.size, "its header")
    magic, version, n, degree, fractional_bits, flags, _ = _LEGACY_HEADER.unpack(head)
    if magic != SPZ_MAGIC:
        raise file_error(shown, "not a .spz file (the gzip stream does not start with 'NGSP')")
    _check_header(shown, version, n, degree, fractional_bits)
    layout = _Layout(version, n, degree, fractional_bits, flags)
    total = n * layout.row_bytes
    if _LEGACY_HEADER.size + total > _GZIP_MAX_RATIO * size + 1024:
        raise file_error(shown, f"corrupt .spz header: {n:,} gaussians ({_LEGACY_HEADER.size + total:,} bytes) "
                                f"cannot come out of {size:,} bytes of gzip")
    data = np.empty(total, dtype=np.uint8)
    inflater.read_into(memoryview(data), "the gaussians", lambda done: report.reading(done, total))
    allowed = MAX_EXTENSION_BYTES if flags & _FLAG_EXTENSIONS else 0
    extra = inflater.finish(allowed, _LEGACY_HEADER.size + total)
    return layout, data, _extension_records(extra) if flags & _FLAG_EXTENSIONS else {}


class _Inflater:
    """A gzip stream read from a file a chunk at a time, never inflating more than asked for."""

    def __init__(self, f, shown: str, chunk: int) -> None:
        self.f, self.shown, self.chunk = f, shown, chunk
        self.z = zlib.decompressobj(16 + zlib.MAX_WBITS)
        self.pending = b""
        self.out = 0

    def _inflate(self, limit: int) -> bytes:
        """Up to ``limit`` (>0) more bytes; b"" only at the end of the stream."""
        while True:
            if self.z.eof:
                return b""
            if not self.pending:
                self.pending = self.z.unconsumed_tail or self.f.read(self.chunk)
                if not self.pending:
                    return b""
            try:
                piece = self.z.decompress(self.pending, limit)
            except zlib.error as exc:
                raise file_error(self.shown, f"corrupt .spz: the gzip data is damaged ({exc})") from None
            self.pending = self.z.unconsumed_tail
            if piece:
                self.out += len(piece)
                return piece

    def read_into(self, view: memoryview, what: str, progress=None) -> None:
        done = 0
        while done < len(view):
            piece = self._inflate(min(len(view) - done, self.chunk))
            if not piece:
                self._ended_early(what)
            view[done: done + len(piece)] = piece
            done += len(piece)
            if progress is not None:
                progress(done)

    def read_exactly(self, count: int, what: str) -> bytes:
        buffer = bytearray(count)
        self.read_into(memoryview(buffer), what)
        return bytes(buffer)

    def _ended_early(self, what: str):
        if self.z.eof:
            raise file_error(self.shown, f"corrupt .spz: the data ends inside {what} (after {self.out:,} bytes)")
        raise file_error(self.shown, f"truncated .spz: the gzip stream is cut off inside {what}")

    def finish(self, allowed: int, expected: int) -> bytes:
        """Up to ``allowed`` trailing bytes, then the end of the stream (checksum checked)."""
        extra = bytearray()
        while True:
            piece = self._inflate(allowed - len(extra) + 1)
            if not piece:
                break
            extra += piece
            if len(extra) > allowed:
                raise file_error(self.shown, f"corrupt .spz: the data runs past the {expected:,} bytes its "
                                             "header declares")
        if not self.z.eof:
            raise file_error(self.shown, "truncated .spz: the gzip stream is cut off at its end")
        return bytes(extra)


def _read_ngsp(f, size: int, shown: str, report: Reporter, chunk: int):
    head = f.read(_NGSP_HEADER.size)
    if len(head) < _NGSP_HEADER.size:
        raise file_error(shown, f"truncated .spz: {size} bytes, less than the 32-byte version 4 header")
    magic, version, n, degree, fractional_bits, flags, streams, toc = _NGSP_HEADER.unpack(head)
    if 1 <= version < 4:
        raise file_error(shown, f"corrupt .spz: version {version} files are gzip-compressed, this one is not")
    _check_header(shown, version, n, degree, fractional_bits)
    layout = _Layout(version, n, degree, fractional_bits, flags)
    if n * _ZSTD_MIN_BYTES_PER_POINT > _ZSTD_MAX_RATIO * size:
        raise file_error(shown, f"corrupt .spz header: {n:,} gaussians cannot come out of a {size:,}-byte file")
    sizes = [s for s in layout.sizes if s]
    if streams != len(sizes):
        raise file_error(shown, f"corrupt .spz header: {streams} streams, expected {len(sizes)} for "
                                f"{n:,} gaussians of SH degree {degree}")
    toc_end = toc + 16 * streams
    if toc < _NGSP_HEADER.size or toc_end > size:
        raise file_error(shown, f"corrupt .spz: the table of contents (bytes {toc:,} to {toc_end:,}) lies "
                                f"outside the file's {size:,} bytes")
    extensions = {}
    if flags & _FLAG_EXTENSIONS and toc > _NGSP_HEADER.size:
        if toc - _NGSP_HEADER.size > MAX_EXTENSION_BYTES:
            raise file_error(shown, f"corrupt .spz: {toc - _NGSP_HEADER.size:,} bytes of extensions")
        extensions = _extension_records(f.read(toc - _NGSP_HEADER.size))
    f.seek(toc)
    entries = np.frombuffer(f.read(16 * streams), dtype="<u8").reshape(streams, 2).astype(object)
    offset = toc_end
    for index, ((packed, unpacked), expected) in enumerate(zip(entries, sizes)):
        if unpacked != expected:
            raise file_error(shown, f"corrupt .spz: stream {index} declares {unpacked:,} bytes, the header "
                                    f"implies {expected:,}")
        offset += packed
    if offset != size:
        raise file_error(shown, f"corrupt .spz: the table of contents accounts for {offset:,} bytes, the file "
                                f"has {size:,}")
    total = sum(sizes)
    data = np.empty(total, dtype=np.uint8)
    view = memoryview(data)
    decompressor = zstandard.ZstdDecompressor()
    f.seek(toc_end)
    done = 0
    for index, (packed, unpacked) in enumerate(entries):
        source = _Window(f, int(packed))
        begin, end = done, done + int(unpacked)
        try:
            reader = decompressor.stream_reader(source, read_size=chunk, read_across_frames=True, closefd=False)
            while done < end:
                piece = reader.read(min(end - done, chunk))
                if not piece:
                    raise file_error(shown, f"truncated .spz: stream {index} ends after {done - begin:,} "
                                            f"of its {unpacked:,} bytes")
                view[done: done + len(piece)] = piece
                done += len(piece)
                report.reading(done, total)
            if reader.read(1):
                raise file_error(shown, f"corrupt .spz: stream {index} holds more than the {unpacked:,} bytes "
                                        "its table of contents declares")
        except zstandard.ZstdError as exc:
            raise file_error(shown, f"corrupt .spz: stream {index}: {exc}") from None
    return layout, data, extensions


class _Window(io.RawIOBase):
    """``count`` bytes of a file from its current position, as a stream of their own."""

    def __init__(self, f, count: int) -> None:
        self.f, self.left = f, count

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        want = min(len(buffer), self.left)
        got = self.f.readinto(memoryview(buffer)[:want]) if want else 0
        self.left -= got
        return got


def _extension_records(data: bytes) -> dict[int, bytes]:
    """type -> payload of the owners' ``[u32 type][u32 byteLength][payload]`` records; a
    record cut short ends the list, as in the owners' reader."""
    records, pos = {}, 0
    while pos + 8 <= len(data):
        kind, length = struct.unpack_from("<II", data, pos)
        if length > len(data) - pos - 8:
            break
        records.setdefault(kind, data[pos + 8: pos + 8 + length])
        pos += 8 + length
    return records


def _coordinate_system(extensions: dict[int, bytes], shown: str) -> int:
    payload = extensions.get(_EXT_COORDINATE_SYSTEM)
    if payload is None or len(payload) < 4:
        return _RUB
    system = struct.unpack_from("<I", payload)[0]
    if system == 0:  # UNSPECIFIED: the owners fall back to RUB
        return _RUB
    if system > len(_SYSTEMS):
        raise file_error(shown, f"corrupt .spz: unknown coordinate system {system} in its extension")
    if system > 8:
        raise file_error(shown, f"this .spz stores its gaussians in the {_SYSTEMS[system - 1]} coordinate system, "
                                "which needs an SH rotation this viewer does not do (RUB and the other "
                                "axis-flipped systems are read)")
    return system


def axis_flips(source: int, target: int) -> np.ndarray:
    """(3,) +1/-1: which axes differ between two standard-family coordinate systems."""
    a, b = source - 1, target - 1
    return np.array([1.0 if (a >> bit) & 1 == (b >> bit) & 1 else -1.0 for bit in range(3)])


def flip_quaternion_xyz(flips: np.ndarray) -> np.ndarray:
    """The factors of a quaternion's x, y, z under the axis flips F (rotation F R F)."""
    fx, fy, fz = flips
    return np.array([fy * fz, fx * fz, fx * fy])


def flip_sh(flips: np.ndarray, k: int) -> np.ndarray:
    """(k,) factors of SH coefficients 1..k under the axis flips (odd functions flip)."""
    return np.prod(np.where(_SH_PARITY[:k] == 1, flips[None, :], 1.0), axis=1)


def _decode(data: np.ndarray, layout: _Layout, system: int, shown: str, report: Reporter, chunk: int) -> Scene:
    n = layout.n
    degree = min(layout.degree, 3)
    k = sh_coefficient_count(degree) - 1
    sections = np.split(data, np.cumsum(layout.sizes)[:-1])
    positions_b, alphas_b, colours_b, scales_b, rotations_b, sh_b = sections
    flips = axis_flips(system, _RDF)
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


# =============================================================================== writing


def spz_bytes(scene: Scene, version: int = 3) -> bytes:
    """The whole ``.spz`` file for a scene: version 2 or 3 (gzip) or 4 (zstd), quantised
    as the owners' ``packGaussians`` does with its default options, in RUB axes.

    Positions use the owners' 12 fractional bits when every coordinate fits the 24-bit
    word (|x| < 2048); otherwise the largest number of fractional bits that fits (the
    header records it, and readers honour it), down to 0 (|x| < 2^23): beyond that,
    and for non-finite positions, a UserError. SH is written as its bytes
    (buckets of 8 for band 1, of 16 for bands 2 and 3, the owners' defaults).
    """
    if version not in (2, 3, 4):
        raise UserError(f"cannot write .spz version {version} (versions 2, 3 and 4 are written)")
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
    flips = axis_flips(_RDF, _RUB)
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
    if version < 4:
        header = _LEGACY_HEADER.pack(SPZ_MAGIC, version, n, degree, fractional_bits, 0, 0)
        return gzip.compress(header + b"".join(arrays), compresslevel=6, mtime=0)
    streams = [zstandard.ZstdCompressor(level=12).compress(a) for a in arrays if a]
    header = _NGSP_HEADER.pack(SPZ_MAGIC, version, n, degree, fractional_bits, 0, len(streams), _NGSP_HEADER.size)
    toc = b"".join(struct.pack("<QQ", len(s), len(a)) for s, a in zip(streams, [a for a in arrays if a]))
    return header + toc + b"".join(streams)


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
