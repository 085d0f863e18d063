"""A large synthetic streamed SOG for timing level of detail at scale (docs/lod.md):
``python docs/lod_synthetic_scene.py OUT N`` writes OUT/lod-meta.json with about N
gaussians at level 0 on a sloping plane of leaves (rising away from a camera that looks
along +z, as ``frame_points`` does, so a view sees near leaves large and far ones small),
three coarser levels (each half the
gaussians of the one before, standard deviations sqrt(2) times larger and opacities kept,
as a decimation that merges pairs would give), and a small environment far around it.

It uses the tests' encoder (tests/lod_kit.py, tests/sog_kit.py: lossless WebP through
Pillow), so its files are what the reader's tests read. The scene is not a capture:
its numbers say what the choice costs and saves at a size no shared scene reaches, not
how a real capture looks (docs/lod.md's pictures use a real one).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from lod_kit import Gaussians, random_gaussians, write_streamed_sog  # noqa: E402  (the tests' kit)

LEVELS = 4
#: Leaves on a square grid this many a side, one unit apart, rising SLOPE per unit of depth.
SIDE = 16
SLOPE = 0.5


def leaf(n: int, centre, level: int, seed: int) -> Gaussians:
    """Level ``level`` of a leaf: n / 2^level gaussians over the leaf's square, larger the coarser."""
    rng = np.random.default_rng(seed)
    count = max(1, n >> level)
    across, depth = rng.uniform(-0.5, 0.5, count), rng.uniform(-0.5, 0.5, count)
    positions = np.column_stack([across, -SLOPE * depth + rng.normal(0.0, 0.02, count), depth]) + centre
    spacing = 1.0 / math.sqrt(count)  # so neighbours overlap at every level
    log_scales = np.log(np.column_stack([np.full(count, spacing), np.full(count, 0.3 * spacing),
                                         np.full(count, spacing)]) * rng.uniform(0.7, 1.3, (count, 1)))
    rotations = rng.normal(size=(count, 4)) * [1.0, 0.1, 0.1, 0.1] + [1.0, 0.0, 0.0, 0.0]
    hue = 0.5 + 0.5 * np.sin(positions[:, [0]] * [1.3, 0.7, 0.2] + positions[:, [2]] * [0.4, 1.1, 1.7])
    f_dc = (hue - 0.5) / 0.28209479177387814
    return Gaussians(positions, log_scales, rotations, rng.uniform(0.3, 0.95, count), f_dc)


def main(out: str, total: int) -> None:
    per_leaf = max(1, total // (SIDE * SIDE))
    leaves = []
    for k in range(SIDE * SIDE):
        row = k // SIDE - SIDE / 2
        centre = np.array([k % SIDE - SIDE / 2, -SLOPE * row, row], np.float64)  # -y is up
        leaves.append([leaf(per_leaf, centre, level, seed=LEVELS * k + level) for level in range(LEVELS)])
    environment = random_gaussians(512, spread=10.0 * SIDE, scale=2.0, seed=1)
    path = write_streamed_sog(Path(out), leaves, environment=environment, file_bin=1 << 20)
    print(f"wrote {path}: {SIDE * SIDE} leaves, level 0 {per_leaf * SIDE * SIDE:,} gaussians, {LEVELS} levels")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python docs/lod_synthetic_scene.py OUT N")
    main(sys.argv[1], int(sys.argv[2]))
