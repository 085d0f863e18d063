"""The streamed SOG kit (tests/lod_kit.py) against the format: the kit's lod-meta.json and
the one splat-transform 3.7.0 wrote (tests/fixtures/lod-small) pass the same checks."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from lod_kit import (Gaussians, ellipsoid_boxes, expected_rows, leaf_bound, level_gaussians, random_gaussians,
                     write_streamed_sog)

from raygs_viewer.scene.io import load_scene

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "lod-small"
ROUNDING = 1e-6  # bounds are written with 7 significant digits


def walk(node, depth=0):
    """(node, depth) of every node, depth first, children in order."""
    yield node, depth
    for child in node.get("children", []):
        yield from walk(child, depth + 1)


def leaves_of(meta) -> list[dict]:
    return [node for node, _ in walk(meta["tree"]) if "lods" in node]


def unit_count(lod_meta_path: Path, name: str) -> int:
    return json.loads((lod_meta_path.parent / name).read_text())["count"]


def assert_follows_the_format(path: Path):
    """lod-meta.json's structure: every range within its file, the ranges of a file tiling it
    in leaf order, counts adding up, each node's bound the union of its children's."""
    meta = json.loads(path.read_text())
    levels = meta["lodLevels"]
    ranges = {i: [] for i in range(len(meta["filenames"]))}
    per_level = [0] * levels
    for leaf in leaves_of(meta):
        assert {"bound", "lods"} <= set(leaf) <= {"bound", "lods", "errors"} and leaf["lods"]
        for key, ref in leaf["lods"].items():
            level = int(key)
            assert 0 <= level < levels and set(ref) == {"file", "offset", "count"}
            assert meta["filenames"][ref["file"]].startswith(f"{level}_"), (key, ref)
            ranges[ref["file"]].append((ref["offset"], ref["count"]))
            per_level[level] += ref["count"]
    for index, name in enumerate(meta["filenames"]):
        assert re.fullmatch(r"\d+_\d+/meta\.json", name), name
        offsets = [offset for offset, _ in ranges[index]]
        assert offsets == sorted(offsets), name  # leaves fill a file in visiting order
        ends = np.cumsum([0] + [count for _, count in ranges[index]])
        assert offsets == list(ends[:-1]) and ends[-1] == unit_count(path, name), name
    if "version" in meta:
        assert meta["version"] == 1 and meta["counts"] == per_level and meta["count"] == sum(per_level)
    for node, _ in walk(meta["tree"]):
        if "children" in node:
            assert set(node) == {"bound", "children"} and len(node["children"]) == 2
            for side, pick in (("min", np.minimum), ("max", np.maximum)):
                union = pick(*[np.array(child["bound"][side]) for child in node["children"]])
                assert np.allclose(node["bound"][side], union, rtol=ROUNDING, atol=0)
    environment = meta.get("environment")
    if environment is not None:
        assert environment == "env/meta.json" and (path.parent / environment).is_file()
    return meta


def assert_inside(points, bound):
    lo, hi = np.array(bound["min"]), np.array(bound["max"])
    slack = ROUNDING * np.maximum(np.abs(lo), np.abs(hi))
    assert np.all(points >= lo - slack) and np.all(points <= hi + slack)


def small_scene(seed=0, sh_degree=0):
    """Three leaves along x; the middle one lacks level 0, the first lacks level 2."""
    def g(n, x, s):
        return random_gaussians(n, centre=(x, 0.0, 0.0), spread=0.3, scale=0.02, seed=seed * 100 + s,
                                sh_degree=sh_degree)
    return [[g(40, 0.0, 1), g(12, 0.0, 2), None],
            [None, g(9, 2.0, 3), g(4, 2.0, 4)],
            [g(30, 4.0, 5), g(10, 4.0, 6), g(3, 4.0, 7)]]


# --- the kit --------------------------------------------------------------------------------


@pytest.mark.parametrize("file_bin", [1 << 30, 25, 0])
@pytest.mark.parametrize("tree", ["balanced", "chain"])
def test_the_kits_scene_follows_the_format(tmp_path, file_bin, tree):
    leaves = small_scene(sh_degree=1)
    path = write_streamed_sog(tmp_path, leaves, environment=random_gaussians(5, spread=30.0), file_bin=file_bin,
                              tree=tree)
    meta = assert_follows_the_format(path)
    assert meta["lodLevels"] == 3 and meta["counts"] == [70, 31, 7] and meta["environment"] == "env/meta.json"
    assert list(meta) == ["version", "asset", "count", "counts", "lodLevels", "environment", "filenames", "tree"]
    found = [{int(level): (r["file"], r["offset"], r["count"]) for level, r in leaf["lods"].items()}
             for leaf in leaves_of(meta)]
    assert found == expected_rows(leaves, file_bin)
    assert ("lods" in meta["tree"]["children"][0]) == (tree == "chain")  # balanced: [[0, 1], 2]
    for leaf, levels in zip(leaves_of(meta), leaves):
        for entry in filter(lambda e: e is not None, levels):
            assert_inside(entry.positions, leaf["bound"])
            for corners in ellipsoid_boxes(entry):
                assert_inside(corners, leaf["bound"])
    everything = np.concatenate([e.positions for levels in leaves for e in levels if e is not None])
    assert_inside(everything, meta["tree"]["bound"])


def test_files_split_after_the_bin_and_each_level_decodes_in_file_order(tmp_path):
    leaves = small_scene()
    path = write_streamed_sog(tmp_path, leaves, file_bin=25)
    meta = json.loads(path.read_text())
    # Leaf 0 fills 0_0 past 25, so leaf 2's level 0 starts 0_1; level 1's 12 + 9 + 10 stay in
    # 1_0 (a file takes ranges until it holds more than the bin).
    assert meta["filenames"] == ["0_0/meta.json", "1_0/meta.json", "2_0/meta.json", "0_1/meta.json"]
    assert meta["tree"]["children"][1]["lods"]["1"] == {"file": 1, "offset": 21, "count": 10}
    level1 = level_gaussians(leaves, 1, file_bin=25)
    assert np.array_equal(level1.positions, np.concatenate([leaves[k][1].positions for k in range(3)]))
    for level in range(3):
        names = [name for name in meta["filenames"] if name.startswith(f"{level}_")]
        decoded = np.concatenate([load_scene(path.parent / name).positions for name in names])
        assert np.allclose(decoded, level_gaussians(leaves, level, file_bin=25).positions, atol=1e-3)
    assert level_gaussians([[None, leaves[1][1]]], 0) is None


def test_a_first_leaf_without_level_0_names_another_level_first(tmp_path):
    leaves = small_scene()[1:]
    meta = json.loads(write_streamed_sog(tmp_path, leaves).read_text())
    assert meta["filenames"] == ["1_0/meta.json", "2_0/meta.json", "0_0/meta.json"]
    assert meta["tree"]["children"][0]["lods"]["1"] == {"file": 0, "offset": 0, "count": 9}


def test_an_unversioned_scene_has_the_old_keys(tmp_path):
    meta = json.loads(write_streamed_sog(tmp_path, small_scene()[:1], versioned=False).read_text())
    assert list(meta) == ["lodLevels", "environment", "filenames", "tree"]
    assert meta["environment"] is None and meta["lodLevels"] == 2
    assert "lods" in meta["tree"]  # a single leaf is the root itself
    assert_follows_the_format(tmp_path / "lod-meta.json")


def test_a_bound_is_the_rotated_ellipsoids_box():
    g = Gaussians(positions=np.array([[1.0, 2.0, 3.0]]), log_scales=np.log([[2.0, 0.5, 0.1]]),
                  rotations=np.array([[np.cos(np.pi / 8), 0.0, 0.0, np.sin(np.pi / 8)]]) * 3,  # 45 deg about z
                  opacities=np.array([0.5]), f_dc=np.zeros((1, 3)))
    lo, hi = leaf_bound([g, None])
    half = np.array([(2.0 + 0.5) / np.sqrt(2), (2.0 + 0.5) / np.sqrt(2), 0.1])
    assert np.allclose(lo, [1, 2, 3] - half) and np.allclose(hi, [1, 2, 3] + half)


# --- splat-transform's own file -------------------------------------------------------------


def test_splat_transforms_scene_follows_the_same_format():
    path = FIXTURE / "scene" / "lod-meta.json"
    meta = assert_follows_the_format(path)
    assert meta["counts"] == [336, 168, 24] and meta["environment"] == "env/meta.json"
    assert [sorted(leaf["lods"]) for leaf in leaves_of(meta)] == [["0", "1", "2"], ["0", "1"], ["0", "1"], ["0", "1"]]
    for level in range(3):
        assert load_scene(FIXTURE / "decoded" / f"level-{level}.ply").count == meta["counts"][level]


def test_splat_transforms_bounds_are_the_kits_bounds_of_the_decoded_gaussians():
    """The kit's bound (ellipsoid boxes, all levels of a leaf) of the gaussians decoded from
    each leaf's ranges is splat-transform's, up to the SOG quantisation: chiefly the scale
    codebook's half step, at most 3 s (e^h - 1) on a box side. (From the PLYs the scene was
    made from, the kit's bounds are splat-transform's to all 7 digits written.)"""
    path = FIXTURE / "scene" / "lod-meta.json"
    meta = json.loads(path.read_text())
    units = {i: load_scene(path.parent / name) for i, name in enumerate(meta["filenames"])}
    books = [json.loads((path.parent / name).read_text())["scales"]["codebook"] for name in meta["filenames"]]
    half_step = max((max(book) - min(book)) / 510 for book in books)
    tolerance = 3 * max(unit.scales.max() for unit in units.values()) * np.expm1(half_step) + 1e-4
    for leaf in leaves_of(meta):
        levels = []
        for ref in leaf["lods"].values():
            unit, rows = units[ref["file"]], slice(ref["offset"], ref["offset"] + ref["count"])
            levels.append(Gaussians(unit.positions[rows], np.log(unit.scales[rows]), unit.rotations[rows],
                                    unit.opacities[rows], unit.sh[rows, 0]))
        lo, hi = leaf_bound(levels)
        assert np.allclose(lo, leaf["bound"]["min"], rtol=0, atol=tolerance)
        assert np.allclose(hi, leaf["bound"]["max"], rtol=0, atol=tolerance)
