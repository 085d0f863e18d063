"""The parallel cull and sort equal the one-worker order exactly, the distance order of a
turn in place is reused from the last sort and equals a fresh one, and the thread pool
goes away on close (also when the viewer changes scene or exits).

Scenes are small; ``chunk_rows``, ``BUCKET_KEYS`` and ``PARALLEL_SORT_MIN`` are made
small so that a few hundred gaussians make many chunks and many buckets, and take the
parallel sort (what millions do by default).
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from testkit import gaussian_columns, make_scene, random_scene, sort_indices, write_ply

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort import ordering
from raygs_viewer.sort.cull import Cull
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.keys import key_values, sort_back_to_front
from raygs_viewer.sort.request import SortRequest
from raygs_viewer.sort.worker import BackgroundSorter

P_MIN = 1 / 255
DEADLOCK = 30.0  # seconds; only reached when the code under test is broken


def with_duplicates(scene: Scene, rng: np.random.Generator) -> Scene:
    """``scene`` with about a third of its centres copied from others (exact key ties in
    both keys), and a run of one repeated centre across chunk boundaries."""
    positions = scene.positions.copy()
    n = scene.count
    copies = rng.choice(n, n // 3, replace=False)
    positions[copies] = positions[rng.integers(0, n, copies.size)]
    positions[n // 4: n // 2] = positions[0]
    return replace(scene, positions=positions)


def camera_for(yaw: float, width: int = 40, height: int = 30):
    eye = 3.0 * np.array([np.sin(yaw), 0.3, -np.cos(yaw)])
    return look_at(eye, [0.1, -0.1, 0.2], width=width, height=height, fov_y_degrees=55)


def orders_of(sorter: DepthSorter, request: SortRequest) -> dict[str, np.ndarray]:
    """{key: (M,) uint32 indices} of ``sorter``'s answer to ``request``."""
    return {key: order.indices for key, order in sorter.sort(request).orders.items()}


def threads_of(sorter: DepthSorter) -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith(sorter.thread_prefix)]


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), workers=st.sampled_from([2, 3, 5]), chunk_rows=st.integers(1, 90),
       bucket_keys=st.sampled_from([1, 16, 1 << 17]), yaw=st.floats(-3.2, 3.2),
       dilation=st.sampled_from([0.0, 0.02, None]), stereo=st.booleans(),
       method=st.sampled_from(["auto", "radix", "float"]))
def test_every_worker_count_gives_the_one_worker_order(seed, workers, chunk_rows, bucket_keys, yaw, dilation,
                                                       stereo, method):
    rng = np.random.default_rng(seed)
    scene = with_duplicates(random_scene(n=int(rng.integers(2, 400)), seed=seed, degree=0, spread=1.5,
                                         log_scale=(-3.0, -1.0)), rng)
    camera = camera_for(yaw)
    cull_cameras = (replace(camera, cx=camera.cx - 8), replace(camera, cx=camera.cx + 8)) if stereo else None
    request = SortRequest(camera, P_MIN, dilation, cull_cameras, ("depth", "distance"), method=method)
    reference = orders_of(DepthSorter(scene, workers=1), request)
    with pytest.MonkeyPatch.context() as patch, DepthSorter(scene, workers, chunk_rows=chunk_rows) as sorter:
        patch.setattr(ordering, "BUCKET_KEYS", bucket_keys)
        patch.setattr(ordering, "PARALLEL_SORT_MIN", 0)
        parallel = orders_of(sorter, request)
        one_worker = orders_of(DepthSorter(scene, workers=1, chunk_rows=chunk_rows), request)
    for key in ("depth", "distance"):
        assert parallel[key].dtype == np.uint32
        np.testing.assert_array_equal(parallel[key], reference[key])
        np.testing.assert_array_equal(one_worker[key], reference[key])
    # The cull is the one every key sorts, and DepthSorter.cull's.
    np.testing.assert_array_equal(np.sort(parallel["distance"]), np.sort(parallel["depth"]))
    np.testing.assert_array_equal(np.sort(parallel["depth"]),
                                  DepthSorter(scene, 1).cull(request))


