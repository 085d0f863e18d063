"""The per-view choice of levels (sort/lod_choice.py) on scenes built so that the right
level of every leaf is known in advance, and the sort restricted to its spans
(sort/cull.py, sort/depth.py, sort/worker.py)."""

from __future__ import annotations

import numpy as np
import pytest
from lod_kit import random_gaussians, write_streamed_sog
from testkit import sort_indices

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.scene.lod_file import load_lod, span_rows
from raygs_viewer.sort.cull import span_chunks
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import REACH_SIGMAS, LodRequest, choose, level_distances, screen_radius
from raygs_viewer.sort.request import SortRequest
from raygs_viewer.sort.worker import BackgroundSorter

LEVELS = 3
PER_LEAF = (16, 8, 4)  # gaussians of each level in every leaf


def tiny_leaves(centres):
    """A leaf at each centre, its gaussians packed within 0.02 of it (its box's distance is
    its centre's to 0.02); every leaf's the same pattern, so their boxes are equal."""
    return [[random_gaussians(PER_LEAF[level], centre=c, spread=0.005, scale=0.001, seed=level)
             for level in range(LEVELS)] for c in centres]


def scene(tmp_path, centres, environment=0, **kwargs):
    env = random_gaussians(environment, spread=50.0, seed=3) if environment else None
    return load_lod(write_streamed_sog(tmp_path / "lod", tiny_leaves(centres), environment=env), **kwargs)


# The camera at the origin looking down +z; leaves straight ahead at these depths.
CAMERA = look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], width=64, height=48)


def test_each_leaf_takes_the_level_of_its_distance_band(tmp_path):
    # distance 1: level 1 from 1, level 2 from 2 (2^(l-1) D)
    depths = [0.5, 1.5, 2.5, 40.0]
    lod = scene(tmp_path, [(0.0, 0.0, d) for d in depths])
    assert level_distances(lod, 1.0).tolist() == [1.0, 2.0]
    choice = choose(lod, CAMERA, distance=1.0)
    assert choice.wanted.tolist() == [0, 1, 2, 2] and choice.levels.tolist() == [0, 1, 2, 2]
    assert choice.count == 16 + 8 + 4 + 4
    rows = span_rows(choice.spans)
    expected = np.concatenate([np.arange(s, s + n) for s, n in (lod.rows[k, lv] for k, lv in enumerate([0, 1, 2, 2]))])
    assert np.array_equal(np.sort(rows), np.sort(expected))
    # Twice the distance: every band twice as far.
    assert choose(lod, CAMERA, distance=2.0).levels.tolist() == [0, 0, 1, 2]


def test_a_fixed_level_everywhere(tmp_path):
    lod = scene(tmp_path, [(0.0, 0.0, d) for d in (0.5, 30.0)], environment=5)
    choice = choose(lod, CAMERA, level=1, budget=1)  # a fixed level takes no budget
    assert choice.levels.tolist() == [1, 1] and choice.count == 5 + 8 + 8


def test_a_leaf_waits_on_its_coarser_level_until_the_finer_one_is_read(tmp_path):
    centres = [(0.0, 0.0, 0.5), (0.0, 0.0, 1.5)]
    partial = scene(tmp_path, centres, levels=(1, 2))
    choice = choose(partial, CAMERA, distance=1.0)
    assert choice.wanted.tolist() == [0, 1] and choice.levels.tolist() == [1, 1]
    assert choose(partial, CAMERA, level=0).levels.tolist() == [1, 1]
    coarsest = load_lod(tmp_path / "lod" / "lod-meta.json", levels=(2,))
    assert choose(coarsest, CAMERA, distance=1.0).levels.tolist() == [2, 2]
    gap = load_lod(tmp_path / "lod" / "lod-meta.json", levels=(0, 2))  # level 1 unread between two read ones
    assert choose(gap, CAMERA, distance=1.0).levels.tolist() == [0, 2]  # coarser, never finer than asked


