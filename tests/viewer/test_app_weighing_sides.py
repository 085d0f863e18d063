"""Selecting what the view shows where one view draws with two sets of cameras or
settings, through real input in the window loop, against the float64 truth
(``render.contributions.max_weights``) of each side: the split view's pixels from the
divider on weigh with the right side's settings, the stereo preview's with the camera of
the eye the shape is drawn on (and the order the eyes share, sorted from their midpoint)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from edit_kit import drag, rich_rows, weighed, write_rows

from raygs_viewer.camera.pinhole import camera_to_json, look_at
from raygs_viewer.camera.stereo import StereoRig, custom_preset
from raygs_viewer.render.contributions import max_weights
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.edits import Operation
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.viewer.state import StereoPreview

W, H = 128, 96
EYE = custom_preset(96, 72, 90.0, 72.0)
#: Rows whose float64 weight lies this near the threshold may fall either side of it in float32.
MARGIN = 1e-4


def gaussians(tmp_path, name, centres, scales, opacities):
    """A PLY of round gaussians (``opacities`` as rendered, 0..1)."""
    rows = rich_rows(n=len(centres), seed=5, filter_3d=False, invalid=())
    for axis, column in zip("xyz", np.array(centres, np.float32).T):
        rows[axis] = column
    for a in range(3):
        rows[f"scale_{a}"] = np.log(scales)
    opacities = np.asarray(opacities, np.float64)
    rows["opacity"] = np.log(opacities / (1 - opacities))
    rows["rot_0"], rows["rot_1"], rows["rot_2"], rows["rot_3"] = 1, 0, 0, 0
    return write_rows(tmp_path / f"{name}.ply", rows)


def camera_file(tmp_path, camera):
    path = tmp_path / "start.json"
    path.write_text(json.dumps([camera_to_json(camera)]))
    return str(path)


def rectangle(camera, a, b):
    """(H, W) bool: the pixels of ``camera`` whose centre lies in the rectangle with
    corners ``a`` and ``b`` (continuous pixels)."""
    (u0, u1), (v0, v1) = sorted((a[0], b[0])), sorted((a[1], b[1]))
    u, v = np.meshgrid(np.arange(camera.width) + 0.5, np.arange(camera.height) + 0.5)
    return (u >= u0) & (u <= u1) & (v >= v0) & (v <= v1)


def truth(scene, frame, settings, camera, inside):
    """(N,) float64: each gaussian's largest weight over ``inside`` of ``camera`` drawn with
    ``settings`` in the order sorted from the frame's camera, culled for ``camera``."""
    order = exact_order(DepthSorter(scene), frame.camera, settings, cull_cameras=[camera])
    return max_weights(scene, camera, settings, order.indices, inside)


def chosen(weights, min_weight):
    """(rows at or over ``min_weight``, rows too near it to say)."""
    return set(np.flatnonzero(weights >= min_weight).tolist()), \
        set(np.flatnonzero(np.abs(weights - min_weight) < MARGIN).tolist())


def assert_selects(viewer, expected, unsure):
    selected = set(np.flatnonzero(viewer.edit_tool.edits.selection).tolist())
    assert selected - unsure == expected - unsure, viewer.panel.message


@pytest.fixture
def row_of_pairs(tmp_path):
    """Six pairs across the view: a wide opaque gaussian behind, in front of each a small
    one, faint (0.3, under the left side's p_min) and opaque by turns."""
    xs = np.linspace(-1.5, 1.5, 6)
    centres = [(x, 0.0, -0.4) for x in xs] + [(x, 0.0, 0.6) for x in xs]
    scales = [0.12] * 6 + [0.3] * 6
    opacities = [0.3, 0.95] * 3 + [0.95] * 6
    return gaussians(tmp_path, "pairs", centres, scales, opacities)


#: "auto": framebuffer fetch where the GPU offers it (the global order), else the lists.
PATHS = ["auto", "lists"]


def assert_weighed_on(viewer, weigh_on):
    if weigh_on == "lists":
        assert viewer.panel.message.endswith("GPU, fragment lists)"), viewer.panel.message


