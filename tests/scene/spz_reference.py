"""A plain, per-gaussian ``.spz`` codec for the tests, written from the owners' format
description (nianticlabs/spz README "File Format" and load-spz.cc) and independent of
raygs_viewer.scene.spz_file: no axis conversion (values are in the file's RUB axes),
no numpy vectorisation, Python integers and ``struct`` throughout.

``pack(g, version)`` quantises a dict of float gaussians the way the owners' writer does
and returns the file's bytes; ``unpack(data)`` reads a file's bytes back into such a
dict (header fields included). Both are slow: use them on a few hundred gaussians.
"""

from __future__ import annotations

import gzip
import math
import struct

import zstandard

MAGIC = 0x5053474E
SQRT1_2 = math.sqrt(0.5)
COLOR_SCALE = 0.15
#: SH coefficients per colour channel, without the DC term, by degree.
SH_DIM = {0: 0, 1: 3, 2: 8, 3: 15, 4: 24}


def c_round(x: float) -> int:
    """C's round(): halves away from zero."""
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


def to_u8(x: float) -> int:
    return min(255, max(0, c_round(x)))


def pack_smallest_three(q) -> bytes:
    """x y z w (unit) -> 4 bytes: 2-bit index of the largest, then the other three in
    index order, each a sign (relative to the largest's) and 9 bits of |q_i| / sqrt(1/2)."""
    largest = max(range(4), key=lambda i: abs(q[i]))
    negate = q[largest] < 0
    word = largest
    for i in range(4):
        if i != largest:
            magnitude = min(511, int(511 * abs(q[i]) / SQRT1_2 + 0.5))
            word = (word << 10) | (int((q[i] < 0) != negate) << 9) | magnitude
    return struct.pack("<I", word)


def unpack_smallest_three(raw: bytes) -> list[float]:
    word = struct.unpack("<I", raw)[0]
    largest = word >> 30
    q = [0.0] * 4
    for i in (3, 2, 1, 0):
        if i != largest:
            bits = word & 0x3FF
            word >>= 10
            q[i] = (-1.0 if bits >> 9 else 1.0) * SQRT1_2 * (bits & 0x1FF) / 511
    q[largest] = math.sqrt(max(0.0, 1.0 - sum(c * c for c in q)))
    return q