def test_under_a_budget_what_is_largest_on_screen_is_refined_first(tmp_path):
    # Every leaf wants level 0 (the distance is far beyond them); sizes on screen 1 : 1/3 : 1/9.
    lod = scene(tmp_path, [(0.0, 0.0, d) for d in (1.0, 3.0, 9.0)], environment=2)
    assert choose(lod, CAMERA, distance=100.0, budget=2 + 3 * 16).levels.tolist() == [0, 0, 0]
    # From the coarsest (2 + 3 * 4 = 14), a step to level 1 costs 4 and to level 0 costs 8;
    # their priorities s 2^l: leaf 0 to 1 (2), leaf 0 to 0 (1), leaf 1 to 1 (2/3), leaf 1 to 0
    # (1/3), leaf 2 to 1 (2/9), leaf 2 to 0 (1/9).
    for budget, expected in [(14, [2, 2, 2]), (18, [1, 2, 2]), (25, [1, 2, 2]), (26, [0, 2, 2]),
                             (30, [0, 1, 2]), (38, [0, 0, 2]), (42, [0, 0, 1]), (49, [0, 0, 1]),
                             (50, [0, 0, 0])]:
        choice = choose(lod, CAMERA, distance=100.0, budget=budget)
        assert choice.levels.tolist() == expected, budget
        assert choice.count <= budget and not choice.over_budget
    squeezed = choose(lod, CAMERA, distance=100.0, budget=5)
    assert squeezed.levels.tolist() == [2, 2, 2] and squeezed.over_budget and squeezed.count == 14


def test_leaves_out_of_view_stay_coarse_and_cost_nothing(tmp_path):
    lod = scene(tmp_path, [(0.0, 0.0, 1.0), (0.0, 0.0, -1.0), (30.0, 0.0, 1.0)])
    assert choose(lod, CAMERA, distance=100.0).levels.tolist() == [0, 2, 2]  # behind, and far to the side
    choice = choose(lod, CAMERA, distance=100.0, budget=16)
    assert choice.levels.tolist() == [0, 2, 2] and choice.count == 16 + 4 + 4  # the budget counts what is in view


def test_span_chunks_slice_long_spans_and_pack_short_ones():
    spans = np.array([[0, 5], [7, 8], [9, 10], [12, 13], [14, 15], [20, 37]])
    chunks = span_chunks(spans, 8)  # a quarter chunk: 2 rows
    assert chunks[0] == slice(0, 5) and chunks[-3:] == [slice(20, 28), slice(28, 36), slice(36, 37)]
    assert [c.tolist() for c in chunks[1:-3]] == [[7, 9, 12, 14]]
    assert span_chunks(np.array([[0, 1], [3, 4], [6, 7]]), 8)[0].tolist() == [0, 3, 6]
    assert span_chunks(np.array([[0, 1], [3, 4], [6, 7]]), 2)[:2] == [slice(0, 1), slice(3, 4)]  # a chunk's worth apart
    assert span_chunks(np.zeros((0, 2), np.int64), 4) == []


@pytest.mark.parametrize("workers,chunk_rows", [(1, 1 << 16), (3, 5), (2, 48)])  # whole; sliced; packed
@pytest.mark.parametrize("key", ["depth", "distance"])
def test_a_sort_of_spans_is_the_sort_of_their_rows_alone(tmp_path, workers, chunk_rows, key):
    lod = scene(tmp_path, [(x, 0.0, 2.0 + x) for x in (-1.0, 0.0, 1.0, 2.0)], environment=4)
    camera = look_at([0.5, 0.2, -1.0], [0.5, 0.0, 3.0], width=64, height=48)
    choice = choose(lod, camera, distance=2.5)
    rows = span_rows(choice.spans)
    sorter = DepthSorter(lod.scene, workers, chunk_rows=chunk_rows)
    alone = DepthSorter(lod.subset(choice.spans), 1)
    for _ in range(3):  # the distance key's turn cache answers the later ones
        order = sort_indices(sorter, camera, 0.01, key=key, levels=choice)
        assert np.array_equal(order, rows[sort_indices(alone, camera, 0.01, key=key)])
    everything = sort_indices(sorter, camera, 0.01, key=key)  # a later whole-scene sort is not filtered by the spans
    assert everything.size > order.size
    assert np.array_equal(everything, sort_indices(DepthSorter(lod.scene, 1), camera, 0.01, key=key))
    sorter.close()


