"""Streamed SOG (scene/lod_meta.py, scene/lod_file.py): scenes written by the test-side
encoder (tests/lod_kit.py: several leaves, levels, files per level and an environment)
and one written by splat-transform itself (tests/fixtures/lod-small), read into a
LodScene whose every leaf's rows hold that leaf's gaussians; and hostile indexes, each
refused in one line."""

from __future__ import annotations

import json
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from lod_kit import Gaussians, expected_rows, random_gaussians, write_streamed_sog
from testkit import assert_user_error, run_cli

from raygs_viewer.errors import UserError
from raygs_viewer.scene.content_hash import file_sha256
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.lod_file import load_level, load_lod, lod_index_file, merged_spans, span_rows
from raygs_viewer.scene.source import SceneSource

FIXTURE = Path(__file__).resolve().parents[1] / "fixtures" / "lod-small"

# Half a 16-bit step of the SOG's log-space positions, for scenes a few units across.
POSITION_TOLERANCE = 2e-3


def leaves_of(levels=3, leaves=4, per_leaf=24, seed=0, degree=0) -> list[list[Gaussians | None]]:
    """``leaves`` leaves along x, 3 units apart; leaf k's level l holds per_leaf / 2^l gaussians."""
    return [[random_gaussians(max(1, per_leaf >> level), centre=(3.0 * k, 0.0, 5.0), spread=0.5,
                              scale=0.05 * 2 ** level, seed=seed + 10 * k + level, sh_degree=degree)
             for level in range(levels)] for k in range(leaves)]


@pytest.fixture
def streamed(tmp_path):
    leaves = leaves_of()
    environment = random_gaussians(6, spread=40.0, scale=1.0, seed=99)
    path = write_streamed_sog(tmp_path / "scene", leaves, environment=environment, file_bin=40)
    return path, leaves, environment


def assert_rows_hold(lod, leaves, environment=None):
    """Every leaf's rows in lod.scene hold its level's gaussians (positions, in order)."""
    for k, per_level in enumerate(leaves):
        for level, gaussians in enumerate(per_level):
            start, count = lod.rows[k, level]
            if not lod.loaded[level] or gaussians is None:
                assert count == 0
                continue
            assert count == len(gaussians)
            np.testing.assert_allclose(lod.scene.positions[start:start + count], gaussians.positions,
                                       atol=POSITION_TOLERANCE)
    if environment is not None:
        start, count = lod.environment
        np.testing.assert_allclose(lod.scene.positions[start:start + count], environment.positions,
                                   atol=0.2)  # 40 units across: half a log-space step is larger


def test_every_leaf_and_level_reads_back_into_its_rows(streamed):
    path, leaves, environment = streamed
    lod = load_lod(path)
    assert lod.levels == 3 and lod.index.leaves == 4 and lod.loaded.all()
    assert len(lod.index.files) > 3  # file_bin made several files for the finer levels
    assert lod.scene.count == sum(len(g) for leaf in leaves for g in leaf) + len(environment)
    assert lod.environment == (0, len(environment))
    assert_rows_hold(lod, leaves, environment)
    rows = expected_rows(leaves, 40)
    for k in range(4):
        for level, (file, offset, count) in rows[k].items():
            assert tuple(lod.index.ranges[k, level]) == (file, offset, count)


def test_the_folder_and_the_index_open_alike_and_levels_come_coarsest_first(streamed):
    path, leaves, _ = streamed
    assert lod_index_file(path.parent) == str(path)
    seen = []
    lod = load_lod(path.parent, on_level=lambda partial: seen.append(partial.loaded.copy()))
    assert [list(s) for s in seen] == [[False, False, True], [False, True, True], [True, True, True]]
    assert lod.scene.count == load_lod(path).scene.count


def test_a_level_alone_is_that_level_and_the_environment(streamed):
    path, leaves, environment = streamed
    for level in range(3):
        scene = load_scene(path, lod=level)
        expected = np.concatenate([environment.positions] + [leaf[level].positions for leaf in leaves])
        # The environment spans 40 units: compare it loosely, the leaves tightly.
        np.testing.assert_allclose(scene.positions[6:], expected[6:], atol=POSITION_TOLERANCE)
        assert scene.count == len(expected) and f"level {level} of 0..2" in scene.format
    assert load_scene(path).count == load_scene(path, lod=0).count  # the finest by default


