"""How a headset's controllers move the user through the scene: by moving the room
(:class:`~raygs_viewer.xr.room.Room`), never the scene.

Every move here is a similarity of the scene as seen from the room (:func:`moved`): the
scene turns about room +y (only about the vertical, so the horizon stays level), grows or
shrinks, and slides. In room terms a scene point seen at room point x before is seen at
``pivot_after + scale * Ry(turn) @ (x - pivot_before)`` after, ``Ry(turn)`` a right-handed
turn about room +y (positive: counter-clockwise seen from above, so the scene swings to
the user's left, which is the user turning right). The room's rotation, origin and
units per metre follow from that; the scene point at ``pivot_before`` is seen at
``pivot_after``.

The moves:

- grabbing with one hand (:func:`grab_one`): the scene point at the hand when the grip
  closed stays at the hand and the scene turns with the hand's heading;
- grabbing with both (:func:`grab_two`): the scene scales with the hands' distance,
  turns with the heading of the left-to-right vector, and the point between the hands
  at the start stays between them;
- turning (:func:`snap_turn`, :func:`smooth_turn`) about the vertical line through the
  head: positive angles turn the user's view to the right;
- flying (:func:`move`) along the head's heading and its right, in room metres.

Each is a pure function of :class:`Room` values; :class:`Locomotion` holds the little
state between headset frames (grips held, the snap turn's arming, the recentre
button's last state) and maps controller input to them.

Headings are taken with :func:`raygs_viewer.xr.room.heading`: a pose's -z axis
projected on the floor plane (its pitch and roll ignored), its up axis where it points
straight up or down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from raygs_viewer.xr.room import ROOM_UP, Pose, Room, heading

#: How far one two-hand grab may scale the scene, either way: units per metre stays
#: within [start / MAX_GRAB_SCALE, start * MAX_GRAB_SCALE], so hands that meet or cross
#: (distance near 0) give a large but finite scale, never 0 or inf.
MAX_GRAB_SCALE = 1e4
#: Hands closer than this (metres) at a grab's start give no distance to compare with:
#: the grab then keeps the scale.
MIN_HAND_DISTANCE = 1e-6
#: Units per metre stays within these whatever the grabs do (so that a Room stays valid
#: after any number of them): the stereo rig's range of scene scales.
MIN_UNITS_PER_METRE, MAX_UNITS_PER_METRE = 1e-9, 1e9
#: A snap turn fires when the turning stick's |x| passes this ...
SNAP_FIRE = 0.7
#: ... and is armed again once |x| falls below this (hysteresis: one push, one turn).
SNAP_REARM = 0.3
#: The default dead zone of a stick axis.
DEAD_ZONE = 0.2


@dataclass(frozen=True)
class HandInput:
    """One controller's state in a headset frame.

    pose: the grip pose in the room, None when the controller is not tracked (it cannot
    grab then; its stick and buttons still count). grip: the grip button held. stick:
    the thumbstick or trackpad, (x right, y forward / up), each in -1..1. recentre: the
    recentre button held.
    """

    pose: Pose | None = None
    grip: bool = False
    stick: tuple[float, float] = (0.0, 0.0)
    recentre: bool = False

    def __post_init__(self) -> None:
        x, y = self.stick  # ValueError unless two values
        object.__setattr__(self, "stick", (float(x), float(y)))
        object.__setattr__(self, "grip", bool(self.grip))
        object.__setattr__(self, "recentre", bool(self.recentre))


#: An untracked controller with nothing pressed.
NO_HAND = HandInput()


def yaw_rotation(angle: float) -> np.ndarray:
    """(3, 3) right-handed rotation by ``angle`` radians about room +y."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def yaw_of(direction: np.ndarray) -> float:
    """The angle in radians of a turn about room +y that takes room forward (0, 0, -1) to
    the floor-plane ``direction`` (its y ignored)."""
    return math.atan2(-float(direction[0]), -float(direction[2]))


def pose_yaw(pose: Pose) -> float:
    """The yaw of ``pose`` about room +y (:func:`yaw_of` its heading, module docstring)."""
    axes = pose.matrix
    return yaw_of(heading(-axes[:, 2], axes[:, 1], ROOM_UP))


