"""The headset's room and eye cameras: OpenXR's room, poses and fields of view carried into
the project's OpenCV cameras. Expected values are worked out by hand in each test (axes
written out, points projected with x / z), never by the functions under test."""

import math

import numpy as np
import pytest

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.xr.room import (
    Fov,
    Pose,
    Room,
    eye_camera,
    intrinsics,
    midpoint,
    midpoint_camera,
    pose_from_matrix,
    room_at_view,
)

IDENTITY_ROOM = Room(np.eye(3), np.zeros(3), 1.0)
WIDE = Fov(-0.7, 0.3, 0.5, -0.6)  # asymmetric on both axes


def yaw(degrees: float) -> np.ndarray:
    """OpenXR (x, y, z, w) quaternion of a turn about room +y (positive: to the left)."""
    half = math.radians(degrees) / 2
    return np.array([0.0, math.sin(half), 0.0, math.cos(half)])


def pitch(degrees: float) -> np.ndarray:
    """OpenXR (x, y, z, w) quaternion of a turn about room +x (positive: looking up)."""
    half = math.radians(degrees) / 2
    return np.array([math.sin(half), 0.0, 0.0, math.cos(half)])


def xyzw_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a b of (x, y, z, w) quaternions, written out."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def image_point(camera: Camera, world: np.ndarray) -> np.ndarray:
    """(u, v) continuous image coordinates of a world point: pixel u spans [u, u + 1]."""
    x, y, z = camera.R @ world + camera.t
    return np.array([camera.fx * x / z + camera.cx, camera.fy * y / z + camera.cy])


def assert_proper_rotation(matrix: np.ndarray) -> None:
    np.testing.assert_allclose(matrix @ matrix.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(matrix) == pytest.approx(1.0)


def test_pose_matrix_reads_openxr_order():
    # A quarter turn left about +y: local -z (forward) becomes room -x, local x becomes room -z.
    pose = Pose(yaw(90) * 3.0, [0.0, 1.0, 0.0])  # normalised on the way in
    np.testing.assert_allclose(np.linalg.norm(pose.orientation), 1.0)
    np.testing.assert_allclose(pose.matrix, [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-15)
    np.testing.assert_allclose(pose.forward, [-1, 0, 0], atol=1e-15)
    back = pose_from_matrix(np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]), [0.0, 1.0, 0.0])
    np.testing.assert_allclose(back.orientation * np.sign(back.orientation[3]), yaw(90), atol=1e-15)
    with pytest.raises(ValueError):
        Pose(np.zeros(4), np.zeros(3))
    with pytest.raises(ValueError):
        Pose(yaw(0), [0.0, np.nan, 0.0])


def test_fov_refuses_impossible_angles():
    for angles in [(0.3, -0.3, 0.4, -0.4), (-0.3, 0.3, -0.4, 0.4), (-1.6, 0.3, 0.4, -0.4), (-0.3, 0.3, np.inf, -0.4),
                   (-0.3, 0.3, 0.4, math.nan), (-0.3, 0.3, True, -0.4)]:
        with pytest.raises(ValueError):
            Fov(*angles)