def test_pre_versioning_files_and_leaves_without_some_levels(tmp_path):
    leaves = leaves_of(levels=2, leaves=3)
    leaves[1][1] = None  # a leaf with nothing at the coarse level
    path = write_streamed_sog(tmp_path / "old", leaves, versioned=False, tree="chain")
    raw = json.loads(path.read_text())
    assert "version" not in raw and "counts" not in raw
    lod = load_lod(path)
    assert lod.rows[1, 1, 1] == 0 and lod.environment == (0, 0)
    assert_rows_hold(lod, leaves)


def test_splat_transforms_own_streamed_sog_decodes_as_it_decodes_it():
    """tests/fixtures/lod-small: written and decoded (--select-lod) by splat-transform 3.7.0."""
    scene_path = FIXTURE / "scene" / "lod-meta.json"
    environment = load_scene(FIXTURE / "decoded" / "env.ply")
    for level in range(3):
        ours = load_scene(scene_path, lod=level)
        theirs = load_scene(FIXTURE / "decoded" / f"level-{level}.ply")
        e = environment.count
        np.testing.assert_array_equal(ours.positions[:e], environment.positions)
        np.testing.assert_array_equal(ours.positions[e:], theirs.positions)
        np.testing.assert_array_equal(ours.scales[e:], theirs.scales)
        np.testing.assert_allclose(ours.opacities[e:], theirs.opacities, atol=1e-7)
        np.testing.assert_allclose(ours.sh[e:], theirs.sh, atol=1e-7)
        dots = np.abs(np.sum(ours.rotations[e:] * theirs.rotations, axis=1))
        assert dots.min() > 1 - 1e-6


def test_a_dropped_gaussian_shrinks_its_leafs_range(tmp_path):
    leaves = leaves_of(levels=2, leaves=3, per_leaf=8)
    leaves[1][0].log_scales[2] = 1.0  # alone at the top of the unit's scale codebook ...
    path = write_streamed_sog(tmp_path / "s", leaves)
    unit = path.parent / "0_0" / "meta.json"
    meta = json.loads(unit.read_text())
    meta["scales"]["codebook"][255] = None  # ... which decodes as NaN: the reader drops it, the rows after it shift
    unit.write_text(json.dumps(meta))
    lod = load_lod(path)
    assert lod.scene.dropped == {"nan": 1}
    assert lod.rows[1, 0, 1] == 7
    keep = np.ones(8, bool)
    keep[2] = False
    np.testing.assert_allclose(lod.scene.positions[lod.rows[1, 0, 0]:][:7], leaves[1][0].positions[keep], atol=2e-3)
    np.testing.assert_allclose(lod.scene.positions[lod.rows[2, 0, 0]:][:8], leaves[2][0].positions, atol=2e-3)


def test_levels_that_do_not_fit_are_left_unread_and_said(streamed):
    path, leaves, _ = streamed
    counts = []

    def fits(count, degree):
        counts.append(count)
        return count < 100

    lod = load_lod(path, fits=fits)
    assert list(lod.loaded) == [False, True, True]
    assert lod.unread == "level 0 not read: with level 0 the scene (174 gaussians) would not fit the GPU's memory"
    assert_rows_hold(lod, leaves)
    assert counts == [6 + 4 * 6 + 4 * 12, 6 + 4 * 6 + 4 * 12 + 4 * 24]  # asked before each finer level: 78, 174


def test_progress_rises_and_cancel_stops(streamed):
    path, _, _ = streamed
    fractions = []
    load_lod(path, progress=lambda f, stage: fractions.append(f), chunk_bytes=64)
    assert fractions == sorted(fractions) and fractions[-1] == 1.0 and len(fractions) > 10
    cancel = threading.Event()
    cancel.set()
    with pytest.raises(UserError, match="cancelled"):
        load_lod(path, cancel=cancel)


def test_the_hash_covers_every_unit(streamed):
    path, _, _ = streamed
    before = file_sha256(path)
    assert file_sha256(path.parent) == before
    image = next((path.parent / "1_0").glob("*.webp"))
    image.write_bytes(image.read_bytes() + b"\0")
    assert file_sha256(path) != before


def test_spans_are_merged_and_expanded():
    spans = np.array([[5, 8], [0, 2], [2, 4], [8, 8], [10, 12]])
    merged = merged_spans(spans)
    assert merged.tolist() == [[0, 4], [5, 8], [10, 12]]
    assert span_rows(merged).tolist() == [0, 1, 2, 3, 5, 6, 7, 10, 11]


