"""Stereo eyes: poses and off-axis projections, disparity, the shared sort and colour,
layouts and headset presets."""

import numpy as np
import pytest
from testkit import assert_matches, make_scene, random_scene

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.camera.stereo import (
    LAYOUTS,
    PRESETS,
    StereoRig,
    compose,
    custom_preset,
    eye_cameras,
)
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.stereo_frame import render_stereo, stereo_order
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings

MID = look_at([0.2, -0.3, -3.0], [0, 0, 0], width=80, height=60, fov_y_degrees=50)


@pytest.fixture
def renderer(gl_ctx):
    r = GLRenderer(gl_ctx, random_scene(n=300, seed=2))
    yield r
    r.release()


def _independent_eye(camera: Camera, rig: StereoRig, side: float) -> Camera:
    """The eye built from first principles: centre moved along the camera's right axis
    (R's first row, in world space), t = -R c, principal point shifted so the midline
    point at the convergence distance keeps its pixel."""
    baseline = rig.ipd / rig.scene_scale / 2
    center = camera.center + side * baseline * camera.R[0]
    shift = camera.fx * baseline / (rig.convergence / rig.scene_scale)
    return Camera(camera.width, camera.height, camera.fx, camera.fy, camera.cx + side * shift, camera.cy,
                  camera.R, -camera.R @ center)


def test_ipd_zero_gives_the_mono_image_in_both_eyes(renderer):
    mono = renderer.render(MID)
    for eye in render_stereo(renderer, MID, RenderSettings(), StereoRig(ipd=0.0)):
        np.testing.assert_array_equal(eye, mono)


@pytest.mark.parametrize("rig", [StereoRig(), StereoRig(ipd=0.07, convergence=1.5, scene_scale=0.25)],
                         ids=["default", "small-scene"])
def test_each_eye_is_a_mono_render_from_that_eye(renderer, rig):
    left, right = render_stereo(renderer, MID, RenderSettings(), rig, shared=False)
    for image, side in ((left, -1.0), (right, +1.0)):
        camera = _independent_eye(MID, rig, side)
        np.testing.assert_allclose(image, renderer.render(camera), atol=1e-6)
    # and the eyes differ from each other and from the midpoint's view
    assert np.abs(left - right).max() > 0.05


def test_eye_cameras_match_the_independent_construction():
    rig = StereoRig(ipd=0.064, convergence=3.0, scene_scale=0.5)
    for camera, side in zip(eye_cameras(MID, rig), (-1.0, 1.0)):
        expected = _independent_eye(MID, rig, side)
        np.testing.assert_allclose(camera.t, expected.t, atol=1e-12)
        np.testing.assert_array_equal(camera.R, MID.R)
        assert camera.cx == pytest.approx(expected.cx) and camera.fx == MID.fx and camera.cy == MID.cy
    left, right = eye_cameras(MID, rig)
    assert np.linalg.norm(left.center - right.center) == pytest.approx(0.064 / 0.5)
    assert (right.center - left.center) @ MID.R[0] > 0  # the right eye is to the right


def _alpha_centroid_u(image):
    alpha = image[..., 3].astype(np.float64)
    return (alpha.sum(axis=0) * (np.arange(image.shape[1]) + 0.5)).sum() / alpha.sum()


@pytest.mark.parametrize("depth", [0.8, 2.0, 5.0])
def test_disparity_has_the_right_sign_and_size(gl_ctx, depth):
    """A small gaussian on the midline at a known depth: the disparity u_left - u_right
    is 2 fx b (1/Z - 1/C): positive (crossed) nearer than the convergence distance,
    zero at it, negative beyond."""
    rig = StereoRig(ipd=0.063, convergence=2.0, scene_scale=1.0)
    camera = Camera(200, 100, 150.0, 150.0, 100.0, 50.0, np.eye(3), np.zeros(3))
    scene = make_scene([[0.0, 0.0, depth]], 0.004 * depth, opacities=0.9)
    renderer = GLRenderer(gl_ctx, scene)
    try:
        left, right = render_stereo(renderer, camera, RenderSettings(p_min=1e-3), rig)
    finally:
        renderer.release()
    disparity = _alpha_centroid_u(left) - _alpha_centroid_u(right)
    expected = 2 * camera.fx * rig.half_baseline * (1 / depth - 1 / rig.convergence_units)
    assert disparity == pytest.approx(expected, abs=0.02)
    if depth < 2.0:
        assert disparity > 1.0
    elif depth > 2.0:
        assert disparity < -1.0


