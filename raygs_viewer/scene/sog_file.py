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

Each image's size is read from its header first and must fit the count
(``N <= W*H <= 2N + 65536``) before it is decoded (:mod:`~raygs_viewer.scene.webp_image`).
Bad input is one :class:`UserError` line naming the file (and the member). Where the
bytes come from, zip bundle or folder, and how a hostile archive is kept in bounds:
:mod:`~raygs_viewer.scene.sog_source`; the meta.json schema:
:mod:`~raygs_viewer.scene.sog_meta`.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DropTally, build_scene, scene_arrays
from raygs_viewer.scene.sog_meta import MAX_PALETTE, SogMeta, parse_meta
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.sog_source import Folder, SogSource, is_bundle, is_sog_folder, meta_file, open_source
from raygs_viewer.scene.webp_image import decode_webp

SOG_FORMAT = "SOG v2"

#: Pixels an image may hold past the count: splat-transform pads to multiples of 4.
_SLACK_PIXELS = 65536
#: A lossless WebP spends at most 4 Huffman codes of 15 bits a pixel.
_MAX_FILE_BYTES_PER_PIXEL = 8
_FILE_OVERHEAD = 1 << 20
#: shN palette: 64 entries a row of the centroids image.
_PALETTE_ROW = 64
_ROW_WORK_BYTES = 64  # roughly what one gaussian costs to decode, for chunking and progress

# The three stored quaternion components for each dropped one (w, x, y, z = 0..3).
_OTHERS = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])
# Every byte's quaternion component: (byte / 255 - 0.5) * sqrt(2).
_QUAT_COMPONENT = (np.arange(256) / 255.0 - 0.5) * math.sqrt(2.0)


def load_sog(source: SceneSource, report: Reporter, chunk_bytes: int) -> Scene:
    """``source.path``: a bundled .sog file, an unbundled scene's meta.json, or its folder."""
    return read_sog(source.path, source.path, report, chunk_bytes)[0]


def read_sog(path, shown: str, report: Reporter, chunk_bytes: int) -> tuple[Scene, np.ndarray | None]:
    """:func:`load_sog`'s scene, and which of the file's rows it dropped ((count,) bool),
    or None where it dropped none: a streamed SOG's index addresses the file's rows."""
    with open_source(path, shown) as source:
        meta = parse_meta(source.shown_meta, source.read_meta())
        chunk_bytes = max(1, chunk_bytes)
        images, done, total = _read_images(source, meta, shown, report, chunk_bytes)
        return _decode(images, meta, shown, report, chunk_bytes, done=done, total=total)


def scene_files(path) -> list[str] | None:
    """The files an unbundled SOG scene's content is, when ``path`` names one (the folder
    holding a meta.json, or a file named *.json): its meta.json and the images that
    names, in the order it names them (what the scene's SHA-256 covers, so that an image
    edited beside an unchanged meta.json is a changed scene); a zip named *.json is
    itself. None for any other path: its one file is the whole scene. UserError as
    :func:`load_sog`'s."""
    if not is_sog_folder(path) and Path(path).suffix.lower() != ".json":
        return None
    shown = os.fspath(path)
    path = meta_file(path)
    if is_bundle(path):
        return [os.fspath(path)]
    folder = Folder(path, shown)
    meta = parse_meta(shown, folder.read_meta())
    return [os.fspath(path), *(folder.resolve(name) for name in meta.image_names)]


def _read_images(source: SogSource, meta: SogMeta, shown: str, report: Reporter,
                 chunk_bytes: int) -> tuple[dict[str, np.ndarray], int, int]:
    """Every image meta.json names, decoded to (pixels, 4) RGBA: the per-gaussian ones cut
    to the count. Also the progress made and the whole job, in stored bytes plus one
    per gaussian left to decode."""
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
    centroid_rows = MAX_PALETTE // _PALETTE_ROW
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
            images[key] = decode_webp(
                shown_image, data, lambda w, h: 1 <= h <= centroid_rows,
                f"an SH palette of {degree} band{'s' if degree > 1 else ''} is {width} pixels wide and at most "
                f"{centroid_rows} rows", width)
        else:
            images[key] = decode_webp(shown_image, data, per_gaussian, need)[:n]
        del data
        report.reading(done, total)
    return images, done, total


def _decode(images: dict[str, np.ndarray], meta: SogMeta, shown: str, report: Reporter, chunk_bytes: int, *,
            done: int, total: int) -> tuple[Scene, np.ndarray | None]:
    """The gaussians of the decoded images, a chunk at a time; progress goes on from
    ``done`` of ``total``."""
    n = meta.count
    degree = meta.bands
    coeffs = sh_coefficient_count(degree) - 1
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
    dropped = drops.bad.copy() if drops.dropped else None
    return (build_scene(arrays=arrays, sh_degree=degree, drops=drops, report=report, source=shown, format=SOG_FORMAT),
            dropped)


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


def _palette(centroids: np.ndarray, meta: SogMeta, coeffs: int):
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