# --------------------------------------------------------------------------- bad input


def edited(path: Path, change) -> Path:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))
    return path


def leaf(data, k=0):
    nodes = [data["tree"]]
    found = []
    while nodes:
        node = nodes.pop(0)
        if "lods" in node:
            found.append(node)
        nodes.extend(node.get("children", []))
    return found[k]


@pytest.mark.parametrize("change,fragment", [
    (lambda d: d.update(version=2), "streamed SOG version 2 is not supported"),
    (lambda d: d.update(lodLevels=0), "'lodLevels' is 0"),
    (lambda d: d.update(lodLevels=1e9), "'lodLevels' is 1000000000"),
    (lambda d: d.update(filenames="0_0/meta.json"), "'filenames' must be a list"),
    (lambda d: d.update(tree=[]), "'tree' is missing or not a JSON object"),
    (lambda d: leaf(d).update(lods={"7": {"file": 0, "offset": 0, "count": 1}}), "level 7 is not one of 0..2"),
    (lambda d: leaf(d)["lods"]["0"].update(file=99), "file' is 99"),
    (lambda d: leaf(d)["lods"]["0"].update(offset=-1), "offset' is -1"),
    (lambda d: leaf(d)["lods"]["0"].update(count=1 << 40), "count' is 1099511627776"),
    (lambda d: leaf(d)["lods"]["0"].update(count="3"), "expected a whole number"),
    (lambda d: leaf(d).update(bound={"min": [0, 0, 0]}), "bound' must hold 'min' and 'max'"),
    (lambda d: leaf(d).update(bound={"min": [1, 0, 0], "max": [0, 1, 1]}), "min above its max"),
    (lambda d: leaf(d).pop("lods"), "has neither 'children' nor 'lods'"),
    (lambda d: d["counts"].__setitem__(0, 5), "'counts[0]' is 5 but the tree references"),
    (lambda d: d.update(count=3), "'count' is 3 but the tree references"),
    (lambda d: leaf(d, 1)["lods"]["0"].update(offset=leaf(d, 0)["lods"]["0"]["offset"]), "share rows"),
    (lambda d: leaf(d, 0)["lods"]["1"].update(file=leaf(d, 0)["lods"]["0"]["file"]), "holds levels"),
    (lambda d: d.update(tree=_deep(300)), "deeper than 256"),
])
def test_a_bad_index_is_one_line(tmp_path, change, fragment):
    path = write_streamed_sog(tmp_path / "s", leaves_of())
    edited(path, change)
    assert_user_error(lambda: load_lod(path), path, fragment)


def _deep(depth):
    node = {"bound": {"min": [0, 0, 0], "max": [1, 1, 1]}, "lods": {}}
    for _ in range(depth):
        node = {"children": [node]}
    return node


def test_units_outside_the_folder_missing_or_short_are_refused(tmp_path):
    path = write_streamed_sog(tmp_path / "s", leaves_of())
    original = path.read_text()
    edited(path, lambda d: d["filenames"].__setitem__(0, "../elsewhere/meta.json"))
    assert_user_error(lambda: load_lod(path), path, "outside the scene's folder")
    path.write_text(original)
    edited(path, lambda d: d["filenames"].__setitem__(0, "nowhere/meta.json"))
    assert_user_error(lambda: load_lod(path), "nowhere", "missing")
    path.write_text(original)

    def longer(d):  # one file a level: the last leaf's range is the file's last rows
        leaf(d, 3)["lods"]["0"]["count"] += 5
        d["counts"][0] += 5
        d["count"] += 5

    edited(path, longer)
    assert_user_error(lambda: load_lod(path), path, "0_0/meta.json", "references rows up to")


def test_a_missing_level_or_a_level_on_another_scene_is_one_line(tmp_path, capsys):
    path = write_streamed_sog(tmp_path / "s", leaves_of())
    assert_user_error(lambda: load_level(path, 3), path, "has levels 0..2; level 3 does not exist")
    code, _, err = run_cli(capsys, "info", tmp_path / "nothing-here" / "lod-meta.json")
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1


def test_a_scene_shown_before_its_hash_is_done_hashes_when_a_document_needs_it(streamed):
    path, _, _ = streamed
    loaded = load_now(SceneSource(path))
    assert loaded.sha256 == file_sha256(path)
    shown_early = replace(loaded, sha256="")  # as a level is handed on while the files are still hashed
    assert shown_early.content_sha256 == loaded.sha256
