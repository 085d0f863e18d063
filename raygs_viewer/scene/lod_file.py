"""Reading a streamed SOG (``lod-meta.json`` and its SOG units) into a :class:`LodScene`:
the gaussians of the levels read, in one Scene, and where each leaf's level lies in it.

The index is :mod:`~raygs_viewer.scene.lod_meta`'s; each unit is an ordinary SOG read by
:mod:`~raygs_viewer.scene.sog_file` (its images named inside the unit's folder, which
must lie inside the index's folder). Levels are read coarsest first, so the first
picture comes from the fewest gaussians and a finer level only adds to what is there;
``fits`` stops before a level that would not fit (the GPU's memory: the scene layer
only counts gaussians, the caller knows what they cost).

Layout of ``LodScene.scene``: the environment's gaussians first, then each level read,
coarsest first, each level's units in index order, each unit's rows in file order
(less any row the SOG reader dropped as invalid: a leaf's range shrinks to the rows
kept). The choice of what to draw (``sort.lod_choice``) names rows of this scene as
ascending spans, so the draw keeps the file order wherever depths tie.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from raygs_viewer.scene.lod_meta import LOD_META_NAME, MAX_INDEX_BYTES, LodIndex, parse_lod_meta
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.progress import ProgressCallback, Reporter
from raygs_viewer.scene.reading import file_error
from raygs_viewer.scene.sog_file import read_sog
from raygs_viewer.scene.sog_file import scene_files as sog_scene_files
from raygs_viewer.scene.sog_meta import parse_meta
from raygs_viewer.scene.sog_source import Folder, open_source

LOD_FORMAT = "streamed SOG"
#: The bytes that say a .json is a streamed index rather than a SOG meta.json.
_INDEX_MARK = b'"lodLevels"'

#: ``fits(count, sh_degree) -> bool``: whether a scene of ``count`` gaussians fits where
#: it is going (the GPU); levels that would not are left unread.
Fits = Callable[[int, int], bool]


def lod_index_file(path) -> str | None:
    """The lod-meta.json that ``path`` names: a folder holding one, a file named
    lod-meta.json, or any other .json file that declares ``lodLevels``; None otherwise."""
    if os.path.isdir(path):
        candidate = os.path.join(path, LOD_META_NAME)
        return candidate if os.path.isfile(candidate) else None
    if not os.path.isfile(path):
        return None
    name = os.path.basename(os.fspath(path)).lower()
    if name == LOD_META_NAME:
        return os.fspath(path)
    if not name.endswith(".json"):
        return None
    with open(path, "rb") as f:
        return os.fspath(path) if _INDEX_MARK in f.read(1 << 16) else None


def read_index(path, shown: str) -> LodIndex:
    """The checked index of the streamed SOG at ``path`` (see :func:`lod_index_file`)."""
    index_file = lod_index_file(path)
    if index_file is None:
        raise file_error(shown, f"no {LOD_META_NAME} here (a streamed SOG keeps one beside its level folders)")
    size = os.path.getsize(index_file)
    if size > MAX_INDEX_BYTES:
        raise file_error(shown, f"{size} bytes: too big for a {LOD_META_NAME} (at most {MAX_INDEX_BYTES})")
    with open(index_file, "rb") as f:
        return parse_lod_meta(shown, f.read(MAX_INDEX_BYTES + 1))


@dataclass(frozen=True, eq=False)  # one reading of a scene is equal to itself alone
class LodScene:
    """A streamed SOG's gaussians, the levels read so far.

    scene:       the gaussians (layout: the module docstring).
    index:       the lod-meta.json, checked.
    rows:        (K, L, 2) int64: start and count in ``scene`` of leaf k's level l;
                 count 0 where the leaf has nothing there or the level was not read.
    loaded:      (L,) bool: the levels in ``scene``.
    environment: (start, count) of the environment's gaussians in ``scene``.
    unread:      why levels were left unread, one line (empty when all were read).
    """

    scene: Scene
    index: LodIndex
    rows: np.ndarray
    loaded: np.ndarray
    environment: tuple[int, int] = (0, 0)
    unread: str = ""

    @property
    def levels(self) -> int:
        return self.index.levels

    @property
    def finest_loaded(self) -> int | None:
        loaded = np.flatnonzero(self.loaded)
        return int(loaded[0]) if loaded.size else None

    @cached_property
    def leaf_scales(self) -> np.ndarray:
        """(K,) float64: the largest standard deviation among each leaf's gaussians read
        (0 for none): how far beyond its box (which holds one standard deviation) they reach."""
        largest = np.zeros(self.index.leaves)
        starts, counts = self.rows[:, :, 0].ravel(), self.rows[:, :, 1].ravel()
        present = np.flatnonzero(counts > 0)
        if present.size:
            row_max = np.append(self.scene.scales.max(axis=1), np.float32(0))  # a sentinel for a range at the end
            bounds = np.stack([starts[present], starts[present] + counts[present]], axis=1)
            order = np.argsort(bounds[:, 0])
            maxima = np.maximum.reduceat(row_max, bounds[order].ravel())[::2]
            np.maximum.at(largest, present[order] // self.levels, maxima)
        return largest

    def spans(self, levels: np.ndarray) -> np.ndarray:
        """(S, 2) int64 ascending, non-overlapping [start, stop) spans of ``scene``: the
        environment and leaf k's level ``levels[k]`` (-1: nothing), adjacent spans merged."""
        levels = np.asarray(levels, np.int64)
        chosen = levels >= 0
        picked = self.rows[np.flatnonzero(chosen), levels[chosen]]
        spans = [np.array([[self.environment[0], self.environment[0] + self.environment[1]]], np.int64),
                 np.stack([picked[:, 0], picked[:, 0] + picked[:, 1]], axis=1)]
        return merged_spans(np.concatenate(spans))

    def level_spans(self, level: int) -> np.ndarray:
        """The spans of every leaf at ``level``, and the environment."""
        return self.spans(np.full(self.index.leaves, level))

    def subset(self, spans: np.ndarray) -> Scene:
        """The gaussians of ``spans`` as a Scene of their own, in scene order."""
        return subset_scene(self.scene, spans, f"{self.scene.format}")