def moved(room: Room, *, pivot_before: np.ndarray, pivot_after: np.ndarray, turn: float = 0.0,
          scale: float = 1.0) -> Room:
    """The room after the scene, as seen in the room, is turned by ``turn`` radians about
    room +y and scaled by ``scale`` about ``pivot_before`` (3,) and carried to
    ``pivot_after`` (3,) (module docstring). With T the old room's :meth:`Room.to_world`,
    the new one is y -> T(pivot_before + Ry(-turn) (y - pivot_after) / scale)."""
    rotation = room.rotation @ yaw_rotation(turn).T
    if np.abs(rotation @ rotation.T - np.eye(3)).max() > 1e-12:  # rounding gathered over a long session
        u, _, vt = np.linalg.svd(rotation)
        rotation = u @ vt
    units = min(max(room.units_per_metre / scale, MIN_UNITS_PER_METRE), MAX_UNITS_PER_METRE)
    origin = room.to_world(np.asarray(pivot_before, np.float64)) - units * rotation @ np.asarray(pivot_after)
    return Room(rotation, origin, units)


def wrapped(angle: float) -> float:
    """``angle`` in radians brought into [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def grab_one(room_at_start: Room, hand_at_start: Pose, hand_now: Pose) -> Room:
    """One hand grabbing the scene: the scene point that was at the hand when the grip
    closed (``room_at_start``, ``hand_at_start``) stays at the hand, and the scene turns
    about the vertical through the hand by the hand's change of yaw (its pitch and roll
    are ignored, so the horizon stays level). The scale is kept."""
    return moved(room_at_start, pivot_before=hand_at_start.position, pivot_after=hand_now.position,
                 turn=wrapped(pose_yaw(hand_now) - pose_yaw(hand_at_start)))


def hands_yaw(left: np.ndarray, right: np.ndarray) -> float | None:
    """The yaw of the floor-plane vector from ``left`` (3,) to ``right`` (3,), None when
    the hands are one above the other (no horizontal vector between them)."""
    between = right - left
    if math.hypot(between[0], between[2]) < MIN_HAND_DISTANCE:
        return None
    return yaw_of(between)


def grab_two(room_at_start: Room, left_start: Pose, right_start: Pose, left_now: Pose, right_now: Pose) -> Room:
    """Both hands grabbing the scene (all poses in the room, ``*_start`` when the second
    grip closed, with ``room_at_start``).

    Scale: the scene grows by (distance now / distance at start): hands apart, the
    scene looks bigger, so units per metre is divided by it; clamped to
    :data:`MAX_GRAB_SCALE` either way (hands that meet give a finite scale), and kept
    when the hands were closer than :data:`MIN_HAND_DISTANCE` at the start. Turn: the
    change of yaw of the left-to-right vector (none while the hands are one above the
    other). Pivot: the scene point between the hands at the start stays between them.
    """
    start = float(np.linalg.norm(right_start.position - left_start.position))
    now = float(np.linalg.norm(right_now.position - left_now.position))
    scale = 1.0 if start < MIN_HAND_DISTANCE else min(max(now / start, 1.0 / MAX_GRAB_SCALE), MAX_GRAB_SCALE)
    yaw_start = hands_yaw(left_start.position, right_start.position)
    yaw_now = hands_yaw(left_now.position, right_now.position)
    turn = 0.0 if yaw_start is None or yaw_now is None else wrapped(yaw_now - yaw_start)
    return moved(room_at_start, pivot_before=0.5 * (left_start.position + right_start.position),
                 pivot_after=0.5 * (left_now.position + right_now.position), turn=turn, scale=scale)


def snap_turn(room: Room, head: Pose, degrees: float) -> Room:
    """The user turned ``degrees`` to the right (negative: left) about the vertical line
    through the head: the head stays at the same scene point."""
    return moved(room, pivot_before=head.position, pivot_after=head.position, turn=math.radians(degrees))


def checked_dt(dt: float) -> float:
    """``dt`` (seconds since the last frame) as a float; ValueError unless finite and >= 0."""
    dt = float(dt)
    if not (math.isfinite(dt) and dt >= 0):
        raise ValueError(f"a frame's time step must be a finite number of seconds >= 0, got {dt!r}")
    return dt


def smooth_turn(room: Room, head: Pose, radians_per_second: float, dt: float, amount: float) -> Room:
    """The user turning right (``amount`` > 0, a stick's x in -1..1) or left at
    ``radians_per_second`` for ``dt`` seconds, about the vertical through the head."""
    angle = radians_per_second * checked_dt(dt) * amount
    return moved(room, pivot_before=head.position, pivot_after=head.position, turn=angle)


def move(room: Room, head: Pose, stick: tuple[float, float], metres_per_second: float, dt: float) -> Room:
    """The user flying along the head's heading (stick y > 0: forward) and its right
    (stick x > 0) at ``metres_per_second`` room metres for ``dt`` seconds: the scene
    moves by speed * dt * units_per_metre units, and is seen moving backwards as the user
    moves forward. A stick pushed past the unit circle (a square gate's corner) is
    brought back to it, so diagonals are no faster."""
    x, y = float(stick[0]), float(stick[1])
    length = math.hypot(x, y)
    if length > 1.0:
        x, y = x / length, y / length
    axes = head.matrix
    forward = heading(-axes[:, 2], axes[:, 1], ROOM_UP)
    right = np.cross(forward, ROOM_UP)
    step = metres_per_second * checked_dt(dt) * (y * forward + x * right)
    return moved(room, pivot_before=np.zeros(3), pivot_after=-step)


def deadzone(value: float, dead: float = DEAD_ZONE) -> float:
    """A stick axis with |value| <= ``dead`` read as 0 and the rest rescaled to the full
    range: (|value| - dead) / (1 - dead) with value's sign, clipped to -1..1."""
    if not 0.0 <= dead < 1.0:
        raise ValueError(f"a dead zone must be in [0, 1), got {dead!r}")
    size = abs(float(value))
    if not size > dead:  # also NaN, a stick that reports nothing
        return 0.0
    return math.copysign(min((size - dead) / (1.0 - dead), 1.0), value)


def gripping(hand: HandInput) -> bool:
    """Whether ``hand`` holds the scene: grip pressed and tracked."""
    return hand.grip and hand.pose is not None


def same_room(a: Room | None, b: Room) -> bool:
    """Whether two rooms are equal value for value (a Room's arrays make == ambiguous)."""
    return a is not None and a.units_per_metre == b.units_per_metre \
        and np.array_equal(a.rotation, b.rotation) and np.array_equal(a.origin, b.origin)


class Locomotion:
    """The controllers' state between headset frames; :meth:`step` once a frame.

    Left stick: fly (:func:`move`). Right stick x: turn, by snaps (one
    ``snap_degrees`` turn per push past :data:`SNAP_FIRE`, armed again below
    :data:`SNAP_REARM`) or smoothly. Grip on one hand: :func:`grab_one` from the room
    and hand pose when it closed; on both: :func:`grab_two` from the state when the
    second closed. Whenever the set of gripping hands changes (a grip closes or opens,
    a gripping hand loses or regains tracking), the grab restarts from the current
    room and poses, so the scene never jumps: letting go of one hand of two carries on
    with the other from where the two left the scene. While a hand grips, the grab
    alone moves the room (the sticks wait; a snap push made meanwhile is spent). If the
    room handed to :meth:`step` is not the one it returned last (the caller recentred
    or reset it), a grab under way restarts from the new one.
    """

    def __init__(self) -> None:
        self._grab_start: Room | None = None
        self._grab_hands: tuple[Pose | None, Pose | None] = (None, None)
        self._returned: Room | None = None
        self._snap_armed = True
        self._recentre_held = False

    def step(self, room: Room, head: Pose, left: HandInput, right: HandInput, dt: float, *,
             turn: Literal["snap", "smooth"], snap_degrees: float = 30.0, smooth_degrees_per_second: float = 90.0,
             speed: float = 1.5) -> tuple[Room, bool]:
        """(the room after this frame's input, whether recentre was asked: the button
        pressed on either hand this frame and on neither the last). ``head``: the
        head's pose in the room; ``dt``: seconds since the last frame; ``speed``: flying
        speed in room metres per second."""
        if turn not in ("snap", "smooth"):
            raise ValueError(f"turn must be 'snap' or 'smooth', got {turn!r}")
        dt = checked_dt(dt)
        pressed = left.recentre or right.recentre
        recentre, self._recentre_held = pressed and not self._recentre_held, pressed

        turning = float(right.stick[0])
        fire = self._snap_armed and abs(turning) > SNAP_FIRE
        if fire:
            self._snap_armed = False
        elif abs(turning) < SNAP_REARM:
            self._snap_armed = True

        hands = (left.pose if gripping(left) else None, right.pose if gripping(right) else None)
        held = tuple(pose is not None for pose in hands)
        if held != tuple(pose is not None for pose in self._grab_hands) or not same_room(self._returned, room):
            self._grab_start, self._grab_hands = room, hands
        if all(held):
            room = grab_two(self._grab_start, *self._grab_hands, *hands)
        elif any(held):
            side = held.index(True)
            room = grab_one(self._grab_start, self._grab_hands[side], hands[side])
        else:
            if turn == "snap" and fire:
                room = snap_turn(room, head, math.copysign(snap_degrees, turning))
            elif turn == "smooth":
                room = smooth_turn(room, head, math.radians(smooth_degrees_per_second), dt, deadzone(turning))
            stick = (deadzone(left.stick[0]), deadzone(left.stick[1]))
            if stick != (0.0, 0.0):
                room = move(room, head, stick, speed, dt)
            self._grab_start = None
        self._returned = room
        return room, recentre
