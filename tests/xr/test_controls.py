"""Controllers moving the room: grabs, turns, flying and the per-frame state machine.
Expected values are worked out by hand (quarter turns written out, distances from the
speeds), and checked through world points: what the user sees of the scene."""

import math

import numpy as np
import pytest

from raygs_viewer.xr.controls import (
    MAX_GRAB_SCALE,
    NO_HAND,
    HandInput,
    Locomotion,
    deadzone,
    grab_one,
    grab_two,
    move,
    smooth_turn,
    snap_turn,
)
from raygs_viewer.xr.room import Fov, Pose, Room, eye_camera

# A room turned 90 degrees about world x (room y -> world -z... written out below), moved and scaled.
#   room x -> world (1, 0, 0), room y -> world (0, 0, 1), room z -> world (0, -1, 0): world up is +z.
TURNED = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
WORLD_UP = np.array([0.0, 0.0, 1.0])
ROOM = Room(TURNED, [3.0, -1.0, 0.5], 2.0)
FOV = Fov(-0.6, 0.6, 0.5, -0.5)


def yaw(degrees: float) -> np.ndarray:
    """OpenXR (x, y, z, w) quaternion of a turn about room +y (positive: to the left)."""
    half = math.radians(degrees) / 2
    return np.array([0.0, math.sin(half), 0.0, math.cos(half)])


def about_x(degrees: float) -> np.ndarray:
    half = math.radians(degrees) / 2
    return np.array([math.sin(half), 0.0, 0.0, math.cos(half)])


def about_z(degrees: float) -> np.ndarray:
    half = math.radians(degrees) / 2
    return np.array([0.0, 0.0, math.sin(half), math.cos(half)])


def yaw_then(degrees: float, other: np.ndarray) -> np.ndarray:
    """yaw(degrees) composed after ``other`` (Hamilton product, (x, y, z, w)): a pose turned
    by ``other`` in its own frame, then yawed."""
    s, c = math.sin(math.radians(degrees) / 2), math.cos(math.radians(degrees) / 2)
    x, y, z, w = other
    return np.array([c * x + s * z, c * y + s * w, c * z - s * x, c * w - s * y])


def pose(position, orientation=None) -> Pose:
    return Pose(yaw(0) if orientation is None else orientation, position)


def world_forward(room: Room, head: Pose) -> np.ndarray:
    return eye_camera(head, FOV, 64, 64, room).R[2]


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, float(a @ b) / np.linalg.norm(a) / np.linalg.norm(b)))))


def test_one_hand_carries_the_scene_point_it_holds():
    start, now = pose([0.2, 1.0, -0.3]), pose([0.3, 1.0, -0.3])  # +0.1 m along room x
    grabbed = ROOM.to_world(start.position)
    room = grab_one(ROOM, start, now)
    np.testing.assert_allclose(room.to_world(now.position), grabbed, atol=1e-12)
    # By hand: the scene slid 0.1 m along room x, so the origin moved 0.2 units against world x.
    np.testing.assert_allclose(room.origin, [2.8, -1.0, 0.5], atol=1e-12)
    np.testing.assert_array_equal(room.rotation, ROOM.rotation)
    assert room.units_per_metre == 2.0


def test_one_hand_turns_the_scene_with_its_yaw_only():
    hand = [0.2, 1.0, -0.3]
    ahead = np.array([0.2, 1.0, -1.3])  # 1 m in front of the hand at the start
    # Hand turned a quarter left (and pitched down 40 degrees, which must not count): the point
    # ahead is now seen 1 m to the hand's left, room -x.
    room = grab_one(ROOM, pose(hand), pose(hand, yaw_then(90.0, about_x(-40.0))))
    np.testing.assert_allclose(room.to_world([-0.8, 1.0, -0.3]), ROOM.to_world(ahead), atol=1e-12)
    np.testing.assert_allclose(room.to_world(hand), ROOM.to_world(hand), atol=1e-12)
    # A roll of the wrist turns nothing.
    rolled = grab_one(ROOM, pose(hand), pose(hand, about_z(50.0)))
    np.testing.assert_allclose(rolled.rotation, ROOM.rotation, atol=1e-15)
    np.testing.assert_allclose(rolled.origin, ROOM.origin, atol=1e-12)


