"""Picking points in the window: a double-click aims the view at the median-depth point
under the mouse (orbit: around it, fly: facing it), or sets the stereo convergence; an
empty pixel changes nothing; the measure tool's clicks, its scale and file, and its
lines over the view (cut at the near plane, never in screenshots).

Double-clicks are injected (InputHandler.inject), the path a real one takes after
imgui's timing has recognised it, so no test waits on real time; single clicks are real
(press and release, no timing)."""

from __future__ import annotations


import numpy as np
import pytest
from appkit import PANEL_HEIGHT, headless, presented
from PIL import Image

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.stereo import StereoRig, custom_preset, eye_cameras
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.capture.measure_file import Measurement, load_measure_document
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.viewer.path_overlay import screen_segments
from raygs_viewer.viewer.path_widget import OVERLAY_NEAR
from raygs_viewer.viewer.pick_tool import NOTHING_THERE
from raygs_viewer.viewer.picking import mono_pixel, pixel_camera, stereo_pixel, unproject
from raygs_viewer.viewer.state import StereoPreview

W, H = 64, 48
PANEL_NARROW = 380  # the panel (360 wide) and a sliver of view: a small scene image to draw
EYE = custom_preset(40, 30, 90.0, 72.0)


def small(open_viewer, mode="fly", **options):
    options.setdefault("hide_panel", True)
    viewer, drive = open_viewer(width=W, height=H, **options)
    viewer.view.navigator.set_mode(mode)
    drive.settle()
    return viewer, drive


def medians(viewer, camera=None, order=None, **kwargs) -> np.ndarray:
    """(H, W) median depth of the whole view, rendered headlessly (with an exact sort of
    its own unless an ``order`` is given)."""
    camera = camera or viewer.camera
    order = order or exact_order(viewer.scene.direct_sorter, camera, viewer.settings)
    return viewer.scene.renderer.render_channels(camera, viewer.settings, order, **kwargs).median_depth


