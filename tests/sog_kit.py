"""A small SOG v2 encoder for the tests (scene/test_sog.py, the fuzz tests and the streamed
SOG kit, lod_kit.py): the test's own reading of the format (developer.playcanvas.com's SOG
page and splat-transform's writer).

It rounds to the nearest code where splat-transform truncates, uses plain linspace codebooks
and a palette of the distinct SH rows, and lays images out with any width, so a reader is
checked against the format, not against itself. test_sog.py states the quantisation bounds
of a decoded scene against the scene encoded.
"""

from __future__ import annotations

import io
import json
import math
import os
import zipfile

import numpy as np
from PIL import Image
from testkit import unit_quaternions


def log_transform(x):
    return np.sign(x) * np.log1p(np.abs(x))


def inverse_log(x):
    return np.sign(x) * np.expm1(np.abs(x))


def codebook(values):
    """A 256-entry linspace codebook over ``values`` and each value's nearest index."""
    lo, hi = float(np.min(values)), float(np.max(values))
    if hi == lo:
        return np.full(256, lo), np.zeros(np.shape(values), np.uint8)
    book = np.linspace(lo, hi, 256)
    return book, np.clip(np.rint((values - lo) / (hi - lo) * 255), 0, 255).astype(np.uint8)


def webp_bytes(rgba: np.ndarray) -> bytes:
    """Lossless WebP; ``exact`` keeps RGB under a zero alpha (libwebp's simple lossless
    encoder, which splat-transform calls, does the same)."""
    out = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(out, "WEBP", lossless=True, exact=True, quality=0, method=0)
    return out.getvalue()


