"""The window's headset mode without a runtime: how the desktop camera carries the room
along (its move and its turn about up, never its pitch), where the mirror is shown,
and the headset statistics' late frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.viewer.headset import HeadsetStats, follow_desktop, mirror_framing
from raygs_viewer.xr.eyes import HeadsetEyes
from raygs_viewer.xr.room import Fov, Pose, Room, eye_camera, room_at_view
from raygs_viewer.xr.session import HeadsetFrame

UP = np.array([0.0, -1.0, 0.0])  # OpenCV scenes: -y is up
HEAD = Pose(np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.1, 1.6, -0.3]))
FOV = Fov(-0.8, 0.7, 0.75, -0.8)


def head_camera(room: Room):
    return eye_camera(HEAD, FOV, 64, 48, room)


def test_a_desktop_move_carries_the_head_by_the_same_move():
    before = look_at([0.0, -1.0, -4.0], [0.0, -1.0, 0.0])
    after = look_at([1.0, -1.5, -3.0], [1.0, -1.5, 1.0])  # moved, same heading
    room = room_at_view(before, HEAD, UP, 2.0)
    moved = follow_desktop(room, before, after, UP)
    np.testing.assert_allclose(head_camera(moved).center, after.center, atol=1e-12)
    np.testing.assert_allclose(head_camera(moved).R, head_camera(room).R, atol=1e-12)
    assert moved.units_per_metre == room.units_per_metre


def test_a_desktop_turn_about_up_turns_the_head_and_keeps_it_at_the_camera():
    before = look_at([0.0, 0.0, -4.0], [0.0, 0.0, 0.0])
    angle = math.radians(40.0)
    after = look_at([0.0, 0.0, -4.0], [math.sin(angle) * 4, 0.0, -4.0 + math.cos(angle) * 4])
    room = room_at_view(before, HEAD, UP, 1.0)
    turned = follow_desktop(room, before, after, UP)
    head = head_camera(turned)
    np.testing.assert_allclose(head.center, after.center, atol=1e-12)
    # The head (looking level along its forward) now looks where the desktop camera does.
    np.testing.assert_allclose(head.R[2], after.R[2], atol=1e-12)


def test_the_desktop_cameras_pitch_never_tilts_the_room():
    before = look_at([0.0, 0.0, -4.0], [0.0, 0.0, 0.0])
    after = look_at([0.0, 0.0, -4.0], [0.0, -3.0, 0.0])  # looking up 37 degrees
    room = room_at_view(before, HEAD, UP, 1.0)
    pitched = follow_desktop(room, before, after, UP)
    np.testing.assert_allclose(pitched.rotation, room.rotation, atol=1e-12)
    # The room's up stays the scene's up.
    np.testing.assert_allclose(pitched.rotation @ [0.0, 1.0, 0.0], UP, atol=1e-12)


def test_the_mirror_is_letterboxed_in_the_view_area_with_the_eyes_aspect():
    left = look_at([0, 0, -4], [0, 0, 0], width=320, height=240)
    right = look_at([0.1, 0, -4], [0.1, 0, 0], width=320, height=240)
    eyes = HeadsetEyes((left, right), left)
    camera, viewport, cameras = mirror_framing(eyes, (100, 0, 800, 600), "both")
    assert camera is left and cameras == (left, right)
    x, y, w, h = viewport
    assert w / h == pytest.approx(640 / 240, rel=1e-2) and x >= 100 and x + w <= 900 and y + h <= 600
    _, (_, _, w, h), _ = mirror_framing(eyes, (100, 0, 800, 600), "left")
    assert w / h == pytest.approx(320 / 240, rel=1e-2)


def test_a_frame_predicted_more_than_one_and_a_half_periods_on_is_late():
    stats = HeadsetStats()
    period = 0.0125
    for time_ns in (0, 12_500_000, 25_000_000, 62_500_000, 75_000_000):
        stats.timed(HeadsetFrame(time_ns, period, True, None))
    assert stats.late == 1 and stats.period == period


def test_the_statistics_lines_average_what_was_measured_and_skip_timers_not_yet_read():
    stats = HeadsetStats(ended=7, skipped=1, late=2, period=0.0125, order_frames=1)
    stats.cpu.extend([0.002, 0.004])
    stats.wall.extend([0.010, 0.020])
    stats.gpu.extend([(float("nan"), float("nan")), (0.005, 0.007), (0.007, 0.009)])  # the first not read yet
    assert stats.lines() == ["headset frames: 7 submitted, 1 skipped, 2 late",
                             "display period 12.5 ms; app CPU 3.0 ms a frame (15.0 ms wall) outside the runtime's wait",
                             "GPU per eye: left 6.0 ms, right 8.0 ms",
                             "order age: 1 headset frame"]
