"""scene/compare.py: per-attribute errors between two scenes, on hand-made scenes whose
answers are known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from testkit import random_scene

from raygs_viewer.scene.compare import attribute_errors, format_errors, rotation_angles
from raygs_viewer.scene.model import Scene

C0 = 0.28209479177387814


def replace(scene: Scene, **arrays) -> Scene:
    fields = {name: getattr(scene, name) for name in ("positions", "rotations", "scales", "opacities", "sh")}
    fields.update({name: np.asarray(value, np.float32) for name, value in arrays.items()})
    return Scene(sh_degree=scene.sh_degree, **fields)


def quaternion(axis, degrees):
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    half = math.radians(degrees) / 2
    return np.concatenate([[math.cos(half)], math.sin(half) * axis])


def multiply(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def box_scene():
    """Three gaussians whose positions span a 3 x 4 x 12 box: extent (diagonal) 13."""
    return Scene(np.float32([[0, 0, 0], [3, 4, 12], [1, 1, 1]]),
                 np.tile(np.float32([1, 0, 0, 0]), (3, 1)), np.full((3, 3), 0.1, np.float32),
                 np.float32([0.2, 0.5, 0.9]), np.zeros((3, 4, 3), np.float32), 1)


def test_identical_scenes_have_no_error():
    scene = random_scene(n=100, seed=1, degree=3)
    errors = attribute_errors(scene, scene)
    assert errors.count == 100 and not errors.sh_degree_lost
    for name in ("position_max", "position_mean", "position_relative", "scale_relative", "colour_max",
                 "colour_max_clipped", "sh_rest_max", "opacity_max", "rotation_degrees"):
        assert getattr(errors, name) == 0.0, name


def test_a_known_position_offset():
    scene = box_scene()
    moved = scene.positions.copy()
    moved[2] += [0.3, 0.4, 0.0]  # 0.5 away
    errors = attribute_errors(scene, replace(scene, positions=moved))
    assert errors.position_max == pytest.approx(0.5, rel=1e-6)
    assert errors.position_mean == pytest.approx(0.5 / 3, rel=1e-6)
    assert errors.extent == pytest.approx(13.0)
    assert errors.position_relative == pytest.approx(0.5 / 13, rel=1e-6)


@pytest.mark.parametrize("degrees", [30.0, 90.0, 179.0, 1e-3])
def test_a_known_rotation_angle(degrees):
    rng = np.random.default_rng(0)
    base = rng.normal(size=(5, 4))
    base /= np.linalg.norm(base, axis=1, keepdims=True)
    turn = quaternion([1.0, -2.0, 0.5], degrees)
    turned = np.array([multiply(q, turn) for q in base])
    angles = np.degrees(rotation_angles(base, turned))
    # float64 throughout: accurate even at a thousandth of a degree, where 2 acos|a.b| is not
    np.testing.assert_allclose(angles, degrees, rtol=1e-6)


def test_q_and_minus_q_are_the_same_rotation():
    scene = random_scene(n=50, seed=2, degree=0)
    errors = attribute_errors(scene, replace(scene, rotations=-scene.rotations))
    assert errors.rotation_degrees == 0.0
    unnormalised = replace(scene, rotations=-3.0 * scene.rotations)  # compared as rotations
    assert attribute_errors(scene, unnormalised).rotation_degrees < 1e-4


def test_rotation_error_is_the_largest_over_the_scene():
    scene = box_scene()
    rotations = scene.rotations.copy()
    rotations[1] = quaternion([0, 0, 1], 12.0)
    rotations[2] = quaternion([1, 0, 0], -40.0)
    assert attribute_errors(scene, replace(scene, rotations=rotations)).rotation_degrees == pytest.approx(40, 1e-5)


def test_scale_colour_opacity_and_sh_rest():
    scene = box_scene()
    scales = scene.scales.copy()
    scales[0, 2] *= 1.1
    scales[1, 0] *= 0.95
    sh = scene.sh.copy()
    sh[1, 0, 2] += 0.1 / C0  # the base colour's blue up by 0.1 (of 0..1)
    sh[2, 3, 0] -= 0.25  # an SH rest coefficient
    opacities = scene.opacities + np.float32([0.0, -0.03, 0.01])
    errors = attribute_errors(scene, replace(scene, scales=scales, sh=sh, opacities=opacities))
    assert errors.scale_relative == pytest.approx(0.1, rel=1e-5)
    assert errors.colour_max == pytest.approx(0.1, rel=1e-5)
    assert errors.colour_max_clipped == pytest.approx(0.1, rel=1e-5)
    assert errors.sh_rest_max == pytest.approx(0.25, rel=1e-6)
    assert errors.opacity_max == pytest.approx(0.03, rel=1e-4)
    assert errors.position_max == 0.0 and errors.rotation_degrees == 0.0


def test_colour_clipped_to_what_bytes_hold():
    scene = box_scene()
    sh = scene.sh.copy()
    sh[0, 0, 0] = 1.0 / C0  # red 1.5: a byte holds 1.0
    other = sh.copy()
    other[0, 0, 0] = 0.5 / C0  # red 1.0
    errors = attribute_errors(replace(scene, sh=sh), replace(scene, sh=other))
    assert errors.colour_max == pytest.approx(0.5) and errors.colour_max_clipped == 0.0


def test_sh_degree_lost_is_reported_not_measured():
    scene = random_scene(n=20, seed=3, degree=3)
    truncated = scene.with_sh_degree(0)
    errors = attribute_errors(scene, truncated)
    assert errors.sh_degree_lost and (errors.reference_sh_degree, errors.other_sh_degree) == (3, 0)
    assert errors.sh_rest_max == 0.0 and errors.colour_max == 0.0
    text = "\n".join(format_errors(errors))
    assert "SH rest    degree 3 -> 0: lost" in text
    partly = attribute_errors(scene, scene.with_sh_degree(1))  # degree 1 kept exactly
    assert partly.sh_degree_lost and partly.sh_rest_max == 0.0
    assert "degree 3 -> 1: lost, max 0 on the coefficients kept" in "\n".join(format_errors(partly))


def test_different_counts_cannot_be_compared():
    with pytest.raises(ValueError, match="20 and 19"):
        attribute_errors(random_scene(n=20, degree=0), random_scene(n=19, degree=0))


def test_empty_and_single_gaussian_scenes():
    empty = random_scene(n=0, degree=0)
    errors = attribute_errors(empty, empty)
    assert errors.count == 0 and errors.position_max == 0.0 and errors.position_relative is None
    one = random_scene(n=1, degree=0)
    assert attribute_errors(one, one).position_relative is None  # no extent to be relative to
    assert "extent" not in format_errors(attribute_errors(one, one))[0]


def test_format_errors_lines():
    scene = box_scene()
    moved = scene.positions.copy()
    moved[2] += [0.3, 0.4, 0.0]
    lines = format_errors(attribute_errors(scene, replace(scene, positions=moved)))
    assert lines[0] == "  position   max 0.5 (0.0385 of the scene's extent 13), mean 0.167"
    assert [line.split()[0] for line in lines] == ["position", "scale", "colour", "SH", "opacity", "rotation"]
    assert lines[-1] == "  rotation   max 0 degrees"
