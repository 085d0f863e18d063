"""Times the SOG writer's SH palette (scene.sog_write) in two levels against one flat k-means.

Usage: .venv/bin/python docs/sog_palette_timing.py
Synthetic SH degree 3 rests: 30,000 base rows plus noise (real scenes' rests cluster
too); the RMS error is of each gaussian's SH rest against its decoded palette row.
"""
import time

import numpy as np
from scipy.cluster.vq import kmeans2, vq

from raygs_viewer.scene import sog_write


def rests(n: int, rng) -> np.ndarray:
    base = rng.normal(size=(30000, 45)).astype(np.float32) * 0.3
    return (base[rng.integers(0, len(base), n)] + rng.normal(size=(n, 45)).astype(np.float32) * 0.05).reshape(n, 15, 3)


rng = np.random.default_rng(0)
for n in (20_000, 200_000, 1_000_000):
    rest = rests(n, rng)
    rows = rest.reshape(n, 45)
    start = time.perf_counter()
    labels, palette, book = sog_write.sh_palette(rest)
    two_level = time.perf_counter() - start
    decoded = book[palette.reshape(len(palette), 45)]
    line = (f"{n:>9,} gaussians, {len(palette):,} entries: two levels {two_level:6.1f} s, "
            f"RMS {np.sqrt(((rows - decoded[labels]) ** 2).mean()):.4f}")
    if n <= 20_000:  # one flat k-means, what the writer did before (minutes past 100k)
        start = time.perf_counter()
        centres, _ = kmeans2(rows, sog_write.palette_size(n), iter=sog_write.KMEANS_ITERATIONS, minit="points",
                             seed=sog_write.KMEANS_SEED)
        flat_book, flat_palette = sog_write.codebook_1d(centres.astype(np.float64))
        flat_decoded = flat_book[flat_palette].astype(np.float32)
        flat_labels, _ = vq(rows, flat_decoded)
        line += (f"; flat {time.perf_counter() - start:6.1f} s, "
                 f"RMS {np.sqrt(((rows - flat_decoded[flat_labels]) ** 2).mean()):.4f}")
    print(line, flush=True)