def merged_spans(spans: np.ndarray) -> np.ndarray:
    """``spans`` (S, 2) sorted by start, the empty ones dropped and touching ones joined."""
    spans = spans[spans[:, 1] > spans[:, 0]]
    if spans.shape[0] == 0:
        return np.zeros((0, 2), np.int64)
    spans = spans[np.argsort(spans[:, 0], kind="stable")]
    starts_new = np.ones(spans.shape[0], bool)
    starts_new[1:] = spans[1:, 0] > np.maximum.accumulate(spans[:-1, 1])
    groups = np.cumsum(starts_new) - 1
    stops = np.zeros(int(groups[-1]) + 1, np.int64)
    np.maximum.at(stops, groups, spans[:, 1])
    return np.stack([spans[starts_new, 0], stops], axis=1)


def span_rows(spans: np.ndarray) -> np.ndarray:
    """(M,) int64: every row of ``spans``, in order."""
    if spans.shape[0] == 0:
        return np.zeros(0, np.int64)
    lengths = spans[:, 1] - spans[:, 0]
    starts = np.repeat(spans[:, 0] - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths)
    return starts + np.arange(int(lengths.sum()))


def subset_scene(scene: Scene, spans: np.ndarray, format_: str) -> Scene:
    """The rows of ``spans`` of ``scene`` as a new Scene (source and drops kept)."""
    return scene.rows(span_rows(spans), format_)