def test_the_sort_thread_chooses_for_each_view(tmp_path):
    lod = scene(tmp_path, [(0.0, 0.0, d) for d in (0.5, 1.5, 2.5)])
    sorter = BackgroundSorter(DepthSorter(lod.scene, 1))
    try:
        request = LodRequest(lod, budget=None, distance=1.0)
        serial = sorter.request(SortRequest(CAMERA, 0.01, levels=request))
        # the same view and choice: not queued again
        assert sorter.request(SortRequest(CAMERA, 0.01, levels=request)) == serial
        result = sorter.wait(serial, timeout=30)
        assert result.choice.levels.tolist() == [0, 1, 2]
        assert result.order.choice is result.choice and np.array_equal(result.order.spans, result.choice.spans)
        assert np.isin(result.order.indices, span_rows(result.choice.spans)).all()
        coarser = sorter.wait(sorter.request(SortRequest(CAMERA, 0.01, levels=LodRequest(lod, level=2))), timeout=30)
        assert coarser.serial > serial and coarser.choice.levels.tolist() == [2, 2, 2]
        assert coarser.order.count == 3 * 4
    finally:
        sorter.close()
        sorter.join(10)


def test_a_leaf_whose_gaussians_reach_into_the_view_is_in_view(tmp_path):
    """Its box (one standard deviation) lies outside the image, its gaussians' tails
    (sqrt(2 ln 255) = 3.3 of them) do not: it keeps its level; one far out does not."""
    assert REACH_SIGMAS == pytest.approx(3.33, abs=0.01)
    wide = [[random_gaussians(PER_LEAF[level], centre=c, spread=0.005, scale=0.3, seed=level)
             for level in range(LEVELS)] for c in ((0.0, 0.0, 5.0), (6.5, 0.0, 5.0), (30.0, 0.0, 5.0))]
    lod = load_lod(write_streamed_sog(tmp_path / "wide", wide))
    box_only, _ = screen_radius(lod.index.bounds, CAMERA)
    assert box_only.tolist() == [True, False, False]
    assert choose(lod, CAMERA, distance=100.0).levels.tolist() == [0, 0, 2]


def test_a_leaf_without_gaussians_at_a_level_draws_its_nearest_level_that_has_them(tmp_path):
    leaves = tiny_leaves([(0.0, 0.0, 1.0), (0.0, 0.0, 3.0), (0.0, 0.0, 9.0)])
    leaves[1][2] = None   # no coarsest gaussians of its own: its finer level stands in
    leaves[2][0] = None   # nothing at the finest: its coarser level stands in
    lod = load_lod(write_streamed_sog(tmp_path / "holes", leaves))
    assert choose(lod, CAMERA, distance=100.0).levels.tolist() == [0, 0, 1]
    assert choose(lod, CAMERA, level=2).levels.tolist() == [2, 1, 2]
    # Under a budget leaf 1 starts at level 1 (8), never at its empty coarsest (0).
    squeezed = choose(lod, CAMERA, distance=100.0, budget=1)
    assert squeezed.levels.tolist() == [2, 1, 2] and squeezed.count == 4 + 8 + 4 and squeezed.over_budget
    assert choose(lod, CAMERA, distance=100.0, budget=4 + 8 + 4 + 12).levels.tolist() == [0, 1, 2]


def test_a_new_reading_of_a_scene_is_another_choice_even_at_the_same_address(tmp_path):
    """The key holds the scene itself: an id() would be free for the next reading to take
    once the first is dropped (CPython reuses it at once), and a newly read level would
    then look like the choice already made."""
    path = write_streamed_sog(tmp_path / "lod", tiny_leaves([(0.0, 0.0, 1.0)]))
    first = LodRequest(load_lod(path, levels=(2,))).key
    second = LodRequest(load_lod(path)).key
    assert first != second and first[0].loaded.sum() == 1 and second[0].loaded.sum() == 3
