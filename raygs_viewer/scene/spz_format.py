"""Niantic's ``.spz`` format: its layout, the header fields every part reads, and the
axis conversion. Reading versions 1 to 4 and writing versions 2, 3 and 4 is split by
job: :mod:`~raygs_viewer.scene.spz_stream` (the header and the compressed streams) and
:mod:`~raygs_viewer.scene.spz_file` (the gaussians' bytes, decoded and encoded).

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

Two conventions for files without that extension (:data:`SPZ_AXES`: a SceneSource's
``spz_axes`` when reading, :class:`SpzEncoding`'s ``axes`` when writing): "rub", the
specification's, which Niantic's library and Scaniverse write; and "rdf", the INRIA
PLY's own axes, which PlayCanvas's splat-transform (and so SuperSplat) writes and
reads with no mark in the file (``src/lib/spz-module.ts``:
``from: CoordinateSystem.UNSPECIFIED`` on data kept in PLY axes;
``readers/read-spz.ts`` decodes without conversion). Nothing in such a file tells the two apart, so the reader
is told; a declaration in the file wins over it. The writer writes no extension for
either, like splat-transform, so what it writes in "rdf" reads in splat-transform as
that tool's own files do.

Decisions:

- Version 1 (float16 positions, never released by the owners) is read; versions
  above 4 are refused naming the version. An "NGSP" file that is not gzip must be
  version 4 or later, as in the owners' loader.
- SH degree 4 (allowed by the owners since version 4) is read and truncated to
  degree 3, the project's maximum (bands are orthogonal: the degree-3 part is exact).
- The antialiased flag (trained with Mip-Splatting's 2D filter) is read but the
  Scene has no field for it; the writer writes 0.
- An empty scene (numPoints 0) is valid, as for PLY (the owners' loader refuses it).
- Hostile files (:mod:`~raygs_viewer.scene.spz_stream`): numPoints is bounded before
  anything is allocated, by an absolute cap (``MAX_POINTS``) and by what the compressed
  bytes can possibly expand to (deflate's ratio limit 1032:1; for zstd the owners' bound
  of 1024 x the file size over 9 bytes per point). The data is then stream-decompressed
  into a buffer of exactly the size the header implies: a stream that ends early or runs
  longer is an error. Extension records are bounded by ``MAX_EXTENSION_BYTES``. Bytes
  after the end of the gzip stream are ignored, as the owners' loader does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import FileAxes, sh_coefficient_count

SPZ_MAGIC = 0x5053474E
LATEST_VERSION = 4
#: The owners' coordinate systems: 1..8 the standard family, bits of (value - 1) say
#: x right (bit 0), y up (bit 1), z front (bit 2); 9..16 the rotated family.
COORDINATE_SYSTEMS = ("LDB", "RDB", "LUB", "RUB", "LDF", "RDF", "LUF", "RUF",
                      "LFD", "RFD", "LFU", "RFU", "LBD", "RBD", "LBU", "RBU")
RUB, RDF = 4, 6
#: The conventions for a .spz that declares no coordinate system (see the module's
#: "Axes"), the first the default: the specification's.
SPZ_AXES = ("rub", "rdf")
DEFAULT_SPZ_AXES = SPZ_AXES[0]
#: Which of x, y, z each SH basis function k = 1..15 (INRIA's order, ``scene/sh.py``)
#: is odd in: flipping an axis negates the coefficient once per odd axis.
_SH_PARITY = np.array([
    (0, 1, 0), (0, 0, 1), (1, 0, 0),                                    # -y, z, -x
    (1, 1, 0), (0, 1, 1), (0, 0, 0), (1, 0, 1), (0, 0, 0),              # xy, yz, 3z^2-1, xz, x^2-y^2
    (0, 1, 0), (1, 1, 1), (0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 0, 1), (1, 0, 0),
])


@dataclass(frozen=True)
class Layout:
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


def spz_axes_system(spz_axes: str) -> int:
    """The coordinate system (an index into COORDINATE_SYSTEMS, from 1) of a convention
    of :data:`SPZ_AXES`; a UserError for any other value."""
    if spz_axes not in SPZ_AXES:
        raise UserError(f"unknown .spz axes convention {spz_axes!r} (expected {' or '.join(SPZ_AXES)})")
    return COORDINATE_SYSTEMS.index(spz_axes.upper()) + 1


@dataclass(frozen=True)
class SpzEncoding:
    """How a ``.spz`` is written: the format ``version`` (the writer refuses one it does
    not write, naming the file) and the ``axes`` its gaussians are stored in, a
    convention of :data:`SPZ_AXES` that the file does not mark. An unknown ``axes`` is a
    UserError when the value is made, before anything is written."""

    version: int = 3
    axes: str = DEFAULT_SPZ_AXES

    def __post_init__(self) -> None:
        spz_axes_system(self.axes)


def axes_description(axes: FileAxes) -> dict:
    """``info``'s "axes" of a .spz: {stored: "RUB", "RDF", ...; declared: whether the file
    said so, else it was assumed; spz_axes: the convention it was read with}."""
    return {"stored": axes.stored, "declared": bool(axes.declared), "spz_axes": axes.assumed}


def axes_words(axes: dict) -> str:
    """How a .spz's axes were taken, in words, from :func:`axes_description`."""
    if axes["declared"]:
        return f"{axes['stored']} declared by the file (--spz-axes does not apply)"
    if axes["spz_axes"] == "rdf":
        return "RDF assumed (--spz-axes rdf: splat-transform's, the PLY's own axes)"
    return "RUB assumed (the .spz specification's; --spz-axes rdf for files splat-transform wrote)"


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