def test_room_maps_points_both_ways():
    rotation = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about world z
    room = Room(rotation, [1.0, 2.0, 3.0], 2.0)
    # room (1, 0, 0) -> world direction (0, 1, 0), doubled, plus the origin.
    np.testing.assert_allclose(room.to_world([1.0, 0.0, 0.0]), [1.0, 4.0, 3.0])
    points = np.array([[0.5, -1.0, 2.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(room.to_world(points), [[3.0, 3.0, 7.0], [1.0, 2.0, 3.0]])
    np.testing.assert_allclose(room.to_room(room.to_world(points)), points, atol=1e-15)
    for bad in [{"rotation": 2 * np.eye(3)}, {"rotation": np.diag([1.0, 1.0, -1.0])}, {"units_per_metre": 0.0},
                {"units_per_metre": math.inf}, {"origin": [0.0, math.nan, 0.0]}]:
        with pytest.raises(ValueError):
            Room(**{"rotation": np.eye(3), "origin": np.zeros(3), "units_per_metre": 1.0, **bad})


def test_symmetric_fov_centres_the_principal_point():
    # tan = +/-0.5 across 200 pixels: fx = 200 / 1; tan = +/-0.25 down 100 pixels: fy = 100 / 0.5.
    fx, fy, cx, cy = intrinsics(Fov(-math.atan(0.5), math.atan(0.5), math.atan(0.25), -math.atan(0.25)), 200, 100)
    assert (fx, fy, cx, cy) == pytest.approx((200.0, 200.0, 100.0, 50.0), rel=1e-14)


def test_asymmetric_fov_edges_have_their_tangents():
    camera = eye_camera(Pose(yaw(0), np.zeros(3)), WIDE, 320, 240, IDENTITY_ROOM)
    depth = 2.0  # metres in front, along room -z
    edges = {  # room point on each edge ray -> the image coordinate it must land on
        "left": ([depth * math.tan(WIDE.left), 0.0, -depth], (0, None)),
        "right": ([depth * math.tan(WIDE.right), 0.0, -depth], (320, None)),
        "top": ([0.0, depth * math.tan(WIDE.up), -depth], (None, 0)),
        "bottom": ([0.0, depth * math.tan(WIDE.down), -depth], (None, 240)),
    }
    for name, (point, expected) in edges.items():
        uv = image_point(camera, np.array(point))
        for got, want in zip(uv, expected):
            if want is not None:
                assert got == pytest.approx(want, abs=1e-9), name
    # The project's pixel convention: column 0's ray passes half a pixel inside the left edge.
    rays = camera.pixel_rays()
    assert rays[0, 0, 0] == pytest.approx(math.tan(WIDE.left) + 0.5 / camera.fx, rel=1e-12)
    assert rays[0, 0, 1] == pytest.approx(-math.tan(WIDE.up) + 0.5 / camera.fy, rel=1e-12)


def test_identity_eye_looks_along_room_minus_z():
    camera = eye_camera(Pose(yaw(0), np.zeros(3)), WIDE, 320, 240, IDENTITY_ROOM)
    np.testing.assert_allclose(image_point(camera, np.array([0.0, 0.0, -2.0])), [camera.cx, camera.cy], atol=1e-12)
    up = image_point(camera, np.array([0.0, 0.3, -2.0]))
    right = image_point(camera, np.array([0.3, 0.0, -2.0]))
    assert up[1] < camera.cy and up[0] == pytest.approx(camera.cx)
    assert right[0] > camera.cx and right[1] == pytest.approx(camera.cy)
    assert (camera.R @ np.array([0.0, 0.0, -2.0]) + camera.t)[2] == pytest.approx(2.0)  # in front


def test_eye_in_a_turned_scaled_moved_room():
    rotation = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # room x -> world y, room y -> world -x
    room = Room(rotation, [1.0, 2.0, 3.0], 2.0)
    camera = eye_camera(Pose(yaw(0), [0.0, 1.6, 0.0]), Fov(-0.5, 0.5, 0.5, -0.5), 100, 100, room)
    # Centre: (1, 2, 3) + 2 * (-1.6, 0, 0). Camera axes in the world: right = room x = (0, 1, 0),
    # down = room -y = (1, 0, 0), forward = room -z = (0, 0, -1).
    np.testing.assert_allclose(camera.center, [-2.2, 2.0, 3.0], atol=1e-15)
    np.testing.assert_allclose(camera.R, [[0, 1, 0], [1, 0, 0], [0, 0, -1]], atol=1e-15)
    # 4 forward, 1 right, 0.5 down: camera (1, 0.5, 4); fx = fy = 100 / (2 tan 0.5), cx = cy = 50.
    world = np.array([-2.2 + 0.5, 2.0 + 1.0, 3.0 - 4.0])
    f = 100 / (2 * math.tan(0.5))
    np.testing.assert_allclose(image_point(camera, world), [50 + f * 0.25, 50 + f * 0.125], atol=1e-9)
    # The eyes' distance scales with the room; their axes do not.
    other = eye_camera(Pose(yaw(0), [0.064, 1.6, 0.0]), Fov(-0.5, 0.5, 0.5, -0.5), 100, 100, room)
    assert np.linalg.norm(other.center - camera.center) == pytest.approx(0.128)
    np.testing.assert_array_equal(other.R, camera.R)


def test_turned_pose_looks_where_it_turned():
    # Turned 90 degrees left from room -z: looking along room -x, at a point 3 m away.
    camera = eye_camera(Pose(yaw(90), [0.5, 1.0, 0.0]), WIDE, 320, 240, IDENTITY_ROOM)
    np.testing.assert_allclose(camera.R[2], [-1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(image_point(camera, np.array([-2.5, 1.0, 0.0])), [camera.cx, camera.cy], atol=1e-12)
    # Room -z is now on the view's right.
    assert image_point(camera, np.array([-2.5, 1.0, -0.5]))[0] > camera.cx


def level_head(degrees: float) -> Pose:
    return Pose(yaw(degrees), [0.1, 1.7, -0.2])


@pytest.mark.parametrize("up, target", [((0.0, -1.0, 0.0), (4.0, 2.0, -1.0)),  # OpenCV: y down
                                        ((0.0, 0.0, 1.0), (-2.0, 5.0, 3.0))])   # z up
@pytest.mark.parametrize("head_yaw", [0.0, 40.0, -170.0])
def test_room_at_view_puts_a_level_head_in_the_desktop_camera(up, target, head_yaw):
    view = look_at([1.0, 2.0, 3.0], target, up=up)  # level: forward normal to up
    head = level_head(head_yaw)
    room = room_at_view(view, head, np.array(up), 2.5)
    np.testing.assert_allclose(room.to_world(head.position), view.center, atol=1e-12)
    np.testing.assert_allclose(room.rotation @ [0.0, 1.0, 0.0], up, atol=1e-12)
    eye = eye_camera(head, WIDE, 320, 240, room)
    np.testing.assert_allclose(eye.R[2], view.R[2], atol=1e-12)
    np.testing.assert_allclose(eye.R @ np.array(up), [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(eye.R, view.R, atol=1e-12)  # a level view has no roll to differ in


def test_room_at_view_takes_only_the_yaw():
    up = np.array([0.0, -1.0, 0.0])
    heading = np.array([0.6, 0.0, 0.8])  # horizontal: normal to up
    down_30 = math.cos(math.radians(30)) * heading - math.sin(math.radians(30)) * up
    view = look_at([0.0, 0.0, 0.0], down_30, up=up)
    room = room_at_view(view, level_head(25.0), up, 1.0)
    eye = eye_camera(level_head(25.0), WIDE, 320, 240, room)
    np.testing.assert_allclose(eye.R[2], heading, atol=1e-12)  # the desktop's pitch dropped
    # A head looking up by 20 degrees keeps its pitch, on the desktop's heading.
    tilted = Pose(xyzw_product(yaw(25.0), pitch(20.0)), [0.1, 1.7, -0.2])
    eye = eye_camera(tilted, WIDE, 320, 240, room_at_view(view, tilted, up, 1.0))
    expected = math.cos(math.radians(20)) * heading + math.sin(math.radians(20)) * up
    np.testing.assert_allclose(eye.R[2], expected, atol=1e-12)


def test_room_at_view_degenerate_headings():
    up = np.array([0.0, -1.0, 0.0])
    top = np.array([0.0, 0.0, 1.0])  # where the top of the straight-down image points
    # Rows right, down, forward: forward = -up (looking straight down), down = -top, right = down x forward.
    R = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    centre = np.array([1.0, -3.0, 2.0])
    view = Camera(320, 240, 300.0, 300.0, 160.0, 120.0, R, -R @ centre)
    head_down = Pose(pitch(-90.0), [0.0, 1.5, 0.0])  # a level head tilted down: its up points room -z
    room = room_at_view(view, head_down, up, 1.0)
    assert_proper_rotation(room.rotation)
    np.testing.assert_allclose(room.rotation @ [0.0, 1.0, 0.0], up, atol=1e-12)
    np.testing.assert_allclose(room.rotation @ [0.0, 0.0, -1.0], top, atol=1e-12)  # room forward -> image top
    np.testing.assert_allclose(eye_camera(head_down, WIDE, 320, 240, room).R, R, atol=1e-12)
    # Each degenerate side alone, and a head looking straight up, still give rotations.
    for head in (Pose(pitch(90.0), [0.0, 1.5, 0.0]), level_head(10.0)):
        assert_proper_rotation(room_at_view(view, head, up, 1.0).rotation)
    # A level head tilted straight down or up still faces room -z (its up points to room -z, or +z):
    # room -z lands on the level desktop camera's forward.
    level_view = look_at([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], up=up)
    for head in (head_down, Pose(pitch(90.0), [0.0, 1.5, 0.0])):
        rotation = room_at_view(level_view, head, up, 1.0).rotation
        assert_proper_rotation(rotation)
        np.testing.assert_allclose(rotation @ [0.0, 1.0, 0.0], up, atol=1e-12)
        np.testing.assert_allclose(rotation @ [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], atol=1e-12)
    # A camera straight up (its image's bottom is where it faces): room -z lands on -top.
    looking_up = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, -1.0, 0.0]])  # right x down = forward = up
    view_up = Camera(320, 240, 300.0, 300.0, 160.0, 120.0, looking_up, -looking_up @ centre)
    rotation = room_at_view(view_up, level_head(0.0), up, 1.0).rotation
    np.testing.assert_allclose(rotation @ [0.0, 0.0, -1.0], -top, atol=1e-12)


def test_midpoint_of_symmetric_eyes():
    left = Pose(yaw(5.0), [-0.032, 1.6, 0.1])
    right = Pose(-yaw(-5.0), [0.032, 1.6, 0.1])  # the other sign of the same rotation
    middle = midpoint(left, right)
    np.testing.assert_allclose(middle.position, [0.0, 1.6, 0.1], atol=1e-15)
    np.testing.assert_allclose(middle.orientation, [0.0, 0.0, 0.0, 1.0], atol=1e-15)
    # Half-way between 0 and 60 degrees of yaw is 30.
    np.testing.assert_allclose(midpoint(Pose(yaw(0), np.zeros(3)), Pose(yaw(60), np.zeros(3))).orientation,
                               yaw(30), atol=1e-15)


def test_midpoint_camera_of_mirrored_eyes():
    room = Room(np.eye(3), [0.0, 0.0, 0.0], 2.0)
    left = eye_camera(Pose(yaw(0), [-0.032, 1.6, 0.0]), Fov(-0.9, 0.7, 0.8, -0.8), 300, 200, room)
    right = eye_camera(Pose(yaw(0), [0.032, 1.6, 0.0]), Fov(-0.7, 0.9, 0.8, -0.8), 300, 200, room)
    middle = midpoint_camera(left, right)
    np.testing.assert_allclose(middle.center, [0.0, 3.2, 0.0], atol=1e-15)
    np.testing.assert_array_equal(middle.R, left.R)
    # fx = 300 / (tan 0.9 + tan 0.7) for both; mean cx = fx (tan 0.9 + tan 0.7) / 2 = 150.
    assert middle.fx == left.fx == pytest.approx(300 / (math.tan(0.9) + math.tan(0.7)))
    assert middle.cx == pytest.approx(150.0) and middle.cy == left.cy
    assert (middle.width, middle.height) == (300, 200)
    # Eyes toed by +/-5 degrees: the midpoint looks straight along room -z (world -z here).
    toed = [eye_camera(Pose(yaw(side * 5.0), [0.0, 0.0, 0.0]), WIDE, 320, 240, room) for side in (1, -1)]
    R = midpoint_camera(*toed).R
    np.testing.assert_allclose(R, np.diag([1.0, -1.0, -1.0]), atol=1e-15)
