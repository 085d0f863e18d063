"""Reading the 32-byte ``.splat`` format (no header: the file size gives the count)."""

from __future__ import annotations

import os

import numpy as np

from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import DropTally, SceneArrays, build_scene, file_error
from raygs_viewer.scene.sh import C0
from raygs_viewer.scene.source import SceneSource

#: The 32-byte ``.splat`` row.
SPLAT_ROW_BYTES = 32
SPLAT_FORMAT = ".splat"
_SPLAT_DTYPE = np.dtype([("position", "<f4", (3,)), ("scale", "<f4", (3,)),
                         ("rgba", "u1", (4,)), ("rotation", "u1", (4,))])


def load_splat(source: SceneSource, report: Reporter, chunk_bytes: int) -> Scene:
    """The 32-byte ``.splat`` rows: float32 position xyz, float32 *linear* scale xyz,
    RGBA uint8 (colour -> SH DC via (c/255 - 0.5)/C0, opacity a/255), quaternion
    as 4 uint8 ``q*128+128`` in order w, x, y, z (normalised here). SH degree 0.
    Read ``chunk_bytes`` at a time, with a progress point after each."""
    path = shown = source.path
    size = os.path.getsize(path)
    if size % SPLAT_ROW_BYTES:
        raise file_error(shown, f"not a .splat file: size {size} bytes is not a multiple of {SPLAT_ROW_BYTES}")
    n = size // SPLAT_ROW_BYTES
    rows = np.empty(n, dtype=_SPLAT_DTYPE)
    # Read straight into the rows' memory, a chunk at a time: the same footprint as
    # one np.fromfile, with progress and cancel points in between.
    buffer = memoryview(rows.view(np.uint8))
    done = 0
    with open(path, "rb") as f:
        while done < size:
            got = f.readinto(buffer[done: min(size, done + max(1, chunk_bytes))])
            if not got:
                raise file_error(shown, "truncated .splat file (the file shrank while reading)")
            done += got
            report.reading(done, size)
    del buffer
    report.activating()
    positions = rows["position"].astype(np.float32)
    scale = rows["scale"].astype(np.float32)
    rgba = rows["rgba"].astype(np.float64)
    q = (rows["rotation"].astype(np.float64) - 128.0) / 128.0
    with np.errstate(all="ignore"):
        norm = np.sqrt(np.sum(q * q, axis=1))
        quat = (q / norm[:, None]).astype(np.float32)
    sh = ((rgba[:, None, :3] / 255.0 - 0.5) / C0).astype(np.float32)
    opacity = (rgba[:, 3] / 255.0).astype(np.float32)
    report.validating()
    tests = {
        "nan": np.isnan(positions).any(axis=1) | np.isnan(scale).any(axis=1),
        "infinite position": np.isinf(positions).any(axis=1),
        "infinite scale": np.isinf(scale).any(axis=1),
        "zero scale": (scale == 0).any(axis=1),
        "negative scale": (scale < 0).any(axis=1),
        "zero quaternion": norm == 0,
    }
    drops = DropTally(n)
    drops.add(0, tests)
    arrays = SceneArrays(positions=positions, rotations=quat, scales=scale, opacities=opacity, sh=sh)
    return build_scene(arrays=arrays, sh_degree=0, drops=drops, report=report, source=shown, format=SPLAT_FORMAT)
