"""Stereo eyes: poses and off-axis projections, layouts, headset presets and the frame
budget. Their GL renders (disparity, the shared sort and colour) are in
tests/render/test_stereo_frame.py."""

import numpy as np
import pytest
from testkit import independent_eye

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.stereo import (
    LAYOUTS,
    PRESETS,
    StereoRig,
    compose,
    composed_size,
    custom_preset,
    eye_cameras,
)
from raygs_viewer.errors import UserError

MID = look_at([0.2, -0.3, -3.0], [0, 0, 0], width=80, height=60, fov_y_degrees=50)


def test_eye_cameras_match_the_independent_construction():
    rig = StereoRig(ipd=0.064, convergence=3.0, scene_scale=0.5)
    for camera, side in zip(eye_cameras(MID, rig), (-1.0, 1.0)):
        expected = independent_eye(MID, rig, side)
        np.testing.assert_allclose(camera.t, expected.t, atol=1e-12)
        np.testing.assert_array_equal(camera.R, MID.R)
        assert camera.cx == pytest.approx(expected.cx) and camera.fx == MID.fx and camera.cy == MID.cy
    left, right = eye_cameras(MID, rig)
    assert np.linalg.norm(left.center - right.center) == pytest.approx(0.064 / 0.5)
    assert (right.center - left.center) @ MID.R[0] > 0  # the right eye is to the right


def test_layouts_put_each_eye_where_it_belongs():
    left = np.zeros((2, 3, 3), np.float32)
    right = np.ones((2, 3, 3), np.float32)
    left[..., 0], right[..., 0] = 0.25, 0.75
    sbs = compose(left, right, "sbs")
    assert sbs.shape == (2, 6, 3)
    np.testing.assert_array_equal(sbs[:, :3], left)
    np.testing.assert_array_equal(sbs[:, 3:], right)
    cross = compose(left, right, "cross")
    np.testing.assert_array_equal(cross[:, :3], right)
    np.testing.assert_array_equal(cross[:, 3:], left)
    anaglyph = compose(left, right, "anaglyph")
    np.testing.assert_array_equal(anaglyph[..., 0], left[..., 0])      # red: the left eye
    np.testing.assert_array_equal(anaglyph[..., 1:], right[..., 1:])   # cyan: the right eye
    np.testing.assert_array_equal(compose(left, right, "left"), left)
    np.testing.assert_array_equal(compose(left, right, "right"), right)
    assert set(LAYOUTS) == {"sbs", "cross", "anaglyph", "left", "right"}
    with pytest.raises(UserError):
        compose(left, right, "top-bottom")


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_render_at_their_per_eye_resolution(name):
    preset = PRESETS[name]
    camera = preset.camera(MID)
    assert (camera.width, camera.height) == (preset.width, preset.height)
    half_fov_x = np.degrees(np.arctan(camera.width / 2 / camera.fx))
    assert 2 * half_fov_x == pytest.approx(preset.fov_x)
    np.testing.assert_array_equal(camera.R, MID.R)
    np.testing.assert_allclose(camera.center, MID.center)


@pytest.mark.parametrize("kwargs", [{"ipd": -0.01}, {"ipd": float("nan")}, {"convergence": 0.0},
                                    {"scene_scale": 0.0}, {"scene_scale": True}])
def test_bad_rig_values_are_one_line_errors(kwargs):
    with pytest.raises(UserError) as info:
        StereoRig(**kwargs)
    assert "\n" not in str(info.value)


def test_bad_custom_presets_are_errors():
    for args in ((0, 10, 90.0, 90.0), (10, 10, 180.0, 90.0), (10, 10, 90.0, float("nan"))):
        with pytest.raises(UserError):
            custom_preset(*args)


def test_frame_budget_compares_both_eyes_with_each_refresh_rate():
    from raygs_viewer.camera.stereo import REFRESH_RATES, frame_budget
    rows = frame_budget(0.011)
    assert [rate for rate, _, _ in rows] == list(REFRESH_RATES) == [72, 90, 120]
    for rate, budget, fraction in rows:
        assert budget == pytest.approx(1 / rate) and fraction == pytest.approx(0.011 * rate)
    assert [fraction <= 1 for _, _, fraction in rows] == [True, True, False]  # 11 ms: fits 72 and 90 Hz


def test_composed_size():
    assert composed_size(37, 23, "sbs") == (74, 23)
    assert composed_size(37, 23, "cross") == (74, 23)
    for layout in ("anaglyph", "left", "right"):
        assert composed_size(37, 23, layout) == (37, 23)
    assert {layout for layout in LAYOUTS if composed_size(5, 3, layout) != (5, 3)} == {"sbs", "cross"}