def test_ties_across_chunks_and_buckets_keep_scene_order(monkeypatch):
    """Many gaussians at a few distinct places: each key value is shared by gaussians in
    every chunk, and the buckets are single keys; the order is by key, then index."""
    monkeypatch.setattr(ordering, "BUCKET_KEYS", 4)
    monkeypatch.setattr(ordering, "PARALLEL_SORT_MIN", 0)
    rng = np.random.default_rng(4)
    places = np.array([[0, 0, 1.0], [0.2, 0.1, 2.0], [-0.3, 0.2, 3.0], [0.1, -0.2, 1.5]])
    label = rng.integers(0, len(places), 500)
    scene = make_scene(positions=places[label], scales=0.01, opacities=0.9)
    camera = look_at([0, 0, -2.0], [0, 0, 1.0], width=64, height=48, fov_y_degrees=90)
    for key in ("depth", "distance"):
        with DepthSorter(scene, workers=3, chunk_rows=37) as sorter:
            order = sort_indices(sorter, camera, P_MIN, key=key)
        values = (scene.positions @ camera.R.T + camera.t)[:, 2] if key == "depth" else \
            np.linalg.norm(scene.positions - camera.center, axis=1)
        np.testing.assert_array_equal(order, np.lexsort((np.arange(scene.count), -values)))


@pytest.mark.parametrize("workers", [1, 2])
def test_empty_one_and_fully_culled_scenes(workers):
    camera = look_at([0, 0, -3.0], [0, 0, 0], width=32, height=24)
    for count in (0, 1):
        scene = random_scene(n=count, seed=1, degree=0)
        with DepthSorter(scene, workers, chunk_rows=1) as sorter:
            result = sorter.sort(SortRequest(camera, P_MIN, keys=("depth", "distance")))
            assert {key: order.indices.tolist() for key, order in result.orders.items()} == \
                {"depth": list(range(count)), "distance": list(range(count))}
            assert all(order.indices.dtype == np.uint32 for order in result.orders.values())
            assert sorter.cull(SortRequest(camera, P_MIN)).dtype == np.int64
    behind = look_at([0, 0, -3.0], [0, 0, -6.0], width=32, height=24)  # the scene is behind it
    with DepthSorter(random_scene(n=50, seed=2, degree=0, log_scale=(-4, -3)), workers, chunk_rows=8) as sorter:
        for key in ("depth", "distance"):
            assert sort_indices(sorter, behind, P_MIN, key=key).size == 0


def test_equal_depths_fall_back_to_scene_order():
    """One key value for all: nothing to quantise; radix keeps scene order, as one worker does."""
    scene = make_scene(positions=[[x, 0.0, 2.0] for x in np.linspace(-0.1, 0.1, 40)], scales=0.01, opacities=0.9)
    camera = look_at([0, 0, 0], [0, 0, 1.0], width=32, height=24)
    for method in ("auto", "radix", "float"):
        with DepthSorter(scene, workers=2, chunk_rows=3) as sorter:
            assert sort_indices(sorter, camera, P_MIN, method).tolist() == list(range(40))


# -- the distance order of a turn in place ------------------------------------------------------
def turned(camera, degrees: float, axis=(0.0, 1.0, 0.0)):
    """``camera`` turned about its own centre (t recomputed from the same centre)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = np.radians(degrees)
    R = (np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k) @ camera.R
    return replace(camera, R=R, t=-R @ camera.center)


def with_a_shell(scene: Scene, centre, radius: float, count: int, seed: int) -> Scene:
    """``scene`` plus ``count`` gaussians about ``radius`` from ``centre``, their distances
    a few float32 ulps apart: any rounding that depends on the rotation reorders them."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    shell = np.asarray(centre) + directions * (radius * (1 + 3e-7 * rng.standard_normal(count)))[:, None]
    extra = random_scene(n=count, seed=seed, degree=0, log_scale=(-4, -3))
    return Scene(*(np.concatenate([a, b]) for a, b in [(scene.positions, shell.astype(np.float32)),
                                                       (scene.rotations, extra.rotations),
                                                       (scene.scales, extra.scales),
                                                       (scene.opacities, extra.opacities),
                                                       (scene.sh, extra.sh)]), 0)