def test_two_hands_scale_turn_and_keep_their_midpoint():
    left, right = pose([-0.2, 1.0, -0.3]), pose([0.2, 1.0, -0.3])
    middle = np.array([0.0, 1.0, -0.3])
    # Twice as far apart: the scene looks twice as big, half the units per metre.
    room = grab_two(ROOM, left, right, pose([-0.4, 1.0, -0.3]), pose([0.4, 1.0, -0.3]))
    assert room.units_per_metre == pytest.approx(1.0)
    np.testing.assert_allclose(room.to_world(middle), ROOM.to_world(middle), atol=1e-12)
    np.testing.assert_allclose(room.to_world([0.4, 1.0, -0.3]), ROOM.to_world([0.2, 1.0, -0.3]), atol=1e-12)
    # Left-to-right turned a quarter left (from +x to -z), same distance, midpoint moved 1 m up:
    # the scene point 1 m right of the start's midpoint is seen 1 m ahead of the new one.
    turned = grab_two(ROOM, left, right, pose([0.0, 2.0, -0.1]), pose([0.0, 2.0, -0.5]))
    assert turned.units_per_metre == pytest.approx(2.0)
    np.testing.assert_allclose(turned.to_world([0.0, 2.0, -1.3]), ROOM.to_world([1.0, 1.0, -0.3]), atol=1e-12)


def test_crossing_hands_give_a_finite_scale():
    left, right = pose([-0.2, 1.0, -0.3]), pose([0.2, 1.0, -0.3])
    met = grab_two(ROOM, left, right, pose([0.0, 1.0, -0.3]), pose([0.0, 1.0, -0.3]))
    assert met.units_per_metre == pytest.approx(2.0 * MAX_GRAB_SCALE)
    apart = grab_two(ROOM, left, right, pose([-5000.0, 1.0, -0.3]), pose([5000.0, 1.0, -0.3]))
    assert apart.units_per_metre == pytest.approx(2.0 / MAX_GRAB_SCALE)
    crossed = grab_two(ROOM, left, right, pose([0.2, 1.0, -0.3]), pose([-0.2, 1.0, -0.3]))
    assert crossed.units_per_metre == pytest.approx(2.0)  # same distance, turned half round
    np.testing.assert_allclose(crossed.to_world([0.2, 1.0, -0.3]), ROOM.to_world([-0.2, 1.0, -0.3]), atol=1e-12)
    together = grab_two(ROOM, pose([0.0, 1.0, 0.0]), pose([0.0, 1.0, 0.0]), left, right)
    assert together.units_per_metre == 2.0  # no distance to start from: the scale is kept
    for room in (met, apart, crossed, together):
        assert np.all(np.isfinite(room.origin)) and np.isfinite(room.units_per_metre)


def test_snap_turn_keeps_the_head_and_turns_the_view_right():
    head = pose([0.3, 1.6, -0.2], yaw(20.0))
    room = snap_turn(ROOM, head, 30.0)
    np.testing.assert_allclose(room.to_world(head.position), ROOM.to_world(head.position), atol=1e-12)
    before, after = world_forward(ROOM, head), world_forward(room, head)
    assert angle_between(before, after) == pytest.approx(30.0)
    # Turned right about up: before x after points down (right x forward = up for OpenCV axes' forward).
    assert np.cross(before, after) @ WORLD_UP == pytest.approx(-math.sin(math.radians(30.0)))
    back = snap_turn(room, head, -30.0)
    np.testing.assert_allclose(back.rotation, ROOM.rotation, atol=1e-15)
    np.testing.assert_allclose(back.origin, ROOM.origin, atol=1e-12)


