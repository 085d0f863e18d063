"""The per-frame sort: back to front, stable, and culling that never drops a visible gaussian."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from testkit import make_scene, random_scene, sort_indices

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.keys import sort_back_to_front
from raygs_viewer.sort.request import SortRequest


def test_order_is_back_to_front():
    scene = random_scene(n=500, seed=2)
    camera = look_at([0.5, -0.4, -3.0], [0, 0, 0])
    order = sort_indices(DepthSorter(scene), camera, 1 / 255, "float")
    depth = (scene.positions.astype(np.float64) @ camera.R.T + camera.t)[order, 2]
    assert order.dtype == np.uint32
    assert np.all(np.diff(depth) <= 1e-6)


@pytest.mark.parametrize("method", ["radix", "float", "auto"])
def test_sort_methods_are_stable_and_agree_on_distinct_depths(method):
    rng = np.random.default_rng(0)
    depth = rng.permutation(np.arange(2000, dtype=np.float32))  # spacing >> range / 65535
    expected = np.argsort(-depth, kind="stable")
    np.testing.assert_array_equal(sort_back_to_front(depth, method), expected)
    ties = np.array([3.0, 1.0, 3.0, 2.0, 1.0, 3.0], np.float32)
    np.testing.assert_array_equal(sort_back_to_front(ties, method), [0, 2, 5, 3, 1, 4])


def test_radix_quantises_but_keeps_order_within_a_bucket():
    depth = np.array([0.0, 1.0, 1.0 + 1e-7, 1.0 + 2e-7, 2.0], np.float32)
    order = sort_back_to_front(depth, "radix")
    assert order[0] == 4 and order[-1] == 0
    assert sorted(order[1:4]) == [1, 2, 3]


def test_degenerate_ranges():
    assert sort_back_to_front(np.zeros(0, np.float32)).size == 0
    np.testing.assert_array_equal(sort_back_to_front(np.full(4, 2.0, np.float32)), [0, 1, 2, 3])
    np.testing.assert_array_equal(sort_back_to_front(np.full(3, 2.0, np.float32), "radix"), [0, 1, 2])


def test_culling_drops_what_cannot_be_seen():
    scene = make_scene(
        positions=[[0, 0, 5], [0, 0, -5], [100, 0, 5], [0, 0, 5]],
        scales=[[0.1, 0.1, 0.1]] * 4, opacities=[0.9, 0.9, 0.9, 0.5 / 255],
    )
    camera = look_at([0, 0, 0], [0, 0, 1], width=64, height=48)
    assert sort_indices(DepthSorter(scene), camera, 1 / 255).tolist() == [0]


@pytest.mark.parametrize("width, height", [(64, 48), (48, 48)])
def test_culling_uses_each_axis_for_its_own_planes(width, height):
    """Far to the side but level (kept only if visible) and far above (dropped), on
    wide and square images alike."""
    scene = make_scene(positions=[[0.0, 0.0, 5.0], [0.0, -50.0, 5.0], [50.0, 0.0, 5.0]],
                       scales=[[0.1, 0.1, 0.1]] * 3, opacities=0.9)
    camera = look_at([0, 0, 0], [0, 0, 1], width=width, height=height)
    assert sort_indices(DepthSorter(scene), camera, 1 / 255).tolist() == [0]


def test_culling_keeps_a_gaussian_whose_support_reaches_the_view():
    """Centre behind the camera or beside the frustum, yet the support reaches in."""
    scene = make_scene(positions=[[0, 0, -0.5], [1.2, 0, 1.0]], scales=[[0.3, 0.3, 0.3]] * 2, opacities=1.0)
    camera = look_at([0, 0, 0], [0, 0, 1], width=64, height=48, fov_y_degrees=60)
    assert sorted(sort_indices(DepthSorter(scene), camera, 1 / 255).tolist()) == [0, 1]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), yaw=st.floats(-3.2, 3.2), pitch=st.floats(-1.5, 1.5),
       distance=st.floats(0.2, 4.0), p_min=st.sampled_from([1e-3, 1 / 255, 0.05]),
       size=st.sampled_from([(24, 18), (20, 20), (12, 26)]))
def test_culling_is_conservative(seed, yaw, pitch, distance, p_min, size):
    """The reference image with every gaussian equals the one with only those kept."""
    scene = random_scene(n=120, seed=seed, spread=1.5, log_scale=(-3.0, -0.5))
    eye = distance * np.array([np.cos(pitch) * np.sin(yaw), np.sin(pitch), -np.cos(pitch) * np.cos(yaw)])
    camera = look_at(eye, [0.1, 0.2, 0.3], width=size[0], height=size[1], fov_y_degrees=70)
    settings_ = RenderSettings(p_min=p_min)
    kept = sort_indices(DepthSorter(scene), camera, p_min, "float")
    depth = (scene.positions.astype(np.float64) @ camera.R.T + camera.t)[:, 2]
    everything = np.argsort(-depth, kind="stable")
    kept = everything[np.isin(everything, kept)]  # same relative order: only culling differs
    full = render_reference(scene, camera, settings_, order=everything)
    culled = render_reference(scene, camera, settings_, order=kept)
    np.testing.assert_allclose(culled, full, atol=1e-12)


# -- the global keys: depth and distance (section 11) ---------------------------------------
def _camera_space(scene, camera) -> np.ndarray:
    return scene.positions.astype(np.float64) @ camera.R.T + camera.t


@pytest.mark.parametrize("method", ["float", "radix"])
def test_distance_order_is_descending_distance_from_the_camera(method):
    scene = random_scene(n=400, seed=5, degree=0)
    camera = look_at([0.3, -0.2, -3.0], [0, 0, 0], width=64, height=48, fov_y_degrees=90)
    order = sort_indices(DepthSorter(scene), camera, 1 / 255, method, dilation=None, key="distance")
    assert order.dtype == np.uint32 and order.size == scene.count  # all in front: nothing culled
    distance = np.linalg.norm(_camera_space(scene, camera), axis=1)
    # radix: keys within range/65535 share a bucket, kept in scene order
    slack = 1e-5 if method == "float" else (distance.max() - distance.min()) / 65535 * 1.01
    assert np.all(np.diff(distance[order]) <= slack)
    if method == "float":
        np.testing.assert_array_equal(order, np.argsort(-distance, kind="stable"))


def test_distance_ties_keep_scene_order_where_depth_differs():
    """Points on one sphere about the camera tie in distance (kept in scene order) but
    not in depth; scene order is the reverse of the depth order."""
    directions = np.array([[0.6, 0, 0.8], [0.0, 0.6, 0.8], [0, 0, 1.0], [0.8, 0, 0.6]])
    scene = make_scene(positions=2.0 * directions, scales=0.05, opacities=0.9)
    camera = look_at([0, 0, 0], [0, 0, 1], width=64, height=48, fov_y_degrees=120)
    sorter = DepthSorter(scene)
    for method in ("float", "radix"):
        assert sort_indices(sorter, camera, 1 / 255, method, dilation=None, key="distance").tolist() == [0, 1, 2, 3]
        assert sort_indices(sorter, camera, 1 / 255, method, dilation=None, key="depth").tolist() == [2, 0, 1, 3]


def _turned(camera, degrees: float, axis):
    """``camera`` turned in place (its centre fixed) by ``degrees`` about ``axis`` (camera space)."""
    from dataclasses import replace
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    angle = np.radians(degrees)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    q = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    return replace(camera, R=q @ camera.R, t=q @ camera.t)


@pytest.mark.parametrize("degrees, axis", [(15.0, (0, 1, 0)), (-10.0, (1, 0, 0)), (25.0, (0, 1, 1)),
                                           (12.0, (1, 1, 0))])
def test_distance_needs_no_new_sort_when_the_camera_turns_in_place_and_depth_does(degrees, axis):
    """Gaussians at distinct distances (0.01 apart) inside a cone every turned camera
    sees: the distance keys and order are the same after the turn, the depth order is not.
    dilation None: no frustum cull, so only the keys differ."""
    rng = np.random.default_rng(3)
    n = 150
    directions = np.column_stack([rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n), np.ones(n)])
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radii = 2.0 + 0.01 * rng.permutation(n)
    eye = np.array([0.2, -0.1, -1.0])
    scene = make_scene(positions=eye + directions * radii[:, None], scales=0.02, opacities=0.9)
    camera = look_at(eye, eye + [0, 0, 1], width=64, height=48, fov_y_degrees=120)
    turned = _turned(camera, degrees, axis)
    np.testing.assert_allclose(turned.center, camera.center, atol=1e-12)
    assert np.all(_camera_space(scene, turned)[:, 2] > 0)  # everything stays in front
    np.testing.assert_allclose(np.linalg.norm(_camera_space(scene, turned), axis=1),
                               np.linalg.norm(_camera_space(scene, camera), axis=1), rtol=1e-12)
    sorter = DepthSorter(scene)
    for method in ("float", "radix"):
        before = sort_indices(sorter, camera, 1 / 255, method, dilation=None, key="distance")
        after = sort_indices(sorter, turned, 1 / 255, method, dilation=None, key="distance")
        assert before.size == n
        np.testing.assert_array_equal(after, before)
        np.testing.assert_array_equal(before, np.argsort(-radii, kind="stable"))
        depth_before = sort_indices(sorter, camera, 1 / 255, method, dilation=None, key="depth")
        depth_after = sort_indices(sorter, turned, 1 / 255, method, dilation=None, key="depth")
        assert depth_before.size == depth_after.size == n
        assert not np.array_equal(depth_after, depth_before)


def test_orders_culls_once_and_sorts_each_key():
    scene = random_scene(n=300, seed=8, degree=0)
    camera = look_at([0.5, 0.2, -2.0], [0, 0, 0], width=48, height=32)
    sorter = DepthSorter(scene)
    request = SortRequest(camera, 1 / 255, keys=("distance", "depth", "distance"))
    result = sorter.sort(request)
    assert list(result.orders) == ["distance", "depth"] and result.keys == ("distance", "depth")
    for key, order in result.orders.items():
        assert order.key == key and order.request == request and order.answers(request)
        np.testing.assert_array_equal(order.indices, sort_indices(sorter, camera, 1 / 255, key=key))
    assert result.order is result.orders["distance"]  # the request's first key
    assert sorted(result.orders["depth"].indices.tolist()) == sorted(result.orders["distance"].indices.tolist())
    with pytest.raises(ValueError, match="sort key"):
        SortRequest(camera, 1 / 255, keys=("nearest",))
