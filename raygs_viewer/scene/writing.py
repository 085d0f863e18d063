"""Writing a :class:`Scene` to disk: INRIA PLY, the 32-byte ``.splat`` rows, ``.spz`` and SOG.

- INRIA PLY (section 2 of the maths page): binary little endian, one ``vertex`` element
  of float32 properties in the trainer's order ``x y z nx ny nz f_dc_0..2 f_rest_*
  opacity scale_0..2 rot_0..3``; normals are zeros (as the INRIA trainer writes them),
  ``f_rest_*`` channel-major, opacity as its logit, scales as their logarithms, the
  quaternion as stored (w first). Lossless to float32 rounding of log/exp and
  logit/sigmoid: see :func:`ply_rows` for the bounds, and :func:`writing_notes` for the
  two values a PLY cannot hold exactly (opacity 0 or 1, scale 0).
- ``.splat`` (antimatter15's WebGL viewer format, the layout
  :mod:`~raygs_viewer.scene.splat_file` reads): position and *linear* scale as float32,
  RGBA bytes (the DC colour ``0.5 + C0 * f_dc`` clipped to 0..1 and opacity, times 255,
  rounded), the quaternion as four bytes ``q * 128 + 128`` rounded and clipped. SH
  beyond the DC term is lost.
- ``.spz``: :func:`raygs_viewer.scene.spz_file.spz_bytes` (Niantic's format, version 3
  or 4), in the axes of its :class:`~raygs_viewer.scene.spz_format.SpzEncoding`: "rub"
  (the specification's) or "rdf" (the PLY's own, as splat-transform writes them).
- ``.sog``: :func:`raygs_viewer.scene.sog_write.sog_bytes` (PlayCanvas's SOG version 2,
  bundled), in the PLY's own axes, as SOG stores them; gaussians keep their order.

:func:`write_scene` picks the format by suffix and writes atomically through
:mod:`raygs_viewer.files`: a temporary beside the target moved into place, never over
an existing file without ``overwrite``. PLY and ``.splat`` rows are produced a chunk
at a time, so writing a multi-GB scene holds one chunk, not a second copy of the file.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.files import atomic_writer, check_writable_folder
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sh import C0
from raygs_viewer.scene.sog_write import FLAT_MARGIN, palette_size, sog_bytes
from raygs_viewer.scene.spz_file import DC_LIMIT, LOG_SCALE_RANGE, spz_bytes
from raygs_viewer.scene.spz_format import SpzEncoding

#: The suffixes :func:`write_scene` writes.
WRITE_SUFFIXES = (".ply", ".splat", ".spz", ".sog")
SPZ_VERSIONS = (3, 4)

#: The logit written for opacity exactly 1 (and, negated, 0), whose logit is infinite.
#: Readers that take +/-inf (this one does) are the exception, so it is finite; at 110
#: the sigmoid is 1 (or 0) in float32 and float64 alike, so it still reads back exactly,
#: and exp(110) overflowing float32 in a float32 sigmoid still gives 0, never NaN.
OPACITY_LOGIT_LIMIT = 110.0
#: Scale 0 has no logarithm (and a reader drops it): written as the smallest positive
#: float32 (a subnormal) instead. Loading never produces it; a scene made in memory can.
SMALLEST_SCALE = float(np.nextafter(np.float32(0), np.float32(1)))

#: Rows produced and written at a time: about 16 MiB of SH-3 PLY rows.
WRITE_CHUNK_ROWS = 1 << 16

# The rows splat_file reads (32 bytes).
_SPLAT_DTYPE = np.dtype([("position", "<f4", (3,)), ("scale", "<f4", (3,)),
                         ("rgba", "u1", (4,)), ("rotation", "u1", (4,))])


def ply_property_names(sh_degree: int) -> list[str]:
    """The vertex properties of an INRIA PLY of that SH degree, in the trainer's order."""
    rest = 3 * (sh_coefficient_count(sh_degree) - 1)
    return (["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
            + [f"f_rest_{i}" for i in range(rest)]
            + ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"])


def ply_header(count: int, sh_degree: int, comment: str = "written by raygs-viewer") -> bytes:
    """The header of a binary little-endian INRIA PLY of ``count`` gaussians."""
    lines = ["ply", "format binary_little_endian 1.0", f"comment {comment}", f"element vertex {count}",
             *(f"property float {name}" for name in ply_property_names(sh_degree)), "end_header"]
    return ("\n".join(lines) + "\n").encode("ascii")


def ply_rows(scene: Scene, start: int = 0, stop: int | None = None) -> np.ndarray:
    """(rows, properties) float32 PLY rows of gaussians ``start..stop``, in the order of
    :func:`ply_property_names`.

    The logit and logarithm are taken in float64 and rounded once to float32, so a read
    back gives ``exp`` of a log-scale ``l`` within a relative ``(|l| + 1) * 2**-24`` of
    the scale (the float32 rounding of ``l``, then of the result), and an opacity ``o``
    with logit ``x`` within ``o(1-o)|x| * 2**-24 + o * 2**-24``; positions, SH and
    rotations are copied exactly.
    """
    stop = scene.count if stop is None else min(stop, scene.count)
    n = max(0, stop - start)
    k = sh_coefficient_count(scene.sh_degree) - 1
    rows = np.empty((n, 17 + 3 * k), np.float32)
    rows[:, 0:3] = scene.positions[start:stop]
    rows[:, 3:6] = 0.0
    sh = scene.sh[start:stop]
    rows[:, 6:9] = sh[:, 0, :]
    # f_rest_* is channel-major: f_rest[c * k + j] is coefficient j + 1 of channel c.
    rows[:, 9:9 + 3 * k] = sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * k)
    rows[:, 9 + 3 * k] = opacity_logits(scene.opacities[start:stop])
    rows[:, 10 + 3 * k:13 + 3 * k] = log_scales(scene.scales[start:stop])
    rows[:, 13 + 3 * k:17 + 3 * k] = scene.rotations[start:stop]
    return rows


def opacity_logits(opacities: np.ndarray) -> np.ndarray:
    """float64 logits of opacities in [0, 1]; 0 and 1 give -/+ :data:`OPACITY_LOGIT_LIMIT`."""
    o = opacities.astype(np.float64)
    if np.any(~((o >= 0.0) & (o <= 1.0))):
        raise ValueError("Scene.opacities must lie in [0, 1] to be written")
    with np.errstate(divide="ignore"):
        logits = np.log(o) - np.log1p(-o)
    return np.clip(logits, -OPACITY_LOGIT_LIMIT, OPACITY_LOGIT_LIMIT)


def log_scales(scales: np.ndarray) -> np.ndarray:
    """float64 logarithms of positive scales; 0 is written as :data:`SMALLEST_SCALE`."""
    return np.log(_positive_scales(scales).astype(np.float64))


def _positive_scales(scales: np.ndarray) -> np.ndarray:
    if np.any(~(scales >= 0.0)) or np.any(np.isinf(scales)):
        raise ValueError("Scene.scales must be finite and positive to be written")
    return np.maximum(scales, np.float32(SMALLEST_SCALE))


def ply_chunks(scene: Scene, chunk_rows: int = WRITE_CHUNK_ROWS) -> Iterator[bytes]:
    """The bytes of the scene's INRIA PLY: the header, then rows ``chunk_rows`` at a time."""
    yield ply_header(scene.count, scene.sh_degree)
    for start in range(0, scene.count, max(1, chunk_rows)):
        yield ply_rows(scene, start, start + chunk_rows).astype("<f4", copy=False).tobytes()


def ply_bytes(scene: Scene) -> bytes:
    """The whole INRIA PLY file of ``scene``."""
    return b"".join(ply_chunks(scene))


def splat_rows(scene: Scene, start: int = 0, stop: int | None = None) -> np.ndarray:
    """The 32-byte ``.splat`` rows of gaussians ``start..stop`` (a structured array).

    Read back, positions and scales are exact, the DC colour (as RGB ``0.5 + C0 *
    f_dc``) and opacity are within 0.5/255 where the colour lies in 0..1 (clipped
    outside it), and the rotation is within about 1.2 degrees (each component rounded
    to 1/128, +1 clipped to 127/128, then normalised); SH beyond degree 0 is dropped.
    """
    stop = scene.count if stop is None else min(stop, scene.count)
    n = max(0, stop - start)
    rows = np.empty(n, _SPLAT_DTYPE)
    rows["position"] = scene.positions[start:stop]
    rows["scale"] = _positive_scales(scene.scales[start:stop])
    rgb = 0.5 + C0 * scene.sh[start:stop, 0, :].astype(np.float64)
    rows["rgba"][:, :3] = _bytes(rgb * 255.0)
    rows["rgba"][:, 3] = _bytes(scene.opacities[start:stop].astype(np.float64) * 255.0)
    rows["rotation"] = _bytes(scene.rotations[start:stop].astype(np.float64) * 128.0 + 128.0)
    return rows


def _bytes(values: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(values), 0, 255).astype(np.uint8)


def splat_chunks(scene: Scene, chunk_rows: int = WRITE_CHUNK_ROWS) -> Iterator[bytes]:
    """The bytes of the scene's ``.splat`` file, ``chunk_rows`` rows at a time."""
    for start in range(0, scene.count, max(1, chunk_rows)):
        yield splat_rows(scene, start, start + chunk_rows).tobytes()


def splat_bytes(scene: Scene) -> bytes:
    """The whole ``.splat`` file of ``scene``."""
    return b"".join(splat_chunks(scene))


def write_ply(scene: Scene, path: str | os.PathLike, overwrite: bool = False) -> Path:
    """Writes ``scene`` as an INRIA PLY at ``path`` (atomically, never clobbering)."""
    return _write(path, ply_chunks(scene), overwrite)


def write_splat(scene: Scene, path: str | os.PathLike, overwrite: bool = False) -> Path:
    """Writes ``scene`` as a ``.splat`` file at ``path`` (atomically, never clobbering)."""
    return _write(path, splat_chunks(scene), overwrite)


def write_scene(scene: Scene, path: str | os.PathLike, overwrite: bool = False,
                spz: SpzEncoding = SpzEncoding()) -> Path:
    """Writes ``scene`` in the format its suffix names (:data:`WRITE_SUFFIXES`), through
    a temporary beside ``path`` moved into place; an existing ``path`` is replaced only
    with ``overwrite``. A ``.spz`` is written as ``spz`` says (its version and axes).
    One-line UserError for an unknown suffix, a .spz version not written, an existing
    file, a missing folder or a failed write."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITE_SUFFIXES:
        raise UserError(f"{path}: cannot write this format: the output must end in {', '.join(WRITE_SUFFIXES)}")
    if suffix == ".ply":
        return write_ply(scene, path, overwrite)
    if suffix == ".splat":
        return write_splat(scene, path, overwrite)
    if suffix == ".sog":
        # Lazily, so that an existing file is refused before the (slow) quantisation.
        return _write(path, (sog_bytes(scene) for _ in range(1)), overwrite)
    if spz.version not in SPZ_VERSIONS:
        raise UserError(f"{path}: .spz version {spz.version} is not written (versions {SPZ_VERSIONS[0]} "
                        f"and {SPZ_VERSIONS[1]} are)")
    return _write(path, [spz_bytes(scene, spz.version, spz.axes)], overwrite)


def _write(path: str | os.PathLike, chunks, overwrite: bool) -> Path:
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{path}: is a folder")
    check_writable_folder(path, path.parent)
    if path.exists() and not overwrite:  # before any work; atomic_writer checks again at the end
        raise UserError(f"{path}: already exists (pass --overwrite to replace it)")
    with atomic_writer(path, overwrite) as stream:
        for chunk in chunks:
            stream.write(chunk)
    return path


def writing_notes(scene: Scene, suffix: str) -> list[str]:
    """What a file of type ``suffix`` changes of ``scene`` beyond rounding, or cannot hold:
    one line each (empty when it holds everything)."""
    suffix = suffix.lower()
    notes = []
    if scene.filter_fused:
        notes.append("the 3D filter was fused into scale and opacity when the scene was read; "
                     "it is written fused (no filter_3D)")
    if suffix == ".splat" and scene.sh_degree > 0:
        notes.append(f"SH degree {scene.sh_degree} -> 0: .splat holds only the base colour "
                     f"(view-dependent colour is lost)")
    if suffix == ".splat":
        # Only a colour whose byte would fall outside 0..255 is changed by the clipping
        # (a decoded byte b/255 is often 1e-8 outside 0..1 after float32 rounding).
        levels = np.rint((0.5 + C0 * scene.sh[:, 0, :].astype(np.float64)) * 255.0)
        outside = int(np.count_nonzero(((levels < 0) | (levels > 255)).any(axis=1)))
        if outside:
            notes.append(f"{outside:,} gaussians have a base colour outside 0..1, clipped in .splat's RGB bytes")
    if suffix == ".ply":
        ones = int(np.count_nonzero(scene.opacities == 1.0))
        zeros = int(np.count_nonzero(scene.opacities == 0.0))
        if ones or zeros:
            notes.append(f"opacity exactly 1 ({ones:,} gaussians) or 0 ({zeros:,}) has an infinite logit: "
                         f"written as +/-{OPACITY_LOGIT_LIMIT:g}, which reads back as 1 or 0")
    if suffix == ".spz":
        with np.errstate(divide="ignore"):
            log_scales = np.log(scene.scales.astype(np.float64))
        low, high = LOG_SCALE_RANGE
        clamped = int(np.count_nonzero((log_scales < low) | (log_scales > high)))
        if clamped:
            notes.append(f"{clamped:,} scale axes lie outside .spz's range e^{low:g}..e^{high:g} "
                         f"({np.exp(low):.3g}..{np.exp(high):.3g}) and are clamped to it")
        bright = int(np.count_nonzero((np.abs(scene.sh[:, 0, :]) > DC_LIMIT).any(axis=1)))
        if bright:
            notes.append(f"{bright:,} gaussian{'s have' if bright != 1 else ' has'} a base colour coefficient "
                         f"beyond .spz's +/-{DC_LIMIT:.3g}, clamped to it")
    if suffix == ".sog":
        palette = (f", SH to a k-means palette of at most {palette_size(scene.count):,} rows of 8-bit codes"
                   if scene.sh_degree else "")
        notes.append("SOG quantises positions to 16 bits an axis in log space, scales and base colours to "
                     f"256-entry codebooks, opacity to 8 bits, rotations to 8-bit smallest-three{palette}")
    zero = int(np.count_nonzero((scene.scales == 0.0).any(axis=1)))
    if zero and suffix in (".ply", ".splat"):
        notes.append(f"{zero:,} gaussians have a scale of 0, written as the smallest positive float32 "
                     f"({SMALLEST_SCALE:.3g}): a reader drops a zero scale")
    if zero and suffix == ".sog":
        notes.append(f"{zero:,} gaussians have a scale of 0, written as a flat codebook entry e^-{FLAT_MARGIN:g} "
                     "times the smallest other scale: a reader drops a zero scale")
    return notes
