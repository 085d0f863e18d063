"""Navigator.aim_at, the window's double-click: orbit mode keeps the view's direction and
centres the point (it becomes the orbit target), fly mode turns in place to face it."""

import numpy as np
import pytest

from raygs_viewer.camera.lens import Lens
from raygs_viewer.camera.navigation import Navigator, Pose, centred_on, facing, up_vector
from raygs_viewer.camera.pinhole import look_at

W, H = 64, 48


def navigator(mode: str) -> Navigator:
    camera = look_at([0.3, -0.2, -4.0], [0.0, 0.0, 0.0], width=W, height=H)
    return Navigator(Pose.from_camera(camera), np.zeros(3), 1.0, up="-y", mode=mode)


def settle(nav: Navigator) -> None:
    for _ in range(20):
        nav.advance(0.1)
    assert not nav.animating


def pixel_of(nav: Navigator, point) -> np.ndarray:
    camera = Lens().camera(nav.pose, W, H)
    p = camera.R @ point + camera.t
    return np.array([camera.fx * p[0] / p[2] + camera.cx, camera.fy * p[1] / p[2] + camera.cy, p[2]])


def test_orbit_aim_keeps_the_direction_and_makes_the_point_the_target():
    nav = navigator("orbit")
    before = nav.pose
    point = np.array([0.7, 0.4, 0.5])
    distance = np.linalg.norm(point - before.position)
    assert nav.aim_at(point)
    settle(nav)
    np.testing.assert_array_equal(nav.pose.R, before.R)        # the same direction
    np.testing.assert_allclose(nav.target, point, atol=1e-12)   # the orbit turns about the point
    assert nav.distance == pytest.approx(distance)
    u, v, _ = pixel_of(nav, point)
    assert (u, v) == pytest.approx((W / 2, H / 2), abs=1e-9)    # on the image centre
    nav.rotate(40, -25)                                          # and orbiting keeps it there
    np.testing.assert_allclose(nav.target, point, atol=1e-9)


def test_fly_aim_turns_in_place_level_to_face_the_point():
    nav = navigator("fly")
    before = nav.pose
    point = np.array([1.5, -0.8, 1.0])
    assert nav.aim_at(point)
    settle(nav)
    np.testing.assert_array_equal(nav.pose.position, before.position)  # turns, does not move
    u, v, z = pixel_of(nav, point)
    assert (u, v) == pytest.approx((W / 2, H / 2), abs=1e-9) and z > 0
    assert abs(nav.pose.R[0] @ up_vector("-y")) < 1e-12                   # level: no roll
    assert nav.distance == pytest.approx(np.linalg.norm(point - before.position))


def test_the_aim_glides_and_a_user_move_stops_it():
    nav = navigator("orbit")
    start = nav.pose.position.copy()
    nav.aim_at([1.0, 0.0, 0.0])
    assert nav.animating
    nav.advance(0.1)
    assert nav.animating and not np.array_equal(nav.pose.position, start)
    nav.rotate(5, 0)
    assert not nav.animating


@pytest.mark.parametrize("point", [[np.nan, 0, 0], [np.inf, 0, 0], [1, 2], "camera"])
def test_a_bad_point_changes_nothing(point):
    for mode in ("orbit", "fly"):
        nav = navigator(mode)
        before, distance = nav.pose, nav.distance
        target = before.position if isinstance(point, str) else point
        assert not nav.aim_at(target)
        assert not nav.animating and nav.distance == distance
        np.testing.assert_array_equal(nav.pose.R, before.R)
        assert centred_on(before, target, up_vector("-y")) is None and facing(before, target, up_vector("-y")) is None
