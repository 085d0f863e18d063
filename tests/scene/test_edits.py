"""Edits and selections on their own: each shape against a brute-force truth, the set
operations, delete and crop, at least 100 undo steps of at most one bitmask each, and a
replay of the operations' JSON to the same masks."""

from __future__ import annotations

import json

import numpy as np
import pytest
from testkit import random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.scene.edits import UNDO_STEPS, Edits, Operation, replay
from raygs_viewer.scene.selection import (
    ATTRIBUTES, SH_C0, Box, Range, Rows, ScreenShape, Sphere, attribute_values, inside_polygon, shape_from_json)

SCENE = random_scene(n=800, seed=5, degree=1, spread=1.5)
CAMERA = look_at((0.4, -0.3, -4.0), (0, 0, 0), width=64, height=48)


def pixels():
    """(N, 2) pixel positions and (N,) in front, one gaussian at a time."""
    out, front = [], []
    for p in SCENE.positions.astype(np.float64):
        x, y, z = CAMERA.R @ p + CAMERA.t
        out.append((CAMERA.fx * x / z + CAMERA.cx, CAMERA.fy * y / z + CAMERA.cy))
        front.append(z > 0)
    return np.array(out), np.array(front)


def test_screen_shapes_select_the_centres_they_cover():
    uv, front = pixels()
    rect = ScreenShape("rectangle", CAMERA, ((40, 30), (20, 10)))  # corners in any order
    truth = front & (uv[:, 0] >= 20) & (uv[:, 0] <= 40) & (uv[:, 1] >= 10) & (uv[:, 1] <= 30)
    np.testing.assert_array_equal(rect.mask(SCENE), truth)
    square = ScreenShape("polygon", CAMERA, ((20, 10), (40, 10), (40, 30), (20, 30)))
    np.testing.assert_array_equal(square.mask(SCENE), truth)
    dab = ScreenShape("brush", CAMERA, ((32, 24),), 7.5)
    np.testing.assert_array_equal(dab.mask(SCENE), front & (np.hypot(uv[:, 0] - 32, uv[:, 1] - 24) <= 7.5))
    assert 10 < truth.sum() < 700


def test_a_lasso_that_crosses_itself_leaves_the_overlap_out():
    """A pentagram drawn in one stroke: its tips are inside, its centre (covered twice) not."""
    angles = np.radians(-90 + 144 * np.arange(5))
    star = np.stack([32 + 20 * np.cos(angles), 24 + 20 * np.sin(angles)], axis=1)
    points = np.array([[32, 24], [31, 26], [33, 23], [32, 9], [32, 6], [32, 3.5], [52.5, 24], [0, 0]])
    assert inside_polygon(points, star).tolist() == [False, False, False, True, True, False, False, False]


def test_attributes_are_what_the_histograms_say():
    np.testing.assert_allclose(attribute_values(SCENE, "opacity"), SCENE.opacities)
    np.testing.assert_allclose(attribute_values(SCENE, "largest scale"), SCENE.scales.max(axis=1), rtol=1e-7)
    np.testing.assert_allclose(attribute_values(SCENE, "volume"), 4 / 3 * np.pi * np.prod(SCENE.scales.astype(float), 1))
    centre = np.median(SCENE.positions, axis=0)
    np.testing.assert_allclose(attribute_values(SCENE, "distance"), np.linalg.norm(SCENE.positions - centre, axis=1),
                               rtol=1e-6)
    np.testing.assert_allclose(attribute_values(SCENE, "green"), 0.5 + SH_C0 * SCENE.sh[:, 0, 1], atol=1e-6)
    with pytest.raises(ValueError):
        attribute_values(SCENE, "shininess")


def test_set_operations_delete_and_crop():
    edits = Edits(SCENE.count)
    a, b = Sphere((0, 0, 0), 1.0), Box((-0.5, -3, -3), (3, 3, 3))
    in_a, in_b = a.mask(SCENE), b.mask(SCENE)
    edits.apply(SCENE, Operation("select", a))
    edits.apply(SCENE, Operation("select", b, "intersect"))
    np.testing.assert_array_equal(edits.selection, in_a & in_b)
    edits.apply(SCENE, Operation("select", b, "add"))
    np.testing.assert_array_equal(edits.selection, in_b)
    edits.apply(SCENE, Operation("select", a, "subtract"))
    np.testing.assert_array_equal(edits.selection, in_b & ~in_a)
    edits.apply(SCENE, Operation("delete"))
    np.testing.assert_array_equal(edits.deleted, in_b & ~in_a)
    edits.apply(SCENE, Operation("select all"))
    np.testing.assert_array_equal(edits.selection, ~(in_b & ~in_a))  # never a deleted one
    edits.apply(SCENE, Operation("invert"))
    assert not edits.selection.any()
    edits.apply(SCENE, Operation("crop", a))
    np.testing.assert_array_equal(~edits.deleted, in_a & ~(in_b & ~in_a))
    assert not edits.apply(SCENE, Operation("crop", a))  # nothing more to remove: no step
    edits.apply(SCENE, Operation("undelete all"))
    assert not edits.deleted.any()


