"""A test-side encoder of PlayCanvas's streamed SOG (``lod-meta.json`` beside one unbundled
SOG v2 folder per unit), built on sog_kit's SOG encoder.

It lays files out as splat-transform's ``write-lod.ts`` does (3.2.0 to 3.7.0), but the test
chooses the leaves and the gaussians in them:

- ``leaves[k][l]`` is leaf k's gaussians at level l (None or empty: no entry for that level);
- the leaves are visited in order, and each leaf's levels in ascending order; a leaf's range
  of level l is appended to that level's current file, ``{l}_{i}/meta.json``, and the next
  range of level l goes to a new file once the file holds more than ``file_bin`` gaussians;
- ``filenames`` lists each file when a range is first put in it (so a leaf lacking level 0
  makes ``filenames[0]`` another level's file, as in real files);
- a leaf's bound is the AABB of the ellipsoids (half extents exp(log scale), rotated: |R| s)
  of all its gaussians, every level together; an interior node's is its children's union;
  numbers are written with 7 significant digits, as splat-transform writes them.

Unlike splat-transform, the kit keeps each range in the order given (splat-transform
Morton-sorts each leaf's range), so a test knows which gaussian each row holds.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sog_kit import encode_sog, write_folder
from testkit import unit_quaternions

from raygs_viewer.camera.rotation import quaternion_to_matrix

Row = tuple[int, int, int]  # (file index into filenames, offset in that file, count)


@dataclass
class Gaussians:
    """Raw INRIA-style values of n gaussians."""

    positions: np.ndarray   # (n, 3)
    log_scales: np.ndarray  # (n, 3)
    rotations: np.ndarray   # (n, 4) w, x, y, z, any norm
    opacities: np.ndarray   # (n,) in [0, 1]
    f_dc: np.ndarray        # (n, 3)
    f_rest: np.ndarray | None = None  # (n, K, 3), K = 3, 8 or 15

    def __len__(self) -> int:
        return len(self.positions)

    def raw(self) -> tuple:
        """The arguments of sog_kit.encode_sog (and of its quantisation checks)."""
        return (self.positions, self.log_scales, self.rotations, self.opacities, self.f_dc, self.f_rest)

    @staticmethod
    def concat(parts: list[Gaussians]) -> Gaussians:
        rests = [p.f_rest for p in parts]
        if any(r is None for r in rests) and not all(r is None for r in rests):
            raise ValueError("gaussians with and without SH rest cannot share a file")
        arrays = [np.concatenate([getattr(p, name) for p in parts]) for name in
                  ("positions", "log_scales", "rotations", "opacities", "f_dc")]
        return Gaussians(*arrays, None if rests[0] is None else np.concatenate(rests))


@dataclass
class Layout:
    """Where a scene's gaussians go: ``filenames`` (as in lod-meta.json), ``files`` (each
    file's gaussians, aligned with filenames) and ``rows`` (per leaf, level -> Row)."""

    filenames: list[str]
    files: list[Gaussians]
    rows: list[dict[int, Row]]


def random_gaussians(n, centre=(0.0, 0.0, 0.0), spread=1.0, scale=0.05, seed=0, sh_degree=0) -> Gaussians:
    """n gaussians around ``centre`` (normal, standard deviation ``spread``), sizes within a
    factor e^0.5 of ``scale``, random rotations and colours, SH rest up to ``sh_degree``."""
    rng = np.random.default_rng(seed)
    k = (sh_degree + 1) ** 2 - 1
    return Gaussians(
        positions=np.asarray(centre, np.float64) + rng.normal(scale=spread, size=(n, 3)),
        log_scales=math.log(scale) + rng.uniform(-0.5, 0.5, (n, 3)),
        rotations=unit_quaternions(rng, n).astype(np.float64),
        opacities=rng.uniform(0.05, 1.0, n),
        f_dc=rng.normal(scale=0.5, size=(n, 3)),
        f_rest=rng.normal(scale=0.1, size=(n, k, 3)) if k else None,
    )


def _present(entry: Gaussians | None) -> bool:
    return entry is not None and len(entry) > 0


def lay_out(leaves: list[list[Gaussians | None]], file_bin: int = 1 << 30) -> Layout:
    """The files and rows of a scene, as splat-transform's writer lays them out."""
    filenames: list[str] = []
    files: list[list[Gaussians]] = []
    rows: list[dict[int, Row]] = []
    current: dict[int, tuple[int, int]] = {}  # level -> (its file number i, gaussians in it)
    for levels in leaves:
        leaf_rows = {}
        for level, entry in enumerate(levels):
            if not _present(entry):
                continue
            number, size = current.get(level, (0, 0))
            name = f"{level}_{number}/meta.json"
            if name not in filenames:
                filenames.append(name)
                files.append([])
            index = filenames.index(name)
            files[index].append(entry)
            leaf_rows[level] = (index, size, len(entry))
            current[level] = (number + 1, 0) if size + len(entry) > file_bin else (number, size + len(entry))
        rows.append(leaf_rows)
    return Layout(filenames, [Gaussians.concat(parts) for parts in files], rows)