@pytest.mark.parametrize("workers, method", [(1, "auto"), (3, "auto"), (2, "float")])
def test_a_turn_in_place_reuses_the_distance_order_and_equals_a_fresh_sort(workers, method):
    eye = [0.1, 0.2, -0.5]
    scene = with_duplicates(random_scene(n=600, seed=6, degree=0, spread=2.0, log_scale=(-4, -2)),
                            np.random.default_rng(6))
    scene = with_a_shell(scene, eye, 1.3, 300, seed=6)
    camera = look_at(eye, [0, 0, 1.0], width=48, height=32, fov_y_degrees=70)
    views = [camera] + [turned(camera, d, axis) for d, axis in
                        [(20, (0, 1, 0)), (-35, (1, 0.5, 0)), (60, (0, 1, 0.3)), (150, (0, 1, 0))]]
    assert len({v.center.astype(np.float32).tobytes() for v in views}) == 1
    with DepthSorter(scene, workers, chunk_rows=50) as sorter:
        sizes = set()
        for number, view in enumerate(views):
            request = SortRequest(view, P_MIN, keys=("distance", "depth"), method=method)
            orders = orders_of(sorter, request)
            fresh = orders_of(DepthSorter(scene, 1), request)
            for key in fresh:
                np.testing.assert_array_equal(orders[key], fresh[key])
            sizes.add(orders["distance"].size)
            # The first view sorts; the second, at the same centre, sorts every candidate
            # and keeps them; every later turn filters them by its cull.
            assert sorter.reused == max(0, number - 1)
            assert sorter.sorted == 2 * min(number + 1, 2) + max(0, number - 1)  # depth always sorts
        assert len(sizes) > 2  # the turns cull differently: the filter is not a no-op
        # A new centre or another p_min sorts afresh (and the cache stays valid only for its own).
        moved = replace(camera, t=camera.t + [0.0, 0.0, 0.3])
        np.testing.assert_array_equal(sort_indices(sorter, moved, P_MIN, method, key="distance"),
                                      sort_indices(DepthSorter(scene, 1), moved, P_MIN, method, key="distance"))
        np.testing.assert_array_equal(sort_indices(sorter, views[2], 0.05, method, key="distance"),
                                      sort_indices(DepthSorter(scene, 1), views[2], 0.05, method, key="distance"))
        assert sorter.reused == len(views) - 2


def test_turns_whose_centres_round_to_either_sign_of_zero_reuse():
    """A turn recomputes C = -R^T t, and a coordinate that was 0 comes back as -1e-19 in
    one view and +1e-17 in the next; both snap to zero, and must be the same centre for
    the cache (the bytes of -0.0 and 0.0 differ). The rotations here are exact (axis
    permutations), so each centre is exactly the one written."""
    scene = random_scene(n=400, seed=11, degree=0, spread=2.0, log_scale=(-4, -2))
    quarter = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # 90 deg about y
    views = []
    for R, x in ((np.eye(3), -1e-19), (quarter, 1e-17), (quarter.T, -1e-19)):
        centre = np.array([x, 0.25, 0.0])
        views.append(Camera(48, 32, 40.0, 40.0, 24.0, 16.0, R, -R @ centre))
        assert views[-1].center[0] == x
    with DepthSorter(scene, workers=2, chunk_rows=64) as sorter:
        for view in views:
            np.testing.assert_array_equal(sort_indices(sorter, view, P_MIN, key="distance"),
                                          sort_indices(DepthSorter(scene, 1), view, P_MIN, key="distance"))
        # The second view keeps the candidates sorted for the first's centre; the third reuses them.
        assert (sorter.sorted, sorter.reused) == (2, 1)


