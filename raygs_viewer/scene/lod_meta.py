"""PlayCanvas's streamed SOG index, ``lod-meta.json``: its schema, checked into a
:class:`LodIndex` whose every fault is one line naming the file and the field.

The format (playcanvas/splat-transform 3.x, ``writers/write-lod.ts`` and
``readers/read-lod.ts``; the PlayCanvas engine's ``gsplat-octree``)::

    {"version": 1, "count": N, "counts": [N0, N1, ...], "lodLevels": L,
     "environment": "env/meta.json",                      (optional)
     "filenames": ["0_0/meta.json", "1_0/meta.json", ...],
     "tree": {"bound": {"min": [3], "max": [3]}, "children": [node, ...]}}

A node with ``lods`` ({"0": {"file": f, "offset": o, "count": c}, ...}) is a unit of
the choice (a *leaf*): its gaussians of level l are rows ``o .. o + c`` of the SOG unit
``filenames[f]``; level 0 is the finest. Files written before splat-transform stamped
a version have no ``version``, ``count`` or ``counts``: those are read too (the counts
then come from the tree). Bounds are in the PLY's own axes, as the SOG units' gaussians.

The tree is walked without recursion and every number is bounded before anything is
allocated from it (levels, files, leaves, depth, rows per file), so a hostile index
fails in one line rather than exhausting memory or the stack.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raygs_viewer.errors import finite_number, is_number
from raygs_viewer.jsonfile import json_key, parse_json, show_json
from raygs_viewer.scene.reading import file_error
from raygs_viewer.scene.sog_meta import MAX_COUNT, whole_number

LOD_META_NAME = "lod-meta.json"
#: What an index may hold: far past any published scene (splat-transform's chunks hold
#: ~512 K gaussians, so 2^20 leaves is half a trillion gaussians), small enough that the
#: arrays made from them stay a few hundred MB at most.
MAX_LEVELS = 32
MAX_FILES = 1 << 16
MAX_LEAVES = 1 << 20
MAX_DEPTH = 256
MAX_INDEX_BYTES = 256 << 20
_SHOWN = 33


@dataclass(frozen=True)
class LodIndex:
    """What ``lod-meta.json`` says, checked.

    levels:      L, the number of levels (0 the finest).
    files:       the SOG units' meta.json names, relative to the index's folder.
    environment: the environment SOG's name (drawn at every level), or None.
    bounds:      (K, 2, 3) float64: each leaf's box, min then max.
    ranges:      (K, L, 3) int64: (file, offset, count) of each leaf's level; file -1 and
                 count 0 where the leaf has nothing at that level.
    """

    levels: int
    files: tuple[str, ...]
    environment: str | None
    bounds: np.ndarray
    ranges: np.ndarray

    @property
    def leaves(self) -> int:
        return int(self.bounds.shape[0])

    @property
    def counts(self) -> np.ndarray:
        """(L,) int64: the gaussians each level holds."""
        return self.ranges[:, :, 2].sum(axis=0)

    def files_of(self, level: int) -> list[int]:
        """The files level ``level`` references, in index order."""
        used = self.ranges[:, level, 0]
        return sorted(set(int(f) for f in used[used >= 0]))

    def rows_needed(self) -> np.ndarray:
        """(F,) int64: the rows each file must hold (the end of its furthest range)."""
        needed = np.zeros(len(self.files), np.int64)
        present = self.ranges[:, :, 0] >= 0
        files = self.ranges[:, :, 0][present]
        ends = (self.ranges[:, :, 1] + self.ranges[:, :, 2])[present]
        np.maximum.at(needed, files, ends)
        return needed


def parse_lod_meta(shown: str, raw: bytes) -> LodIndex:
    """The index in ``raw``, checked; ``shown`` names the file in messages."""
    meta = parse_json(raw, shown, constants=False)
    if not isinstance(meta, dict):
        raise file_error(shown, "not a streamed SOG lod-meta.json (expected a JSON object)")
    version = meta.get("version")
    if version is not None and not (is_number(version) and version == 1):
        raise file_error(shown, f"streamed SOG version {show_json(version, _SHOWN)} is not supported "
                                "(this reader reads version 1, and files without a version)")
    levels = whole_number(shown, "lodLevels", meta.get("lodLevels"), (1, MAX_LEVELS), "levels")
    files = _names(shown, meta.get("filenames"))
    environment = meta.get("environment")
    if environment is not None and not (isinstance(environment, str) and environment):
        raise file_error(shown, f"'environment' is {show_json(environment, _SHOWN)}, expected a file name")
    tree = meta.get("tree")
    if not isinstance(tree, dict):
        raise file_error(shown, "'tree' is missing or not a JSON object")
    bounds, ranges = _leaves(shown, tree, levels, len(files))
    index = LodIndex(levels, files, environment, bounds, ranges)
    _check_counts(shown, meta, index)
    _check_files(shown, index)
    return index


def _names(shown: str, value) -> tuple[str, ...]:
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise file_error(shown, "'filenames' must be a list of file names (the SOG units of a streamed SOG)")
    if len(value) > MAX_FILES:
        raise file_error(shown, f"'filenames' lists {len(value)} files: at most {MAX_FILES} are read")
    return tuple(value)


def _bound(shown: str, node: dict, where: str) -> list[list[float]]:
    bound = node.get("bound")
    corners = [bound.get(key) if isinstance(bound, dict) else None for key in ("min", "max")]
    if not all(isinstance(c, list) and len(c) == 3 and all(finite_number(v) is not None for v in c) for c in corners):
        raise file_error(shown, f"'{where}.bound' must hold 'min' and 'max', three finite numbers each")
    if any(lo > hi for lo, hi in zip(*corners)):
        raise file_error(shown, f"'{where}.bound' has a min above its max")
    return [[float(v) for v in c] for c in corners]


def _leaves(shown: str, tree: dict, levels: int, file_count: int) -> tuple[np.ndarray, np.ndarray]:
    """Every node with ``lods``, depth first in the file's order: its box and ranges."""
    bounds, ranges = [], []
    stack = [(tree, "tree", 0)]
    while stack:
        node, where, depth = stack.pop()
        if not isinstance(node, dict):
            raise file_error(shown, f"'{where}' must be a JSON object")
        if depth > MAX_DEPTH:
            raise file_error(shown, f"'tree' is nested deeper than {MAX_DEPTH} levels")
        children = node.get("children")
        lods = node.get("lods")
        if children is None and lods is None:
            raise file_error(shown, f"'{where}' has neither 'children' nor 'lods'")
        if lods is not None:
            if len(bounds) == MAX_LEAVES:
                raise file_error(shown, f"'tree' has more than {MAX_LEAVES} leaves")
            bounds.append(_bound(shown, node, where))
            ranges.append(_lods(shown, lods, f"{where}.lods", levels, file_count))
        if children is not None:
            if not isinstance(children, list):
                raise file_error(shown, f"'{where}.children' must be a list of nodes")
            # Reversed onto the stack: popped in the file's order.
            stack.extend((child, f"{where}.children[{i}]", depth + 1) for i, child in reversed(list(enumerate(children))))
    return (np.array(bounds, np.float64).reshape(-1, 2, 3),
            np.array(ranges, np.int64).reshape(-1, levels, 3))


