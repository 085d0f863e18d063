"""Camera paths: the spline passes through its keyframes, flies at an even speed, keeps
orientations proper, smooth and roll-free, and refuses bad numbers in one line."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from testkit import random_rotation

from raygs_viewer.camera.navigation import Pose, up_vector
from raygs_viewer.camera.path import (
    MAX_DURATION,
    MAX_KEYFRAMES,
    CameraPath,
    Interpolation,
    Keyframe,
    dolly_path,
    orbit_path,
    path_through_cameras,
)
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.rotation import (
    axis_rotation,
    level_rotation,
    matrix_to_quaternion,
)
from raygs_viewer.errors import UserError

UP = up_vector("-y")


def level(forward, up=UP):
    return level_rotation(np.asarray(forward, dtype=np.float64), up)


def rolled(R, degrees):
    """R turned about its own forward by ``degrees`` (camera x towards camera y)."""
    return axis_rotation(np.array([0.0, 0.0, 1.0]), math.radians(degrees)).T @ R


def path_of(positions, rotations=None, fovs=None, times=None, **kwargs):
    count = len(positions)
    rotations = [np.eye(3)] * count if rotations is None else rotations
    fovs = [60.0] * count if fovs is None else fovs
    times = [None] * count if times is None else times
    keys = tuple(Keyframe(Pose(p, R), f, t) for p, R, f, t in zip(positions, rotations, fovs, times))
    interpolation = kwargs.pop("interpolation", Interpolation())
    return CameraPath(keys, interpolation=interpolation, **kwargs)


def dense(path, count=4001):
    times = np.linspace(0.0, path.duration, count)
    return times, path.sample(times)


def angle_between(Ra, Rb):
    """(M,) rotation angles in radians between stacks of rotations."""
    trace = np.einsum("mij,mij->m", Ra, Rb)
    return np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))


def angular_velocity(path, t, h):
    """World angular velocity vectors just before and just after ``t`` (one-sided)."""
    R = path.sample([t - h, t, t + h]).rotations

    def omega(Ra, Rb):
        # Rb = Ra exp(...) in world terms: W = Ra^T Rb - I ~ skew(w) * dt
        W = Ra.T @ Rb
        return np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / (2.0 * h)

    return omega(R[0], R[1]), omega(R[1], R[2])


def random_keyframes(rng, count, roll=True):
    keys = []
    for _ in range(count):
        R = random_rotation(rng) if roll else level(rng.normal(size=3) * [1, 0.3, 1])
        keys.append(Keyframe(Pose(rng.normal(size=3) * 2.0, R), float(rng.uniform(20, 100))))
    return tuple(keys)


# --------------------------------------------------------------------------- keyframes


@pytest.mark.parametrize("loop", [False, True])
def test_the_flight_passes_through_every_keyframe_position_rotation_and_fov(loop):
    rng = np.random.default_rng(3)
    keys = list(random_keyframes(rng, 6))
    keys[3] = Keyframe(keys[3].pose, keys[3].fov_y_degrees, 4.5)     # one anchored
    path = CameraPath(tuple(keys), duration=9.0, interpolation=Interpolation(loop=loop))
    times = path.keyframe_times()
    assert times[3] == 4.5
    assert np.all(np.diff(times) > 0)
    samples = path.sample(times)
    for i, key in enumerate(keys):
        assert np.allclose(samples.positions[i], key.pose.position, atol=1e-9)
        assert np.allclose(samples.rotations[i], key.pose.R, atol=1e-9)
        assert samples.fov_y_degrees[i] == pytest.approx(key.fov_y_degrees, abs=1e-9)
        single = path.pose_at(times[i])
        assert np.allclose(single.pose.R, key.pose.R, atol=1e-9)
    end = path.pose_at(path.duration)
    assert np.allclose(end.pose.position, keys[0 if loop else -1].pose.position, atol=1e-9)


def test_one_keyframe_holds_and_two_fly_a_straight_line():
    key = Keyframe(Pose([1.0, 2.0, 3.0], level([1, 0, 1])), 45.0)
    one = CameraPath((key,), duration=2.0, fps=5)
    for t in (-1.0, 0.0, 0.7, 2.0, 50.0):
        pose = one.pose_at(t)
        assert np.array_equal(pose.pose.position, key.pose.position) and pose.fov_y_degrees == 45.0
    assert len(one.cameras(64, 48)) == 10
    assert one.polyline().shape == (1, 3)
    assert np.array_equal(one.keyframe_times(), [0.0])
    assert CameraPath((key,), interpolation=Interpolation(loop=True)).pose_at(3.0).fov_y_degrees == 45.0

    two = path_of([[0, 0, 0], [3, 4, 0]])
    times, samples = dense(two, 101)
    assert np.allclose(samples.positions, np.outer(times / two.duration, [3, 4, 0]), atol=1e-9)
    assert two.length == pytest.approx(5.0)


def test_empty_path():
    path = CameraPath()
    assert path.frame_count == 0 and path.cameras(64, 48) == [] and path.polyline().shape == (0, 3)
    assert path.keyframe_times().shape == (0,) and path.length == 0.0
    with pytest.raises(ValueError):
        path.pose_at(0.0)


# --------------------------------------------------------------------------- pacing


def test_speed_is_even_along_a_straight_path_with_uneven_keyframes():
    direction = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    offsets = [0.0, 0.1, 0.15, 2.0, 2.3, 7.0]
    path = path_of([d * direction for d in offsets], duration=7.0)
    times, samples = dense(path)
    speed = np.linalg.norm(np.diff(samples.positions, axis=0), axis=1) / np.diff(times)
    assert np.abs(speed / speed.mean() - 1.0).max() < 1e-3
    assert speed.mean() == pytest.approx(1.0, rel=1e-6)        # 7 units in 7 s
    assert np.allclose(path.keyframe_times(), offsets, atol=1e-6)  # time in proportion to distance
    # Keyframe spacing does not leak into the position: off the line by nothing.
    along = samples.positions @ direction
    assert np.allclose(samples.positions, along[:, None] * direction, atol=1e-9)


def test_explicit_times_are_anchors_with_even_speed_between_them():
    positions = [[0, 0, 0], [1, 0, 0], [1.5, 0, 0], [4, 0, 0], [5, 0, 0]]
    path = path_of(positions, times=[None, None, 6.0, None, None], duration=8.0)
    times = path.keyframe_times()
    # Before the anchor: 1.5 units in 6 s; after it: 3.5 units in 2 s, split by distance.
    assert np.allclose(times, [0.0, 4.0, 6.0, 6.0 + 2.0 * 2.5 / 3.5, 8.0], atol=1e-6)
    for lo, hi, speed in ((0.0, 6.0, 1.5 / 6.0), (6.0, 8.0, 3.5 / 2.0)):
        t = np.linspace(lo + 1e-3, hi - 1e-3, 1001)
        x = path.sample(t).positions[:, 0]
        v = np.diff(x) / np.diff(t)
        assert np.abs(v / speed - 1.0).max() < 1e-3


def test_tension_one_flies_straight_segments_at_one_speed_without_stopping():
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 2, 0], [3, 2, 1]], dtype=np.float64)
    path = path_of(corners, interpolation=Interpolation(tension=1.0), duration=5.0)
    times, samples = dense(path, 20001)
    keys = path.keyframe_times()
    for a, b, lo, hi in zip(corners[:-1], corners[1:], keys[:-1], keys[1:]):
        inside = samples.positions[(times >= lo) & (times <= hi)]
        chord = (b - a) / np.linalg.norm(b - a)
        offset = inside - a
        assert np.allclose(offset - np.outer(offset @ chord, chord), 0, atol=1e-9)
    speed = np.linalg.norm(np.diff(samples.positions, axis=0), axis=1) / np.diff(times)
    middle = 0.5 * (times[1:] + times[:-1])
    off_corners = np.min(np.abs(middle[:, None] - keys[None, :]), axis=1) > np.diff(times)[0]
    # Where a plain cubic would brake to a stop at each keyframe, the pacing keeps going.
    assert np.abs(speed[off_corners] / (path.length / 5.0) - 1.0).max() < 1e-3


def test_a_loop_whose_first_keyframe_is_timed_later_wraps_round():
    path = path_of([[0, 0, 0], [1, 0, 0], [3, 0, 0]], times=[1.0, None, None], duration=4.0,
                   interpolation=Interpolation(loop=True))
    # 6 units in 4 s from t = 1: keyframe 2 at 3 s, back at keyframe 0 at 5 s = 1 s.
    assert np.allclose(path.keyframe_times(), [1.0, 1.0 + 2.0 / 3.0, 3.0])
    assert np.allclose(path.pose_at(0.0).pose.position, [1.5, 0, 0])
    assert np.allclose(path.pose_at(1.0).pose.position, [0, 0, 0])


def test_keyframes_at_the_same_time_are_a_cut():
    path = path_of([[0, 0, 0], [1, 0, 0], [5, 0, 0], [6, 0, 0]], times=[None, 2.0, 2.0, None], duration=4.0)
    assert np.allclose(path.pose_at(1.999).pose.position, [0.9995, 0, 0])
    assert np.allclose(path.pose_at(2.0).pose.position, [5, 0, 0])


def test_the_camera_holds_before_its_first_anchor_and_after_its_last():
    path = path_of([[0, 0, 0], [1, 0, 0], [2, 0, 0]], times=[2.0, None, 5.0], duration=10.0)
    assert np.allclose(path.keyframe_times(), [2.0, 3.5, 5.0])
    assert np.array_equal(path.pose_at(0.5).pose.position, [0, 0, 0])
    assert np.allclose(path.pose_at(9.0).pose.position, [2, 0, 0])
    assert np.allclose(path.pose_at(2.75).pose.position, [0.5, 0, 0])


def test_a_turn_in_place_gets_time():
    spin = [level([0, 0, 1]), level([1, 0, 0]), level([1, 0, 0])]
    path = path_of([[0, 0, 0], [0, 0, 0], [3, 0, 0]], rotations=spin, duration=6.0)
    times = path.keyframe_times()
    # rho = L / (4 pi): a quarter turn is worth L / 8 of length.
    assert times[1] == pytest.approx(6.0 * (3.0 / 8.0) / (3.0 + 3.0 / 8.0))
    assert np.array_equal(path.pose_at(times[1] / 2).pose.position, [0, 0, 0])

    zoom = path_of([[0, 0, 0], [0, 0, 0]], fovs=[30.0, 90.0])
    assert zoom.pose_at(5.0).fov_y_degrees != 30.0


def test_coincident_keyframes_stay_finite_and_identical_ones_share_time_evenly():
    R = level([0, 0, 1])
    path = path_of([[0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 1, 0]], rotations=[R] * 5)
    times, samples = dense(path, 501)
    assert np.all(np.isfinite(samples.positions)) and np.all(np.isfinite(samples.rotations))
    assert np.allclose(path.sample(path.keyframe_times()).positions, [k.pose.position for k in path.keyframes])
    still = path_of([[2, 2, 2]] * 4, rotations=[R] * 4, duration=3.0)
    assert np.allclose(still.keyframe_times(), [0, 1, 2, 3])
    assert np.allclose(still.sample(np.linspace(0, 3, 7)).positions, [2, 2, 2])


# --------------------------------------------------------------------------- shape


def test_centripetal_has_no_overshoot_on_uneven_collinear_keyframes_where_uniform_does():
    xs = [0.0, 1.0, 1.05, 6.0]

    def along(alpha):
        path = path_of([[x, 0, 0] for x in xs], interpolation=Interpolation(alpha=alpha))
        curve = path.polyline(400)
        assert np.allclose(curve[:, 1:], 0, atol=1e-12)
        return curve[:, 0]

    x = along(0.5)
    assert np.all(np.diff(x) >= -1e-12) and x.min() >= -1e-12 and x.max() <= 6.0 + 1e-12
    uniform = along(0.0)
    assert np.any(np.diff(uniform) < -1e-3)                    # goes back: the cusp centripetal avoids


def test_a_loop_closes_with_continuous_position_and_velocity():
    ring = [[2, 0, 0], [0.5, 0, 1.5], [-1, 0, 0.2], [-0.3, 0, -1.8], [1.2, 0, -1.1]]
    path = path_of(ring, interpolation=Interpolation(loop=True), duration=5.0)
    assert np.allclose(path.pose_at(path.duration).pose.position, ring[0])
    assert np.allclose(path.pose_at(-1.0).pose.position, path.pose_at(4.0).pose.position)
    assert all(np.all(np.isfinite(path.pose_at(t).pose.position)) for t in (math.nan, math.inf, 1e300))
    h = 1e-4
    for t in (0.0, path.keyframe_times()[2]):
        p = path.sample([t - h, t, t + h]).positions
        before, after = (p[1] - p[0]) / h, (p[2] - p[1]) / h
        assert np.linalg.norm(after - before) < 1e-3 * np.linalg.norm(after)
    # The polyline is closed.
    line = path.polyline(8)
    assert np.allclose(line[0], line[-1]) and len(line) == 5 * 8 + 1


# --------------------------------------------------------------------------- orientation


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), count=st.integers(1, 6), loop=st.booleans(),
       tension=st.sampled_from([0.0, 0.5, 1.0]), alpha=st.sampled_from([0.0, 0.5, 1.0]))
def test_orientations_stay_proper_rotations(seed, count, loop, tension, alpha):
    rng = np.random.default_rng(seed)
    path = CameraPath(random_keyframes(rng, count), duration=3.0,
                      interpolation=Interpolation(alpha=alpha, tension=tension, loop=loop))
    _, samples = dense(path, 301)
    R = samples.rotations
    assert np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max() < 1e-9
    assert np.abs(np.linalg.det(R) - 1.0).max() < 1e-9
    assert np.all(np.isfinite(samples.positions))
    assert np.all((samples.fov_y_degrees >= 20 - 1e-9) & (samples.fov_y_degrees <= 100 + 1e-9))


def test_no_flips_when_neighbouring_quaternions_have_opposite_signs():
    # A slow turn about up through more than a full circle: the keyframes' quaternions
    # change sign along the way, and slerp must not take the long way round there.
    rotations = [level([math.sin(a), 0.2, math.cos(a)]) for a in np.radians(np.arange(0, 500, 50))]
    quats = np.array([matrix_to_quaternion(R) for R in rotations])
    assert np.any(np.sum(quats[1:] * quats[:-1], axis=1) < 0)     # the case under test occurs
    positions = [[0.1 * i, 0, 0] for i in range(len(rotations))]
    for loop in (False, True):
        path = path_of(positions, rotations=rotations, interpolation=Interpolation(loop=loop))
        _, samples = dense(path, 2001)
        step = angle_between(samples.rotations[1:], samples.rotations[:-1])
        # 500 degrees over 2000 steps is 0.25 each; a flip would be ~100 times that.
        assert step.max() < math.radians(1.0)


def test_roll_free_keyframes_give_a_roll_free_flight():
    rng = np.random.default_rng(7)
    for up_name in ("-y", "+z"):
        up = up_vector(up_name)
        keys = []
        for _ in range(6):
            forward = rng.normal(size=3)
            forward -= 0.7 * np.dot(forward, up) * up                # away from the poles
            keys.append(Keyframe(Pose(rng.normal(size=3), level(forward, up)), 60.0))
        path = CameraPath(tuple(keys), interpolation=Interpolation(up=tuple(up)))
        _, samples = dense(path, 1001)
        assert np.abs(samples.rotations[:, 0] @ up).max() < 1e-9   # camera x stays horizontal
        assert np.all(samples.rotations[:, 1] @ up < 0)             # and upright


def test_a_keyframe_with_roll_keeps_it_and_the_roll_fades_to_its_neighbours():
    R = level([0, 0, 1])
    path = path_of([[0, 0, 0], [1, 0, 0], [2, 0, 0]], rotations=[R, rolled(R, 30.0), R])
    t = path.keyframe_times()
    samples = path.sample([t[0], 0.5 * (t[0] + t[1]), t[1], t[2]])
    roll = np.degrees(np.arctan2(samples.rotations[:, 0] @ -UP, samples.rotations[:, 0] @ R[0]))
    assert abs(roll[0]) < 1e-9 and abs(roll[3]) < 1e-9
    assert abs(abs(roll[2]) - 30.0) < 1e-9
    assert 5.0 < abs(roll[1]) < 25.0


def test_looking_straight_down_on_the_way_stays_smooth():
    # Forward passes the up axis: roll is undefined there and the plain squad takes over.
    rotations = [level([0, 0, 1]), np.array(look_at([0, 0, 0], [0, 1, 0], up=[0, 0, 1]).R), level([1, 0, 0])]
    path = path_of([[0, 0, 0], [0, 0, 1], [1, 0, 1]], rotations=rotations)
    _, samples = dense(path, 2001)
    step = angle_between(samples.rotations[1:], samples.rotations[:-1])
    assert np.all(np.isfinite(step)) and step.max() < math.radians(1.0)
    assert np.allclose(path.pose_at(path.keyframe_times()[1]).pose.R, rotations[1], atol=1e-9)


def test_angular_velocity_is_continuous_at_keyframes_with_uneven_durations():
    rotations = [level([0, 0, 1]), level([1, 0.3, 1]), level([1, -0.2, -0.3]), level([-0.5, 0, -1])]
    rotations[2] = rolled(rotations[2], 20.0)
    # Uneven segments, so the keyframes sit at uneven times.
    path = path_of([[0, 0, 0], [0.2, 0, 0], [3, 0, 0], [3.5, 0, 0]], rotations=rotations)
    durations = np.diff(path.keyframe_times())
    assert durations.max() > 2.5 * durations.min()
    for t in path.keyframe_times()[1:3]:
        before, after = angular_velocity(path, t, 1e-5)
        assert np.linalg.norm(after) > 0.05
        assert np.linalg.norm(after - before) < 1e-2 * np.linalg.norm(after)


def test_field_of_view_runs_linearly_in_log_tan():
    path = path_of([[0, 0, 0], [1, 0, 0]], fovs=[20.0, 100.0])
    mid = path.pose_at(path.duration / 2).fov_y_degrees
    expected = 2.0 * math.degrees(math.atan(math.sqrt(math.tan(math.radians(10)) * math.tan(math.radians(50)))))
    assert mid == pytest.approx(expected, abs=1e-9)
    assert mid != pytest.approx(60.0, abs=1.0)


# --------------------------------------------------------------------------- generators


@pytest.mark.parametrize("up_name", ["-y", "+z"])
def test_orbit_stays_on_its_circle_and_looks_at_the_centre(up_name):
    up = up_vector(up_name)
    center = np.array([1.0, -2.0, 0.5])
    path = orbit_path(center, 3.0, up, elevation_degrees=25.0, duration=6.0)
    assert path.interpolation.loop and len(path.keyframes) == 12
    _, samples = dense(path, 2001)
    offset = samples.positions - center
    height = offset @ up
    flat = np.linalg.norm(offset - height[:, None] * up, axis=1)
    circle = 3.0 * math.cos(math.radians(25.0))
    assert np.abs(flat / circle - 1.0).max() < 0.005
    assert np.allclose(height, 3.0 * math.sin(math.radians(25.0)), atol=1e-9)
    to_center = -offset / np.linalg.norm(offset, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.sum(to_center * samples.rotations[:, 2], axis=1), -1, 1))).max() < 0.05
    assert np.abs(samples.rotations[:, 0] @ up).max() < 1e-9
    # It turns right: the camera moves along its own +x.
    step = samples.positions[1] - samples.positions[0]
    assert np.dot(step, samples.rotations[0, 0]) > 0.9 * np.linalg.norm(step)


def test_orbit_starts_at_the_heading_of_a_given_pose():
    start = Pose([5.0, -1.0, 5.0], level([-1, 0, 0]))
    path = orbit_path(np.zeros(3), 2.0, UP, start=start, elevation_degrees=0.0)
    assert np.allclose(path.keyframes[0].pose.forward, [-1, 0, 0], atol=1e-12)
    assert np.allclose(path.keyframes[0].pose.position, [2, 0, 0], atol=1e-12)


def test_dolly_is_straight_even_and_keeps_its_orientation():
    start = Pose([1.0, 2.0, 3.0], level([1, 0.5, 2]))
    path = dolly_path(start, -4.0, duration=4.0, fov_y_degrees=50.0)
    times, samples = dense(path, 401)
    expected = start.position + np.outer(-4.0 * times / 4.0, start.forward)
    assert np.allclose(samples.positions, expected, atol=1e-9)
    assert np.allclose(samples.rotations, start.R, atol=1e-12)
    assert np.allclose(samples.fov_y_degrees, 50.0)


def test_a_path_through_cameras_takes_their_fov_from_fy():
    cams = [look_at([0, 0, -3], [0, 0, 0], fov_y_degrees=40.0), look_at([2, 0, -3], [0, 0, 0], fov_y_degrees=70.0)]
    path = path_through_cameras(cams, duration=4.0)
    assert [k.fov_y_degrees for k in path.keyframes] == pytest.approx([40.0, 70.0])
    assert np.allclose(path.pose_at(4.0).camera(640, 480).R, cams[1].R)


def test_cameras_are_one_per_frame_and_equal_pose_at():
    path = orbit_path(np.zeros(3), 1.0, UP, duration=2.0, fps=12.0)
    cams = path.cameras(64, 48)
    assert len(cams) == 24 == path.frame_count
    for t, cam in zip(path.frame_times()[::5], cams[::5]):
        single = path.pose_at(t).camera(64, 48)
        assert np.array_equal(single.R, cam.R) and np.array_equal(single.t, cam.t) and single.fy == cam.fy


# --------------------------------------------------------------------------- validation


def one_line_error(make, *fragments):
    with pytest.raises(UserError) as info:
        make()
    message = str(info.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message, message


def test_bad_numbers_are_one_line_user_errors():
    key = Keyframe(Pose(np.zeros(3), np.eye(3)))
    for duration in (0.0, -1.0, math.nan, math.inf, MAX_DURATION * 2, "10", True):
        one_line_error(lambda: CameraPath((key,), duration=duration), "duration")
    for fps in (0.0, 1000.0, math.nan):
        one_line_error(lambda: CameraPath((key,), fps=fps), "fps")
    one_line_error(lambda: CameraPath((key,), duration=MAX_DURATION, fps=240.0), "frames")
    for fov in (0.5, 180.0, math.nan):
        one_line_error(lambda: CameraPath((Keyframe(key.pose, fov),)), "keyframe 0 fov")
    one_line_error(lambda: CameraPath((Keyframe(key.pose, 60, 11.0),), duration=10.0), "keyframe 0 time")
    one_line_error(lambda: CameraPath((Keyframe(key.pose, 60, -1.0),)), "keyframe 0 time")
    one_line_error(lambda: CameraPath((Keyframe(key.pose, 60, 5.0), key, Keyframe(key.pose, 60, 4.0))),
                   "keyframe 2 time", "must not decrease")
    one_line_error(lambda: CameraPath((key,) * (MAX_KEYFRAMES + 1)), "keyframes")
    for up in ((0, 0, 0), (math.nan, 1, 0), (1, 2)):
        one_line_error(lambda: Interpolation(up=up), "up")
    one_line_error(lambda: Interpolation(alpha=2.0), "alpha")
    one_line_error(lambda: Interpolation(tension=-0.1), "tension")
    one_line_error(lambda: orbit_path(np.zeros(3), 0.0, UP), "radius")
    one_line_error(lambda: orbit_path(np.zeros(3), 1.0, UP, elevation_degrees=90.0), "elevation")
    one_line_error(lambda: orbit_path(np.zeros(3), 1.0, UP, keyframes=2), "keyframes")
    one_line_error(lambda: dolly_path(key.pose, math.nan), "distance")
    assert Interpolation(up=(0, 0, 5)).up == (0.0, 0.0, 1.0)


def test_an_edit_that_puts_times_out_of_order_is_refused():
    pose = Pose(np.zeros(3), np.eye(3))
    path = CameraPath((Keyframe(pose, 60, 1.0), Keyframe(pose), Keyframe(pose, 60, 3.0)))
    one_line_error(lambda: path.moved(2, 0), "must not decrease")
    assert path.moved(1, 0).keyframes[0].time is None
    one_line_error(lambda: path.with_keyframe_changed(0, time=4.0), "must not decrease")
