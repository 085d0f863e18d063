"""The box's and the sphere's handles: each drag moves what it names so that the handle
follows the mouse (a centre across the view at its depth, a face along its axis, the rim
to the radius under the mouse), a face never passes the opposite one, and a drag back
returns the shape; in the window, a real drag on a handle moves it and not the camera."""

from __future__ import annotations

import numpy as np
import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.scene.selection import Box, Sphere
from raygs_viewer.viewer.volume_handles import (
    HandleDrag, along_the_view, box_edges, box_handles, moved, sphere_handles)

CAMERA = look_at((0.8, -0.6, -4.0), (0.1, 0.0, 0.2), width=160, height=120)
RECT = (40.0, 10.0, 360.0, 250.0)  # the image shown at twice its size, offset
BOX = Box((-0.5, -0.4, -0.3), (0.6, 0.5, 0.7))
SPHERE = Sphere((0.2, -0.1, 0.3), 0.8)


def screen(point):
    """Screen position of a world point, written out here."""
    q = CAMERA.R @ np.asarray(point, float) + CAMERA.t
    u, v = CAMERA.fx * q[0] / q[2] + CAMERA.cx, CAMERA.fy * q[1] / q[2] + CAMERA.cy
    return RECT[0] + u / CAMERA.width * (RECT[2] - RECT[0]), RECT[1] + v / CAMERA.height * (RECT[3] - RECT[1])


def depth(point):
    return (CAMERA.R @ np.asarray(point, float) + CAMERA.t)[2]


def drag(name, shape, to):
    handle = (box_handles(shape) if isinstance(shape, Box) else sphere_handles(shape, CAMERA))[name]
    return moved(HandleDrag(name, screen(handle), shape, CAMERA, RECT), *to)


@pytest.mark.parametrize("shape, name", [(BOX, "box centre"), (SPHERE, "sphere centre")])
def test_a_centre_follows_the_mouse_across_the_view_at_its_depth(shape, name):
    start = box_handles(BOX)["box centre"] if shape is BOX else np.array(SPHERE.centre)
    x, y = screen(start)
    after = drag(name, shape, (x + 37.0, y - 21.0))
    centre = box_handles(after)["box centre"] if shape is BOX else np.array(after.centre)
    np.testing.assert_allclose(screen(centre), (x + 37.0, y - 21.0), atol=1e-9)
    assert depth(centre) == pytest.approx(depth(start), abs=1e-12)
    if shape is BOX:
        np.testing.assert_allclose(np.subtract(after.high, after.low), np.subtract(BOX.high, BOX.low), atol=1e-12)
    else:
        assert after.radius == SPHERE.radius
    np.testing.assert_allclose(box_handles(drag(name, shape, (x, y)))["box centre"] if shape is BOX
                               else drag(name, shape, (x, y)).centre, start, atol=1e-12)


@pytest.mark.parametrize("face", ["box -x", "box +x", "box -y", "box +y", "box -z", "box +z"])
def test_a_face_moves_along_its_axis_by_the_mouse_move_along_it(face):
    axis = "xyz".index(face[-1])
    start = box_handles(BOX)[face]
    step = np.zeros(3)
    step[axis] = 0.05  # a small move along the axis: the screen motion is linear to first order
    target = screen(start + step)
    after = drag(face, BOX, target)
    moved_by = (after.high[axis] - BOX.high[axis]) if face[4] == "+" else (after.low[axis] - BOX.low[axis])
    assert moved_by == pytest.approx(0.05, rel=0.05)
    others = [a for a in range(3) if a != axis]
    for bound in (after.low, after.high):
        np.testing.assert_array_equal(np.take(bound, others), np.take(BOX.low if bound is after.low else BOX.high, others))
    # A mouse across the view, off the axis: only its part along the axis counts, and the
    # face stops at the opposite one.
    far = screen(start - 40 * step) if face[4] == "+" else screen(start + 40 * step)
    crushed = drag(face, BOX, far)
    assert crushed.low[axis] == crushed.high[axis]


def test_the_rim_sets_the_radius_to_the_point_under_the_mouse():
    centre = np.array(SPHERE.centre)
    point = centre + 1.3 * (0.6 * CAMERA.R[0] + 0.8 * CAMERA.R[1])  # in the plane facing the view
    after = drag("sphere radius", SPHERE, screen(point))
    assert after.radius == pytest.approx(1.3, rel=1e-9) and after.centre == SPHERE.centre
    np.testing.assert_allclose(sphere_handles(SPHERE, CAMERA)["sphere radius"], centre + 0.8 * CAMERA.R[0])


def test_the_box_has_its_twelve_edges():
    starts, ends = box_edges(BOX)
    lengths = np.sort(np.linalg.norm(ends - starts, axis=1))
    np.testing.assert_allclose(lengths, np.repeat(np.sort(np.subtract(BOX.high, BOX.low)), 4))


def test_a_real_drag_on_a_face_handle_moves_the_face_and_not_the_camera(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.reveal("Edit")
    drive.click("Edit")
    drive.frames(1)
    drive.reveal("show in the view##box")
    drive.click("show in the view##box")
    tool = viewer.edit_tool
    positions = viewer.loaded.scene.positions
    tool.box = Box(tuple(np.percentile(positions, 30, axis=0).tolist()),
                   tuple(np.percentile(positions, 70, axis=0).tolist()))  # all six faces in the view
    drive.settle()
    camera = viewer.camera
    assert tool.handles.show_box and "box +x" in tool.handles.drawn
    before = tool.box
    x, y = tool.handles.drawn["box +x"]
    drive.move_mouse(x, y)
    drive.frames(1)
    drive.button(0, True)
    drive.frames(1)
    for k in range(1, 4):
        drive.move_mouse(x - 10.0 * k, y + 3.0 * k)
        drive.frames(1)
    drive.button(0, False)
    drive.frames(1)
    assert np.array_equal(viewer.camera.R, camera.R) and np.array_equal(viewer.camera.t, camera.t)
    assert tool.box.low == before.low and tool.box.high[1:] == before.high[1:]
    assert tool.box.high[0] < before.high[0]
    # The face moved along x by what the mouse's move along x's screen direction asks.
    vx, vy, vw, vh = viewer.viewport  # the framebuffer scale is 1
    expected = moved(HandleDrag("box +x", (x, y), before, camera, (vx, vy, vx + vw, vy + vh)), x - 30.0, y + 9.0)
    assert tool.box.high[0] == pytest.approx(expected.high[0], rel=1e-12)


def test_a_face_whose_axis_points_along_the_view_offers_no_dot():
    camera = look_at((0.0, 0.0, -4.0), (0.0, 0.0, 0.0), width=160, height=120)  # along +z
    handles = box_handles(BOX)
    assert along_the_view(camera, handles["box +z"], 2) and along_the_view(camera, handles["box -z"], 2)
    assert not any(along_the_view(camera, handles[f"box {s}{a}"], "xyz".index(a)) for s in "-+" for a in "xy")
    assert not along_the_view(CAMERA, handles["box +z"], 0)