def test_shared_sort_and_colour_stay_close_to_per_eye(demo_renderer, gl_ctx):
    """The viewer sorts once from the midpoint and evaluates SH there; at a human IPD
    on the demo (metre scale, SH degree 3) the eyes barely differ from their own sort
    and colour (measured: at most 0.009 at 320x240). With an absurd baseline (the scene
    a few centimetres across) they do differ, so the comparison can fail."""
    from raygs_viewer.scene.demo import demo_camera
    camera = demo_camera().resized(160, 120)
    settings = RenderSettings()
    for rig, bound in ((StereoRig(), 0.02), (StereoRig(scene_scale=0.01), None)):
        shared = render_stereo(demo_renderer, camera, settings, rig)
        own = render_stereo(demo_renderer, camera, settings, rig, shared=False)
        error = max(np.abs(a[..., :3] - b[..., :3]).max() for a, b in zip(shared, own))
        if bound is None:
            assert error > 0.1, error
        else:
            assert error < bound, error


def test_shared_images_match_the_reference_with_the_shared_order(renderer):
    """Each shared eye is a true RayGS render of that eye with the midpoint's order and
    colour: the float64 reference of the eye, drawing the same order, agrees, but only
    where colour does not depend on the view (SH degree 0 here)."""
    scene = random_scene(n=300, seed=2, degree=0)
    renderer = GLRenderer(renderer.ctx, scene)
    try:
        rig = StereoRig(scene_scale=0.2)
        order = stereo_order(renderer, MID, RenderSettings(), rig)
        left, right = render_stereo(renderer, MID, RenderSettings(), rig)
        for image, eye in zip((left, right), eye_cameras(MID, rig)):
            assert_matches(image, render_reference(scene, eye, order=order))
    finally:
        renderer.release()


def test_the_shared_order_keeps_what_either_eye_sees(gl_ctx):
    """Gaussians beyond the midpoint's left border that only the left eye sees (its
    frustum is shifted) stay in the order."""
    xs = np.linspace(-3.0, 3.0, 61)
    scene = make_scene(np.column_stack([xs, np.zeros_like(xs), np.full_like(xs, 2.0)]), 0.01, opacities=0.9)
    camera = Camera(64, 32, 40.0, 40.0, 32.0, 16.0, np.eye(3), np.zeros(3))
    rig = StereoRig(ipd=0.5, convergence=0.5)  # strong convergence: the eyes' views differ a lot
    renderer = GLRenderer(gl_ctx, scene)
    try:
        order = set(stereo_order(renderer, camera, RenderSettings(), rig).tolist())
        for eye in eye_cameras(camera, rig):
            assert set(renderer.sort(eye, RenderSettings()).tolist()) <= order
        assert len(order) > len(renderer.sort(camera, RenderSettings()))
    finally:
        renderer.release()


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


def test_a_preset_camera_renders_at_that_size(renderer):
    preset = custom_preset(96, 64, 100.0, 80.0)
    left, right = render_stereo(renderer, preset.camera(MID), RenderSettings(), StereoRig())
    assert left.shape == right.shape == (64, 96, 4)


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


def test_shared_colour_is_the_midpoints(gl_ctx):
    """One gaussian whose SH colour swings with the view direction (degree 1, along x):
    with shared colour both eyes see the midpoint's colour; each eye's own colour
    differs between the eyes."""
    sh = np.zeros((1, 4, 3), np.float32)
    sh[0, 0] = 0.0
    sh[0, 3] = [-2.0, 0.0, 2.0]  # basis -C1 x: red to the right, blue to the left
    scene = make_scene([[0.0, 0.0, 2.0]], 0.2, opacities=1.0, sh=sh, degree=1)
    camera = Camera(96, 64, 60.0, 60.0, 48.0, 32.0, np.eye(3), np.zeros(3))
    rig = StereoRig(ipd=0.8, convergence=2.0)
    renderer = GLRenderer(gl_ctx, scene)
    try:
        mono = renderer.render(camera)
        shared = render_stereo(renderer, camera, RenderSettings(), rig)
        own = render_stereo(renderer, camera, RenderSettings(), rig, shared=False)
    finally:
        renderer.release()
    # Zero disparity at the convergence distance: the gaussian's centre pixel is the same.
    centre = (32, 48)
    for eye in shared:
        np.testing.assert_allclose(eye[centre][:3], mono[centre][:3], atol=2e-3)
    assert np.abs(own[0][centre][:3] - own[1][centre][:3]).max() > 0.1


def test_frame_budget_compares_both_eyes_with_each_refresh_rate():
    from raygs_viewer.camera.stereo import REFRESH_RATES, frame_budget
    rows = frame_budget(0.011)
    assert [rate for rate, _, _ in rows] == list(REFRESH_RATES) == [72, 90, 120]
    for rate, budget, fraction in rows:
        assert budget == pytest.approx(1 / rate) and fraction == pytest.approx(0.011 * rate)
    assert [fraction <= 1 for _, _, fraction in rows] == [True, True, False]  # 11 ms: fits 72 and 90 Hz
