"""Sorting on a background thread (raygs_viewer.sort.worker).

The fake sorter (the ``Sorter`` protocol: ``sort(request) -> SortResult``, ``close()``)
blocks inside ``sort()`` until the test lets it go, one sort at a time, so every claim
about "while a sort runs" is checked at a point where the worker provably is inside
``sort()``. No test measures time: the generous
timeouts below only turn a deadlock into a failure instead of a hang.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
from testkit import sort_indices

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.demo import demo_cameras, demo_scene
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import Order, SortRequest, SortResult
from raygs_viewer.sort.worker import BackgroundSorter

P_MIN = 1 / 255
FAIL_P_MIN = 0.5
DEADLOCK = 30.0  # seconds; only ever reached when the code under test is broken


def view(k: int, width: int = 64) -> Camera:
    """A camera tagged by its x translation, which the fake sorter echoes back."""
    return Camera(width, 48, 50.0, 50.0, width / 2, 24.0, np.eye(3), np.array([float(k), 0.0, 0.0]))


class GatedSorter:
    """sort() records the request, announces it has started, then waits for one permit.

    Returns, for the first key, a 1-element order holding the camera's tag (for the
    k-th key after it: [tag, k]); raises for p_min == FAIL_P_MIN.
    ``dilations`` records the cull dilation of every call, in order.
    """

    def __init__(self) -> None:
        self.calls: list[tuple[int, float]] = []
        self.dilations: list[float | None] = []
        self.culled_for: list = []  # cull_cameras of every call, as tags of their t[0]
        self.keys: list[tuple[str, ...]] = []  # the sort keys of every call
        self._entered = threading.Semaphore(0)
        self._permits = threading.Semaphore(0)
        self.inside = 0
        self.returned = 0
        self.starved = False
        self.closed = False

    def sort(self, request: SortRequest) -> SortResult:
        tag, p_min, keys = int(request.camera.t[0]), request.p_min, request.keys
        self.calls.append((tag, p_min))
        self.dilations.append(request.dilation)
        self.keys.append(keys)
        self.culled_for.append(None if request.cull_cameras is None else [int(c.t[0]) for c in request.cull_cameras])
        self.inside += 1
        self._entered.release()
        try:
            if not self._permits.acquire(timeout=DEADLOCK):
                self.starved = True
                raise AssertionError("the test never released this sort")
            if p_min == FAIL_P_MIN:
                raise ValueError("bad view\nsecond line")
            # Each key's order tells the keys apart: the tag, then the key's position.
            orders = {key: Order([tag, index] if index else [tag], key, request) for index, key in enumerate(keys)}
            return SortResult(request, orders, times={"cull": 0.0, "sort": 0.0})
        finally:
            self.inside -= 1
            self.returned += 1

    def close(self) -> None:
        self.closed = True

    def wait_entered(self) -> None:
        """Blocks until the worker is inside sort() for the next sort."""
        assert self._entered.acquire(timeout=DEADLOCK), "the worker never started a sort"

    def allow(self, sorts: int = 1) -> None:
        for _ in range(sorts):
            self._permits.release()


@pytest.fixture
def fake():
    sorter = GatedSorter()
    yield sorter
    sorter.allow(100)  # never leave a worker blocked behind a failed test


@pytest.fixture
def worker(fake):
    background = BackgroundSorter(fake)
    yield background
    background.close()


def tags(fake: GatedSorter) -> list[int]:
    return [tag for tag, _ in fake.calls]


def returns(call):
    """call()'s value, from a helper thread: a call that never returns fails the test
    after DEADLOCK instead of hanging it."""
    out = []
    helper = threading.Thread(target=lambda: out.append(call()), daemon=True)
    helper.start()
    helper.join(DEADLOCK)
    assert not helper.is_alive(), "the call never returned"
    return out[0]


def test_request_and_latest_never_wait_for_a_running_sort(fake, worker):
    assert worker.latest() is None
    first = worker.request(SortRequest(view(1), P_MIN))
    fake.wait_entered()
    serials = []
    for k in range(2, 202):
        serials.append(worker.request(SortRequest(view(k), P_MIN)))
        assert worker.latest() is None
    # Had request() or latest() waited on the sort, the sort would still be blocked
    # here forever (nobody released it) and we would not have got this far; the
    # fake's own timeout turns that into starved=True instead of a hang.
    assert fake.inside == 1 and fake.returned == 0 and not fake.starved
    assert first == 1 and serials == list(range(2, 202))
    assert worker.started == 1 and worker.finished == 0
    assert worker.requested == 201 and worker.superseded == 199
    fake.allow(2)
    result = worker.wait(201, timeout=DEADLOCK)
    assert result is not None and result.serial == 201
    assert tags(fake) == [1, 201]


def test_a_newer_request_replaces_the_queued_one(fake, worker):
    a = worker.request(SortRequest(view(1), P_MIN))
    fake.wait_entered()
    b = worker.request(SortRequest(view(2), P_MIN))
    c = worker.request(SortRequest(view(3), P_MIN))
    assert (a, b, c) == (1, 2, 3)
    assert worker.superseded == 1
    assert worker.wait(c, timeout=0) is None  # still blocked: nothing newer than nothing
    fake.allow()
    fake.wait_entered()   # the next sort starts at once, and it is the newest view
    assert tags(fake) == [1, 3]
    assert worker.latest().serial == a
    fake.allow()
    newest = worker.wait(c, timeout=DEADLOCK)
    assert isinstance(newest, SortResult)
    assert newest.serial == c and newest.order.indices.tolist() == [3] and newest.order.indices.dtype == np.uint32
    assert newest.request.camera.t[0] == 3 and newest.request.p_min == P_MIN and newest.seconds >= 0
    assert newest.order.answers(SortRequest(newest.request.camera, P_MIN))
    assert worker.wait(b, timeout=DEADLOCK) is newest  # the superseded request is answered by a newer one
    assert worker.latest() is newest
    assert tags(fake) == [1, 3]  # view 2 was never sorted
    assert (worker.requested, worker.started, worker.finished, worker.superseded) == (3, 2, 2, 1)


def test_wait_returns_the_newest_once_released(fake, worker):
    serial = worker.request(SortRequest(view(5), P_MIN))
    fake.wait_entered()
    assert worker.wait(serial, timeout=0) is None
    fake.allow()
    result = worker.wait(serial)
    assert result.serial == serial and result.order.indices.tolist() == [5]


def test_an_identical_request_is_not_queued_again(fake, worker):
    first = worker.request(SortRequest(view(1), P_MIN))
    fake.wait_entered()
    assert worker.request(SortRequest(view(1), P_MIN)) == first  # equal values, different arrays
    assert worker.requested == 1 and worker.repeated == 1 and worker.superseded == 0
    fake.allow()
    assert worker.wait(first, timeout=DEADLOCK).serial == first
    assert worker.request(SortRequest(view(1), P_MIN)) == first   # already sorted: still not again
    # Anything that changes the order is a new request: p_min, intrinsics, pose.
    other_p = worker.request(SortRequest(view(1), 2 / 255))
    fake.wait_entered()
    fake.allow()
    wider = worker.request(SortRequest(view(1, width=80), 2 / 255))
    fake.wait_entered()
    fake.allow()
    moved = worker.request(SortRequest(view(2), 2 / 255))
    fake.wait_entered()
    fake.allow()
    assert (other_p, wider, moved) == (2, 3, 4)
    assert worker.wait(moved, timeout=DEADLOCK).serial == moved
    # The worker is single-threaded and FIFO: no extra sort of view 1 / P_MIN ran.
    assert fake.calls == [(1, P_MIN), (1, 2 / 255), (1, 2 / 255), (2, 2 / 255)]
    assert worker.repeated == 2


def test_dilation_is_passed_to_the_sorter_and_recorded(fake, worker):
    results = []
    for k, dilation in ((1, 0.25), (2, None), (3, 0.0)):
        serial = worker.request(SortRequest(view(k), P_MIN, dilation))
        fake.allow()
        results.append(worker.wait(serial, timeout=DEADLOCK))
    plain = worker.request(SortRequest(view(4), P_MIN))  # the default: 0.0, the tight cull
    fake.allow()
    results.append(worker.wait(plain, timeout=DEADLOCK))
    assert fake.dilations == [0.25, None, 0.0, 0.0]
    assert [r.request.dilation for r in results] == [0.25, None, 0.0, 0.0]
    assert [r.order.indices.tolist() for r in results] == [[1], [2], [3], [4]]


def test_dilation_is_part_of_the_request_identity(fake, worker):
    first = worker.request(SortRequest(view(1), P_MIN, 0.1))
    fake.wait_entered()
    assert worker.request(SortRequest(view(1), P_MIN, 0.1)) == first  # the same view and cull: not again
    wider = worker.request(SortRequest(view(1), P_MIN, 0.2))          # a wider cull is another order
    assert wider == first + 1
    unculled = worker.request(SortRequest(view(1), P_MIN, None))  # None (no frustum cull) differs from any number
    assert unculled == wider + 1 and worker.superseded == 1
    assert worker.request(SortRequest(view(1), P_MIN, None)) == unculled
    tight = worker.request(SortRequest(view(1), P_MIN, 0.0))
    assert tight == unculled + 1
    assert worker.request(SortRequest(view(1), P_MIN)) == tight       # 0.0 is the default
    fake.allow(2)
    assert worker.wait(tight, timeout=DEADLOCK).request.dilation == 0.0
    assert fake.dilations == [0.1, 0.0]  # 0.2 and None were superseded before they started
    assert (worker.requested, worker.repeated) == (4, 3)


def test_cull_cameras_are_passed_recorded_and_part_of_the_request_identity(fake, worker):
    first = worker.request(SortRequest(view(1), P_MIN))
    fake.wait_entered()
    eyes = (view(2), view(3))
    both = worker.request(SortRequest(view(1), P_MIN, 0.0, eyes))  # the view culled for two eyes: another order
    assert both == first + 1
    assert worker.request(SortRequest(view(1), P_MIN, 0.0, (view(2), view(3)))) == both  # equal values: not again
    eyes[1].t[0] = 9.0  # changed in place after the request: the queued sort keeps its copy
    fake.allow(2)
    result = worker.wait(both, timeout=DEADLOCK)
    assert fake.culled_for == [None, [2, 3]]
    assert [int(c.t[0]) for c in result.request.cull_cameras] == [2, 3]
    moved = worker.request(SortRequest(view(1), P_MIN, 0.0, (view(2), view(4))))
    assert moved == both + 1


def test_caller_changing_its_camera_in_place_does_not_change_the_queued_sort(fake, worker):
    worker.request(SortRequest(view(1), P_MIN))
    fake.wait_entered()
    camera = view(2)
    serial = worker.request(SortRequest(camera, P_MIN))
    camera.t[0] = 7.0  # after the request, before its sort starts
    fake.allow(2)
    result = worker.wait(serial, timeout=DEADLOCK)
    assert result.order.indices.tolist() == [2] and tags(fake) == [1, 2]


def test_an_exception_in_order_is_reported_and_the_worker_keeps_going(fake, worker):
    bad = worker.request(SortRequest(view(1), FAIL_P_MIN))
    fake.allow()
    assert returns(lambda: worker.wait(bad)) is None  # a failed request is answered, not waited on forever
    assert worker.error == "ValueError: bad view second line"
    assert worker.failed == 1 and worker.finished == 0
    # The same view is not retried (a frame loop would spin on it)...
    assert worker.request(SortRequest(view(1), FAIL_P_MIN)) == bad
    # ... a different one is served normally, and clears the error.
    good = worker.request(SortRequest(view(2), P_MIN))
    fake.allow()
    result = worker.wait(good, timeout=DEADLOCK)
    assert result is not None and result.order.indices.tolist() == [2]
    assert worker.error is None and worker.finished == 1
    assert tags(fake) == [1, 2]


def test_close_returns_while_a_sort_is_blocked(fake):
    worker = BackgroundSorter(fake)
    worker.request(SortRequest(view(1), P_MIN))
    fake.wait_entered()
    worker.request(SortRequest(view(2), P_MIN))  # queued: dropped by close
    worker.close()
    assert fake.inside == 1 and fake.returned == 0 and not fake.starved  # close did not wait for it
    assert worker.closed
    assert worker.wait(2, timeout=DEADLOCK) is None  # closed: answers at once
    with pytest.raises(RuntimeError):
        worker.request(SortRequest(view(3), P_MIN))
    assert not fake.closed  # the worker closes its sorter once the running sort is done
    fake.allow()
    assert worker.join(DEADLOCK)
    assert fake.closed
    assert tags(fake) == [1]


def test_real_depth_sorter_gives_the_same_order():
    scene = demo_scene()
    sorter = DepthSorter(scene)
    with BackgroundSorter(sorter) as worker:
        for camera in demo_cameras(160, 120):
            serial = worker.request(SortRequest(camera, P_MIN))
            result = worker.wait(serial, timeout=DEADLOCK)
            assert result is not None and result.serial == serial
            expected = sort_indices(sorter, camera, P_MIN)
            assert result.order.indices.dtype == np.uint32 and result.order.count > 0
            np.testing.assert_array_equal(result.order.indices, expected)
            np.testing.assert_array_equal(result.request.camera.R, camera.R)
            assert result.order.answers(SortRequest(camera, P_MIN))
        assert worker.finished == 6 and worker.error is None
        # The cull dilation reaches DepthSorter.sort: None keeps the gaussians outside
        # the frustum that the tight cull drops.
        camera = demo_cameras(160, 120)[4]
        tight = worker.wait(worker.request(SortRequest(camera, P_MIN, 0.0)), timeout=DEADLOCK).order.indices
        loose = worker.wait(worker.request(SortRequest(camera, P_MIN, None)), timeout=DEADLOCK).order.indices
        np.testing.assert_array_equal(loose, sort_indices(sorter, camera, P_MIN, dilation=None))
        assert loose.size > tight.size
        # Stereo: culled for both eyes, sorted from the midpoint.
        left, right = replace(camera, cx=camera.cx - 60), replace(camera, cx=camera.cx + 60)
        union = worker.wait(worker.request(SortRequest(camera, P_MIN, 0.0, (left, right))),
                            timeout=DEADLOCK).order.indices
        np.testing.assert_array_equal(union, sort_indices(sorter, camera, P_MIN, cull_cameras=(left, right)))
        assert union.size > tight.size


def test_keys_are_passed_part_of_the_request_identity_and_each_has_its_order(fake, worker):
    first = worker.request(SortRequest(view(1), P_MIN))  # the default: depth only
    fake.wait_entered()
    assert worker.request(SortRequest(view(1), P_MIN, 0.0, None, ("depth",))) == first
    distance = worker.request(SortRequest(view(1), P_MIN, 0.0, None, ("distance",)))  # another key, another order
    assert distance == first + 1
    both = worker.request(SortRequest(view(1), P_MIN, 0.0, None, ("depth", "distance", "depth")))
    assert both == distance + 1
    # repeats do not count
    assert worker.request(SortRequest(view(1), P_MIN, 0.0, None, ("depth", "distance"))) == both
    fake.allow(2)
    result = worker.wait(both, timeout=DEADLOCK)
    assert fake.keys == [("depth",), ("depth", "distance")]  # one call for both keys (one cull)
    assert result.keys == ("depth", "distance")
    assert result.order_for("depth").indices.tolist() == [1]
    assert result.order_for("distance").indices.tolist() == [1, 1]
    assert result.order is result.order_for("depth") and result.order_for("other") is None
    assert all(order.indices.dtype == np.uint32 for order in result.orders.values())
    with pytest.raises(ValueError):
        SortRequest(view(2), P_MIN, 0.0, None, ())  # no key: no request to make


def test_the_real_sorter_culls_once_and_sorts_each_key_asked():
    scene = demo_scene()
    sorter = DepthSorter(scene)
    camera = demo_cameras(160, 120)[4]
    with BackgroundSorter(sorter) as worker:
        for keys in (("distance",), ("distance", "depth"), ("depth", "distance")):
            result = worker.wait(worker.request(SortRequest(camera, P_MIN, 0.0, None, keys)), timeout=DEADLOCK)
            assert result.keys == keys
            for key in keys:
                np.testing.assert_array_equal(result.order_for(key).indices,
                                              sort_indices(sorter, camera, P_MIN, key=key))
            assert result.order is result.order_for(keys[0])
        assert not np.array_equal(result.order_for("depth").indices, result.order_for("distance").indices)


def test_a_result_says_when_it_was_requested_and_when_it_finished(fake, worker):
    """The panel shows the drawn order's age from these (perf_counter times)."""
    import time
    before = time.perf_counter()
    serial = worker.request(SortRequest(view(1), P_MIN))
    fake.wait_entered()
    assert worker.request(SortRequest(view(1), P_MIN)) == serial  # a repeat is the same request, of the same time
    sorting = time.perf_counter()
    fake.allow()
    result = worker.wait(serial, timeout=DEADLOCK)
    assert before <= result.requested_at <= sorting <= result.finished_at <= time.perf_counter()
    assert result.seconds <= result.finished_at - result.requested_at