def quantize_sh(x: float, bucket: int) -> int:
    q = c_round(x * 128) + 128
    q = int((q + bucket // 2) / bucket) * bucket  # C's integer division truncates
    return min(255, max(0, q))


def pack_arrays(g: dict, version: int, fractional_bits: int) -> list[bytes]:
    """positions, alphas, colours, scales, rotations, sh as the file holds them."""
    n, degree = len(g["positions"]), g["degree"]
    positions, alphas, colours, scales, rotations, sh = (bytearray() for _ in range(6))
    for i in range(n):
        for v in g["positions"][i]:
            if version == 1:
                positions += struct.pack("<e", v)
            else:
                positions += (c_round(v * (1 << fractional_bits)) & 0xFFFFFF).to_bytes(3, "little")
        alphas.append(to_u8(g["alphas"][i] * 255))
        colours.extend(to_u8(c * COLOR_SCALE * 255 + 127.5) for c in g["colors"][i])
        scales.extend(to_u8((s + 10) * 16) for s in g["log_scales"][i])
        q = list(g["rotations"][i])
        norm = math.sqrt(sum(c * c for c in q))
        q = [c / norm for c in q]
        if version >= 3:
            rotations += pack_smallest_three(q)
        else:
            sign = -127.5 if q[3] < 0 else 127.5
            rotations.extend(to_u8(c * sign + 127.5) for c in q[:3])
        for k in range(SH_DIM[degree]):
            for channel in range(3):
                sh.append(quantize_sh(g["sh"][i][k][channel], 8 if k < 3 else 16))
    return [bytes(a) for a in (positions, alphas, colours, scales, rotations, sh)]


def pack(g: dict, version: int = 3, fractional_bits: int = 12, flags: int = 0, extensions: bytes = b"") -> bytes:
    """The file's bytes. ``g``: positions (n,3), log_scales (n,3), rotations (n,4) x y z w,
    alphas (n,) in [0, 1], colors (n,3) SH DC, sh (n, dim, 3), degree; all in RUB axes.
    ``extensions``: raw extension records (the flag 2 is the caller's to set)."""
    arrays = pack_arrays(g, version, fractional_bits)
    n, degree = len(g["positions"]), g["degree"]
    if version < 4:
        header = struct.pack("<IIIBBBB", MAGIC, version, n, degree, fractional_bits, flags, 0)
        return gzip.compress(header + b"".join(arrays) + extensions)
    arrays = [a for a in arrays if a]
    streams = [zstandard.ZstdCompressor(level=3).compress(a) for a in arrays]
    header = struct.pack("<IIIBBBBI", MAGIC, version, n, degree, fractional_bits, flags, len(streams),
                         32 + len(extensions)) + bytes(12)
    toc = b"".join(struct.pack("<QQ", len(s), len(a)) for s, a in zip(streams, arrays))
    return header + extensions + toc + b"".join(streams)


def payload(data: bytes) -> tuple[dict, list[bytes]]:
    """(header fields, the six arrays' bytes) of a file, by the spec."""
    if data[:2] == b"\x1f\x8b":
        raw = gzip.decompress(data)
        magic, version, n, degree, bits, flags, _ = struct.unpack_from("<IIIBBBB", raw)
        offset, arrays = 16, []
        widths = [6 if version == 1 else 9, 1, 3, 3, 4 if version >= 3 else 3, 3 * SH_DIM[degree]]
        for width in widths:
            arrays.append(raw[offset: offset + n * width])
            offset += n * width
    else:
        magic, version, n, degree, bits, flags, count, toc = struct.unpack_from("<IIIBBBBI", data)
        offset = toc + 16 * count
        arrays = []
        for i in range(count):
            packed, _ = struct.unpack_from("<QQ", data, toc + 16 * i)
            arrays.append(zstandard.ZstdDecompressor().decompress(data[offset: offset + packed]))
            offset += packed
        if not degree:
            arrays.append(b"")
    assert magic == MAGIC
    return {"version": version, "n": n, "degree": degree, "fractional_bits": bits, "flags": flags}, arrays


def unpack(data: bytes) -> dict:
    """The gaussians of a file, in its own (RUB) axes: the inverse of :func:`pack` up to
    quantisation, with ``alphas`` as the stored a/255 and ``scales`` linear."""
    head, (positions, alphas, colours, scales, rotations, sh) = payload(data)
    n, degree, version = head["n"], head["degree"], head["version"]
    out = dict(head, positions=[], scales=[], rotations=[], alphas=[], colors=[], sh=[])
    dim = SH_DIM[degree]
    for i in range(n):
        if version == 1:
            out["positions"].append(list(struct.unpack_from("<3e", positions, 6 * i)))
        else:
            p = []
            for axis in range(3):
                v = int.from_bytes(positions[9 * i + 3 * axis: 9 * i + 3 * axis + 3], "little")
                p.append((v - (1 << 24) if v & 0x800000 else v) / (1 << head["fractional_bits"]))
            out["positions"].append(p)
        out["alphas"].append(alphas[i] / 255)
        out["colors"].append([(c / 255 - 0.5) / COLOR_SCALE for c in colours[3 * i: 3 * i + 3]])
        out["scales"].append([math.exp(s / 16 - 10) for s in scales[3 * i: 3 * i + 3]])
        if version >= 3:
            out["rotations"].append(unpack_smallest_three(rotations[4 * i: 4 * i + 4]))
        else:
            xyz = [r / 127.5 - 1 for r in rotations[3 * i: 3 * i + 3]]
            out["rotations"].append(xyz + [math.sqrt(max(0.0, 1 - sum(c * c for c in xyz)))])
        row = sh[3 * dim * i: 3 * dim * (i + 1)]
        out["sh"].append([[(row[3 * k + c] - 128) / 128 for c in range(3)] for k in range(dim)])
    return out
