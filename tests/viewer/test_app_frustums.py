"""The training cameras drawn in the scene: frustums where the cameras are, coloured by the
train/test split, named under the pointer, a click flying there, their photos inside,
and never in a screenshot."""

from __future__ import annotations

import random
from dataclasses import replace

import moderngl
import numpy as np
import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, project, text_past_the_panel
from datasets_kit import write_dataset
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from PIL import Image
from testkit import random_scene

from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.photos.dataset import open_dataset, select_split
from raygs_viewer.scene.demo import demo_cameras
from raygs_viewer.viewer.path_overlay import image_corners
from raygs_viewer.viewer.training_frustums import (
    FRUSTUM_SIZE,
    HOVER_COLOUR,
    TEST_COLOUR,
    TRAIN_COLOUR,
    image_slopes,
    in_test_split,
)

SIZE = (48, 32)
RED = (1.0, 0.0, 0.0)


def overview(viewer, drive) -> None:
    """The whole demo framed (every training camera in view), the flight landed."""
    viewer.reset_view()
    drive.frames(2)


def tooltips(monkeypatch) -> list[str]:
    """The tooltips set from now on (imgui's set_tooltip, wrapped)."""
    shown, original = [], imgui.set_tooltip
    monkeypatch.setattr(imgui, "set_tooltip", lambda text: (shown.append(text), original(text))[1])
    return shown


# -- the geometry, without a window ------------------------------------------------------
def test_image_corners_are_the_cameras_pixel_corners_and_the_split_is_evaluate_s():
    camera = look_at((0.5, -1.0, -3.0), (0.2, 0.1, 0.0), width=64, height=40, fov_y_degrees=55)
    camera = replace(camera, cx=20.0, cy=25.0)  # the principal point off the centre
    corners = image_corners(camera.R[None], camera.center[None], image_slopes([camera]), 0.3)[0]
    projected = [project(camera, corner) for corner in corners]
    np.testing.assert_allclose([p[:2] for p in projected], [(0, 0), (64, 0), (64, 40), (0, 40)], atol=1e-9)
    np.testing.assert_allclose([p[2] for p in projected], 0.3)

    names = [f"view_{i:03d}" for i in range(17)]
    shuffled = random.Random(1).sample(names, len(names))
    test = in_test_split(shuffled)
    assert {name for name, t in zip(shuffled, test) if t} == {"view_000", "view_008", "view_016"}


def test_the_split_is_select_split_s_on_a_dataset(tmp_path):
    cameras = [look_at((np.cos(a), 0.0, np.sin(a) - 3.0), (0, 0, 0), width=8, height=6) for a in np.linspace(0, 1, 10)]
    names = [f"img{i}" for i in (5, 1, 9, 0, 3, 8, 2, 7, 4, 6)]  # cameras.json in another order than by name
    root = write_dataset(tmp_path / "d", "inria", cameras, [np.zeros((6, 8, 3))] * 10, names)
    expected = {v.name for v in select_split(open_dataset(root).views, "test")}
    assert {n for n, t in zip(names, in_test_split(names)) if t} == expected == {"img0", "img8"}


