"""PlayCanvas's SOG ("Spatially Ordered Gaussians"), version 2: lossless WebP images and
a ``meta.json``, bundled in a zip (``.sog``) or side by side in a folder (the path is
then the ``meta.json``, or the folder holding it).

Sources read (the decoding below mirrors them; no code was copied):

- The specification: https://developer.playcanvas.com/user-manual/gaussian-splatting/formats/sog
  (file set, row-major pixel indexing, ``count <= W*H`` with trailing pixels ignored,
  ``meta.json`` at the root of a bundle), and its proposal, playcanvas/splat-transform
  issue #38.
- playcanvas/splat-transform 3.2.0 (commit 8d6b801f): ``src/lib/writers/write-sog.ts``,
  ``src/lib/readers/read-sog.ts`` and ``read-sog-v1.ts``, ``src/lib/spatial/quantize-1d-core.ts``
  (the 256-entry codebooks), ``src/lib/utils/math.ts`` (``Transform.PLY``).
- playcanvas/engine: ``src/framework/parsers/sog-bundle.js`` (the zip) and
  ``src/scene/gsplat/gsplat-sog-data.js`` (the CPU decode and the codebook patch).

Layout (N = ``meta.count``; pixel i of every per-gaussian image is gaussian i, row-major
from the top left; each image has W*H >= N pixels, the rest ignored):

- ``means_l`` / ``means_u``: RGB = the low / high byte of a 16-bit value per axis x, y, z;
  ``l' = mins + (maxs - mins) * v / 65535`` in the log space ``l = sign(x) ln(|x| + 1)``
  (``maxs == mins`` counts as a span of 1, as splat-transform reads it), then
  ``x = sign(l') (exp(|l'|) - 1)``.
- ``scales``: RGB = indices into ``scales.codebook`` (256 log-scales); scale = exp(entry).
- ``quats``: smallest three. A = 252 + m, m the index (in w, x, y, z order) of the
  largest-magnitude component, made positive and dropped; RGB = the other three in
  increasing index order, each ``c = (byte / 255 - 0.5) * sqrt(2)`` (they lie within
  +-1/sqrt(2)); ``q[m] = sqrt(max(0, 1 - a^2 - b^2 - c^2))``. An A outside 252..255
  decodes as the identity (splat-transform's reader does so).
- ``sh0``: RGB = indices into ``sh0.codebook`` (256 f_dc values); A = the *activated*
  opacity, ``round-down(255 sigmoid(logit))``: opacity = A / 255 as the engine draws it
  (splat-transform's reader clamps it to [1e-6, 1 - 1e-6] on its way to a logit).
- ``shN`` (optional, ``bands`` 1..3): ``shN_labels`` RG = a 16-bit palette index
  (R the low byte); ``shN_centroids`` is 64 * (bands+1)^2-1 pixels wide, 64 palette
  entries a row, entry e at row e // 64, columns (e % 64) * K + j for its K coefficients
  j, RGB = codebook indices of channels R, G, B (``shN.codebook``, 256 values). A label
  >= ``shN.count`` has zero SH; an entry past the image's rows reads as codebook[0]
  (both as splat-transform reads them).
- A codebook whose first entry is JSON ``null`` (old writers' -Infinity) gets
  ``cb[1] + (cb[1] - cb[255]) / 255`` as the engine patches it; any other ``null`` is
  NaN and drops the gaussians using it.

Axes: the values are the INRIA PLY's own, unchanged: splat-transform writes a PLY to SOG
and reads it back with no axis change (both sit in its ``Transform.PLY`` space; the
engine's 180-degree turn about z is applied at display, whence the specification's
"x right, y up, z back"). So nothing is converted here.

WebP images are decoded with Pillow (already a dependency; its wheels bundle libwebp):
lossless WebP comes back exactly, RGB under a zero alpha included. Each image's size is
read from its header here first, and must fit the count (``N <= W*H <= 2N + 65536``),
before Pillow allocates anything.

Bad input is one :class:`UserError` line naming the file (and the member). Hostile
archives: every member used is read by its central-directory entry with a cap on its
declared size, decompressed with a bound one byte past that size (a member that inflates
to more, or less, than it declares is refused), and checked against its CRC. An
unbundled ``meta.json`` may only name images inside its own folder.
"""

