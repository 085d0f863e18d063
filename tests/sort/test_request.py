"""The values of a sort (sort/request.py): a request's identity, the order that answers
it, and the result that holds one order per key."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from lod_kit import random_gaussians, write_streamed_sog
from testkit import random_scene, spans_choice

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.scene.lod_file import load_lod
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import LodRequest
from raygs_viewer.sort.request import Order, SortRequest, SortResult

P_MIN = 1 / 255


def camera(x: float = 0.0) -> Camera:
    return look_at([x, 0.2, -3.0], [0.0, 0.0, 0.0], width=48, height=32)


def test_equal_requests_are_equal_and_hash_alike():
    a = SortRequest(camera(), P_MIN, 0.1, (camera(-0.1), camera(0.1)), ("depth", "distance"))
    b = SortRequest(camera(), P_MIN, 0.1, (camera(-0.1), camera(0.1)), ("depth", "distance", "depth"))
    assert a is not b and a == b and hash(a) == hash(b) and a.identity == b.identity
    assert len({a, b}) == 1
    assert a.keys == ("depth", "distance")  # repeats dropped: the normal form
    assert SortRequest(camera(), np.float32(0.5)) == SortRequest(camera(), 0.5)  # numbers by value
    assert a != (camera(), P_MIN) and a != None  # noqa: E711 - only a request equals a request


@pytest.mark.parametrize("change", [
    dict(camera=camera(0.5)),
    dict(camera=replace(camera(), fx=camera().fx + 1e-9)),
    dict(camera=camera().resized(64, 40)),
    dict(p_min=2 / 255),
    dict(dilation=0.2),
    dict(dilation=None),  # no frustum cull differs from every number
    dict(cull_cameras=(camera(-0.1), camera(0.2))),
    dict(cull_cameras=None),
    dict(keys=("distance", "depth")),  # the first key is the main one
    dict(keys=("depth",)),
    dict(method="float"),
], ids=lambda change: ",".join(change))
def test_anything_that_changes_the_order_changes_the_identity(change):
    base = SortRequest(camera(), P_MIN, 0.1, (camera(-0.1), camera(0.1)), ("depth", "distance"))
    other = replace(base, **change)
    assert other != base and other.identity != base.identity


def test_a_request_keeps_its_own_copy_of_the_cameras():
    mine, eye = camera(), camera(0.3)
    request = SortRequest(mine, P_MIN, cull_cameras=[eye])
    before = request.identity
    mine.t[0] += 1.0
    mine.R[0, 0] = 0.5
    eye.t[1] = 7.0
    assert request.identity == before and request == SortRequest(camera(), P_MIN, cull_cameras=[camera(0.3)])
    assert request.camera.t[0] == camera().t[0] and request.cull_cameras[0].t[1] == camera(0.3).t[1]
    assert request != SortRequest(mine, P_MIN, cull_cameras=[eye])  # the changed view is another request


def test_levels_a_request_to_choose_and_a_choice_made(tmp_path):
    leaves = [[random_gaussians(n, centre=(x, 0.0, 2.0), spread=0.005, scale=0.001, seed=level)
               for level, n in enumerate((8, 4))] for x in (-0.5, 0.5)]
    lod = load_lod(write_streamed_sog(tmp_path / "lod", leaves))
    view = look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], width=64, height=48)
    asked = LodRequest(lod, distance=1.0)
    # A LodRequest is the same choice for the same scene and settings, whatever the object.
    again = SortRequest(view, P_MIN, levels=LodRequest(lod, distance=1.0))
    assert SortRequest(view, P_MIN, levels=asked) == again
    assert hash(SortRequest(view, P_MIN, levels=asked)) == hash(again)
    assert SortRequest(view, P_MIN, levels=asked) != SortRequest(view, P_MIN, levels=LodRequest(lod, distance=2.0))
    assert SortRequest(view, P_MIN, levels=asked) != SortRequest(view, P_MIN)  # None: the whole scene
    # A LodChoice is made already: equal by the rows it covers, and it chooses itself for any camera.
    choice = asked.choose(view)
    assert choice.choose(camera(2.0)) is choice
    made = SortRequest(view, P_MIN, levels=choice)
    assert made == SortRequest(view, P_MIN, levels=spans_choice(choice.spans))
    assert made != SortRequest(view, P_MIN, levels=asked)  # to choose is not the same as chosen
    assert made != SortRequest(view, P_MIN, levels=spans_choice(choice.spans - [0, 1]))  # one row fewer
    # Sorting either gives the same order, over the choice's rows.
    with DepthSorter(lod.scene, 1) as sorter:
        chosen, made_result = sorter.sort(SortRequest(view, P_MIN, levels=asked)), sorter.sort(made)
    np.testing.assert_array_equal(chosen.order.indices, made_result.order.indices)
    np.testing.assert_array_equal(chosen.choice.spans, choice.spans)
    assert made_result.choice is choice and made_result.order.spans is choice.spans


def test_an_order_answers_only_its_request():
    request = SortRequest(camera(), P_MIN)
    order = Order([3, 1, 2], "depth", request)
    assert order.indices.dtype == np.uint32 and order.count == 3 and order.spans is None
    assert order.answers(request) and order.answers(SortRequest(camera(), P_MIN))  # an equal request
    assert not order.answers(SortRequest(camera(0.5), P_MIN))
    assert not order.answers(None)
    assert not Order([3, 1, 2]).answers(request) and not Order([3, 1, 2]).answers(None)  # an order given by hand
    tile = order.with_indices(np.array([1, 2]))
    assert tile.indices.tolist() == [1, 2] and tile.answers(request) and tile.key == "depth"
    choice = spans_choice([[0, 2], [5, 9]])
    limited = Order(np.array([[6], [1]]), choice=choice)
    assert limited.indices.tolist() == [6, 1] and limited.spans.tolist() == [[0, 2], [5, 9]]


def test_a_result_s_order_is_its_first_key_s():
    request = SortRequest(camera(), P_MIN, keys=("distance", "depth"))
    orders = {"distance": Order([0, 1], "distance", request), "depth": Order([1, 0], "depth", request)}
    result = SortResult(request, orders, times={"choice": 0.25, "cull": 0.5, "sort": 1.0})
    assert result.order is orders["distance"] and result.keys == ("distance", "depth")
    assert result.order_for("depth") is orders["depth"] and result.order_for("other") is None
    assert result.seconds == 1.75
    assert result.serial == 0 and result.requested_at == result.finished_at == 0.0  # sorted in place
    # What a sorter returns: an order per key, each answering the request, with its times.
    with DepthSorter(random_scene(n=200, seed=1, degree=0)) as sorter:
        real = sorter.sort(SortRequest(camera(), P_MIN, keys=("depth", "distance")))
    assert real.order is real.orders["depth"] and set(real.times) == {"choice", "wait", "cull", "sort"}
    assert all(order.answers(real.request) and order.key == key for key, order in real.orders.items())
    assert real.choice is None and real.order.spans is None and real.seconds >= 0


@pytest.mark.parametrize("workers", [1, 2])
def test_a_choice_of_no_rows_gives_empty_orders_and_an_empty_cull(workers):
    """A level-of-detail choice may hold no rows (every part culled before a level was
    read): every key's order is empty, a turn in place too, and the cull keeps nothing."""
    scene = random_scene(n=200, seed=3)
    camera = look_at((0.0, 0.0, -3.0), (0.0, 0.0, 0.0), width=32, height=32)
    empty = spans_choice(np.zeros((0, 2), np.int64))
    with DepthSorter(scene, workers) as sorter:
        for keys in (("depth",), ("distance",), ("depth", "distance"), ("distance",)):  # the last: a turn, reused
            result = sorter.sort(SortRequest(camera, 1 / 255, levels=empty, keys=keys))
            assert [order.count for order in result.orders.values()] == [0] * len(keys)
        assert sorter.cull(SortRequest(camera, 1 / 255, levels=empty)).size == 0
