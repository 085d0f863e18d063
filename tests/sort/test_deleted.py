"""Hidden rows (deleted in the window): no order holds them, and every order equals the
one of the scene without them, mapped back to the scene's rows (the ranges the keys are
quantised over come from what is left); a turn in place reuses no order of other deleted
rows; equal masks make equal requests."""

from __future__ import annotations

import numpy as np
import pytest
from testkit import random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.request import SortRequest

KEYS = ("depth", "distance")


def deleted_mask(count, seed, fraction=0.3):
    rng = np.random.default_rng(seed)
    mask = rng.random(count) < fraction
    mask[:50] = True  # a run, as a box crop leaves
    return mask


@pytest.mark.parametrize("method", ["auto", "radix", "float"])
@pytest.mark.parametrize("dilation", [None, 0.0, 0.03])
def test_orders_are_those_of_the_scene_without_the_deleted_rows(method, dilation):
    scene = random_scene(n=3000, seed=11, degree=0, spread=1.5, log_scale=(-3.0, -1.0))
    camera = look_at((0.3, -0.2, -2.5), (0, 0, 0), width=64, height=48)
    deleted = deleted_mask(scene.count, 1)
    kept_rows = np.flatnonzero(~deleted)
    with DepthSorter(scene, workers=2, chunk_rows=700) as sorter, DepthSorter(scene.rows(kept_rows)) as kept:
        got = sorter.sort(SortRequest(camera, 1 / 255, dilation, keys=KEYS, method=method,
                                      deleted=DeletedRows(deleted)))
        expected = kept.sort(SortRequest(camera, 1 / 255, dilation, keys=KEYS, method=method))
        plain = sorter.sort(SortRequest(camera, 1 / 255, dilation, keys=KEYS, method=method))
    for key in KEYS:
        indices = got.orders[key].indices
        np.testing.assert_array_equal(indices, kept_rows[expected.orders[key].indices])
        assert not deleted[indices].any()
        assert deleted[plain.orders[key].indices].any()  # the mask bites


def test_a_turn_in_place_reuses_no_order_of_other_deleted_rows():
    scene = random_scene(n=2000, seed=12, degree=0, spread=1.5, log_scale=(-3.0, -1.0))
    camera = look_at((0.0, 0.0, -3.0), (0, 0, 0), width=48, height=48)
    turned = look_at((0.0, 0.0, -3.0), (0.2, 0.1, 0), width=48, height=48)
    first, second = DeletedRows(deleted_mask(scene.count, 2)), DeletedRows(deleted_mask(scene.count, 3))
    with DepthSorter(scene, workers=1) as sorter, DepthSorter(scene, workers=1) as fresh:
        for view in (camera, camera, turned):  # the second sort at a centre keeps its candidates
            sorter.sort(SortRequest(view, 1 / 255, 0.0, keys=("distance",), deleted=first))
        got = sorter.sort(SortRequest(turned, 1 / 255, 0.0, keys=("distance",), deleted=second)).order.indices
        expected = fresh.sort(SortRequest(turned, 1 / 255, 0.0, keys=("distance",), deleted=second)).order.indices
        assert sorter.reused >= 1  # the cache was in use, and is not used across masks
    np.testing.assert_array_equal(got, expected)


def test_equal_masks_make_equal_requests_and_no_mask_is_none():
    camera = look_at((0.0, 0.0, -3.0), (0, 0, 0), width=8, height=8)
    a, b = np.zeros(100, bool), np.zeros(100, bool)
    a[7] = b[7] = True
    assert SortRequest(camera, 0.01, deleted=DeletedRows(a)) == SortRequest(camera, 0.01, deleted=DeletedRows(b))
    b[8] = True
    assert SortRequest(camera, 0.01, deleted=DeletedRows(a)) != SortRequest(camera, 0.01, deleted=DeletedRows(b))
    assert SortRequest(camera, 0.01, deleted=DeletedRows(a)) != SortRequest(camera, 0.01)
    assert DeletedRows.of(np.zeros(5, bool)) is None and DeletedRows.of(None) is None
    held = DeletedRows(a)
    a[9] = True  # the request holds its own copy
    assert not held.mask[9] and not held.mask.flags.writeable
