"""Stereo frames on the GPU (render/gl/stereo_frame): each eye a mono render from
that eye, disparity, the shared sort and colour of the midpoint."""

import numpy as np
import pytest
from testkit import assert_matches, independent_eye, make_scene, random_scene, rendered, sorted_render

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.camera.stereo import StereoRig, custom_preset, eye_cameras
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.stereo_frame import StereoFrame, render_stereo, stereo_order
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

MID = look_at([0.2, -0.3, -3.0], [0, 0, 0], width=80, height=60, fov_y_degrees=50)


def stereo(renderer, camera, settings, rig, shared=True):
    """render_stereo with a DepthSorter of the renderer's scene."""
    with DepthSorter(renderer.scene) as sorter:
        return render_stereo(renderer, sorter, camera, settings, rig, shared=shared)


@pytest.fixture
def renderer(gl_ctx):
    r = GLRenderer(gl_ctx, random_scene(n=300, seed=2))
    yield r
    r.release()


def test_ipd_zero_gives_the_mono_image_in_both_eyes(renderer):
    mono = sorted_render(renderer, MID)
    for eye in stereo(renderer, MID, RenderSettings(), StereoRig(ipd=0.0)):
        np.testing.assert_array_equal(eye, mono)


@pytest.mark.parametrize("rig", [StereoRig(), StereoRig(ipd=0.07, convergence=1.5, scene_scale=0.25)],
                         ids=["default", "small-scene"])
def test_each_eye_is_a_mono_render_from_that_eye(renderer, rig):
    left, right = stereo(renderer, MID, RenderSettings(), rig, shared=False)
    for image, side in ((left, -1.0), (right, +1.0)):
        camera = independent_eye(MID, rig, side)
        np.testing.assert_allclose(image, sorted_render(renderer, camera), atol=1e-6)
    # and the eyes differ from each other and from the midpoint's view
    assert np.abs(left - right).max() > 0.05


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
        left, right = stereo(renderer, camera, RenderSettings(p_min=1e-3), rig)
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
        shared = stereo(demo_renderer, camera, settings, rig)
        own = stereo(demo_renderer, camera, settings, rig, shared=False)
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
        with DepthSorter(scene) as sorter:
            order = stereo_order(sorter, MID, RenderSettings(), rig)
        left, right = stereo(renderer, MID, RenderSettings(), rig)
        for image, eye in zip((left, right), eye_cameras(MID, rig)):
            assert_matches(image, render_reference(scene, eye, order=order.indices))
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
        with DepthSorter(scene) as sorter:
            order = set(stereo_order(sorter, camera, RenderSettings(), rig).indices.tolist())
            for eye in eye_cameras(camera, rig):
                assert set(exact_order(sorter, eye, RenderSettings()).indices.tolist()) <= order
            assert len(order) > exact_order(sorter, camera, RenderSettings()).count
    finally:
        renderer.release()


def test_a_preset_camera_renders_at_that_size(renderer):
    preset = custom_preset(96, 64, 100.0, 80.0)
    left, right = stereo(renderer, preset.camera(MID), RenderSettings(), StereoRig())
    assert left.shape == right.shape == (64, 96, 4)


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
        mono = sorted_render(renderer, camera)
        shared = stereo(renderer, camera, RenderSettings(), rig)
        own = stereo(renderer, camera, RenderSettings(), rig, shared=False)
    finally:
        renderer.release()
    # Zero disparity at the convergence distance: the gaussian's centre pixel is the same.
    centre = (32, 48)
    for eye in shared:
        np.testing.assert_allclose(eye[centre][:3], mono[centre][:3], atol=2e-3)
    assert np.abs(own[0][centre][:3] - own[1][centre][:3]).max() > 0.1


def test_draw_eyes_returns_each_eye_s_result_in_the_left_eye_s_depth_range(renderer):
    """A depth picture's automatic range is the left eye's, fixed for the right eye, so
    both results carry it; each eye is the mono render of that eye with its range."""
    rig = StereoRig(scene_scale=0.2)
    settings = RenderSettings()
    with DepthSorter(renderer.scene) as sorter:
        order = stereo_order(sorter, MID, settings, rig)
    eyes = left_eye, right_eye = eye_cameras(MID, rig)
    frame = StereoFrame(renderer.ctx)
    try:
        left, right = frame.draw_eyes(renderer, MID, settings, eyes, order, view=ChannelView("depth"))
        own_left = rendered(renderer, left_eye, settings, order, color_origin=MID.center, view=ChannelView("depth"))
        own_right = rendered(renderer, right_eye, settings, order, color_origin=MID.center, view=ChannelView("depth"))
        assert left.view_range is not None and left.view_range == own_left[1].view_range
        assert right.view_range == left.view_range != own_right[1].view_range  # the right eye's own would differ
        colour = frame.draw_eyes(renderer, MID, settings, eyes, order)
        assert all(result.view_range is None and result.order_stats is None for result in colour)
        per_pixel = frame.draw_eyes(renderer, MID, RenderSettings(order="per-pixel"), eyes, order)
        assert [result.order_stats.width for result in per_pixel] == [left_eye.width, right_eye.width]
    finally:
        frame.release()


def test_draw_eyes_draws_the_eyes_it_is_handed(renderer, monkeypatch):
    """The eyes are the caller's (the window makes them once a frame, with the frame's
    sort): the stereo frame derives none of its own, whatever they are."""
    settings = RenderSettings()
    with DepthSorter(renderer.scene) as sorter:
        order = stereo_order(sorter, MID, settings, StereoRig())
    eyes = eye_cameras(MID, StereoRig(ipd=0.3, scene_scale=0.5))  # not what StereoRig() would make
    drawn = []
    render_into = renderer.render_into
    monkeypatch.setattr(renderer, "render_into", lambda target, eye, *args, **kwargs: (
        drawn.append(eye), render_into(target, eye, *args, **kwargs))[1])
    frame = StereoFrame(renderer.ctx)
    try:
        frame.draw_eyes(renderer, MID, settings, eyes, order)
        assert len(drawn) == 2 and all(made is eye for made, eye in zip(drawn, eyes)) and frame.eyes is eyes
    finally:
        frame.release()