# -- in the window -----------------------------------------------------------------------
def test_frustums_are_drawn_where_the_cameras_are_coloured_by_split(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    assert 0 not in viewer.frustums.drawn.depths  # the view stands at camera 0: not drawn over it
    overview(viewer, drive)
    drawn, camera, cameras = viewer.frustums.drawn, viewer.camera, demo_cameras()
    assert set(drawn.apexes) == set(range(6)) and drawn.segments == 48
    depth = FRUSTUM_SIZE * viewer.view.radius
    for i, training in enumerate(cameras):
        assert drawn.apexes[i] == pytest.approx(tuple(project(camera, training.center)[:2]), abs=1e-6)
        # the image's top-right corner, through the camera's own inverse projection
        ray = np.array([(training.width - training.cx) / training.fx, -training.cy / training.fy, 1.0])
        assert drawn.quads[i][1] == pytest.approx(project(camera, training.center + depth * training.R.T @ ray)[:2])
    # "default" comes first by name: the demo's one test view
    assert drawn.colours == {0: TEST_COLOUR} | {i: TRAIN_COLOUR for i in range(1, 6)}
    shown = viewer.capture_window()
    for i, colour in ((0, TEST_COLOUR), (3, TRAIN_COLOUR)):
        x, y = (int(c) for c in drawn.apexes[i])
        pixel = shown[y, x].astype(int)
        # the centre's dot is the split's colour, not the other's
        other = TRAIN_COLOUR if colour == TEST_COLOUR else TEST_COLOUR
        assert np.abs(pixel - colour[:3]).sum() < np.abs(pixel - other[:3]).sum()
    assert drawn.images == frozenset() and viewer.frustums.thumbnails.status.startswith("no photos")


def test_pointing_names_a_camera_and_a_click_flies_there(open_viewer, monkeypatch):
    viewer, drive = open_viewer(hide_panel=True)
    overview(viewer, drive)
    shown = tooltips(monkeypatch)
    x, y = viewer.frustums.drawn.apexes[2]
    drive.move_mouse(x + 3, y - 3)
    drive.frames(1)
    assert viewer.frustums.drawn.hovered == 2 and viewer.frustums.drawn.colours[2] == HOVER_COLOUR
    assert shown[-1] == "2: through-the-sheets (train view): click to fly there"

    drive.click_at(x + 3, y - 3)
    assert viewer.view.training_index == 2
    drive.frames(8)  # the flight (0.6 s at 0.1 s a frame) lands
    target = Pose.from_camera(demo_cameras()[2])
    np.testing.assert_array_equal(viewer.view.navigator.pose.position, target.position)
    np.testing.assert_array_equal(viewer.view.navigator.pose.R, target.R)
    assert 2 not in viewer.frustums.drawn.depths  # now stood at


def test_a_double_click_on_a_frustum_flies_there_and_picks_nothing(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    overview(viewer, drive)
    x, y = viewer.frustums.drawn.apexes[2]
    drive.move_mouse(x, y)
    drive.frames(1)
    for _ in range(2):  # a person's double-click: its first click flies, its second must not aim the flight
        drive.button(0, True)
        drive.frames(1)
        drive.button(0, False)
        drive.frames(1)
    assert viewer.view.training_index == 2
    assert viewer.picker.last is None and "nothing to pick" not in viewer.panel.message
    drive.frames(8)
    target = Pose.from_camera(demo_cameras()[2])
    np.testing.assert_array_equal(viewer.view.navigator.pose.position, target.position)


def test_no_flight_with_the_frustums_hidden_or_the_measure_tool_on(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    overview(viewer, drive)
    x, y = viewer.frustums.drawn.apexes[2]
    viewer.frustums.show = False
    drive.click_at(x, y)
    assert viewer.view.training_index is None and viewer.frustums.drawn.segments == 0

    viewer.frustums.show = True
    viewer.measure.on = True
    drive.click_at(x, y)
    assert viewer.view.training_index is None and viewer.frustums.drawn.hovered is None
    viewer.measure.on = False
    drive.click_at(x, y)
    assert viewer.view.training_index == 2


def test_the_panel_checkbox_hides_them_and_its_legend_fits(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.click("###training")
    drive.frames(1)
    drive.reveal("show in the scene")
    assert {"train", "test"} <= set(drive.panel.labels("text"))
    assert text_past_the_panel(drive) == []
    assert viewer.frustums.drawn.segments > 0
    drive.click("show in the scene")
    drive.frames(1)
    assert not viewer.frustums.show and viewer.frustums.drawn.segments == 0
    assert "train" not in drive.panel.labels("text")


def test_screenshots_are_the_same_with_the_frustums_shown(open_viewer, tmp_path):
    viewer, drive = open_viewer(hide_panel=True)
    overview(viewer, drive)
    drive.settle()
    assert viewer.frustums.drawn.segments > 0
    with_frustums = viewer.save_screenshot(tmp_path / "with.png")[0]
    window = viewer.capture_window(overlay=False)
    assert not np.array_equal(viewer.capture_window(), window)  # drawn in the window, over the view
    viewer.frustums.show = False
    drive.frames(1)
    without = viewer.save_screenshot(tmp_path / "without.png")[0]
    np.testing.assert_array_equal(np.asarray(Image.open(with_frustums)), np.asarray(Image.open(without)))
    np.testing.assert_array_equal(viewer.capture_window(overlay=False), window)


@pytest.fixture
def model(tmp_path):
    """An INRIA model folder: a small scene, two cameras; view_001's photo plain red,
    view_000's a file that is no picture."""
    scene = random_scene(n=80, seed=3, degree=0)
    cameras = [look_at(eye, (0, 0, 0), width=SIZE[0], height=SIZE[1], fov_y_degrees=50)
               for eye in ((0.3, -0.2, -4.0), (-1.5, 0.4, -3.6))]
    photos = [np.zeros((SIZE[1], SIZE[0], 3)), np.broadcast_to(RED, (SIZE[1], SIZE[0], 3))]
    root = write_dataset(tmp_path / "data", "inria", cameras, photos, scene=scene)
    (tmp_path / "data" / "source" / "images" / "view_000.png").write_bytes(b"not a picture")
    return root, cameras


def test_the_photo_is_shown_inside_its_frustum_and_a_bad_one_is_a_line(open_viewer, model):
    root, cameras = model
    viewer, drive = open_viewer(str(root / "point_cloud" / "iteration_7000" / "point_cloud.ply"), hide_panel=True)
    far_behind = look_at((-0.6, 0.1, -6.5), (0, 0, 0), width=SIZE[0], height=SIZE[1])
    viewer.view.navigator.set_pose(Pose.from_camera(far_behind))
    drive.frames(2)  # both in view: both photos read
    assert set(viewer.frustums.drawn.quads) == {0, 1} and viewer.frustums.drawn.images == {1}
    assert viewer.frustums.thumbnails.status.startswith("1 photo not shown: ")
    assert "view_000.png: cannot read the photo" in viewer.frustums.thumbnails.status
    # Behind camera 1, looking its way: its image fills the middle third of the view.
    behind = cameras[1].center - 2 * FRUSTUM_SIZE * viewer.view.radius * cameras[1].R[2]
    viewer.view.navigator.set_pose(Pose(behind, cameras[1].R))
    drive.frames(1)
    drawn = viewer.frustums.drawn
    quad = drawn.quads[1]
    x, y = quad.mean(axis=0) + (0, 0.3 * (quad[2, 1] - quad[1, 1]))  # below the centre, between the edges
    r, g, b = viewer.capture_window()[int(y), int(x)]
    assert r > 200 and g < 60 and b < 60
    assert tuple(viewer.capture_window(overlay=False)[int(y), int(x)]) != (r, g, b)

    texture = viewer.frustums.thumbnails.texture(1)
    viewer.open_scene("demo")
    drive.wait_for_load()
    assert viewer.frustums.thumbnails.texture(1) is None and isinstance(texture.mglo, moderngl.InvalidObject)