def _lods(shown: str, lods, where: str, levels: int, file_count: int) -> list[list[int]]:
    if not isinstance(lods, dict):
        raise file_error(shown, f"'{where}' must be a JSON object of levels")
    row = [[-1, 0, 0] for _ in range(levels)]
    for key, entry in lods.items():
        name = f"{where}.{json_key(key)}"
        if not (key.isdigit() and int(key) < levels):
            raise file_error(shown, f"'{name}': level {json_key(key)!s} is not one of 0..{levels - 1} ('lodLevels')")
        if not isinstance(entry, dict):
            raise file_error(shown, f"'{name}' must hold 'file', 'offset' and 'count'")
        file = whole_number(shown, f"{name}.file", entry.get("file"), (0, max(file_count - 1, 0)),
                            "(an index into 'filenames')")
        if file_count == 0:
            raise file_error(shown, f"'{name}.file' names a file, but 'filenames' is empty")
        offset = whole_number(shown, f"{name}.offset", entry.get("offset"), (0, MAX_COUNT), "rows")
        count = whole_number(shown, f"{name}.count", entry.get("count"), (0, MAX_COUNT - offset),
                             "rows (with the offset)")
        row[int(key)] = [file, offset, count]
    return row


def _check_counts(shown: str, meta: dict, index: LodIndex) -> None:
    """``counts`` and ``count``, where given, must be what the tree references."""
    found = index.counts
    counts = meta.get("counts")
    if counts is not None:
        if (not isinstance(counts, list) or len(counts) != index.levels
                or not all(finite_number(c) is not None and c == int(c) and c >= 0 for c in counts)):
            raise file_error(shown, f"'counts' must list {index.levels} whole numbers (one a level)")
        for level, (said, got) in enumerate(zip(counts, found)):
            if int(said) != int(got):
                raise file_error(shown, f"'counts[{level}]' is {int(said)} but the tree references {int(got)} "
                                        f"gaussians of level {level}")
    count = meta.get("count")
    if count is not None and (finite_number(count) is None or int(count) != int(found.sum())):
        raise file_error(shown, f"'count' is {show_json(count, _SHOWN)} but the tree references "
                                f"{int(found.sum())} gaussians")


def _check_files(shown: str, index: LodIndex) -> None:
    """Each file belongs to one level, holds at most a SOG's count, and its ranges do not
    overlap (two leaves sharing rows would draw them twice)."""
    present = index.ranges[:, :, 0] >= 0
    leaf, level = np.nonzero(present)
    entries = index.ranges[leaf, level]
    if entries.size == 0:
        return
    by_file = np.lexsort((entries[:, 1], entries[:, 0]))
    files, offsets, counts = entries[by_file].T
    levels = level[by_file]
    same = files[1:] == files[:-1]
    mixed = same & (levels[1:] != levels[:-1])
    if mixed.any():
        at = int(np.argmax(mixed))
        raise file_error(shown, f"file {index.files[files[at]]!r} holds levels {levels[at]} and {levels[at + 1]}; "
                                "a SOG unit belongs to one level")
    overlap = same & (offsets[1:] < offsets[:-1] + counts[:-1])
    if overlap.any():
        at = int(np.argmax(overlap))
        raise file_error(shown, f"two leaves share rows {offsets[at + 1]}.. of file {index.files[files[at]]!r}")
    too_many = index.rows_needed() > MAX_COUNT
    if too_many.any():
        name = index.files[int(np.argmax(too_many))]
        raise file_error(shown, f"file {name!r} would need more than {MAX_COUNT} rows: refused")