def test_smooth_turn_goes_by_rate_time_and_amount():
    head = pose([0.3, 1.6, -0.2])
    room = smooth_turn(ROOM, head, math.pi / 2, 0.5, -1.0)  # left at 90 degrees a second for half a second
    before, after = world_forward(ROOM, head), world_forward(room, head)
    assert angle_between(before, after) == pytest.approx(45.0)
    assert np.cross(before, after) @ WORLD_UP == pytest.approx(math.sin(math.radians(45.0)))
    np.testing.assert_allclose(room.to_world(head.position), ROOM.to_world(head.position), atol=1e-12)


def test_move_flies_along_the_heading_in_room_metres():
    head = pose([0.3, 1.6, -0.2], yaw(40.0))
    forward = world_forward(ROOM, head)
    room = move(ROOM, head, (0.0, 1.0), 1.5, 1.0)  # 1.5 m at 2 units a metre
    np.testing.assert_allclose(room.to_world(head.position) - ROOM.to_world(head.position), 3.0 * forward,
                               atol=1e-12)
    # Looking 30 degrees down changes nothing: the flight stays level.
    looking_down = pose([0.3, 1.6, -0.2], yaw_then(40.0, about_x(-30.0)))
    low = move(ROOM, looking_down, (0.0, 1.0), 1.5, 1.0)
    np.testing.assert_allclose(low.origin, room.origin, atol=1e-12)
    # Stick right: along the eye's right; a full diagonal is no faster than straight.
    right = eye_camera(head, FOV, 64, 64, ROOM).R[0]
    sideways = move(ROOM, head, (1.0, 0.0), 1.5, 2.0)
    np.testing.assert_allclose(sideways.to_world(head.position) - ROOM.to_world(head.position), 6.0 * right,
                               atol=1e-12)
    diagonal = move(ROOM, head, (1.0, 1.0), 1.5, 1.0)
    assert np.linalg.norm(diagonal.origin - ROOM.origin) == pytest.approx(3.0)


def test_moving_forward_brings_the_scene_closer():
    head = pose([0.0, 1.6, 0.0])
    tree = ROOM.to_world([0.0, 1.6, -5.0])  # 5 m ahead
    room = move(ROOM, head, (0.0, 1.0), 1.0, 2.0)
    np.testing.assert_allclose(room.to_room(tree), [0.0, 1.6, -3.0], atol=1e-12)


def test_deadzone():
    assert deadzone(0.1) == 0.0 and deadzone(-0.2) == 0.0 and deadzone(math.nan) == 0.0
    assert deadzone(0.6) == pytest.approx(0.5) and deadzone(-0.6) == pytest.approx(-0.5)
    assert deadzone(1.0) == 1.0 and deadzone(-1.3) == -1.0
    assert deadzone(0.5, dead=0.0) == 0.5
    with pytest.raises(ValueError):
        deadzone(0.5, dead=1.0)


HEAD = pose([0.0, 1.6, 0.0])


def stepper(turn="snap"):
    """A Locomotion and a function stepping it with (left, right) inputs, dt = 0.1 s."""
    locomotion = Locomotion()

    def step(room, left=NO_HAND, right=NO_HAND, dt=0.1):
        return locomotion.step(room, HEAD, left, right, dt, turn=turn)
    return step


def stick(x=0.0, y=0.0) -> HandInput:
    return HandInput(stick=(x, y))


def same(a: Room, b: Room) -> bool:
    return bool(np.allclose(a.rotation, b.rotation, atol=1e-12) and np.allclose(a.origin, b.origin, atol=1e-12)
                and math.isclose(a.units_per_metre, b.units_per_metre))


def test_recentre_is_an_edge():
    step = stepper()
    pressed = HandInput(recentre=True)
    asked = [step(ROOM, left=left, right=right)[1]
             for left, right in [(NO_HAND, pressed), (NO_HAND, pressed), (pressed, NO_HAND), (NO_HAND, NO_HAND),
                                 (pressed, pressed), (NO_HAND, NO_HAND)]]
    assert asked == [True, False, False, False, True, False]