from __future__ import annotations

import io
import json
import math
import os
import struct
import warnings
import zipfile
import zlib

import numpy as np

from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DropTally, build_scene, file_error, scene_arrays, shown_token

SOG_FORMAT = "SOG v2"
META_NAME = "meta.json"

#: The most gaussians a SOG may declare: 32 Mi, far past what a single SOG holds in
#: practice (PlayCanvas advises streamed SOG beyond 1-2 M). It bounds every image at
#: 2^26 + 65536 pixels (under Pillow's own bomb limit), whatever a header claims.
MAX_COUNT = 1 << 25
#: meta.json holds three 256-entry codebooks and file names: about 10 KB.
MAX_META_BYTES = 4 << 20
#: Pixels an image may hold past the count: splat-transform pads to multiples of 4.
_SLACK_PIXELS = 65536
#: A lossless WebP spends at most 4 Huffman codes of 15 bits a pixel.
_MAX_FILE_BYTES_PER_PIXEL = 8
_FILE_OVERHEAD = 1 << 20
#: shN palette: 16-bit labels, 64 entries a row of the centroids image.
_MAX_PALETTE = 1 << 16
_PALETTE_ROW = 64
_CODEBOOK_SIZE = 256
_ZIP_MAGIC = b"PK\x03\x04"
_ROW_WORK_BYTES = 64  # roughly what one gaussian costs to decode, for chunking and progress

# The three stored quaternion components for each dropped one (w, x, y, z = 0..3).
_OTHERS = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])
# Every byte's quaternion component: (byte / 255 - 0.5) * sqrt(2).
_QUAT_COMPONENT = (np.arange(256) / 255.0 - 0.5) * math.sqrt(2.0)


def load_sog(path, shown: str, report: Reporter, chunk_bytes: int) -> Scene:
    """``path``: a bundled .sog file, an unbundled scene's meta.json, or its folder."""
    if os.path.isdir(path):
        path = os.path.join(path, META_NAME)
        if not os.path.isfile(path):
            raise file_error(shown, f"folder has no {META_NAME} (an unbundled SOG scene keeps one beside its images)")
    with open(path, "rb") as f:
        head = f.read(4)
    source = _Bundle(path, shown) if head == _ZIP_MAGIC else _Folder(path, shown)
    with source:
        meta = _parse_meta(source.shown_meta, source.read_meta())
        return _load(source, meta, shown, report, max(1, chunk_bytes))


def scene_files(path) -> list[str]:
    """The files a SOG scene's content is: a bundled .sog is itself; an unbundled scene is
    its meta.json (``path``, or the folder holding it) and the images that names, in the
    order it names them (what the scene's SHA-256 covers, so that an image edited beside
    an unchanged meta.json is a changed scene). UserError as :func:`load_sog`'s."""
    shown = os.fspath(path)
    if os.path.isdir(path):
        path = os.path.join(path, META_NAME)
    with open(path, "rb") as f:
        if f.read(4) == _ZIP_MAGIC:
            return [os.fspath(path)]
    folder = _Folder(path, shown)
    meta = _parse_meta(shown, folder.read_meta())
    names = [*meta.means_files, meta.scales_file, meta.quats_file, meta.sh0_file, *meta.shn_files]
    return [os.fspath(path), *(folder.resolve(name) for name in names)]


# --- where the bytes come from ---------------------------------------------------------


