"""The per-frame sort: back to front, stable, and culling that never drops a visible gaussian."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from testkit import make_scene, random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.depth import DepthSorter, sort_back_to_front


def test_order_is_back_to_front():
    scene = random_scene(n=500, seed=2)
    camera = look_at([0.5, -0.4, -3.0], [0, 0, 0])
    order = DepthSorter(scene).order(camera, 1 / 255, method="float")
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
    assert DepthSorter(scene).order(camera, 1 / 255).tolist() == [0]


@pytest.mark.parametrize("width, height", [(64, 48), (48, 48)])
def test_culling_uses_each_axis_for_its_own_planes(width, height):
    """Far to the side but level (kept only if visible) and far above (dropped), on
    wide and square images alike."""
    scene = make_scene(positions=[[0.0, 0.0, 5.0], [0.0, -50.0, 5.0], [50.0, 0.0, 5.0]],
                       scales=[[0.1, 0.1, 0.1]] * 3, opacities=0.9)
    camera = look_at([0, 0, 0], [0, 0, 1], width=width, height=height)
    assert DepthSorter(scene).order(camera, 1 / 255).tolist() == [0]


def test_culling_keeps_a_gaussian_whose_support_reaches_the_view():
    """Centre behind the camera or beside the frustum, yet the support reaches in."""
    scene = make_scene(positions=[[0, 0, -0.5], [1.2, 0, 1.0]], scales=[[0.3, 0.3, 0.3]] * 2, opacities=1.0)
    camera = look_at([0, 0, 0], [0, 0, 1], width=64, height=48, fov_y_degrees=60)
    assert sorted(DepthSorter(scene).order(camera, 1 / 255).tolist()) == [0, 1]


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
    kept = DepthSorter(scene).order(camera, p_min, method="float")
    depth = (scene.positions.astype(np.float64) @ camera.R.T + camera.t)[:, 2]
    everything = np.argsort(-depth, kind="stable")
    kept = everything[np.isin(everything, kept)]  # same relative order: only culling differs
    full = render_reference(scene, camera, settings_, order=everything)
    culled = render_reference(scene, camera, settings_, order=kept)
    np.testing.assert_allclose(culled, full, atol=1e-12)