@pytest.mark.parametrize("weigh_on", PATHS)
def test_the_split_view_weighs_each_side_with_its_own_settings(open_viewer, row_of_pairs, tmp_path, weigh_on):
    start = look_at((0.0, 0.0, -4.0), (0.0, 0.0, 0.0), width=W, height=H, fov_y_degrees=45.0)
    viewer, drive = open_viewer(str(row_of_pairs), hide_panel=True, width=W, height=H,
                                camera=camera_file(tmp_path, start))
    # Left: a p_min no faint gaussian reaches (it draws none of them); right: 1e-3.
    viewer.settings = replace(viewer.settings, p_min=0.5)
    viewer.split.on, viewer.split.preset = True, "RayGS p_min 1e-3"
    tool = viewer.edit_tool
    tool.tool, tool.selects, tool.weigh_on = "rectangle", "visible", weigh_on
    drive.settle()
    frame, scene = viewer.shown, viewer.loaded.scene
    camera = frame.camera
    assert frame.right is not None and frame.right.p_min == 1e-3 and (camera.width, camera.height) == (W, H)
    x, y, w, h = viewer.viewport
    assert (w, h) == (W, H)  # one screen unit a pixel
    divider = viewer.split.column(camera.width)
    corners = [(x + 0.05 * W, y + 0.3 * H), (x + 0.5 * W, y + 0.5 * H), (x + 0.95 * W, y + 0.7 * H)]
    corners = [(float(round(a)), float(round(b))) for a, b in corners]
    drag(drive, corners)
    weighed(drive, viewer)

    inside = rectangle(camera, (corners[0][0] - x, corners[0][1] - y), (corners[-1][0] - x, corners[-1][1] - y))
    left, right = inside.copy(), inside.copy()
    left[:, divider:], right[:, :divider] = False, False
    assert left.any() and right.any()
    sides = np.maximum(truth(scene, frame, frame.settings, camera, left),
                       truth(scene, frame, frame.right, camera, right))
    expected, unsure = chosen(sides, tool.min_weight)
    assert_selects(viewer, expected, unsure)
    assert_weighed_on(viewer, weigh_on)
    # The faint ones count right of the divider alone: the whole shape with either side's
    # settings would select otherwise.
    seen = scene.positions.astype(np.float64) @ camera.R.T + camera.t
    columns = camera.fx * seen[:, 0] / seen[:, 2] + camera.cx
    faint = (0, 2, 4)
    assert all(inside[H // 2, int(columns[row])] for row in faint)
    assert [row in expected for row in faint] == [columns[row] >= divider for row in faint] == [False, False, True]
    for settings in (frame.settings, frame.right):
        whole, unsure_whole = chosen(truth(scene, frame, settings, camera, inside), tool.min_weight)
        assert whole - unsure - unsure_whole != expected - unsure - unsure_whole


@pytest.fixture
def near_and_far(tmp_path):
    """A small opaque gaussian near the eyes (a large disparity) before a wide one far
    behind it."""
    return gaussians(tmp_path, "near", [(0.0, 0.0, -2.5), (0.0, 0.0, 2.0)], [0.03, 1.2], [0.95, 0.95])


@pytest.mark.parametrize("weigh_on", PATHS)
def test_the_stereo_preview_weighs_with_the_eye_the_shape_is_drawn_on(open_viewer, near_and_far, tmp_path,
                                                                       weigh_on):
    rig = StereoRig(ipd=0.4, convergence=1000.0, scene_scale=1.0)
    start = look_at((0.0, 0.0, -4.0), (0.0, 0.0, 0.0), width=EYE.width, height=EYE.height)
    stereo = StereoPreview.of(EYE, on=True, layout="sbs", rig=rig)
    viewer, drive = open_viewer(str(near_and_far), hide_panel=True, width=2 * EYE.width, height=EYE.height,
                                stereo=stereo, camera=camera_file(tmp_path, start))
    tool = viewer.edit_tool
    tool.tool, tool.selects, tool.weigh_on = "rectangle", "visible", weigh_on
    drive.settle()
    frame, scene = viewer.shown, viewer.loaded.scene
    camera, (left_eye, right_eye) = frame.camera, frame.eyes
    assert viewer.viewport == (0, 0, 2 * EYE.width, EYE.height)  # the eyes side by side, 1:1

    def pixel(eye):
        p = eye.R @ scene.positions[0].astype(np.float64) + eye.t
        return eye.fx * p[0] / p[2] + eye.cx, eye.fy * p[1] / p[2] + eye.cy

    (ru, rv), (lu, lv), (mu, _) = pixel(right_eye), pixel(left_eye), pixel(camera)
    assert lu - ru > 8 and mu - ru > 4  # the near one's disparity, in pixels
    a, b = (round(ru) - 3, round(rv) - 3), (round(ru) + 3, round(rv) + 3)
    drag(drive, [(float(EYE.width + a[0]), float(a[1])), (float(EYE.width + ru), float(rv)),
                 (float(EYE.width + b[0]), float(b[1]))])
    weighed(drive, viewer)
    inside = rectangle(camera, a, b)
    weights = {name: truth(scene, frame, frame.settings, eye, inside)
               for name, eye in (("right", right_eye), ("left", left_eye), ("midpoint", camera))}
    expected, unsure = chosen(weights["right"], tool.min_weight)
    assert_selects(viewer, expected, unsure)
    assert_weighed_on(viewer, weigh_on)
    for other in ("left", "midpoint"):
        found, unsure_other = chosen(weights[other], tool.min_weight)
        assert found - unsure - unsure_other != expected - unsure - unsure_other, other

    # A click on an eye takes the gaussian that eye's pixel shows most.
    tool.tool = "click"
    for offset, eye, (u, v) in ((EYE.width, right_eye, (ru, rv)), (0, left_eye, (lu, lv))):
        u, v = int(u), int(v)
        one = np.zeros((EYE.height, EYE.width), bool)
        one[v, u] = True
        tops = {name: int(np.argmax(truth(scene, frame, frame.settings, each, one)))
                for name, each in (("eye", eye), ("other", left_eye if eye is right_eye else right_eye),
                                   ("midpoint", camera))}
        assert tops["eye"] != tops["other"] and tops["eye"] != tops["midpoint"]
        tool.apply(Operation("select none"), scene)
        drive.click_at(float(offset + u) + 0.5, float(v) + 0.5)
        weighed(drive, viewer)
        assert np.flatnonzero(tool.edits.selection).tolist() == [tops["eye"]]