class _Bundle:
    """A zip archive, its members found by the central directory; see :meth:`read`."""

    def __init__(self, path, shown: str) -> None:
        self.shown = shown
        self.shown_meta = f"{shown}: {META_NAME}"
        self.file = open(path, "rb")
        try:
            self.size = os.fstat(self.file.fileno()).st_size
            # zipfile only parses the central directory here; members are read below.
            with zipfile.ZipFile(self.file) as archive:
                infos = archive.infolist()
        except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, ValueError, EOFError,
                struct.error, IndexError, KeyError, OverflowError) as exc:
            self.file.close()
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise file_error(shown, f"not a readable SOG bundle (zip: {shown_token(detail, 80)[1:-1]})") from None
        except BaseException:
            self.file.close()
            raise
        self.members: dict[str, zipfile.ZipInfo] = {}
        for info in infos:
            self.members.setdefault(info.filename, info)  # the first of a name, as the engine finds it

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.file.close()

    def read_meta(self) -> bytes:
        if META_NAME not in self.members:
            raise file_error(self.shown, f"no {META_NAME} at the root of the archive: not a SOG bundle")
        return self.read(META_NAME, MAX_META_BYTES, 1 << 20, lambda n: None)

    def stored_size(self, name: str) -> int:
        info = self.members.get(name)
        if info is None:
            raise file_error(self.shown, f"{name}: missing from the archive (meta.json names it)")
        return info.compress_size

    def read(self, name: str, cap: int, chunk_bytes: int, progress) -> bytes:
        """Member ``name``'s bytes. Refused: a declared size over ``cap``; a member that
        inflates past its declared size (stopped one byte past it) or short of it; a CRC
        mismatch; encryption; methods other than stored and deflate."""
        shown = f"{self.shown}: {name}"
        info = self.members.get(name)
        if info is None:
            raise file_error(self.shown, f"{name}: missing from the archive (meta.json names it)")
        if info.flag_bits & 0x1:
            raise file_error(shown, "encrypted zip member")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise file_error(shown, f"zip compression method {info.compress_type} (expected stored or deflate)")
        declared = info.file_size
        if declared > cap:
            raise file_error(shown, f"declares {declared} bytes uncompressed, more than this scene can need "
                                    f"({cap}): refused")
        if info.compress_type == zipfile.ZIP_STORED and info.compress_size != declared:
            raise file_error(shown, f"stored zip member of {info.compress_size} bytes declares {declared}")
        if info.header_offset < 0:  # zipfile shifts offsets by what precedes the archive
            raise file_error(shown, "zip member starts before the file (corrupt archive)")
        self.file.seek(info.header_offset)
        local = self.file.read(30)
        if len(local) < 30 or local[:4] != _ZIP_MAGIC:
            raise file_error(shown, "bad zip local header (corrupt archive)")
        name_length, extra_length = struct.unpack("<HH", local[26:30])
        start = info.header_offset + 30 + name_length + extra_length
        if start + info.compress_size > self.size:
            raise file_error(shown, "zip member extends past the end of the file (truncated archive)")
        self.file.seek(start)
        out = bytearray()
        inflate = zlib.decompressobj(-zlib.MAX_WBITS) if info.compress_type == zipfile.ZIP_DEFLATED else None
        left = info.compress_size
        try:
            while left:
                chunk = self.file.read(min(left, chunk_bytes))
                if not chunk:
                    raise file_error(shown, "truncated zip member (the file shrank while reading)")
                left -= len(chunk)
                if inflate is None:
                    out += chunk
                else:
                    while chunk and not inflate.eof:
                        out += inflate.decompress(chunk, declared + 1 - len(out))
                        if len(out) > declared:
                            raise file_error(shown, f"inflates to more than its declared {declared} bytes: refused")
                        chunk = inflate.unconsumed_tail
                progress(info.compress_size - left)
        except zlib.error as exc:
            raise file_error(shown, f"corrupt deflate data ({exc})") from None
        if inflate is not None and not inflate.eof:
            raise file_error(shown, "truncated deflate data (corrupt archive)")
        if len(out) != declared:
            raise file_error(shown, f"holds {len(out)} bytes but declares {declared} (corrupt archive)")
        if zlib.crc32(out) != info.CRC:
            raise file_error(shown, "CRC mismatch (corrupt archive)")
        return bytes(out)


