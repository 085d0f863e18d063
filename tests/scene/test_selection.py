"""Screen shapes select through the view, and the view looks one way: a centre behind
the camera is never selected, though the pinhole maps it onto the image (mirrored
through the principal point), here onto the middle of every shape drawn."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from testkit import random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.scene.selection import ScreenShape

CAMERA = look_at((0.4, -0.3, -4.0), (0, 0, 0), width=64, height=48)
#: Camera-space (x, y) of the centres: on the optical axis and just off it, so that each
#: one's image lies near the principal point whether a centre behind is divided by its
#: depth (mirrored) or not.
OFF_AXIS = ((0.0, 0.0), (0.05, 0.03), (-0.04, 0.02))
DEPTH = 2.0


def centres_in_front_and_behind():
    """A scene of len(OFF_AXIS) centres DEPTH in front of the camera, then as many DEPTH
    behind it; and (2 * len(OFF_AXIS),) bool, which are in front."""
    right, down, forward = CAMERA.R
    positions = [CAMERA.center + side * DEPTH * forward + x * right + y * down
                 for side in (1.0, -1.0) for x, y in OFF_AXIS]
    scene = random_scene(n=len(positions), seed=3, degree=0)
    scene = dataclasses.replace(scene, positions=np.array(positions, np.float32))
    return scene, np.repeat([True, False], len(OFF_AXIS))


CX, CY = CAMERA.cx, CAMERA.cy


@pytest.mark.parametrize("shape", [
    ScreenShape("rectangle", CAMERA, ((CX - 8, CY - 8), (CX + 8, CY + 8))),
    ScreenShape("polygon", CAMERA, ((CX - 10, CY - 9), (CX + 11, CY - 7), (CX + 1, CY + 12))),  # a lasso
    ScreenShape("brush", CAMERA, ((CX - 3, CY), (CX + 3, CY)), 8.0),
], ids=lambda shape: shape.kind)
def test_a_screen_shape_never_selects_a_centre_behind_the_camera(shape):
    scene, in_front = centres_in_front_and_behind()
    mu = scene.positions.astype(np.float64) @ CAMERA.R.T + CAMERA.t
    np.testing.assert_allclose(np.abs(mu[:, 2]), DEPTH, rtol=1e-5)  # the scene is what it says
    for z in (mu[:, 2], np.where(mu[:, 2] > 0, mu[:, 2], 1.0)):  # where the behind ones land, mirrored or not
        uv = np.stack([CAMERA.fx * mu[:, 0] / z + CX, CAMERA.fy * mu[:, 1] / z + CY], axis=1)
        assert shape.holds(uv).all()
    np.testing.assert_array_equal(shape.mask(scene), in_front)
