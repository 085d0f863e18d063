"""Writing a :class:`Scene` as PlayCanvas SOG version 2: the bundled ``.sog`` zip that
:mod:`~raygs_viewer.scene.sog_file` reads (its docstring is the layout; this is its inverse).

What is quantised, and how:

- positions: per axis, ``l = sign(x) ln(|x| + 1)`` rounded to the nearest of 65536 steps
  between the scene's lowest and highest ``l`` (meta's ``mins`` / ``maxs``);
- scales (as their logarithms) and the DC colours: each to the nearest entry of a
  256-entry codebook shared by the three axes (channels), made by :func:`codebook_1d`
  (density-weighted 1D k-means, as splat-transform weighs it);
- opacity: ``round(255 o)`` in sh0's alpha, so 0 and 1 are exact;
- rotations: smallest three, each stored component rounded to the nearest byte;
- SH rest (degree >= 1): a palette of at most :func:`palette_size` rows, the distinct rows
  themselves when there are no more than that, else k-means centroids
  (``scipy.cluster.vq.kmeans2``, fixed seeds) learnt in two levels (:data:`COARSE_CELLS`);
  each palette value is then a byte into a 256-entry codebook, and each gaussian is
  labelled with the nearest palette row of its cell *as decoded*, so the codebook's
  rounding cannot leave it with a worse row of its cell than another.

Unlike splat-transform, gaussians are not put in Morton order: pixel i is gaussian i, so a
scene reads back in its own order (the images compress a little less).

The same scene gives the same bytes: fixed seeds, zip entries stored with a fixed time and
attributes, a fixed libwebp effort. (Another libwebp may compress the images to other bytes;
the pixels, and so the scene read back, stay the same.)
"""

from __future__ import annotations

import io
import json
import math
import warnings
import zipfile

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sog_meta import CODEBOOK_SIZE, MAX_PALETTE
from raygs_viewer.scene.sog_source import META_NAME

GENERATOR = "raygs-viewer"
#: Palette entries a row of the centroids image (the format's).
PALETTE_ROW = 64
KMEANS_SEED = 0x5067
#: splat-transform's default for its SH k-means (``--sh-iterations``).
KMEANS_ITERATIONS = 10
#: The SH palette is learnt in two levels: the rows are first split into this many cells
#: (k-means of every row), then each cell learns its share of the palette from its own
#: rows. An iteration costs N (cells + entries / cells) distances instead of N entries:
#: about 60 times less at the format's 65,536 entries. A row's label is the nearest entry
#: of its own cell (one near a cell's edge may have a slightly nearer one in the next).
COARSE_CELLS = 256
#: A cell learns at least this many entries on average (small palettes have fewer cells).
CELL_ENTRIES = 64
#: Lloyd steps of the 1D codebooks (:func:`_lloyd_1d`): each costs one binary search of
#: 255 cuts, so many are cheap; it stops sooner once the entries no longer move.
LLOYD_ITERATIONS = 100
#: The 1D codebooks' density weighting (splat-transform's ``alpha``): see :func:`_lloyd_1d`.
CODEBOOK_ALPHA = 0.5
#: Bins of the histogram that estimates the density of the values.
_DENSITY_BINS = 1024
#: libwebp's lossless effort, 0..6: 4 is its default; 6 is 20 times slower for about the
#: same size on this kind of data.
WEBP_METHOD = 4
#: A zero scale (log -inf) gets a codebook entry of its own this far below the smallest
#: other log-scale (splat-transform's margin for -Infinity): flat, and not zero, which a
#: reader would drop.
FLAT_MARGIN = 20.0
# The lowest log-scale whose exp is still a positive float32 (the smallest subnormal's).
_LOWEST_LOG_SCALE = math.log(float(np.nextafter(np.float32(0), np.float32(1))))
# A fixed time keeps the bytes the same from run to run (the zip format's earliest).
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)
# The three stored quaternion components for each dropped one (w, x, y, z = 0..3).
_KEPT = np.array([[c for c in range(4) if c != m] for m in range(4)])


def sog_bytes(scene: Scene) -> bytes:
    """The whole ``.sog`` file (a zip: meta.json and lossless WebP images) of ``scene``.
    One-line UserError for what SOG cannot hold (non-finite values, a zero rotation)."""
    meta, images = sog_images(scene)
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_STORED) as archive:
        # Stored, not deflated, as splat-transform writes its bundles: the images are
        # compressed already, and so every reader of its bundles reads these.
        for name, data in [*((name, webp_bytes(rgba)) for name, rgba in images.items()),
                           (META_NAME, json.dumps(meta, separators=(",", ":")).encode("ascii"))]:
            info = zipfile.ZipInfo(name, _ZIP_TIME)
            info.create_system, info.external_attr = 3, 0o100644 << 16  # the same on every platform
            archive.writestr(info, data)
    return out.getvalue()


