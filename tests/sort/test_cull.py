"""A pass of the cull returns everything it found: its pieces and the mask of what it
kept, which no later pass changes (the sorter filters a cached order by the mask of
the pass it made, not by whatever the cull last left behind)."""

from __future__ import annotations

import numpy as np
from testkit import random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.sort.cull import Cull

P_MIN = 1 / 255


def one_thread(task, count):
    return [task(index) for index in range(count)]


def test_a_pass_returns_what_it_kept_and_a_later_pass_leaves_that_alone():
    scene = random_scene(n=400, seed=5, degree=0, spread=2.0)
    cull = Cull(scene, chunk_rows=64)
    front = look_at([0.0, 0.0, -3.0], [0.0, 0.0, 0.0], width=40, height=30)
    side = look_at([3.0, 0.0, 0.0], [0.0, 0.0, 0.0], width=40, height=30)
    first = cull.pieces(cull.request(front, P_MIN, 0.0, None), one_thread)
    kept = first.union.copy()
    np.testing.assert_array_equal(np.flatnonzero(kept), np.concatenate([piece.visible for piece in first.pieces]))
    assert 0 < kept.sum() < scene.count  # the view culls: the mask says something
    second = cull.pieces(cull.request(side, P_MIN, 0.0, None), one_thread)
    assert not np.array_equal(second.union, kept)  # the two views keep different rows
    np.testing.assert_array_equal(first.union, kept)  # and the first pass's mask is still its own
