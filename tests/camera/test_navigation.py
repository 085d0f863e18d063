"""Navigation (camera/navigation.py) and the lens (camera/lens.py): every direction is
checked by what it does to the image, plus the pole limit, the animation, the letterbox
lens, framing, and robustness against garbage input."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from testkit import random_rotation

from raygs_viewer.camera.lens import Lens
from raygs_viewer.camera.navigation import (
    UP_AXES,
    Navigator,
    Pose,
    framing_pose,
    scene_bounds,
)
from raygs_viewer.camera.pinhole import Camera, frame_points, look_at
from raygs_viewer.camera.up_axis import cameras_up

W, H = 640, 480


# --------------------------------------------------------------------------- helpers


def project(camera, world):
    """(u, v, z): continuous pixel coordinates and depth of a world point."""
    cam = camera.R @ np.asarray(world, dtype=np.float64) + camera.t
    return camera.fx * cam[0] / cam[2] + camera.cx, camera.fy * cam[1] / cam[2] + camera.cy, cam[2]


def view(nav, lens=Lens()):
    return lens.camera(nav.pose, W, H)


def assert_rotation(R, atol=1e-12):
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=atol)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=atol)


def level_pose(eye=(0.0, 0.0, -5.0), target=(0.0, 0.0, 0.0), up="-y"):
    return Pose.from_camera(look_at(eye, target, UP_AXES[up]))


def rolled_pose(roll_degrees=20.0, eye=(0.0, 0.0, -5.0)):
    """A level camera looking along +z, then rolled about its own forward axis."""
    a = math.radians(roll_degrees)
    roll = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    base = level_pose(eye)
    return Pose(base.position, roll @ base.R)


def angle_between(a, b):
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    return math.atan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b))


def rotation_angle(R0, R1):
    return math.acos(max(-1.0, min(1.0, (np.trace(R0 @ R1.T) - 1) / 2)))


def nav_at(pose=None, mode="fly", up="-y", center=(0.0, 0.0, 0.0), radius=1.0):
    return Navigator(pose if pose is not None else level_pose(up=up), np.array(center), radius, up=up, mode=mode)


# --------------------------------------------------------------------------- pose


def test_up_axes_are_the_six_signed_unit_axes():
    assert UP_AXES["-y"] == (0, -1, 0) and UP_AXES["+z"] == (0, 0, 1)
    vectors = {name: np.array(v) for name, v in UP_AXES.items()}
    assert len(vectors) == 6
    for name, v in vectors.items():
        axis = "xyz".index(name[1])
        expected = np.zeros(3)
        expected[axis] = 1.0 if name[0] == "+" else -1.0
        np.testing.assert_array_equal(v, expected)


def test_pose_from_camera_round_trips():
    rng = np.random.default_rng(3)
    for _ in range(20):
        R = random_rotation(rng)
        camera = Camera(63, 41, 70.0, 55.0, 30.2, 19.7, R, rng.normal(size=3) * 4)
        pose = Pose.from_camera(camera)
        np.testing.assert_allclose(pose.position, camera.center, atol=1e-12)
        np.testing.assert_array_equal(pose.R, camera.R)
        back = pose.camera(camera.width, camera.height, fx=camera.fx, fy=camera.fy, cx=camera.cx, cy=camera.cy)
        assert (back.width, back.height, back.fx, back.fy, back.cx, back.cy) == (63, 41, 70.0, 55.0, 30.2, 19.7)
        np.testing.assert_array_equal(back.R, camera.R)
        np.testing.assert_allclose(back.t, camera.t, atol=1e-12)
        point = rng.normal(size=3) * 3
        np.testing.assert_allclose(project(back, point), project(camera, point), rtol=1e-9, atol=1e-9)


def test_pose_validates_and_is_immutable():
    R = np.eye(3)
    with pytest.raises(ValueError):
        Pose(np.zeros(3), np.diag([1.0, 1.0, -1.0]))      # a reflection
    with pytest.raises(ValueError):
        Pose(np.zeros(3), 2 * R)
    with pytest.raises(ValueError):
        Pose(np.array([0.0, np.nan, 0.0]), R)
    with pytest.raises(ValueError):
        Pose(np.zeros(2), R)
    source = np.zeros(3)
    pose = Pose(source, R)
    source[0] = 7.0                                       # the pose kept its own copy
    assert pose.position[0] == 0.0
    with pytest.raises(ValueError):
        pose.position[0] = 1.0
    # Small drift (a JSON round-trip) is snapped onto a rotation.
    drifted = Pose(np.zeros(3), R + 1e-7)
    assert_rotation(drifted.R)


# --------------------------------------------------------------------------- lens


def test_lens_viewport_letterboxes_wide_and_tall_windows():
    camera = look_at([0, 0, -5], [0, 0, 0], width=640, height=480)
    lens = Lens.of_camera(camera)
    # Wide window: full height, bars left and right.
    assert lens.viewport(2000, 500) == (666, 0, 667, 500)
    # Tall window: full width, bars top and bottom.
    assert lens.viewport(640, 1000) == (0, 260, 640, 480)
    assert lens.viewport(320, 1000) == (0, 380, 320, 240)
    # Same aspect: the whole window.
    assert lens.viewport(1280, 960) == (0, 0, 1280, 960)
    # Degenerate windows still give a usable viewport.
    for size in [(1, 1), (1, 1000), (1000, 1), (0, 0)]:
        x, y, w, h = lens.viewport(*size)
        assert w >= 1 and h >= 1 and x >= 0 and y >= 0
    # The free lens always fills the window.
    assert Lens().viewport(2000, 500) == (0, 0, 2000, 500)
    assert Lens().viewport(640, 1000) == (0, 0, 640, 1000)


def test_lens_of_training_camera_at_its_own_size_is_exactly_its_intrinsics():
    rng = np.random.default_rng(5)
    camera = Camera(97, 61, 81.3, 77.9, 45.1, 33.6, random_rotation(rng), rng.normal(size=3))
    lens = Lens.of_camera(camera)
    out = lens.camera(Pose.from_camera(camera), 97, 61)
    assert (out.width, out.height, out.fx, out.fy, out.cx, out.cy) == (97, 61, 81.3, 77.9, 45.1, 33.6)
    np.testing.assert_array_equal(out.R, camera.R)
    assert lens.fov_y_degrees == pytest.approx(math.degrees(2 * math.atan(30.5 / 77.9)))


def test_letterboxed_lens_shows_the_training_view_scaled():
    rng = np.random.default_rng(6)
    camera = Camera(200, 100, 150.0, 140.0, 90.0, 55.0, random_rotation(rng), rng.normal(size=3))
    lens = Lens.of_camera(camera)
    x, y, w, h = lens.viewport(500, 700)   # tall: 500 x 250 in the middle
    assert (x, y, w, h) == (0, 225, 500, 250)
    out = lens.camera(Pose.from_camera(camera), 500, 700)
    assert (out.width, out.height) == (w, h)
    for _ in range(10):
        point = camera.center + camera.R.T @ np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), 3.0])
        u0, v0, _ = project(camera, point)
        u1, v1, _ = project(out, point)
        assert u1 == pytest.approx(u0 * 2.5) and v1 == pytest.approx(v0 * 2.5)


def test_free_lens_has_the_field_of_view_and_centred_square_pixels():
    pose = level_pose()
    lens = Lens(fov_y_degrees=50.0)
    camera = lens.camera(pose, 300, 200)
    assert (camera.width, camera.height, camera.cx, camera.cy) == (300, 200, 150, 100)
    assert camera.fx == camera.fy
    # A point 25 degrees above the axis lands on the top edge.
    point = pose.position + 4.0 * (pose.R[2] * math.cos(math.radians(25)) - pose.R[1] * math.sin(math.radians(25)))
    u, v, _ = project(camera, point)
    assert u == pytest.approx(150) and v == pytest.approx(0, abs=1e-9)
    free = Lens.of_camera(look_at([0, 0, -5], [0, 0, 0])).with_fov(30.0)
    assert free.source is None and free.fov_y_degrees == 30.0
    assert Lens().with_fov(500.0).fov_y_degrees == 179.0 and Lens().with_fov(-3).fov_y_degrees == 1.0
    for bad in (0.0, 180.0, float("nan")):
        with pytest.raises(ValueError):
            Lens(fov_y_degrees=bad)
    with pytest.raises(ValueError):
        Lens().with_fov(float("inf"))


# --------------------------------------------------------------------------- framing


def test_scene_bounds_matches_frame_points_and_handles_degenerate_clouds():
    rng = np.random.default_rng(8)
    points = rng.normal(size=(5000, 3)) * [1.0, 2.0, 0.5] + [3.0, -1.0, 2.0]
    points[::50] = np.nan
    points[7] = [1e30, 0, 0]                            # a stray point beyond the 99th percentile
    center, radius = scene_bounds(points.astype(np.float32))
    finite = points[np.all(np.isfinite(points), axis=1)].astype(np.float32).astype(np.float64)
    low, high = np.percentile(finite, [1, 99], axis=0)
    np.testing.assert_allclose(center, (low + high) / 2, rtol=1e-12)
    assert radius == pytest.approx(np.linalg.norm(high - low) / 2, rel=1e-12)
    assert radius < 10
    # Same view as the CLI's default framing.
    camera = frame_points(points.astype(np.float32), 640, 480)
    pose = framing_pose(center, radius, "-y", 60.0, 640 / 480)
    np.testing.assert_allclose(pose.position, camera.center, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(pose.R, camera.R, atol=1e-12)

    empty_center, empty_radius = scene_bounds(np.zeros((0, 3)))
    np.testing.assert_array_equal(empty_center, np.zeros(3))
    assert empty_radius == 1.0
    assert scene_bounds(np.full((4, 3), np.inf))[1] == 1.0
    one_center, one_radius = scene_bounds(np.array([[1.0, 2.0, 3.0]]))
    np.testing.assert_array_equal(one_center, [1.0, 2.0, 3.0])
    assert one_radius == 1e-6
    huge_center, huge_radius = scene_bounds(np.array([[-1e308, 0, 0], [1e308, 0, 0]]))
    assert np.all(np.isfinite(huge_center)) and math.isfinite(huge_radius)


@pytest.mark.parametrize("up", list(UP_AXES))
@pytest.mark.parametrize("aspect", [0.5, 4 / 3, 3.0])
def test_framing_pose_keeps_the_whole_sphere_in_view_level_and_upright(up, aspect):
    rng = np.random.default_rng(9)
    center, radius = np.array([1.0, -2.0, 0.5]), 2.5
    pose = framing_pose(center, radius, up, 60.0, aspect)
    width, height = round(240 * aspect), 240
    camera = Lens(60.0).camera(pose, width, height)
    up_vec = np.array(UP_AXES[up], dtype=np.float64)
    assert_rotation(pose.R)
    assert abs(np.dot(pose.R[2], up_vec)) < 1e-12   # horizontal view
    assert abs(np.dot(pose.R[0], up_vec)) < 1e-12   # no roll
    assert np.dot(pose.R[1], up_vec) < -0.99        # up is up on screen
    np.testing.assert_allclose(pose.position + np.dot(center - pose.position, pose.R[2]) * pose.R[2], center)
    directions = rng.normal(size=(4000, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    # ... and the silhouette: the points where rays from the camera graze the sphere.
    depth = float(np.dot(center - pose.position, pose.R[2]))
    sin_a = radius / depth
    phis = np.linspace(0, 2 * math.pi, 721)
    in_plane = np.cos(phis)[:, None] * pose.R[0] + np.sin(phis)[:, None] * pose.R[1]
    graze = -sin_a * pose.R[2] + math.sqrt(1 - sin_a ** 2) * in_plane
    sphere = center + radius * np.vstack([directions, graze])
    uvz = np.array([project(camera, p) for p in sphere])
    assert np.all(uvz[:, 2] > 0)
    assert uvz[:, 0].min() >= -1e-9 and uvz[:, 0].max() <= width + 1e-9
    assert uvz[:, 1].min() >= -1e-9 and uvz[:, 1].max() <= height + 1e-9
    if up == "+z":                                  # Blender's front view: from -y, x to the right
        np.testing.assert_allclose(pose.R, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)
    if up in ("-y", "+y", "+x", "-x"):              # along +z, like frame_points
        np.testing.assert_allclose(pose.R[2], [0, 0, 1], atol=1e-12)
    # Tight: the sphere touches the narrower pair of edges.
    spread = max((uvz[:, 0].max() - uvz[:, 0].min()) / width, (uvz[:, 1].max() - uvz[:, 1].min()) / height)
    assert spread > 0.999


# --------------------------------------------------------------------------- fly: move


def test_move_forward_brings_the_scene_closer_by_speed_times_dt():
    nav = nav_at(radius=2.0)
    z0 = project(view(nav), nav.center)[2]
    nav.move(0.05, 0, 0, 1)                       # W
    z1 = project(view(nav), nav.center)[2]
    assert z1 == pytest.approx(z0 - 0.05 * 1.0)  # default speed 0.5 * radius
    nav.move(0.05, 0, 0, -1)                      # S
    assert project(view(nav), nav.center)[2] == pytest.approx(z0)


def test_move_right_shifts_the_scene_left_on_screen():
    nav = nav_at(rolled_pose(30.0))
    camera = view(nav)
    ahead = nav.pose.position + 3.0 * nav.pose.R[2]
    right_axis = nav.pose.R[0].copy()
    nav.move(0.1, 1, 0, 0)                        # D
    u, v, _ = project(view(nav), ahead)
    assert u < camera.cx and v == pytest.approx(camera.cy)
    np.testing.assert_allclose(nav.pose.position - camera.center, 0.05 * right_axis, atol=1e-12)
    nav.move(0.1, -1, 0, 0)                       # A
    np.testing.assert_allclose(nav.pose.position, camera.center, atol=1e-12)


@pytest.mark.parametrize("up", list(UP_AXES))
def test_q_and_e_move_along_the_world_up_axis(up):
    pose = framing_pose(np.zeros(3), 1.0, up, 60.0, W / H)
    nav = nav_at(pose, up=up)
    ahead = pose.position + 3.0 * pose.R[2]
    nav.move(0.1, 0, 1, 0)                        # E
    np.testing.assert_allclose(nav.pose.position - pose.position, 0.05 * np.array(UP_AXES[up]), atol=1e-12)
    u, v, _ = project(view(nav), ahead)
    assert v > H / 2 and u == pytest.approx(W / 2)  # camera went up, so the scene went down
    nav.move(0.1, 0, -1, 0)                       # Q
    nav.move(0.1, 0, -1, 0)
    np.testing.assert_allclose(nav.pose.position - pose.position, -0.05 * np.array(UP_AXES[up]), atol=1e-12)
    # Up is world up, not camera up: a tilted camera still rises straight up.
    nav.look(0, 200)
    before = nav.pose.position
    nav.move(0.1, 0, 1, 0)
    np.testing.assert_allclose(nav.pose.position - before, 0.05 * np.array(UP_AXES[up]), atol=1e-12)


def test_speed_scale_fast_slow_dt_clamp_and_diagonals():
    nav = nav_at(radius=4.0)
    assert nav.speed == 2.0
    nav.scale(2)
    assert nav.speed == pytest.approx(2.0 * 1.25 ** 2)
    nav.scale(-2)
    assert nav.speed == pytest.approx(2.0)

    def step(**kwargs):
        before = nav.pose.position
        nav.move(kwargs.pop("dt", 0.01), 0, 0, 1, **kwargs)
        return float(np.linalg.norm(nav.pose.position - before))

    assert step() == pytest.approx(0.02)
    assert step(fast=True) == pytest.approx(0.08)
    assert step(slow=True) == pytest.approx(0.005)
    assert step(dt=5.0) == pytest.approx(0.2)      # dt clamped to 0.1 s
    assert step(dt=1e9) == pytest.approx(0.2)
    before = nav.pose.position
    nav.move(0.1, 1, 0, 1)                          # W + D: no faster than W alone
    assert np.linalg.norm(nav.pose.position - before) == pytest.approx(0.2)
    nav.scale(1e6)
    assert nav.speed == pytest.approx(2.0 * 1e4)
    nav.scale(-1e6)
    assert nav.speed == pytest.approx(2.0 * 1e-4)


# --------------------------------------------------------------------------- fly: look


def test_look_right_and_down_turn_the_view_by_0_003_rad_per_pixel():
    nav = nav_at()
    camera = view(nav)
    ahead = nav.pose.position + 5.0 * nav.pose.R[2]
    nav.look(100, 0)                              # mouse right: view turns right
    u, v, _ = project(view(nav), ahead)
    assert u == pytest.approx(camera.cx - camera.fx * math.tan(0.3)) and v == pytest.approx(camera.cy)
    nav = nav_at()
    nav.look(0, 100)                              # mouse down: view tilts down
    u, v, _ = project(view(nav), ahead)
    assert v == pytest.approx(camera.cy - camera.fy * math.tan(0.3)) and u == pytest.approx(camera.cx)


@pytest.mark.parametrize("up", list(UP_AXES))
def test_yaw_turns_about_world_up_and_keeps_roll(up):
    rng = np.random.default_rng(11)
    up_vec = np.array(UP_AXES[up], dtype=np.float64)
    base = framing_pose(np.zeros(3), 1.0, up, 60.0, 1.0)
    a = math.radians(25.0)
    roll = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    nav = nav_at(Pose(base.position, roll @ base.R), up=up)
    x_up = float(np.dot(nav.pose.R[0], up_vec))
    assert abs(x_up) > 0.3
    f_up = float(np.dot(nav.pose.R[2], up_vec))
    nav.look(150, 0)
    assert np.dot(nav.pose.R[2], up_vec) == pytest.approx(f_up, abs=1e-12)  # yaw keeps elevation
    assert nav.pose.R[2] @ np.cross(base.R[2], up_vec) > 0.1  # turned towards the right
    for _ in range(2000):
        nav.look(*rng.uniform(-40, 40, 2))
    assert np.dot(nav.pose.R[0], up_vec) == pytest.approx(x_up, abs=1e-9)   # no roll growth
    assert_rotation(nav.pose.R)


def test_look_pitch_stops_one_degree_short_of_either_pole():
    for up in UP_AXES:
        up_vec = np.array(UP_AXES[up], dtype=np.float64)
        for dy in (1e9, -1e9):
            nav = nav_at(framing_pose(np.zeros(3), 1.0, up, 60.0, 1.0), up=up)
            nav.look(0, dy)
            forward = nav.pose.R[2]
            # Exactly at the limit, not short of it nor past it.
            pole = -up_vec if dy > 0 else up_vec
            assert math.degrees(angle_between(forward, pole)) == pytest.approx(1.0, abs=1e-9)
            assert np.dot(nav.pose.R[1], up_vec) < 0      # still upright: never flipped over
            assert_rotation(nav.pose.R)
    # Many small steps the same way stop at the same place.
    nav = nav_at()
    for _ in range(500):
        nav.look(3, 40)
    assert math.degrees(angle_between(nav.pose.R[2], np.array([0.0, 1.0, 0.0]))) == pytest.approx(1.0, abs=1e-9)
    nav.look(0, -100)                                     # and it can come back up
    assert math.degrees(angle_between(nav.pose.R[2], np.array([0.0, 1.0, 0.0]))) > 5


def test_pitch_limit_holds_for_a_rolled_camera_and_one_that_starts_at_the_pole():
    up_vec = np.array([0.0, -1.0, 0.0])
    nav = nav_at(rolled_pose(35.0))
    for dy in (1e9, -1e9, 1e9):
        nav.look(7, dy)
        assert angle_between(nav.pose.R[2], up_vec) >= math.radians(1.0) - 1e-12
        assert angle_between(nav.pose.R[2], -up_vec) >= math.radians(1.0) - 1e-12
    # A nadir camera (looking straight down) may tilt up, not further down.
    nadir = Pose(np.zeros(3), np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]))
    assert np.dot(nadir.R[2], up_vec) == -1.0
    nav = nav_at(nadir)
    nav.look(0, 50)
    np.testing.assert_allclose(nav.pose.R, nadir.R, atol=1e-12)
    nav.look(0, -50)
    assert angle_between(nav.pose.R[2], -up_vec) == pytest.approx(0.15, rel=1e-9)


# --------------------------------------------------------------------------- orbit


def test_rotate_keeps_the_target_centred_and_turns_the_scene_with_the_mouse():
    nav = nav_at(mode="orbit", center=(0.2, 0.1, 0.3), radius=1.0)
    target, distance = nav.target, nav.distance
    old = view(nav)
    near = target - 0.5 * distance * nav.pose.R[2]         # a point between camera and target
    nav.rotate(80, 0)                                      # drag right
    camera = view(nav)
    u, v, z = project(camera, target)
    assert (u, v) == (pytest.approx(W / 2, abs=1e-9), pytest.approx(H / 2, abs=1e-9))
    assert z == pytest.approx(distance) and nav.distance == distance
    np.testing.assert_allclose(nav.target, target, atol=1e-12)
    assert (old.R @ camera.center + old.t)[0] < 0          # the camera went left...
    assert project(camera, near)[0] > W / 2                # ...so the near side turned right
    assert (old.R @ camera.center + old.t)[1] == pytest.approx(0, abs=1e-12)  # about the up axis

    old = camera
    nav.rotate(0, 80)                                      # drag down
    camera = view(nav)
    u, v, z = project(camera, target)
    assert (u, v) == (pytest.approx(W / 2, abs=1e-9), pytest.approx(H / 2, abs=1e-9))
    assert z == pytest.approx(distance)
    assert (old.R @ camera.center + old.t)[1] < 0          # camera went up (camera y is down)...
    assert np.dot(camera.R[2], [0.0, -1.0, 0.0]) < 0       # ...and now looks down at the target


def test_rotate_respects_the_pole_and_stays_centred_over_long_sessions():
    rng = np.random.default_rng(12)
    nav = nav_at(mode="orbit")
    target = nav.target
    for _ in range(3000):
        nav.rotate(*rng.normal(0, 60, 2))
        assert angle_between(nav.pose.R[2], np.array([0.0, 1.0, 0.0])) >= math.radians(1.0) - 1e-12
        assert angle_between(nav.pose.R[2], np.array([0.0, -1.0, 0.0])) >= math.radians(1.0) - 1e-12
    assert_rotation(nav.pose.R)
    np.testing.assert_allclose(nav.target, target, atol=1e-9)
    u, v, z = project(view(nav), target)
    assert u == pytest.approx(W / 2, abs=1e-6) and v == pytest.approx(H / 2, abs=1e-6)
    assert z == pytest.approx(nav.distance)


@pytest.mark.parametrize("dx,dy", [(30.0, 0.0), (0.0, -25.0), (-12.5, 40.0)])
def test_pan_moves_the_target_with_the_mouse_pixel_for_pixel(dx, dy):
    nav = nav_at(rolled_pose(10.0), mode="orbit")
    camera = view(nav)
    target, R, distance = nav.target, nav.pose.R, nav.distance
    nav.pan(dx, dy, camera.fx)
    u, v, _ = project(view(nav), target)                  # the old target point
    assert u == pytest.approx(camera.cx + dx) and v == pytest.approx(camera.cy + dy)
    np.testing.assert_array_equal(nav.pose.R, R)
    assert nav.distance == distance
    np.testing.assert_allclose(nav.target - target, nav.pose.position - camera.center, atol=1e-12)


def test_zoom_scales_the_distance_about_the_target():
    nav = nav_at(mode="orbit")
    target, d0 = nav.target, nav.distance
    nav.zoom(3)                                            # wheel up: closer
    assert nav.distance == pytest.approx(d0 * 0.85 ** 3)
    assert np.linalg.norm(nav.pose.position - target) == pytest.approx(d0 * 0.85 ** 3)
    np.testing.assert_allclose(nav.target, target, atol=1e-12)
    assert project(view(nav), target)[2] == pytest.approx(d0 * 0.85 ** 3)
    nav.zoom(-5)
    assert nav.distance == pytest.approx(d0 * 0.85 ** -2)
    nav.zoom(1e6)
    assert nav.distance == pytest.approx(1e-6 * nav.radius)
    nav.zoom(-1e6)
    assert math.isfinite(nav.distance) and np.all(np.isfinite(nav.pose.position))


def test_switching_modes_places_the_target_on_the_forward_axis():
    # Scene centre in front: the first orbit distance is its depth.
    nav = nav_at(level_pose(eye=(0.3, 0.0, -5.0), target=(0.3, 0.0, 0.0)), center=(0.0, 0.2, 0.0), radius=1.0)
    assert nav.distance == pytest.approx(5.0)
    pose = nav.pose
    nav.set_mode("orbit")
    np.testing.assert_allclose(nav.target, [0.3, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(nav.pose.R, pose.R)
    np.testing.assert_array_equal(nav.pose.position, pose.position)
    nav.zoom(2)
    nav.set_mode("fly")
    moved = nav.pose
    nav.move(0.1, 0, 0, 1)
    nav.set_mode("orbit")                                  # keeps the zoomed distance
    assert nav.distance == pytest.approx(5.0 * 0.85 ** 2)
    np.testing.assert_allclose(nav.target, nav.pose.position + nav.distance * moved.R[2])
    # Scene centre behind the camera (or too close): the radius.
    assert nav_at(level_pose(eye=(0, 0, 5.0), target=(0, 0, 10.0)), radius=2.0).distance == 2.0
    assert nav_at(level_pose(eye=(0, 0, -0.05)), radius=1.0).distance == 1.0
    with pytest.raises(ValueError):
        nav.set_mode("walk")
    with pytest.raises(ValueError):
        Navigator(pose, np.zeros(3), 1.0, mode="walk")


def test_set_up_relevels_and_validates():
    nav = nav_at(rolled_pose(30.0))
    forward = nav.pose.R[2]
    nav.set_up("-y")
    np.testing.assert_allclose(nav.pose.R[2], forward, atol=1e-12)
    assert abs(nav.pose.R[0] @ [0.0, -1.0, 0.0]) < 1e-12
    assert nav.pose.R[1] @ [0.0, -1.0, 0.0] < 0
    nav.set_up("+z")
    assert nav.up == "+z"
    # Forward was along +z, now the pole: tilted 1 degree off it, still level.
    assert math.degrees(angle_between(nav.pose.R[2], np.array([0.0, 0.0, 1.0]))) == pytest.approx(1.0)
    assert abs(nav.pose.R[0] @ [0.0, 0.0, 1.0]) < 1e-12
    assert nav.pose.R[1] @ [0.0, 0.0, 1.0] < 0
    assert_rotation(nav.pose.R)
    before = nav.pose.position
    nav.move(0.1, 0, 1, 0)
    np.testing.assert_allclose(nav.pose.position - before, [0.0, 0.0, 0.05], atol=1e-12)
    with pytest.raises(ValueError):
        nav.set_up("up")
    with pytest.raises(ValueError):
        Navigator(nav.pose, np.zeros(3), 1.0, up="y")


# --------------------------------------------------------------------------- animation


def test_fly_to_reaches_the_exact_pose_and_is_in_between_midway():
    rng = np.random.default_rng(13)
    start = Pose(rng.normal(size=3), random_rotation(rng))
    end = Pose(rng.normal(size=3) * 3, random_rotation(rng))
    nav = nav_at(start)
    nav.fly_to(end, duration=0.6)
    assert nav.animating
    nav.advance(0.3)
    mid = nav.pose
    np.testing.assert_allclose(mid.position, (start.position + end.position) / 2, atol=1e-12)
    total = rotation_angle(start.R, end.R)
    assert rotation_angle(start.R, mid.R) == pytest.approx(total / 2, abs=1e-9)
    assert rotation_angle(mid.R, end.R) == pytest.approx(total / 2, abs=1e-9)
    assert_rotation(mid.R)
    nav.advance(0.1)
    early = np.linalg.norm(nav.pose.position - start.position) / np.linalg.norm(end.position - start.position)
    assert early == pytest.approx((2 / 3) ** 2 * (3 - 4 / 3))   # smoothstep(0.4 / 0.6), not linear
    nav.advance(0.25)                                      # past the end
    assert not nav.animating
    np.testing.assert_array_equal(nav.pose.position, end.position)
    np.testing.assert_array_equal(nav.pose.R, end.R)
    nav.advance(1.0)
    np.testing.assert_array_equal(nav.pose.position, end.position)


def test_fly_to_takes_the_shortest_arc():
    start = level_pose()
    a = math.radians(200.0)                                # the short way is 160 degrees back
    turn = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    end = Pose(start.position, turn @ start.R)
    nav = nav_at(start)
    nav.fly_to(end, duration=1.0)
    nav.advance(0.5)
    assert math.degrees(rotation_angle(start.R, nav.pose.R)) == pytest.approx(80.0)


def test_input_cancels_fly_to_but_idle_frames_do_not():
    rng = np.random.default_rng(14)
    end = Pose(np.array([3.0, 0.0, 1.0]), random_rotation(rng))
    nav = nav_at()
    nav.fly_to(end, duration=0.6)
    nav.advance(0.2)
    nav.move(0.016, 0, 0, 0)                               # no key held
    nav.look(0, 0)
    nav.scale(1)
    assert nav.animating
    nav.advance(0.1)
    between = nav.pose
    nav.look(5, 0)
    assert not nav.animating
    after_look = nav.pose
    assert rotation_angle(between.R, after_look.R) == pytest.approx(0.015, abs=1e-9)
    np.testing.assert_array_equal(after_look.position, between.position)
    nav.advance(0.5)
    np.testing.assert_array_equal(nav.pose.R, after_look.R)
    for cancel in (lambda n: n.move(0.01, 0, 0, 1), lambda n: n.rotate(1, 0), lambda n: n.pan(1, 0, 500.0),
                   lambda n: n.zoom(1), lambda n: n.set_pose(end)):
        nav.fly_to(level_pose(), duration=0.6)
        nav.advance(0.1)
        cancel(nav)
        assert not nav.animating
    nav.fly_to(level_pose(eye=(1, 2, -5)), duration=0)      # zero duration: a jump
    assert not nav.animating
    np.testing.assert_array_equal(nav.pose.position, [1, 2, -5])


def test_reset_restores_pose_speed_and_distance():
    start = level_pose()
    nav = nav_at(start, mode="orbit", radius=0.5)
    nav.scale(5)
    nav.zoom(4)
    nav.rotate(100, 30)
    nav.fly_to(Pose(np.ones(3), np.eye(3)))
    nav.reset(start)
    assert not nav.animating
    assert nav.speed == 0.25 and nav.distance == pytest.approx(5.0)
    np.testing.assert_array_equal(nav.pose.position, start.position)
    np.testing.assert_array_equal(nav.pose.R, start.R)


# --------------------------------------------------------------------------- robustness


def test_non_finite_input_is_ignored_and_huge_input_is_clamped():
    nav = nav_at()
    pose = nav.pose
    nan, inf = float("nan"), float("inf")
    nav.move(nan, 0, 0, 1)
    nav.move(0.1, nan, 0, 1)
    nav.move(-1.0, 0, 0, 1)
    nav.look(nan, 5)
    nav.look(5, inf)
    nav.rotate(inf, 0)
    nav.pan(nan, 1, 500)
    nav.pan(1, 1, 0.0)
    nav.zoom(nan)
    nav.scale(inf)
    nav.advance(nan)
    np.testing.assert_array_equal(nav.pose.position, pose.position)
    np.testing.assert_array_equal(nav.pose.R, pose.R)
    assert nav.speed == 0.5 and nav.distance == 5.0
    for call in (lambda: nav.move(1e9, 1e9, -1e9, 1e9, fast=True), lambda: nav.look(1e9, -1e9),
                 lambda: nav.rotate(-1e9, 1e9), lambda: nav.pan(1e9, 1e9, 1e-9), lambda: nav.zoom(-1e6),
                 lambda: nav.scale(1e6), lambda: nav.move(1e9, 0, 0, 1), lambda: nav.zoom(1e6)):
        call()
        assert np.all(np.isfinite(nav.pose.position))
        assert_rotation(nav.pose.R)
        assert math.isfinite(nav.speed) and nav.speed > 0
        assert math.isfinite(nav.distance) and nav.distance > 0


_value = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-1e3, 1e3))
_op = st.tuples(st.sampled_from(["move", "look", "rotate", "pan", "zoom", "scale", "mode", "up", "fly", "advance"]),
                _value, _value, _value, st.booleans())


@settings(max_examples=150, deadline=None)
@given(st.lists(_op, max_size=40))
def test_any_sequence_of_calls_keeps_a_finite_orthonormal_pose(ops):
    nav = nav_at(rolled_pose(15.0), radius=0.7)
    other = Pose(np.array([1.0, -2.0, 3.0]), look_at([0, 0, 0], [1, 1, 1]).R)
    for name, a, b, c, flag in ops:
        if name == "move":
            nav.move(a, b, c, 1.0, fast=flag, slow=not flag)
        elif name == "look":
            nav.look(a, b)
        elif name == "rotate":
            nav.rotate(a, b)
        elif name == "pan":
            nav.pan(a, b, c)
        elif name == "zoom":
            nav.zoom(a)
        elif name == "scale":
            nav.scale(a)
        elif name == "mode":
            nav.set_mode("orbit" if flag else "fly")
        elif name == "up":
            nav.set_up(list(UP_AXES)[int(abs(c)) % 6] if math.isfinite(c) else "-y")
        elif name == "fly":
            nav.fly_to(other, a)
        else:
            nav.advance(a)
        pose = nav.pose
        assert np.all(np.isfinite(pose.position))
        assert_rotation(pose.R, atol=1e-9)
        assert math.isfinite(nav.speed) and nav.speed > 0
        assert math.isfinite(nav.distance) and nav.distance > 0
        assert np.all(np.isfinite(nav.target))


# --------------------------------------------------------------------------- up from the cameras


def rolled(camera: Camera) -> Camera:
    """``camera`` turned 180 degrees about its optical axis: its image down is the other way."""
    flip = np.diag([-1.0, -1.0, 1.0])
    return Camera(camera.width, camera.height, camera.fx, camera.fy, camera.width - camera.cx,
                  camera.height - camera.cy, flip @ camera.R, flip @ camera.t)


def test_cameras_up_is_the_axis_nearest_their_mean_up():
    level = [look_at(eye, (0, 0, 0)) for eye in ((0, -1, -4), (3, -0.5, -2), (-4, 0.3, 1))]  # image down ~ +y
    assert cameras_up(level) == "-y"
    assert cameras_up([rolled(c) for c in level]) == "+y"
    # Blender-style cameras, z up, tilted and one of them rolled by 30 degrees: snapped to +z.
    blender = [look_at(eye, (0, 0, 0), up=(0, 0, 1)) for eye in ((0, -4, 1), (4, 1, 2), (-3, 3, -1))]
    roll = math.radians(30)
    tilt = np.array([[math.cos(roll), -math.sin(roll), 0], [math.sin(roll), math.cos(roll), 0], [0, 0, 1]])
    blender[1] = Camera(*[getattr(blender[1], f) for f in ("width", "height", "fx", "fy", "cx", "cy")],
                        tilt @ blender[1].R, tilt @ blender[1].t)
    assert cameras_up(blender) == "+z"


def test_cameras_up_is_none_without_cameras_or_an_agreed_axis():
    camera = look_at((0, 0, -4), (0, 0, 0))
    assert cameras_up([]) is None
    assert cameras_up([camera, rolled(camera)]) is None  # their ups cancel out
    # Half-way between -y and +z: no axis is nearer.
    between = look_at((0, -4, -4), (0, 0, 0), up=(0, -1, 1))
    assert abs(-between.R[1] @ np.array([0, -1, 0]) - (-between.R[1] @ np.array([0, 0, 1]))) < 1e-9
    assert cameras_up([between]) is None