def sog_images(scene: Scene) -> tuple[dict, dict[str, np.ndarray]]:
    """(meta.json as a dict, {image name: (H, W, 4) uint8 RGBA}) of ``scene``, in the
    order splat-transform writes them."""
    _check(scene)
    n, degree = scene.count, scene.sh_degree
    width, height = image_size(n)

    def image(*channels) -> np.ndarray:
        full = np.zeros((width * height, 4), np.uint8)
        full[:n] = np.stack([np.broadcast_to(c, (n,)) for c in channels], axis=1)
        return full.reshape(height, width, 4)

    codes, mins, maxs = _means(scene.positions)
    opaque = np.uint8(255)
    images = {"means_l.webp": image(*(codes & 255).T, opaque), "means_u.webp": image(*(codes >> 8).T, opaque)}
    kept, largest = _smallest_three(scene.rotations)
    images["quats.webp"] = image(*kept.T, 252 + largest)
    with np.errstate(divide="ignore"):
        scale_book, scale_idx = codebook_1d(np.log(scene.scales.astype(np.float64)))
    images["scales.webp"] = image(*scale_idx.T, opaque)
    dc_book, dc_idx = codebook_1d(scene.sh[:, 0, :].astype(np.float64))
    alpha = np.rint(scene.opacities.astype(np.float64) * 255).astype(np.uint8)
    images["sh0.webp"] = image(*dc_idx.T, alpha)
    meta = {
        "version": 2, "asset": {"generator": GENERATOR}, "count": n,
        "means": {"mins": mins.tolist(), "maxs": maxs.tolist(), "files": ["means_l.webp", "means_u.webp"]},
        "scales": {"codebook": scale_book.tolist(), "files": ["scales.webp"]},
        "quats": {"files": ["quats.webp"]},
        "sh0": {"codebook": dc_book.tolist(), "files": ["sh0.webp"]},
    }
    if degree:
        labels, palette, sh_book = sh_palette(scene.sh[:, 1:, :])
        coeffs = sh_coefficient_count(degree) - 1
        rows = max(1, math.ceil(len(palette) / PALETTE_ROW))
        centroids = np.zeros((rows * PALETTE_ROW, coeffs, 4), np.uint8)
        centroids[: len(palette), :, :3] = palette
        centroids[:, :, 3] = 255
        images["shN_centroids.webp"] = centroids.reshape(rows, PALETTE_ROW * coeffs, 4)
        images["shN_labels.webp"] = image(labels & 255, labels >> 8, np.uint8(0), opaque)
        meta["shN"] = {"count": len(palette), "bands": degree, "codebook": sh_book.tolist(),
                       "files": ["shN_centroids.webp", "shN_labels.webp"]}
    return meta, images


def image_size(n: int) -> tuple[int, int]:
    """(width, height) of the per-gaussian images: splat-transform's near-square layout in
    multiples of 4 (4 x 4 for an empty scene: an image has at least one pixel)."""
    width = max(4, math.ceil(math.sqrt(n) / 4) * 4)
    return width, max(4, math.ceil(n / width / 4) * 4)


def palette_size(n: int) -> int:
    """The SH palette's entries for ``n`` gaussians: the largest power of two <= n, at most
    the format's 65536 (the labels are 16 bits), so that a small scene's palette is not
    padded with centroids no gaussian uses."""
    return min(MAX_PALETTE, 1 << (n.bit_length() - 1)) if n else 0


def webp_bytes(rgba: np.ndarray) -> bytes:
    """A lossless WebP of ``rgba`` ((H, W, 4) uint8). ``exact`` keeps the RGB under a zero
    alpha (sh0's alpha is the opacity, and 0 is common): libwebp would otherwise clear it."""
    # Pillow is imported here, not at module level, as the SOG reader does: only SOG needs it.
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(out, format="WEBP", lossless=True, quality=100, method=WEBP_METHOD,
                                       exact=True)
    return out.getvalue()