def load_lod(path, *, levels: tuple[int, ...] | None = None, fits: Fits | None = None,
             progress: ProgressCallback | None = None, cancel: threading.Event | None = None,
             on_level: Callable[[LodScene], None] | None = None, chunk_bytes: int = 4 << 20) -> LodScene:
    """Read the streamed SOG at ``path`` (its lod-meta.json, or the folder holding it):
    the environment and ``levels`` (None: every level), coarsest first.

    ``fits``: levels are read only while the scene so far plus the next level fits; the
    rest are left unread and ``unread`` says so (the coarsest is read whatever it costs:
    without it there is no picture). ``on_level``: called with the scene so far after
    each level, from the loading thread (the window shows a level as soon as it is read).
    ``progress``/``cancel`` as :func:`~raygs_viewer.scene.io.load_scene`'s; UserError for
    anything unreadable, naming the file."""
    shown = os.fspath(path)
    report = Reporter(progress, cancel)
    report(0.0, "reading")
    index = read_index(path, shown)
    folder = Folder(lod_index_file(path), shown)
    wanted = tuple(range(index.levels)) if levels is None else tuple(sorted(set(levels)))
    for level in wanted:
        if not 0 <= level < index.levels:
            raise file_error(shown, f"has levels 0..{index.levels - 1}; level {level} does not exist")
    order = sorted(wanted, reverse=True)  # coarsest first
    needed = index.rows_needed()
    total_rows = max(1, int(needed[[f for level in order for f in index.files_of(level)]].sum()))
    reader = _UnitReader(folder, shown, report, chunk_bytes, total_rows)
    parts: list[Scene] = []
    starts: dict[int, int] = {}   # file -> its first row in the scene
    kept: dict[int, np.ndarray | None] = {}
    environment = (0, 0)
    if index.environment is not None:
        env = reader.read(index.environment, None)
        parts.append(env)
        environment = (0, env.count)
    loaded = np.zeros(index.levels, bool)
    unread = ""
    result = None
    for step, level in enumerate(order):
        files = index.files_of(level)
        count = sum(p.count for p in parts) + int(needed[files].sum())
        if step and fits is not None and not fits(count, _degree(parts)):
            skipped = sorted(order[step:])
            unread = (f"level{'s' if len(skipped) > 1 else ''} {', '.join(map(str, skipped))} not read: with "
                      f"level {order[step]} the scene ({count:,} gaussians) would not fit the GPU's memory")
            break
        for file in files:
            starts[file] = sum(p.count for p in parts)
            unit, kept[file] = reader.read(index.files[file], int(needed[file]))
            parts.append(unit)
        loaded[level] = True
        result = None  # one Scene of every part is made once, unless each level is handed on
        if on_level is not None:
            result = _assemble(parts, index, shown, starts=starts, kept=kept, loaded=loaded, environment=environment)
            on_level(result)
    if result is None:
        result = _assemble(parts, index, shown, starts=starts, kept=kept, loaded=loaded, environment=environment)
    report(1.0, "done")
    return replace(result, unread=unread) if unread else result


def _degree(parts: list[Scene]) -> int:
    return max((p.sh_degree for p in parts), default=0)


class _UnitReader:
    """Reads SOG units inside the index's folder, each a share of the whole progress."""

    def __init__(self, folder: Folder, shown: str, report: Reporter, chunk_bytes: int, total_rows: int):
        self.folder, self.shown, self.report = folder, shown, report
        self.chunk_bytes, self.total_rows = chunk_bytes, total_rows

    def read(self, name: str, needed: int | None):
        """The unit ``name``'s scene; with ``needed`` (rows the index references), also
        the mask of the rows it dropped, after checking it holds them."""
        target = self.folder.resolve(name)
        unit_shown = f"{self.shown}: {name}"
        if not os.path.exists(target):
            raise file_error(unit_shown, f"missing ({LOD_META_NAME} names it)")
        share = (needed or 0) / self.total_rows
        begin = self.report.last

        def scaled(fraction: float, stage: str) -> None:
            self.report(begin + share * fraction, stage)

        scene, dropped = read_sog(target, unit_shown, Reporter(scaled, self.report.cancel), self.chunk_bytes)
        if needed is None:
            return scene
        rows = scene.count if dropped is None else dropped.size
        if rows < needed:
            raise file_error(unit_shown, f"holds {rows} gaussians but {LOD_META_NAME} references rows up to {needed}")
        return scene, dropped