def surface_pixel(median: np.ndarray, near: tuple[int, int] | None = None) -> tuple[int, int]:
    """(u, v) of a pixel whose 3 x 3 neighbours all have about its median depth (a
    surface, not an edge), nearest ``near``."""
    h, w = median.shape
    good = [(u, v) for v in range(1, h - 1) for u in range(1, w - 1)
            if median[v, u] > 0 and np.ptp(median[v - 1:v + 2, u - 1:u + 2]) < 0.05 * median[v, u]]
    near = near or (w // 2, h // 2)
    return min(good, key=lambda p: (p[0] - near[0]) ** 2 + (p[1] - near[1]) ** 2)


def screen(viewer, u: int, v: int) -> tuple[float, float]:
    x, y = viewer.viewport[:2]
    return x + u + 0.5, y + v + 0.5


def double_click(drive, viewer, u: int, v: int, frames: int = 6) -> None:
    x, y = screen(viewer, u, v)
    drive.move_mouse(x, y)
    viewer.input.inject(x, y)
    drive.frames(frames)  # the aim glides over 0.3 s of 0.1 s frames


def test_pixel_camera_and_unproject_agree_with_the_view():
    camera = look_at([0.5, -0.3, -3.0], [0.0, 0.1, 0.0], width=W, height=H)
    u, v, depth = 17, 30, 2.75
    point = unproject(camera, u, v, depth)
    p = camera.R @ point + camera.t
    assert p[2] == pytest.approx(depth)
    assert (camera.fx * p[0] / p[2] + camera.cx, camera.fy * p[1] / p[2] + camera.cy) == pytest.approx((u + .5, v + .5))
    one = pixel_camera(camera, u, v)
    assert (one.width, one.height) == (1, 1)
    np.testing.assert_allclose(one.pixel_rays()[0, 0], camera.pixel_rays()[v, u], rtol=1e-12)
    np.testing.assert_allclose(unproject(one, 0, 0, depth), point, rtol=1e-12)


def test_screen_positions_map_to_pixels_and_stereo_eyes():
    camera = look_at([0.0, 0.0, -3.0], [0.0, 0.0, 0.0], width=40, height=30)
    viewport = (10, 5, 80, 60)  # shown at twice its size
    assert mono_pixel(10 + 2 * 7 + 1, 5 + 2 * 4 + 1, viewport, (1.0, 1.0), camera) == (7, 4)
    assert mono_pixel(9.9, 20, viewport, (1.0, 1.0), camera) is None
    assert mono_pixel(40, 5 + 60, viewport, (1.0, 1.0), camera) is None
    assert mono_pixel(float("nan"), 20, viewport, (1.0, 1.0), camera) is None
    view = StereoPreview.of(EYE, on=True, layout="sbs", rig=StereoRig(ipd=0.2)).view()
    left, right = eye_cameras(camera, view.rig)
    sbs = (0, 0, 80, 30)
    eye, u, v = stereo_pixel(45.5, 3.5, sbs, (1.0, 1.0), camera, eyes=(left, right), layout="sbs")
    assert (u, v) == (5, 3) and eye is right
    eye, u, v = stereo_pixel(45.5, 3.5, sbs, (1.0, 1.0), camera, eyes=(left, right), layout="cross")
    assert (u, v) == (5, 3) and eye is left
    eye, u, v = stereo_pixel(5.5, 3.5, (0, 0, 40, 30), (1.0, 1.0), camera, eyes=(left, right), layout="anaglyph")
    assert (u, v) == (5, 3) and eye is camera


def test_double_click_in_orbit_mode_orbits_around_the_median_depth_point(open_viewer):
    viewer, drive = small(open_viewer, mode="orbit")
    camera = viewer.camera
    median = medians(viewer)
    u, v = surface_pixel(median, near=(20, 34))
    expected = unproject(camera, u, v, float(median[v, u]))
    double_click(drive, viewer, u, v)
    navigator = viewer.view.navigator
    assert not navigator.animating
    np.testing.assert_allclose(navigator.target, expected, rtol=1e-4, atol=1e-4)
    np.testing.assert_array_equal(navigator.pose.R, camera.R)  # it keeps its direction
    assert navigator.distance == pytest.approx(np.linalg.norm(expected - camera.center), rel=1e-4)
    picked = viewer.picker.last
    assert picked.depth == pytest.approx(median[v, u], rel=1e-4)
    assert viewer.panel.message.startswith("point (") and "orbiting around it" in viewer.panel.message
    drive.frames(1)
    camera = viewer.camera
    p = camera.R @ expected + camera.t
    assert (camera.fx * p[0] / p[2] + camera.cx, camera.fy * p[1] / p[2] + camera.cy) == pytest.approx(
        (camera.cx, camera.cy), abs=0.05)  # now on the image centre


def test_double_click_in_fly_mode_turns_in_place_to_face_the_point(open_viewer):
    viewer, drive = small(open_viewer, mode="fly")
    camera = viewer.camera
    median = medians(viewer)
    u, v = surface_pixel(median, near=(50, 40))
    expected = unproject(camera, u, v, float(median[v, u]))
    double_click(drive, viewer, u, v)
    after = viewer.camera
    np.testing.assert_allclose(after.center, camera.center, rtol=0, atol=1e-12)  # turned, not moved
    assert after.R[2] @ (expected - after.center) / np.linalg.norm(expected - after.center) == pytest.approx(1.0)
    assert "facing it" in viewer.panel.message


def test_double_click_on_an_empty_pixel_changes_nothing_and_says_so(open_viewer):
    viewer, drive = small(open_viewer, mode="orbit")
    median = medians(viewer)
    assert median[2, 2] == 0  # the demo's sky: alpha never reaches 0.5
    pose, target = viewer.view.navigator.pose, viewer.view.navigator.target.copy()
    double_click(drive, viewer, 2, 2)
    np.testing.assert_array_equal(viewer.view.navigator.pose.R, pose.R)
    np.testing.assert_array_equal(viewer.view.navigator.pose.position, pose.position)
    np.testing.assert_array_equal(viewer.view.navigator.target, target)
    assert viewer.panel.message == NOTHING_THERE and viewer.picker.last is None


def test_double_click_over_the_panel_is_the_panels(open_viewer):
    viewer, drive = open_viewer(width=PANEL_NARROW, height=PANEL_HEIGHT)
    drive.frames(2)
    pose = viewer.view.navigator.pose
    x0, y0, x1, y1 = drive.panel.rect("Reset view (R)")
    drive.move_mouse(x1 + 4, y0 + 2)  # on the panel's window, beside the button
    drive.frames(1)
    viewer.input.inject(x1 + 4, y0 + 2)
    drive.frames(4)
    np.testing.assert_array_equal(viewer.view.navigator.pose.R, pose.R)
    assert viewer.picker.last is None


def test_a_stereo_double_click_can_set_the_convergence_to_the_points_depth(open_viewer):
    rig = StereoRig(ipd=0.1, convergence=20.0, scene_scale=0.5)
    stereo = StereoPreview.of(EYE, on=True, layout="sbs", rig=rig, converge_on_pick=True)
    viewer, drive = open_viewer(hide_panel=True, width=2 * EYE.width, height=EYE.height, stereo=stereo)
    drive.settle()
    camera, pose = viewer.camera, viewer.view.navigator.pose
    left, right = eye_cameras(camera, rig)
    median = medians(viewer, right, color_origin=camera.center)
    u, v = surface_pixel(median)
    double_click(drive, viewer, EYE.width + u, v, frames=2)  # in the right eye's half
    assert viewer.stereo.rig.convergence == pytest.approx(median[v, u] * rig.scene_scale, rel=1e-4)
    assert viewer.stereo.rig.ipd == rig.ipd and viewer.stereo.rig.scene_scale == rig.scene_scale
    np.testing.assert_array_equal(viewer.view.navigator.pose.R, pose.R)  # the view stays
    assert viewer.panel.message.startswith("convergence set to")
    drive.frames(1)
    assert viewer.shown_stereo.rig.convergence == viewer.stereo.rig.convergence
    viewer.stereo.converge_on_pick = False  # off: the double-click aims the view as in mono
    double_click(drive, viewer, u, v)
    assert not np.array_equal(viewer.view.navigator.pose.R, pose.R)


# -- measuring -----------------------------------------------------------------------------
def click(drive, label: str) -> None:
    """Clicks the panel's widget ``label`` as it is now, scrolling the panel to it first."""
    drive.frames(1)  # an edit in the last frame may have moved the widgets below it
    drive.reveal(label)
    drive.click(label)


def measured_points(viewer, pixels) -> list[np.ndarray]:
    median = medians(viewer)
    return [unproject(viewer.camera, u, v, float(median[v, u])) for u, v in pixels]


def test_two_clicks_measure_the_distance_between_the_picked_points(open_viewer):
    viewer, drive = small(open_viewer)
    median = medians(viewer)
    pixels = [surface_pixel(median, near=(12, 40)), surface_pixel(median, near=(52, 30))]
    a, b = measured_points(viewer, pixels)
    viewer.frustums.show = False  # a training camera's frustum there would take the click and fly to it
    drive.click_at(*screen(viewer, *pixels[0]))  # measuring is off: a click does nothing
    assert viewer.measure.pending is None and not viewer.measure.measurements
    viewer.measure.on = True
    camera = viewer.camera
    for pixel in pixels:
        drive.click_at(*screen(viewer, *pixel))
    np.testing.assert_array_equal(viewer.camera.R, camera.R)  # clicks do not turn the view
    [measurement] = viewer.measure.measurements
    np.testing.assert_allclose(measurement.a, a, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(measurement.b, b, rtol=1e-4, atol=1e-4)
    assert measurement.distance == pytest.approx(np.linalg.norm(b - a), rel=1e-3)
    assert viewer.panel.message == f"measurement 0: {measurement.distance:.4g} units"
    # A double-click while measuring neither aims the view nor measures a length of 0.
    double_click(drive, viewer, *pixels[0])
    np.testing.assert_array_equal(viewer.camera.R, camera.R)
    drive.click_at(*screen(viewer, *pixels[0]))
    drive.click_at(*screen(viewer, *pixels[0]))
    assert len(viewer.measure.measurements) == 1 and viewer.measure.pending is not None


def test_a_drag_while_measuring_turns_the_view_and_picks_nothing(open_viewer):
    viewer, drive = small(open_viewer)
    viewer.measure.on = True
    u, v = surface_pixel(medians(viewer))
    drive.move_mouse(*screen(viewer, u, v))
    drive.frames(1)
    drive.button(0, True)
    drive.frames(1)
    drive.move_mouse(*screen(viewer, u + 10, v))
    drive.frames(1)
    drive.button(0, False)
    drive.frames(1)
    assert viewer.measure.pending is None


def test_a_scale_from_one_known_length_converts_every_distance(open_viewer):
    viewer, drive = small(open_viewer)
    widget = viewer.measure
    widget.measurements = [Measurement([0, 0, 0], [0, 0, 2.5]), Measurement([1, 1, 1], [1, 2, 1])]
    widget.known_length, widget.unit = 1.2, "m"
    widget.set_scale(0)
    assert widget.describe(0) == "1.2 m" and widget.describe(1) == f"{1.2 / 2.5:.4g} m"
    widget.set_unit("metres")
    assert widget.describe(1).endswith(" metres") and widget.scale.factor == pytest.approx(1.2 / 2.5)
    widget.delete(0)  # the scale stays, no longer naming a measurement
    assert widget.scale.reference is None and widget.describe(0) == f"{1.2 / 2.5:.4g} metres"
    widget.known_length = -1.0
    viewer.panel.say(widget.set_scale(0))
    assert viewer.panel.error.startswith("error: scale not set") and widget.scale.factor == pytest.approx(0.48)


def test_the_measure_section_lists_deletes_saves_and_loads(open_viewer, tmp_path):
    viewer, drive = open_viewer(width=PANEL_NARROW, height=PANEL_HEIGHT)
    drive.frames(2)
    widget = viewer.measure
    widget.measurements = [Measurement([0, 0, 0], [0, 0, 2.0]), Measurement([0, 0, 0], [3, 4, 0])]
    click(drive, "Measure")
    drive.reveal("Delete##measurement")  # the list above it: a list box out of view draws no entries
    click(drive, "1: 5 units##measurement1")
    assert widget.selected == 1
    click(drive, "Set scale")  # known length 1, unit "m": 5 units are 1 m
    drive.frames(1)
    assert "1: 1 m##measurement1" in drive.panel and "0: 0.4 m##measurement0" in drive.panel
    widget.file = str(tmp_path / "m.json")
    click(drive, "Save##measure")
    assert viewer.panel.message == f"saved {tmp_path / 'm.json'}"
    saved = load_measure_document(tmp_path / "m.json")
    assert len(saved.measurements) == 2 and saved.scale.reference == 1 and saved.scene_path == "demo"
    click(drive, "Delete##measurement")
    assert len(widget.measurements) == 1
    click(drive, "Load##measure")
    assert len(widget.measurements) == 2 and widget.scale == saved.scale
    assert viewer.panel.message == f"loaded {widget.file}: 2 measurements"  # the same scene: no warning
    (tmp_path / "bad.json").write_text('{"format": "raygs-viewer measurements", "version": 1, "measurements": [1]}')
    widget.file = str(tmp_path / "bad.json")
    click(drive, "Load##measure")
    assert viewer.panel.error.startswith("error: measurements not loaded: ") and "\n" not in viewer.panel.error
    assert "'measurements[0]' must be a JSON object" in viewer.panel.error and len(widget.measurements) == 2
    widget.file = str(tmp_path / "m.json")
    click(drive, "Save##measure")  # it exists: never replaced without "replace file"
    assert "already exists" in viewer.panel.error and len(load_measure_document(widget.file).measurements) == 2


def test_measurements_are_drawn_over_the_view_but_never_in_screenshots(open_viewer):
    viewer, drive = small(open_viewer)
    a, b = measured_points(viewer, [(10, 40), (54, 36)])
    viewer.measure.measurements = [Measurement(a, b)]
    drive.frames(1)
    assert list(viewer.measure.drawn.lines) == [0]
    with_overlay = viewer.capture_window()[:H, :W].astype(int)
    assert np.abs(with_overlay - presented(viewer)).max() > 100  # the line is in the window
    png, _ = viewer.save_screenshot()
    saved = np.asarray(Image.open(png).convert("RGB")).astype(int)
    assert np.abs(saved - to_rgb8(headless(viewer)[..., :3]).astype(int)).max() <= 2  # and not in the file


def test_a_measurement_partly_behind_the_camera_is_cut_at_the_near_plane(open_viewer):
    viewer, drive = small(open_viewer)
    camera = viewer.camera
    ahead = camera.center + 2.0 * camera.R[2] + 0.5 * camera.R[0]
    behind = camera.center - 1.0 * camera.R[2] - 0.3 * camera.R[0]
    viewer.measure.measurements = [Measurement(ahead, behind)]
    drive.frames(1)
    camera = viewer.camera
    near = OVERLAY_NEAR * viewer.view.radius
    (x0, y0), (x1, y1) = viewer.measure.drawn.lines[0]
    a, b = (camera.R @ p + camera.t for p in (ahead, behind))

    def image(p):  # camera space -> pixel
        return np.array([camera.fx * p[0] / p[2] + camera.cx, camera.fy * p[1] / p[2] + camera.cy])

    start = image(a)
    assert (x0, y0) == pytest.approx(tuple(start), abs=1e-6)
    # The drawn line heads for where the segment passes the near plane (stopping at the
    # image's edge on the way), not for the behind point's projection, which lies the
    # other way (a segment through infinity, wrapped).
    drawn = np.array([x1, y1]) - start
    assert drawn @ (image(a + (near - a[2]) / (b[2] - a[2]) * (b - a)) - start) > 0
    assert drawn @ (image(b) - start) < 0


def test_screen_segments_cut_a_segment_at_the_near_plane_not_through_infinity():
    camera = look_at([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], width=W, height=H)
    rect = (0.0, 0.0, float(W), float(H))
    near = 0.1
    start, end = np.array([[0.2, 0.1, 2.0]]), np.array([[-0.4, -0.2, -1.0]])
    [[p, q]] = screen_segments(camera, start, end, rect, near)
    crossing = start[0] + (near - 2.0) / (-1.0 - 2.0) * (end[0] - start[0])
    assert tuple(p) == pytest.approx((camera.fx * 0.2 / 2.0 + camera.cx, camera.fy * 0.1 / 2.0 + camera.cy))
    image_q = [camera.fx * crossing[0] / near + camera.cx, camera.fy * crossing[1] / near + camera.cy]
    # The near-plane crossing projects far outside the image (up and to the left): the
    # segment heads there and is cut at the image's edge on the way.
    d = np.subtract(image_q, p)
    t = (np.asarray(q) - p) @ d / (d @ d)
    assert 0 < t <= 1 and np.allclose(p + t * d, q)
    assert min(q[0], q[1]) == pytest.approx(0.0, abs=1e-9) or q[0] == pytest.approx(W) or q[1] == pytest.approx(H)
    # Wholly behind: nothing drawn.
    assert len(screen_segments(camera, -start, end, rect, near)) == 0