def encode_sog(positions, log_scales, rotations, opacities, f_dc, f_rest=None, width=None, fill=0, seed=0):
    """(meta, {file name: (H, W, 4) uint8}, codes) of N gaussians. ``f_rest``: (N, K, 3) SH
    rest in the project's layout, or None. ``fill``: the trailing pixels' bytes ("random")."""
    n = len(positions)
    width = width or max(1, math.ceil(math.sqrt(n)))
    height = max(1, math.ceil(n / width))
    rng = np.random.default_rng(seed)

    def image(channels):
        full = (rng.integers(0, 256, (height * width, 4), dtype=np.uint8) if fill == "random"
                else np.full((height * width, 4), fill, np.uint8))
        full[:n] = np.stack([np.broadcast_to(c, (n,)) for c in channels], axis=1)
        return full.reshape(height, width, 4)

    logged = log_transform(np.asarray(positions, np.float64))
    mins, maxs = logged.min(axis=0), logged.max(axis=0)
    span = np.where(maxs > mins, maxs - mins, 1.0)
    v = np.rint((logged - mins) / span * 65535).astype(np.int64)
    images = {"means_l.webp": image([*(v & 255).T, 255]), "means_u.webp": image([*(v >> 8).T, 255])}

    q = np.asarray(rotations, np.float64)
    q = q / np.linalg.norm(q, axis=1)[:, None]
    largest = np.argmax(np.abs(q), axis=1)
    q = q * np.where(q[np.arange(n), largest] < 0, -1.0, 1.0)[:, None]
    stored = np.empty((n, 3))
    for m in range(4):
        rows = largest == m
        stored[rows] = q[rows][:, [c for c in range(4) if c != m]]
    quat_bytes = np.clip(np.rint((stored / math.sqrt(2) + 0.5) * 255), 0, 255).astype(np.uint8)
    images["quats.webp"] = image([*quat_bytes.T, 252 + largest])

    scale_book, scale_idx = codebook(np.asarray(log_scales, np.float64))
    images["scales.webp"] = image([*scale_idx.T, 255])
    dc_book, dc_idx = codebook(np.asarray(f_dc, np.float64))
    alpha = np.rint(np.asarray(opacities, np.float64) * 255).astype(np.uint8)
    images["sh0.webp"] = image([*dc_idx.T, alpha])
    meta = {
        "version": 2, "asset": {"generator": "raygs-viewer tests"}, "count": n,
        "means": {"mins": mins.tolist(), "maxs": maxs.tolist(), "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"codebook": scale_book.tolist(), "files": ["scales.webp"]},
        "quats": {"files": ["quats.webp"]},
        "sh0": {"codebook": dc_book.tolist(), "files": ["sh0.webp"]},
    }
    codes = {"means": v, "scales": scale_idx, "quats": quat_bytes, "tags": 252 + largest, "sh0": dc_idx,
             "alpha": alpha, "scale_book": scale_book, "dc_book": dc_book}
    if f_rest is not None:
        k = f_rest.shape[1]
        palette, labels = np.unique(np.asarray(f_rest, np.float64).reshape(n, -1), axis=0, return_inverse=True)
        labels = labels.reshape(-1)
        rest_book, rest_idx = codebook(palette)
        rest_idx = rest_idx.reshape(-1, k, 3)
        rows = math.ceil(len(palette) / 64)
        centroids = np.zeros((rows * 64, k, 4), np.uint8)
        centroids[: len(palette), :, :3] = rest_idx
        centroids[:, :, 3] = 255
        images["shN_centroids.webp"] = centroids.reshape(rows, 64 * k, 4)
        images["shN_labels.webp"] = image([labels & 255, labels >> 8, 0, 255])
        meta["shN"] = {"count": len(palette), "bands": {3: 1, 8: 2, 15: 3}[k], "codebook": rest_book.tolist(),
                       "files": ["shN_centroids.webp", "shN_labels.webp"]}
        codes.update(labels=labels, rest=rest_idx, rest_book=rest_book)
    return meta, images, codes


def write_folder(folder, meta, images, meta_name="meta.json"):
    os.makedirs(folder, exist_ok=True)
    for name, rgba in images.items():
        with open(os.path.join(folder, name), "wb") as f:
            f.write(rgba if isinstance(rgba, bytes) else webp_bytes(rgba))
    path = os.path.join(folder, meta_name)
    with open(path, "w") as f:
        json.dump(meta, f)
    return path


def bundle_bytes(meta, images, compression=zipfile.ZIP_STORED) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression) as archive:
        for name, rgba in images.items():
            archive.writestr(name, rgba if isinstance(rgba, bytes) else webp_bytes(rgba))
        if meta is not None:
            archive.writestr("meta.json", meta if isinstance(meta, bytes) else json.dumps(meta))
    return out.getvalue()


def write_bundle(path, meta, images, compression=zipfile.ZIP_STORED):
    with open(path, "wb") as f:
        f.write(bundle_bytes(meta, images, compression))
    return path


def gaussians(n=300, degree=0, seed=0, palette=7):
    """A scene's raw values: positions over several orders of magnitude (the log transform's
    reason), log-scales, unnormalised quaternions, opacities, f_dc, and f_rest drawn from
    ``palette`` distinct rows (so the SH palette itself is exact)."""
    rng = np.random.default_rng(seed)
    positions = rng.normal(size=(n, 3)) * np.array([0.3, 3.0, 40.0])
    positions[:2] = ((0.0, -0.0, 1e-6), (-1e-7, 0.0, 0.0))[:n]
    log_scales = rng.uniform(-7.0, 0.5, (n, 3))
    rotations = unit_quaternions(rng, n).astype(np.float64) * rng.uniform(0.5, 2.0, (n, 1))
    rotations[-1] = (0.0, 0.0, 0.0, -1.0)  # a negative largest component
    opacities = rng.uniform(0.0, 1.0, n)
    opacities[:2] = (0.0, 1.0)[:n]
    f_dc = rng.normal(scale=0.8, size=(n, 3))
    f_rest = None
    if degree:
        k = (degree + 1) ** 2 - 1
        rows = rng.normal(scale=0.2, size=(palette, k, 3))
        f_rest = rows[rng.integers(0, palette, n)]
    return positions, log_scales, rotations, opacities, f_dc, f_rest