def codebook_1d(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A 256-entry codebook for ``values`` (float64, any shape) and each value's nearest
    entry (uint8, the same shape).

    Entries are rounded to float32 (what readers hold) before the values are assigned, so
    "nearest" is nearest as read. As many distinct values as entries or fewer are entries
    themselves (exact). -inf (a zero scale's log) gets an entry of its own,
    :data:`FLAT_MARGIN` below the rest. The entries: :func:`_lloyd_1d`."""
    flat = values.reshape(-1)
    finite = flat[np.isfinite(flat)]
    flat_entry = np.isneginf(flat).any()
    entries = _lloyd_1d(finite, CODEBOOK_SIZE - int(flat_entry))
    if flat_entry:
        low = finite.min() if finite.size else 0.0
        entries = np.concatenate([[max(low - FLAT_MARGIN, _LOWEST_LOG_SCALE)], entries])
    entries = np.unique(entries.astype(np.float32)).astype(np.float64)
    index = np.searchsorted((entries[:-1] + entries[1:]) / 2, flat)
    book = np.concatenate([entries, np.full(CODEBOOK_SIZE - entries.size, entries[-1])])
    return book, index.astype(np.uint8).reshape(values.shape)


def _lloyd_1d(values: np.ndarray, k: int) -> np.ndarray:
    """Up to ``k`` sorted entries for the finite ``values``: 1D k-means (Lloyd's steps)
    with each value weighted by its local density to the power
    :data:`CODEBOOK_ALPHA` - 1.

    Why: plain k-means (alpha 1) gives the least squared error but leaves the sparse tails
    (the largest gaussians, the brightest colours) with errors of a tenth of the range;
    uniform steps (alpha 0) bound the worst error but waste entries where few values are.
    alpha 0.5 is splat-transform's own trade, so files written here quantise like its own.
    Lloyd's steps start from where they end up for smooth data (entries spaced as the
    density to the power alpha / 3), so a fixed number of them converges; on the sorted
    distinct values each is a binary search and prefix sums, cheap for millions of values,
    and with no random start the result is deterministic."""
    distinct, counts = np.unique(values, return_counts=True)
    if distinct.size <= k:
        return distinct if distinct.size else np.zeros(1)
    span = distinct[-1] - distinct[0]
    bins = np.minimum(((distinct - distinct[0]) / span * _DENSITY_BINS).astype(np.int64), _DENSITY_BINS - 1)
    density = np.bincount(bins, weights=counts, minlength=_DENSITY_BINS)[bins]
    start = np.cumsum(counts * density ** (CODEBOOK_ALPHA / 3 - 1))
    centres = np.unique(distinct[np.minimum(np.searchsorted(start, (np.arange(k) + 0.5) / k * start[-1]),
                                            distinct.size - 1)])
    weights = counts * density ** (CODEBOOK_ALPHA - 1)
    mass = np.concatenate([[0.0], np.cumsum(weights)])
    moment = np.concatenate([[0.0], np.cumsum(weights * distinct)])
    for _ in range(LLOYD_ITERATIONS):
        cuts = np.concatenate([[0], np.searchsorted(distinct, (centres[:-1] + centres[1:]) / 2), [distinct.size]])
        got = mass[cuts[1:]] - mass[cuts[:-1]]
        # An emptied entry keeps its place (it may take values again as others move).
        moved = np.sort(np.where(got > 0, (moment[cuts[1:]] - moment[cuts[:-1]]) / np.where(got > 0, got, 1), centres))
        if np.array_equal(moved, centres):
            break
        centres = moved
    return centres


def _means(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 3) 16-bit codes (int64) of the positions in log space, and the log-space mins
    and maxs per axis (zeros for an empty scene)."""
    x = positions.astype(np.float64)
    logged = np.sign(x) * np.log1p(np.abs(x))
    if not len(x):
        return np.zeros((0, 3), np.int64), np.zeros(3), np.zeros(3)
    mins, maxs = logged.min(axis=0), logged.max(axis=0)
    span = np.where(maxs > mins, maxs - mins, 1.0)  # a flat axis: every code 0, as readers take it
    codes = np.clip(np.rint((logged - mins) / span * 65535), 0, 65535).astype(np.int64)
    return codes, mins, maxs


def _smallest_three(rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) bytes of the three smaller components, in w x y z order, and (N,) the index
    of the largest, which is made positive (q and -q are the same rotation) and dropped."""
    q = rotations.astype(np.float64)
    q /= np.linalg.norm(q, axis=1)[:, None]
    rows = np.arange(len(q))
    largest = np.argmax(np.abs(q), axis=1)
    q *= np.where(q[rows, largest] < 0, -1.0, 1.0)[:, None]
    kept = q[rows[:, None], _KEPT[largest]]  # within +-1/sqrt(2), the byte range's ends
    return np.clip(np.rint((kept / math.sqrt(2.0) + 0.5) * 255), 0, 255).astype(np.uint8), largest.astype(np.uint8)


def sh_palette(rest: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N,) int64 labels, (entries, K, 3) uint8 codebook indices of the palette, and the
    256-entry SH codebook, for the SH rest ``rest`` ((N, K, 3) float32)."""
    n, coeffs = rest.shape[0], rest.shape[1]
    rows = np.ascontiguousarray(rest.reshape(n, coeffs * 3))
    distinct, inverse = np.unique(rows, axis=0, return_inverse=True)
    if len(distinct) <= palette_size(n):
        # The rows themselves: each decodes to its nearest codebook values, and no other
        # row of the palette can lie nearer (they are all made of codebook values too).
        book, palette = codebook_1d(distinct.astype(np.float64))
        return inverse.reshape(-1).astype(np.int64), palette.reshape(-1, coeffs, 3), book
    cells = palette_cells(rows, palette_size(n))
    centres = [_kmeans(rows[members], share, KMEANS_SEED + cell)
               for cell, (members, share) in enumerate(zip(cells, cell_shares(palette_size(n), cells)))]
    book, palette = codebook_1d(np.concatenate(centres).astype(np.float64))
    decoded = book[palette].astype(np.float32)
    labels, first = np.zeros(n, np.int64), 0
    for members, part in zip(cells, centres):  # each row's nearest decoded entry of its own cell
        labels[members] = first + _nearest(rows[members], decoded[first:first + len(part)])
        first += len(part)
    return labels, palette.reshape(-1, coeffs, 3), book


def palette_cells(rows: np.ndarray, entries: int) -> list[np.ndarray]:
    """The first level of the SH palette: ``rows`` ((N, D) float32) split into cells by
    k-means of every row, as ascending index arrays (no empty one). There are
    :data:`COARSE_CELLS` cells, or one per :data:`CELL_ENTRIES` of the palette's
    ``entries`` where that is fewer."""
    cells = max(1, min(COARSE_CELLS, entries // CELL_ENTRIES, len(rows)))
    if cells == 1:
        return [np.arange(len(rows))]
    nearest = _nearest(rows, _kmeans(rows, cells, KMEANS_SEED - 1))
    order = np.argsort(nearest, kind="stable")
    return [members for members in np.split(order, np.cumsum(np.bincount(nearest, minlength=cells))[:-1])
            if members.size]


def cell_shares(entries: int, cells: list[np.ndarray]) -> list[int]:
    """How many of the palette's ``entries`` each cell learns: one each, the rest in
    proportion to its rows (largest remainders first), never more than its rows; so at
    most ``entries`` in all."""
    counts = np.array([len(members) for members in cells])
    exact = (entries - len(cells)) * counts / counts.sum()
    shares = np.floor(exact).astype(np.int64)
    shares[np.argsort(shares - exact, kind="stable")[:entries - len(cells) - int(shares.sum())]] += 1
    return np.minimum(shares + 1, counts).tolist()


def _kmeans(rows: np.ndarray, k: int, seed: int) -> np.ndarray:
    """(k, D) float32 centres of ``rows`` ((M, D) float32): :data:`KMEANS_ITERATIONS` of
    scipy's k-means from ``k`` of the rows (their distinct values where there are no more)."""
    # scipy is imported here: only writing SOG with SH uses it, and it is slow to import.
    from scipy.cluster.vq import kmeans2

    distinct = np.unique(rows, axis=0)
    if len(distinct) <= k:
        return distinct
    with warnings.catch_warnings():
        # A cluster left empty keeps its centre; labels are made again from the decoded palette.
        warnings.simplefilter("ignore")
        centres, _ = kmeans2(rows, k, iter=KMEANS_ITERATIONS, minit="points", seed=seed)
    return centres.astype(np.float32)


def _nearest(rows: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(M,) int64: each row's nearest of ``centres`` (squared distance, first on ties)."""
    from scipy.cluster.vq import vq  # here, as in _kmeans: only writing SOG with SH needs scipy

    return vq(rows, centres, check_finite=False)[0].astype(np.int64)


def _check(scene: Scene) -> None:
    """One UserError line for a value SOG has no code for."""
    faults = [
        ("non-finite positions", not np.isfinite(scene.positions).all()),
        ("non-finite colours or SH", not np.isfinite(scene.sh).all()),
        ("scales that are negative, infinite or NaN", not (np.isfinite(scene.scales) & (scene.scales >= 0)).all()),
        ("opacities outside 0..1", not ((scene.opacities >= 0) & (scene.opacities <= 1)).all()),
        ("zero or non-finite rotations",
         not (np.isfinite(scene.rotations).all() and (np.abs(scene.rotations).max(axis=1) > 0).all())),
    ]
    for what, bad in faults:
        if bad:
            raise UserError(f"cannot write .sog: the scene has {what}")