def test_the_distance_key_does_not_change_with_the_rotation():
    """|p - C| in float32: bit for bit the same after any turn, which the reuse relies on."""
    scene = random_scene(n=300, seed=9, degree=0, spread=3.0)
    camera = look_at([0.3, -0.2, -1.0], [0, 0, 1.0], width=32, height=24)
    scale = Cull(scene).coordinate_scale
    first = key_values(scene.positions, camera, "distance", scale)
    for degrees in (17.0, 90.0, 181.0):
        values = key_values(scene.positions, turned(camera, degrees, (1, 2, 3)), "distance", scale)
        np.testing.assert_array_equal(values, first)
        np.testing.assert_array_equal(sort_back_to_front(values, "float"), sort_back_to_front(first, "float"))


# -- the pool -------------------------------------------------------------------------------
def test_close_leaves_no_thread_and_orders_still_work():
    scene = random_scene(n=300, seed=3, degree=0)
    camera = camera_for(0.3)
    expected = sort_indices(DepthSorter(scene, 1), camera, P_MIN)
    sorter = DepthSorter(scene, workers=3, chunk_rows=16)
    assert threads_of(sorter) == []  # made lazily
    np.testing.assert_array_equal(sort_indices(sorter, camera, P_MIN), expected)
    # The calling thread is the third worker (the pool starts a thread only when none is idle).
    assert 1 <= len(threads_of(sorter)) <= 2
    sorter.close()
    assert threads_of(sorter) == [] and sorter.closed
    sorter.close()  # idempotent
    np.testing.assert_array_equal(sort_indices(sorter, camera, P_MIN), expected)  # on the calling thread
    assert threads_of(sorter) == []
    with DepthSorter(scene, workers=2, chunk_rows=16) as other:
        sort_indices(other, camera, P_MIN)
        assert len(threads_of(other)) == 1
    assert threads_of(other) == []
    single = DepthSorter(scene, workers=1, chunk_rows=16)
    sort_indices(single, camera, P_MIN)
    assert threads_of(single) == []  # one worker: no pool at all


def test_a_closed_background_sorter_closes_its_depth_sorter():
    scene = random_scene(n=300, seed=3, degree=0)
    sorter = DepthSorter(scene, workers=2, chunk_rows=16)
    worker = BackgroundSorter(sorter)
    assert worker.wait(worker.request(SortRequest(camera_for(0.1), P_MIN)), timeout=DEADLOCK) is not None
    assert len(threads_of(sorter)) == 1
    worker.close()
    assert worker.join(DEADLOCK)
    assert sorter.closed and threads_of(sorter) == []


def test_the_viewer_closes_the_pool_on_scene_change_and_exit(open_viewer, tmp_path, monkeypatch):
    made: list[tuple[DepthSorter, BackgroundSorter]] = []
    # The demo scene is one chunk by default: every DepthSorter made here (the viewer's)
    # makes it many, on two workers.
    monkeypatch.setattr(DepthSorter.__init__, "__defaults__", (2,))
    monkeypatch.setattr(DepthSorter.__init__, "__kwdefaults__", {"chunk_rows": 64})

    def factory(depth_sorter: DepthSorter) -> BackgroundSorter:
        assert (depth_sorter.workers, depth_sorter.chunk_rows) == (2, 64)
        made.append((depth_sorter, BackgroundSorter(depth_sorter)))
        return made[-1][1]

    viewer, drive = open_viewer(hide_panel=True, sorter_factory=factory)
    drive.settle()
    first, first_worker = made[0]
    assert len(threads_of(first)) == 1
    path = write_ply(tmp_path / "next.ply", gaussian_columns(n=400, degree=0, seed=2))
    viewer.open_scene(str(path))
    drive.wait_for_load()
    assert viewer.loaded.path == str(path) and len(made) == 2
    assert first_worker.join(DEADLOCK) and first.closed and threads_of(first) == []
    drive.settle()
    second, second_worker = made[1]
    assert len(threads_of(second)) == 1
    viewer.close()
    assert second_worker.join(DEADLOCK) and second.closed and threads_of(second) == []