def test_undo_keeps_at_least_100_steps_of_at_most_a_bitmask_each():
    edits = Edits(SCENE.count)
    rng = np.random.default_rng(0)
    history = []
    for step in range(150):
        low = rng.uniform(-2, 1, 3)
        op = Operation("select", Box(tuple(low), tuple(low + 1)), ("set", "add", "subtract")[step % 3])
        if edits.apply(SCENE, op):
            history.append((edits.selected.copy(), edits.deleted.copy()))
        if step % 10 == 9 and edits.apply(SCENE, Operation("delete")):
            history.append((edits.selected.copy(), edits.deleted.copy()))
    assert len(history) >= 100 and UNDO_STEPS >= 100
    assert edits.undo_bytes() <= len(history) * -(-SCENE.count // 8)
    for selected, deleted in reversed(history[-100:]):
        np.testing.assert_array_equal(edits.selected, selected)
        np.testing.assert_array_equal(edits.deleted, deleted)
        assert edits.undo()
    for selected, deleted in history[-100:]:
        assert edits.redo()
        np.testing.assert_array_equal(edits.selected, selected)
    assert not edits.redo()


def test_the_operations_replay_from_json_to_the_same_masks():
    edits = Edits(SCENE.count)
    operations = [Operation("select", ScreenShape("brush", CAMERA, ((10, 10), (50, 30)), 6.0)),
                  Operation("select", Range("opacity", 0.2, 0.6), "add"), Operation("delete"),
                  Operation("select", ScreenShape("polygon", CAMERA, ((5, 5), (60, 8), (30, 45)))),
                  Operation("invert"), Operation("crop", Sphere((0.1, 0, 0), 1.7)), Operation("select none")]
    for operation in operations:
        edits.apply(SCENE, operation)
    edits.apply(SCENE, Operation("select all"))
    edits.undo()  # undone: not recorded
    text = json.dumps([op.to_json() for op in edits.operations])
    again = replay(SCENE, [Operation.from_json(entry) for entry in json.loads(text)])
    np.testing.assert_array_equal(again.deleted, edits.deleted)
    np.testing.assert_array_equal(again.selected, edits.selected)
    assert edits.deleted.sum() > 50


@pytest.mark.parametrize("entry, words", [
    ({"kind": "box", "low": [1, 0, 0], "high": [0, 1, 1]}, "X0 = 1 is greater"),
    ({"kind": "sphere", "centre": [0, 0, 0]}, "needs 'radius'"),
    ({"kind": "range", "attribute": "shine", "low": 0, "high": 1}, "unknown attribute"),
    ({"kind": "range", "attribute": "opacity", "low": 1, "high": 0}, "low <= high"),
    ({"kind": "brush", "points": [[1, 2]], "radius": 0, "camera": {"width": 4, "height": 4, "fx": 1, "fy": 1,
      "cx": 2, "cy": 2, "R": np.eye(3).tolist(), "t": [0, 0, 0]}}, "radius > 0"),
    ({"kind": "polygon", "points": [[1, 2], [3, 4]], "camera": {}}, "a polygon shape needs '"),
    ({"kind": "star"}, "unknown shape kind"),
    ({"kind": "rows", "rows": [3, 1], "found by": "top", "through": ScreenShape("rectangle", CAMERA, ((0, 0), (1, 1)))
      .to_json()}, "distinct, ascending"),
    ({"kind": "rows", "rows": [1.5], "found by": "top", "through": {}}, "a rows shape"),
    ({"kind": "rows", "rows": [1], "found by": "guess", "through": ScreenShape("rectangle", CAMERA, ((0, 0), (1, 1)))
      .to_json()}, "found_by must be"),
    ({"kind": "rows", "rows": [1], "found by": "top", "through": {"kind": "box", "low": [0, 0, 0],
                                                                  "high": [1, 1, 1]}}, "'through' must be"),
])
def test_bad_shapes_are_refused_with_what_is_wrong(entry, words):
    with pytest.raises(ValueError, match=words):
        shape_from_json(entry)


def test_every_attribute_can_be_selected_by_range():
    for attribute in ATTRIBUTES:
        values = attribute_values(SCENE, attribute)
        middle = np.median(values)
        mask = Range(attribute, values.min(), middle).mask(SCENE)
        np.testing.assert_array_equal(mask, values <= middle)


@pytest.mark.parametrize("shape", [
    ScreenShape("rectangle", CAMERA, ((40.5, 30.0), (20.0, 10.5))),
    ScreenShape("rectangle", CAMERA, ((7, 9), (8, 10))),  # one pixel: the click's shape
    ScreenShape("polygon", CAMERA, ((-20, 5), (60, 8), (30, 70))),  # past the image's edges
    ScreenShape("brush", CAMERA, ((10, 10), (50, 30), (52, 47)), 6.5),
    ScreenShape("rectangle", CAMERA, ((100, 100), (120, 130))),  # off the image: no pixel
])
def test_a_screen_shape_holds_the_pixels_whose_centres_it_covers(shape):
    v, u = np.mgrid[0:CAMERA.height, 0:CAMERA.width]
    centres = np.stack([u.ravel() + 0.5, v.ravel() + 0.5], axis=1)
    truth = shape.holds(centres).reshape(CAMERA.height, CAMERA.width)
    np.testing.assert_array_equal(shape.pixel_mask(), truth)
    if shape.points == ((7.0, 9.0), (8.0, 10.0)):
        assert np.argwhere(truth).tolist() == [[9, 7]]


def test_rows_select_exactly_their_rows_and_replay_from_json():
    through = ScreenShape("brush", CAMERA, ((10, 10),), 4.0)
    rows = Rows((2, 40, 799), "visible", through, 0.05)
    mask = rows.mask(SCENE)
    assert np.flatnonzero(mask).tolist() == [2, 40, 799]
    entry = json.loads(json.dumps(Operation("select", rows, "add").to_json()))
    assert entry["shape"]["min weight"] == 0.05 and entry["shape"]["through"]["kind"] == "brush"
    again = Operation.from_json(entry)
    np.testing.assert_array_equal(again.shape.mask(SCENE), mask)
    assert again.shape.through.to_json() == through.to_json()
    with pytest.raises(ValueError, match="row 799 is past the scene's 10 gaussians"):
        rows.mask(SCENE.rows(np.arange(10)))


def test_edits_grown_with_the_scene_keep_every_mask_operation_and_step():
    """A streamed SOG's finer level adds rows after those read: the edits grow with them.
    The rows before keep their selection and deletion (deleted gaussians must not come
    back), the new rows start unedited, and undo and redo go on over the grown masks."""
    coarse = SCENE.rows(np.arange(300))
    edits = Edits(coarse.count)
    edits.apply(coarse, Operation("select", Sphere((0.0, 0.0, 0.0), 1.0)))
    edits.apply(coarse, Operation("delete"))
    edits.apply(coarse, Operation("select", Box((-2.0, -2.0, -2.0), (0.0, 2.0, 2.0))))
    deleted, selected = edits.deleted.copy(), edits.selected.copy()
    assert 0 < deleted.sum() < 300 and selected.any()
    grown = edits.grow(SCENE.count)
    assert grown.count == SCENE.count and grown.generation != edits.generation
    np.testing.assert_array_equal(grown.deleted[:300], deleted)
    np.testing.assert_array_equal(grown.selected[:300], selected)
    assert not grown.deleted[300:].any() and not grown.selected[300:].any()
    assert grown.operations == edits.operations and grown.edited
    assert grown.undo()  # the last selection undone over the grown rows
    np.testing.assert_array_equal(grown.deleted[:300], deleted)
    assert grown.undo() and not grown.deleted.any()  # the delete undone: every row back
    assert grown.redo() and np.array_equal(grown.deleted[:300], deleted) and not grown.deleted[300:].any()
    assert grown.apply(SCENE, Operation("select all")) and grown.selected[300:].all()
    with pytest.raises(ValueError, match="cannot grow"):
        edits.grow(299)