class _Folder:
    """An unbundled scene: meta.json and the images it names, all inside its folder."""

    def __init__(self, meta_path, shown: str) -> None:
        self.shown = shown
        self.shown_meta = shown
        self.meta_path = meta_path
        self.folder = os.path.dirname(os.path.abspath(meta_path))
        self.real_folder = os.path.realpath(self.folder)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        pass

    def read_meta(self) -> bytes:
        size = os.path.getsize(self.meta_path)
        if size > MAX_META_BYTES:
            raise file_error(self.shown, f"{size} bytes: too big for a SOG meta.json (at most {MAX_META_BYTES})")
        with open(self.meta_path, "rb") as f:
            return f.read(MAX_META_BYTES + 1)

    def resolve(self, name: str) -> str:
        parts = name.replace("\\", "/").split("/")
        outside = os.path.isabs(name) or ".." in parts or "\x00" in name
        if not outside:
            target = os.path.realpath(os.path.join(self.folder, name))
            outside = os.path.commonpath([target, self.real_folder]) != self.real_folder
        if outside:
            raise file_error(self.shown, f"image {shown_token(name)} lies outside the scene's folder: refused")
        return target

    def stored_size(self, name: str) -> int:
        target = self.resolve(name)
        try:
            return os.path.getsize(target)
        except OSError:
            raise file_error(self.shown, f"{name}: no such file beside {os.path.basename(self.meta_path)} "
                                         "(meta.json names it)") from None

    def read(self, name: str, cap: int, chunk_bytes: int, progress) -> bytes:
        shown = f"{self.shown}: {name}"
        target = self.resolve(name)
        try:
            with open(target, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                if size > cap:
                    raise file_error(shown, f"{size} bytes, more than this scene can need ({cap}): refused")
                out = bytearray()
                while len(out) < size:
                    chunk = f.read(min(chunk_bytes, size - len(out)))
                    if not chunk:
                        raise file_error(shown, "truncated (the file shrank while reading)")
                    out += chunk
                    progress(len(out))
        except OSError as exc:
            raise file_error(shown, f"cannot read: {exc.strerror or exc}") from None
        return bytes(out)


# --- meta.json ----------------------------------------------------------------------------


class _Meta:
    def __init__(self) -> None:
        self.count = 0
        self.mins = self.maxs = None
        self.means_files: list[str] = []
        self.scales_codebook = self.sh0_codebook = None
        self.scales_file = self.quats_file = self.sh0_file = ""
        self.bands = 0
        self.palette_count = 0
        self.shn_codebook = None
        self.shn_files: list[str] = []


def _reject_constant(token: str):
    raise ValueError(f"{token} is not JSON")


def _parse_meta(shown: str, raw: bytes) -> _Meta:
    try:
        meta = json.loads(raw.decode("utf-8-sig"), parse_constant=_reject_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        detail = " ".join(str(exc).split()) or type(exc).__name__
        raise file_error(shown, f"not valid JSON ({shown_token(detail, 80)[1:-1]})") from None
    if not isinstance(meta, dict):
        raise file_error(shown, "not a SOG meta.json (expected a JSON object)")
    if "version" not in meta:
        if "means" in meta:
            raise file_error(shown, "SOG version 1 (a meta.json without 'version') is not supported; "
                                    "this reader reads SOG version 2 (re-export it with splat-transform)")
        raise file_error(shown, "not a SOG meta.json (no 'version' and no 'means')")
    version = meta["version"]
    if not _is_number(version) or version != 2:
        if "lodLevels" in meta or "tree" in meta:
            raise file_error(shown, "a streamed SOG index (lod-meta.json) is not supported; "
                                    "open one of its chunks' meta.json")
        raise file_error(shown, f"SOG version {_shown_json(version)} is not supported "
                                "(this reader reads version 2)")
    out = _Meta()
    out.count = _integer(shown, meta, "count", 0, MAX_COUNT, "gaussians")
    means = _section(shown, meta, "means")
    out.mins = _numbers(shown, means, "means", "mins", 3)
    out.maxs = _numbers(shown, means, "means", "maxs", 3)
    out.means_files = _files(shown, means, "means", 2)
    scales = _section(shown, meta, "scales")
    out.scales_codebook = _codebook(shown, scales, "scales")
    out.scales_file = _files(shown, scales, "scales", 1)[0]
    out.quats_file = _files(shown, _section(shown, meta, "quats"), "quats", 1)[0]
    sh0 = _section(shown, meta, "sh0")
    out.sh0_codebook = _codebook(shown, sh0, "sh0")
    out.sh0_file = _files(shown, sh0, "sh0", 1)[0]
    if meta.get("shN") is not None:
        shn = _section(shown, meta, "shN")
        out.bands = _integer(shown, shn, "bands", 0, 3, "SH bands", where="shN")
        if out.bands:
            out.palette_count = _integer(shown, shn, "count", 0, _MAX_PALETTE, "palette entries", where="shN")
            out.shn_codebook = _codebook(shown, shn, "shN")
            out.shn_files = _files(shown, shn, "shN", 2)[:2]
    return out


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_finite(value) -> bool:
    """A JSON number that fits a float64 (json gives integers of any size)."""
    try:
        return _is_number(value) and math.isfinite(value)
    except OverflowError:
        return False


def _shown_json(value) -> str:
    text = json.dumps(value)
    return text if len(text) <= 30 else text[:30] + "..."


def _section(shown: str, meta: dict, key: str) -> dict:
    value = meta.get(key)
    if not isinstance(value, dict):
        what = "missing" if value is None else f"a {_json_type(value)}, expected an object"
        raise file_error(shown, f"'{key}' is {what}")
    return value


def _json_type(value) -> str:
    names = {dict: "object", list: "list", str: "string", bool: "boolean", int: "number", float: "number"}
    return names.get(type(value), "null")


def _integer(shown: str, section: dict, key: str, low: int, high: int, what: str, where: str = "") -> int:
    name = f"{where}.{key}" if where else key
    value = section.get(key)
    if not _is_finite(value) or value != int(value):
        raise file_error(shown, f"'{name}' is {_shown_json(value)}, expected a whole number")
    value = int(value)
    if not low <= value <= high:
        raise file_error(shown, f"'{name}' is {value}: expected {low}..{high} {what}")
    return value


def _numbers(shown: str, section: dict, where: str, key: str, length: int) -> np.ndarray:
    value = section.get(key)
    if (not isinstance(value, list) or len(value) != length
            or not all(_is_finite(v) for v in value)):
        raise file_error(shown, f"'{where}.{key}' must be a list of {length} finite numbers")
    return np.array(value, dtype=np.float64)


def _codebook(shown: str, section: dict, where: str) -> np.ndarray:
    value = section.get("codebook")
    if not isinstance(value, list) or len(value) != _CODEBOOK_SIZE:
        got = f"{len(value)} entries" if isinstance(value, list) else ("missing" if value is None else
                                                                         f"a {_json_type(value)}")
        raise file_error(shown, f"'{where}.codebook' is {got}, expected a list of {_CODEBOOK_SIZE} numbers")
    if not all(v is None or _is_finite(v) for v in value):
        raise file_error(shown, f"'{where}.codebook' holds something other than finite numbers and null")
    book = np.array([math.nan if v is None else float(v) for v in value], dtype=np.float64)
    if value[0] is None:
        # Old writers stored -Infinity, which JSON writes as null; the engine extrapolates it.
        with np.errstate(all="ignore"):
            book[0] = book[1] + (book[1] - book[255]) / 255.0
    return book


def _files(shown: str, section: dict, where: str, needed: int) -> list[str]:
    value = section.get("files")
    if (not isinstance(value, list) or len(value) < needed
            or not all(isinstance(v, str) and v for v in value[:needed])):
        raise file_error(shown, f"'{where}.files' must list {needed} image file name{'s' if needed > 1 else ''}")
    return value[:needed]


# --- images ---------------------------------------------------------------------------------


def _webp_size(shown: str, data: bytes) -> tuple[int, int]:
    """Width and height from a WebP file's first bytes (the RIFF container's first chunk:
    lossless VP8L, extended VP8X or lossy VP8), before anything is decoded."""
    if len(data) < 30 or data[:4] != b"RIFF" or data[8:12] != b"WEBP":
        raise file_error(shown, "not a WebP image")
    kind = data[12:16]
    if kind == b"VP8L" and data[20] == 0x2F:
        bits = int.from_bytes(data[21:25], "little")
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if kind == b"VP8X":
        if data[20] & 0x02:
            raise file_error(shown, "animated WebP: a SOG image has one frame")
        return int.from_bytes(data[24:27], "little") + 1, int.from_bytes(data[27:30], "little") + 1
    if kind == b"VP8 " and data[23:26] == b"\x9d\x01\x2a":
        return int.from_bytes(data[26:28], "little") & 0x3FFF, int.from_bytes(data[28:30], "little") & 0x3FFF
    raise file_error(shown, "not a WebP image (unknown or corrupt first chunk)")


def _decode_webp(shown: str, data: bytes, pixels_ok, need: str, width: int | None = None) -> np.ndarray:
    """(H * W, 4) uint8 RGBA pixels, row-major. The header's size is checked with
    ``pixels_ok(w, h)`` (and ``width``) before Pillow decodes anything."""
    # Pillow is imported here, not at module level: only SOG reading needs it, and a
    # viewer that opens PLY files never pays for importing it.
    from PIL import Image, features

    w, h = _webp_size(shown, data)
    if (width is not None and w != width) or not pixels_ok(w, h):
        raise file_error(shown, f"image is {w}x{h}; {need}")
    if not features.check_module("webp"):
        raise file_error(shown, "this Pillow was built without WebP support: cannot decode SOG images")
    try:
        with warnings.catch_warnings():
            # Sizes were bounded above; Pillow's own, global, bomb limit is not ours to apply twice.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data), formats=["WEBP"]) as image:
                if getattr(image, "n_frames", 1) != 1:
                    raise file_error(shown, "animated WebP: a SOG image has one frame")
                if image.size != (w, h):
                    raise file_error(shown, f"WebP header says {w}x{h} but the image is "
                                            f"{image.size[0]}x{image.size[1]} (corrupt image)")
                image.load()
                rgba = image if image.mode == "RGBA" else image.convert("RGBA")
                pixels = np.asarray(rgba, dtype=np.uint8)
    except (OSError, SyntaxError, ValueError, EOFError, Image.DecompressionBombError) as exc:
        detail = " ".join(str(exc).split()) or type(exc).__name__
        raise file_error(shown, f"cannot decode the WebP image ({shown_token(detail, 80)[1:-1]})") from None
    if pixels.shape != (h, w, 4):
        raise file_error(shown, "image decoded to an unexpected shape (corrupt image)")
    return pixels.reshape(h * w, 4)


# --- the gaussians --------------------------------------------------------------------------


def _load(source, meta: _Meta, shown: str, report: Reporter, chunk_bytes: int) -> Scene:
    n = meta.count
    degree = meta.bands
    coeffs = sh_coefficient_count(degree) - 1
    max_pixels = 2 * n + _SLACK_PIXELS
    image_cap = _MAX_FILE_BYTES_PER_PIXEL * max_pixels + _FILE_OVERHEAD
    per_gaussian_names = [*meta.means_files, meta.scales_file, meta.quats_file, meta.sh0_file]
    keys = ["means_l", "means_u", "scales", "quats", "sh0"]
    if degree:
        per_gaussian_names.append(meta.shn_files[1])
        keys.append("labels")
    reads = [(key, name, image_cap) for key, name in zip(keys, per_gaussian_names)]
    centroid_rows = _MAX_PALETTE // _PALETTE_ROW
    if degree:
        reads.append(("centroids", meta.shn_files[0],
                      _MAX_FILE_BYTES_PER_PIXEL * _PALETTE_ROW * coeffs * centroid_rows + _FILE_OVERHEAD))
    sizes = [source.stored_size(name) for _, name, _ in reads]
    total = max(1, sum(sizes) + n)
    done = 0

    def per_gaussian(w: int, h: int) -> bool:
        return n <= w * h <= max_pixels

    need = f"expected at least {n} pixels (meta.json's count) and at most {max_pixels}"
    images = {}
    for (key, name, cap), size in zip(reads, sizes):
        bytes_before = done
        data = source.read(name, cap, chunk_bytes, lambda got: report.reading(bytes_before + got, total))
        done = bytes_before + size
        shown_image = f"{shown}: {name}"
        if key == "centroids":
            width = _PALETTE_ROW * coeffs
            images[key] = _decode_webp(
                shown_image, data, lambda w, h: 1 <= h <= centroid_rows,
                f"an SH palette of {degree} band{'s' if degree > 1 else ''} is {width} pixels wide and at most "
                f"{centroid_rows} rows", width)
        else:
            images[key] = _decode_webp(shown_image, data, per_gaussian, need)[:n]
        del data
        report.reading(done, total)

    means_l, means_u = images["means_l"], images["means_u"]
    scales_px, quats_px, sh0_px = images["scales"], images["quats"], images["sh0"]
    with np.errstate(all="ignore"):
        scale_lut = np.exp(meta.scales_codebook).astype(np.float32)
        sh0_lut = meta.sh0_codebook.astype(np.float32)
        opacity_lut = (np.arange(256) / 255.0).astype(np.float32)
        span = meta.maxs - meta.mins
        span[span == 0] = 1.0
        palette = palette_bad = labels_px = None
        if degree:
            labels_px = images["labels"]
            palette, palette_bad = _palette(images.pop("centroids"), meta, coeffs)

    arrays = scene_arrays(n, degree)
    positions, rotations, scales, opacities, sh = arrays
    drops = DropTally(n)
    scale_nan, scale_inf, scale_zero = np.isnan(scale_lut), np.isinf(scale_lut), scale_lut == 0
    colour_nan, colour_inf = np.isnan(sh0_lut), np.isinf(sh0_lut)
    step = max(1, chunk_bytes // _ROW_WORK_BYTES)
    for start in range(0, n, step):
        stop = min(n, start + step)
        with np.errstate(all="ignore"):
            v = means_l[start:stop, :3].astype(np.int64) | (means_u[start:stop, :3].astype(np.int64) << 8)
            logged = meta.mins + span * (v / 65535.0)
            positions[start:stop] = np.sign(logged) * np.expm1(np.abs(logged))
        rotations[start:stop] = _quaternions(quats_px[start:stop])
        s_idx = scales_px[start:stop, :3]
        c_idx = sh0_px[start:stop, :3]
        scales[start:stop] = scale_lut[s_idx]
        opacities[start:stop] = opacity_lut[sh0_px[start:stop, 3]]
        sh[start:stop, 0, :] = sh0_lut[c_idx]
        nan = np.isnan(positions[start:stop]).any(axis=1) | scale_nan[s_idx].any(axis=1) | colour_nan[c_idx].any(axis=1)
        inf_colour = colour_inf[c_idx].any(axis=1)
        if degree:
            labels = labels_px[start:stop, 0].astype(np.int64) | (labels_px[start:stop, 1].astype(np.int64) << 8)
            entry = np.where(labels < meta.palette_count, labels, palette.shape[0] - 1)
            sh[start:stop, 1:, :] = palette[entry]
            nan |= palette_bad[0][entry]
            inf_colour |= palette_bad[1][entry]
        drops.add(start, {
            "nan": nan,
            "infinite position": np.isinf(positions[start:stop]).any(axis=1),
            "infinite scale": scale_inf[s_idx].any(axis=1),
            "zero scale": scale_zero[s_idx].any(axis=1),
            "infinite colour": inf_colour,
        })
        report.reading(done + stop, total)
    report.activating()
    report.validating()
    return build_scene(arrays=arrays, sh_degree=degree, drops=drops, report=report, source=shown, format=SOG_FORMAT)


def _quaternions(pixels: np.ndarray) -> np.ndarray:
    """(rows, 4) RGBA quats pixels -> (rows, 4) unit quaternions (w, x, y, z), float32."""
    rows = pixels.shape[0]
    abc = _QUAT_COMPONENT[pixels[:, :3]]
    tag = pixels[:, 3].astype(np.int64)
    valid = tag >= 252
    largest = np.where(valid, tag - 252, 0)
    q = np.zeros((rows, 4))
    at = np.arange(rows)
    q[at[:, None], _OTHERS[largest]] = abc
    q[at, largest] = np.sqrt(np.maximum(0.0, 1.0 - np.sum(abc * abc, axis=1)))
    q[~valid] = (1.0, 0.0, 0.0, 0.0)
    # Unit already, unless quantisation pushed a^2 + b^2 + c^2 past 1 (the norm is then
    # above 1, never 0: no byte decodes to a zero component).
    q /= np.sqrt(np.sum(q * q, axis=1))[:, None]
    return q.astype(np.float32)


def _palette(centroids: np.ndarray, meta: _Meta, coeffs: int):
    """The SH palette as (entries + 1, coeffs, 3) float32 (the last row zero, for labels at
    or past ``shN.count``), and (nan, inf) flags per row."""
    lut = meta.shn_codebook.astype(np.float32)
    in_image = centroids.reshape(-1, coeffs, 4)[:, :, :3]
    entries = max(in_image.shape[0], meta.palette_count)
    palette = np.zeros((entries + 1, coeffs, 3), np.float32)
    palette[: in_image.shape[0]] = lut[in_image]
    palette[in_image.shape[0]: entries] = lut[0]  # entries the image lacks read byte 0
    flat = palette.reshape(entries + 1, -1)
    return palette, (np.isnan(flat).any(axis=1), np.isinf(flat).any(axis=1))