def _assemble(parts: list[Scene], index: LodIndex, shown: str, *, starts: dict[int, int],
              kept: dict[int, np.ndarray | None], loaded: np.ndarray, environment: tuple[int, int]) -> LodScene:
    """The LodScene of the units read so far: one Scene, and each leaf's rows in it.
    ``starts``: each file's first row in the scene; ``kept``: each file's mask of the
    rows its unit dropped (None: none); ``loaded``: (levels,) bool, the levels read;
    ``environment``: the environment's rows (first, count)."""
    rows = np.zeros((index.leaves, index.levels, 2), np.int64)
    for level in np.flatnonzero(loaded):
        files, offsets, counts = index.ranges[:, level].T
        for file in set(files[files >= 0].tolist()):
            at = files == file
            begin, end = offsets[at], offsets[at] + counts[at]
            dropped = kept[file]
            if dropped is not None:  # the kept rows before each offset: the range shrinks to what was kept
                before = np.concatenate([[0], np.cumsum(~dropped)])
                begin, end = before[begin], before[end]
            rows[at, level, 0] = starts[file] + begin
            rows[at, level, 1] = end - begin
    return LodScene(_concatenate(parts, shown), index, rows, loaded.copy(), environment)


def _concatenate(parts: list[Scene], shown: str) -> Scene:
    """One Scene of ``parts`` in order, at the highest SH degree among them (the others'
    higher bands zero)."""
    degree = _degree(parts)
    coeffs = sh_coefficient_count(degree)
    count = sum(p.count for p in parts)
    sh = np.zeros((count, coeffs, 3), np.float32)
    at = 0
    for part in parts:
        sh[at: at + part.count, : part.sh.shape[1]] = part.sh
        at += part.count

    def joined(name: str, shape: tuple[int, ...]) -> np.ndarray:
        arrays = [getattr(p, name) for p in parts]
        return np.concatenate(arrays) if arrays else np.zeros((0, *shape), np.float32)

    dropped: dict[str, int] = {}
    for part in parts:
        for reason, number in part.dropped.items():
            dropped[reason] = dropped.get(reason, 0) + number
    return Scene(joined("positions", (3,)), joined("rotations", (4,)), joined("scales", (3,)),
                 joined("opacities", ()), sh, degree, False, shown, dropped, LOD_FORMAT)


def lod_scene_files(path) -> list[str] | None:
    """Every file a streamed SOG's content is, when ``path`` names one: its
    lod-meta.json, then each unit's files (the environment's first, then in index
    order; see ``sog_file.scene_files``); None for any other path."""
    index_file = lod_index_file(path)
    if index_file is None:
        return None
    shown = os.fspath(path)
    index = read_index(path, shown)
    folder = Folder(index_file, shown)
    files = [index_file]
    for name in ([index.environment] if index.environment else []) + list(index.files):
        unit = folder.resolve(name)
        files.extend(sog_scene_files(unit) or [unit])
    return files


def load_level(path, level: int, *, progress: ProgressCallback | None = None,
               cancel: threading.Event | None = None, chunk_bytes: int = 4 << 20) -> Scene:
    """One level of the streamed SOG at ``path`` (0 the finest) and its environment, as
    a Scene of their own: what ``--lod N`` renders and ``convert --lod N`` writes."""
    return level_scene(load_lod(path, levels=(level,), progress=progress, cancel=cancel, chunk_bytes=chunk_bytes),
                       level)


def level_scene(lod: LodScene, level: int) -> Scene:
    """Level ``level`` of ``lod`` (read) and its environment, as a Scene of their own:
    the environment's gaussians first, then the level's in file order."""
    environment = lod.environment[1]
    with_environment = f" with its environment ({environment:,})" if environment else ""
    return subset_scene(lod.scene, lod.level_spans(level),
                        f"{LOD_FORMAT}, level {level} of 0..{lod.levels - 1}{with_environment}")


def lod_summary(path) -> dict | None:
    """What ``info`` lists of a streamed SOG, without decoding it: levels, the gaussians
    of each, leaves, files and the environment's count (JSON-serialisable); None for any
    other path."""
    if lod_index_file(path) is None:
        return None
    shown = os.fspath(path)
    index = read_index(path, shown)
    environment = None
    if index.environment is not None:
        target = Folder(lod_index_file(path), shown).resolve(index.environment)
        with open_source(target, f"{shown}: {index.environment}") as source:
            environment = parse_meta(source.shown_meta, source.read_meta()).count
    return {"levels": index.levels, "counts": [int(c) for c in index.counts], "leaves": index.leaves,
            "files": len(index.files), "environment": environment}