def expected_rows(leaves, file_bin: int = 1 << 30) -> list[dict[int, Row]]:
    """Per leaf, level -> (file index, offset, count) of the scene write_streamed_sog writes."""
    return lay_out(leaves, file_bin).rows


def level_gaussians(leaves, level: int, file_bin: int = 1 << 30) -> Gaussians | None:
    """Level ``level`` as splat-transform's ``--select-lod`` decodes it: the level's files
    whole, by file index (None if no leaf has that level)."""
    layout = lay_out(leaves, file_bin)
    parts = [g for name, g in zip(layout.filenames, layout.files) if name.startswith(f"{level}_")]
    return Gaussians.concat(parts) if parts else None


def ellipsoid_boxes(g: Gaussians) -> tuple[np.ndarray, np.ndarray]:
    """Each gaussian's ellipsoid AABB (half extents |R| exp(log scale)): (mins, maxs), (n, 3)."""
    q = np.asarray(g.rotations, np.float64)
    half = np.abs(quaternion_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))) @ \
        np.exp(np.asarray(g.log_scales, np.float64))[:, :, None]
    centres = np.asarray(g.positions, np.float64)
    return centres - half[:, :, 0], centres + half[:, :, 0]


def leaf_bound(levels: list[Gaussians | None]) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) over the ellipsoid boxes of every level of a leaf (+inf, -inf if empty)."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for entry in filter(_present, levels):
        mins, maxs = ellipsoid_boxes(entry)
        lo, hi = np.minimum(lo, mins.min(axis=0)), np.maximum(hi, maxs.max(axis=0))
    return lo, hi


def _json_number(value: float):
    """As splat-transform's replacer and JSON.stringify write it: 7 significant digits,
    null for a non-finite number."""
    return float(f"{value:.7g}") if math.isfinite(value) else None


def _bound_json(lo, hi) -> dict:
    return {"min": [_json_number(v) for v in lo], "max": [_json_number(v) for v in hi]}


def leaf_nodes(leaves, layout: Layout) -> list[tuple[dict, np.ndarray, np.ndarray]]:
    """Each leaf's node (bound and lods) with its unrounded (min, max)."""
    nodes = []
    for levels, rows in zip(leaves, layout.rows):
        lo, hi = leaf_bound(levels)
        lods = {str(level): {"file": f, "offset": o, "count": c} for level, (f, o, c) in sorted(rows.items())}
        nodes.append(({"bound": _bound_json(lo, hi), "lods": lods}, lo, hi))
    return nodes


def build_tree(nodes, shape: str = "balanced") -> tuple[dict, np.ndarray, np.ndarray]:
    """A binary tree over the leaf nodes, in order: "balanced" halves them, "chain" makes
    each interior node's first child a leaf (a tree as deep as it has leaves). One leaf is
    the root itself."""
    if len(nodes) == 1:
        return nodes[0]
    split = 1 if shape == "chain" else (len(nodes) + 1) // 2
    children = [build_tree(nodes[:split], shape), build_tree(nodes[split:], shape)]
    lo = np.minimum(children[0][1], children[1][1])
    hi = np.maximum(children[0][2], children[1][2])
    return {"bound": _bound_json(lo, hi), "children": [c[0] for c in children]}, lo, hi


def lod_meta(leaves, layout: Layout, *, environment: bool, versioned: bool, tree: str) -> dict:
    """lod-meta.json's content, keys in splat-transform's order. Unversioned, as written
    before version 1: no version, asset, count or counts, and environment null if absent."""
    counts = [0] * (1 + max((level for rows in layout.rows for level in rows), default=-1))
    for rows in layout.rows:
        for level, (_, _, count) in rows.items():
            counts[level] += count
    root = build_tree(leaf_nodes(leaves, layout), tree)[0]
    if not versioned:
        return {"lodLevels": len(counts), "environment": "env/meta.json" if environment else None,
                "filenames": layout.filenames, "tree": root}
    meta = {"version": 1, "asset": {"generator": "raygs-viewer tests (lod_kit)"}, "count": sum(counts),
            "counts": counts, "lodLevels": len(counts)}
    if environment:
        meta["environment"] = "env/meta.json"
    return meta | {"filenames": layout.filenames, "tree": root}


def write_streamed_sog(folder, leaves: list[list[Gaussians | None]], *, environment: Gaussians | None = None,
                       file_bin: int = 1 << 30, versioned: bool = True, tree: str = "balanced") -> Path:
    """Writes the scene under ``folder`` (made if absent); returns its lod-meta.json."""
    if not leaves:
        raise ValueError("a streamed SOG needs at least one leaf")
    folder = Path(folder)
    layout = lay_out(leaves, file_bin)
    for name, gaussians in zip(layout.filenames, layout.files):
        meta, images, _ = encode_sog(*gaussians.raw())
        write_folder(folder / Path(name).parent, meta, images)
    if environment is not None:
        meta, images, _ = encode_sog(*environment.raw())
        write_folder(folder / "env", meta, images)
    content = lod_meta(leaves, layout, environment=environment is not None, versioned=versioned, tree=tree)
    path = folder / "lod-meta.json"
    path.write_text(json.dumps(content, separators=(",", ":")))
    return path