def test_snap_turns_once_per_push():
    step = stepper("snap")
    room, turns = ROOM, 0
    for x in (0.8, 0.95, 0.5, 0.9, 0.1, 0.75, 0.0, -0.8, -0.2, -0.9):
        new, _ = step(room, right=stick(x))
        turns += not same(new, room)
        room = new
    assert turns == 4  # 0.8, then (re-armed at 0.1) 0.75, (re-armed at 0.0) -0.8, (at -0.2) -0.9
    # Twice right, twice left: back where it started.
    assert same(room, ROOM)


def test_smooth_turn_and_flight_from_the_sticks():
    step = stepper("smooth")
    room, _ = step(ROOM, right=stick(1.0), dt=0.5)  # full right at 90 degrees a second
    assert angle_between(world_forward(ROOM, HEAD), world_forward(room, HEAD)) == pytest.approx(45.0)
    still, _ = step(ROOM, right=stick(0.15))  # inside the dead zone
    assert same(still, ROOM)
    flown, _ = step(ROOM, left=stick(y=1.0), dt=1.0)  # 1.5 m forward at 2 units a metre
    np.testing.assert_allclose(flown.to_world(HEAD.position) - ROOM.to_world(HEAD.position),
                               3.0 * world_forward(ROOM, HEAD), atol=1e-12)


def grip(position, *, stick_xy=(0.0, 0.0)) -> HandInput:
    return HandInput(pose=pose(position), grip=True, stick=stick_xy)


def test_grabs_hand_over_without_a_jump():
    step = stepper()
    room, _ = step(ROOM, left=grip([0.0, 1.0, -0.3]))
    assert same(room, ROOM)  # closing a grip moves nothing
    room, _ = step(room, left=grip([0.1, 1.0, -0.3], stick_xy=(0.0, 1.0)))  # the stick waits while gripping
    held = ROOM.to_world([0.0, 1.0, -0.3])
    np.testing.assert_allclose(room.to_world([0.1, 1.0, -0.3]), held, atol=1e-12)
    # The second grip closes: nothing moves; then the hands go twice as far apart.
    before = room
    room, _ = step(room, left=grip([0.1, 1.0, -0.3]), right=grip([0.5, 1.0, -0.3]))
    assert same(room, before)
    room, _ = step(room, left=grip([-0.1, 1.0, -0.3]), right=grip([0.7, 1.0, -0.3]))
    assert room.units_per_metre == pytest.approx(1.0)
    # Letting go of the left: the right carries on from here, no jump.
    before = room
    room, _ = step(room, right=grip([0.7, 1.0, -0.3]))
    assert same(room, before)
    under_right = room.to_world([0.7, 1.0, -0.3])
    room, _ = step(room, right=grip([0.9, 1.2, -0.3]))
    np.testing.assert_allclose(room.to_world([0.9, 1.2, -0.3]), under_right, atol=1e-12)
    # Losing tracking while gripping lets go; regaining it grabs again from there.
    lost, _ = step(room, right=HandInput(pose=None, grip=True))
    assert same(lost, room)
    again, _ = step(lost, right=grip([0.0, 0.0, 0.0]))
    assert same(again, lost)


def test_untracked_hands_cannot_grab():
    step = stepper()
    room, _ = step(ROOM, left=HandInput(pose=None, grip=True), right=HandInput(pose=None, grip=True))
    assert same(room, ROOM)
    # ... but their sticks still fly.
    room, _ = step(ROOM, left=HandInput(pose=None, grip=True, stick=(0.0, 1.0)))
    assert not same(room, ROOM)


def test_a_room_replaced_during_a_grab_restarts_it():
    step = stepper()
    step(ROOM, left=grip([0.0, 1.0, -0.3]))
    elsewhere = Room(np.eye(3), [10.0, 0.0, 0.0], 1.0)  # the caller recentred
    room, _ = step(elsewhere, left=grip([0.1, 1.0, -0.3]))
    assert same(room, elsewhere)  # the grab starts again from the new room, where the hand is now
