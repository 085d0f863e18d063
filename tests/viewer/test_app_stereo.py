"""The stereo preview in the real window loop (GLFW's null platform, synthetic imgui
input): each eye at the headset preset's size, the layouts as shown, the scaled
presentation, the lens preview, the frame-budget meter and stereo screenshots."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from appkit import (
    PANEL_HEIGHT,
    PANEL_WIDTH,
    RecordingSorter,
    click_choice,
    headless,
    presented,
    window_image,
)
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from PIL import Image
from testkit import assert_differs, assert_matches

from raygs_viewer.camera.lens_model import DEFAULT_LENS, lens_warp_reference
from raygs_viewer.camera.stereo import (
    LAYOUTS,
    PRESETS,
    StereoRig,
    compose,
    custom_preset,
    eye_cameras,
)
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.render.gl.stereo_frame import render_stereo, stereo_order
from raygs_viewer.viewer.state import StereoPreview

EYE = custom_preset(96, 72, 90.0, 72.0)


def stereo_viewer(open_viewer, layout="sbs", width=None, height=None, rig=StereoRig(), lens_preview=False,
                  save_eyes=False, headset_size=False, **options):
    """A viewer in the stereo preview with the small EYE headset, the window sized so
    that the composed image is shown 1:1 (unless width/height say otherwise)."""
    shown_width = EYE.width * (2 if layout in ("sbs", "cross") else 1)
    options.setdefault("hide_panel", True)
    stereo = StereoPreview.of(EYE, on=True, layout=layout, rig=rig, lens_preview=lens_preview, save_eyes=save_eyes,
                              headset_size=headset_size)
    return open_viewer(width=width or shown_width, height=height or EYE.height, stereo=stereo, **options)


def headless_eyes(viewer) -> tuple[np.ndarray, np.ndarray]:
    """Both eyes rendered headlessly with the shared order and colour, for the viewer's
    midpoint camera and rig."""
    return render_stereo(viewer.scene.renderer, viewer.scene.direct_sorter, viewer.camera, viewer.settings, viewer.stereo.view().rig)


def composed(viewer) -> np.ndarray:
    return viewer.drawer.stereo.image.read()


def eye_sizes(viewer) -> list[tuple[int, int]]:
    """(width, height) of each eye's image as the stereo frame drew it."""
    return [(eye.shape[1], eye.shape[0]) for eye in viewer.drawer.stereo.read_eyes()]


@pytest.mark.parametrize("layout", LAYOUTS)
def test_each_layout_shows_the_headless_eyes_where_they_belong(open_viewer, layout):
    viewer, drive = stereo_viewer(open_viewer, layout)
    drive.settle()
    camera = viewer.camera
    # The view is the midpoint between the eyes, at the preset's per-eye size and field of view.
    assert (camera.width, camera.height) == (EYE.width, EYE.height)
    assert camera.fx == pytest.approx(EYE.width / 2 / np.tan(np.radians(EYE.fov_x / 2)))
    assert camera.fy == pytest.approx(EYE.height / 2 / np.tan(np.radians(EYE.fov_y / 2)))
    assert eye_sizes(viewer) == [(EYE.width, EYE.height)] * 2
    left, right = headless_eyes(viewer)
    assert_differs(left, right)
    expected = compose(left, right, layout)
    assert_matches(composed(viewer), expected)
    # Shown 1:1, filling the window: the present pass puts each eye where the layout says.
    assert viewer.viewport == (0, 0, expected.shape[1], expected.shape[0])
    assert np.abs(presented(viewer) - to_rgb8(expected).astype(int)).max() <= 1
    if layout in ("sbs", "cross"):
        first, second = (left, right) if layout == "sbs" else (right, left)
        shown = presented(viewer)
        assert np.abs(shown[:, :EYE.width] - to_rgb8(first).astype(int)).max() <= 1
        assert np.abs(shown[:, EYE.width:] - to_rgb8(second).astype(int)).max() <= 1


def test_a_pair_larger_than_the_window_is_box_filtered_into_it(open_viewer):
    # At the headset's size the sbs pair is 192 x 72; the window has half of that each
    # way: each window pixel is the mean of a 2 x 2 block.
    viewer, drive = stereo_viewer(open_viewer, "sbs", width=EYE.width, height=EYE.height // 2, headset_size=True)
    drive.settle()
    assert viewer.viewport == (0, 0, EYE.width, EYE.height // 2)
    image = np.clip(composed(viewer)[..., :3], 0.0, 1.0)
    blocks = image.reshape(EYE.height // 2, 2, EYE.width, 2, 3).mean(axis=(1, 3))
    shown = presented(viewer)
    assert np.abs(shown - np.round(blocks * 255)).max() <= 1
    nearest = to_rgb8(image[::2, ::2]).astype(int)
    assert np.abs(shown - nearest).max() > 20  # not merely every other texel


def test_one_eye_is_letterboxed_in_a_wide_window(open_viewer):
    viewer, drive = stereo_viewer(open_viewer, "right", width=3 * EYE.width, height=EYE.height)
    drive.settle()
    assert viewer.viewport == (EYE.width, 0, EYE.width, EYE.height)
    _, right = headless_eyes(viewer)
    assert np.abs(presented(viewer) - to_rgb8(right).astype(int)).max() <= 1


def test_the_sort_is_culled_for_both_eyes_from_the_midpoint(open_viewer):
    viewer, drive = stereo_viewer(open_viewer, sorter_factory=RecordingSorter)
    drive.settle()
    rig = viewer.stereo.view().rig
    eyes = viewer.scene.sorter.culled_for[-1]
    expected = eye_cameras(viewer.camera, rig)
    assert len(eyes) == 2
    for got, want in zip(eyes, expected):
        assert (got.cx, got.width) == (want.cx, want.width)
        np.testing.assert_array_equal(got.t, want.t)
    np.testing.assert_array_equal(viewer.scene.sorter.latest().order.indices,
                                  stereo_order(viewer.scene.direct_sorter, viewer.camera, viewer.settings, rig).indices)
    # A new IPD is another cull: the drawn order catches up with it.
    viewer.stereo.rig = replace(viewer.stereo.rig, ipd=0.2)
    drive.settle()
    assert viewer.scene.sorter.culled_for[-1][0].t[0] != eyes[0].t[0]


def test_rig_changes_from_the_panel_redraw_the_eyes(open_viewer):
    viewer, drive = stereo_viewer(open_viewer, "sbs")
    drive.settle()
    before = composed(viewer).copy()
    viewer.stereo.rig = StereoRig(0.0, 5.0, 0.5)
    drive.settle()
    assert viewer.stereo.view().rig == StereoRig(0.0, 5.0, 0.5)
    after = composed(viewer)
    assert_differs(after, before)
    # IPD 0: both halves are the mono view of the midpoint camera.
    mono = headless(viewer)
    assert_matches(after[:, :EYE.width], mono)
    assert_matches(after[:, EYE.width:], mono)


def test_lens_preview_in_the_window_is_the_lens_pass_of_each_eye(open_viewer):
    viewer, drive = stereo_viewer(open_viewer, "sbs", lens_preview=True)
    drive.settle()
    assert viewer.stereo.view().lens == DEFAULT_LENS
    left, right = headless_eyes(viewer)
    left_eye, right_eye = eye_cameras(viewer.camera, viewer.stereo.view().rig)
    expected = compose(lens_warp_reference(left, left_eye, DEFAULT_LENS),
                       lens_warp_reference(right, right_eye, DEFAULT_LENS), "sbs")
    image = composed(viewer)
    assert np.abs(image[..., :3] - expected[..., :3]).max() < 2e-3
    assert_differs(image, compose(left, right, "sbs"))  # the lens did something
    assert np.all(image[0, 0, :3] == 0) and np.all(image[-1, -1, :3] == 0)  # the corners are black


def test_the_preview_draws_the_eyes_at_the_size_the_view_area_shows(open_viewer, tmp_path):
    """A Quest 3's eyes (2064 x 2208 each) in a window with the panel open: each eye is
    drawn at the size the view beside the panel shows, its aspect and field of view kept,
    and both lie whole right of the panel; F12 still saves the headset's size."""
    preset = PRESETS["quest3"]
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT, stereo=StereoPreview.of(preset, on=True))
    drive.settle()
    x, y, w, h = viewer.viewport
    panel = round(viewer.panel.width)
    assert x >= panel and x + w <= PANEL_WIDTH and y >= 0 and y + h <= PANEL_HEIGHT  # both eyes beside the panel
    camera = viewer.camera
    assert camera.width == (PANEL_WIDTH - panel) // 2 and (w, h) == (2 * camera.width, camera.height)
    assert abs(camera.height - camera.width * preset.height / preset.width) <= 1  # the headset's aspect
    full = viewer.shown.full_camera
    assert (full.width, full.height) == (preset.width, preset.height)
    assert camera.fx / camera.width == pytest.approx(full.fx / full.width)  # its field of view
    assert eye_sizes(viewer) == [(camera.width, camera.height)] * 2
    left, right = headless_eyes(viewer)
    assert_matches(composed(viewer), compose(left, right, "sbs"))
    assert np.abs(presented(viewer) - to_rgb8(compose(left, right, "sbs")).astype(int)).max() <= 1  # shown 1:1
    # The headset's own size on request, shrunk into the same place.
    viewer.stereo.headset_size = True
    drive.settle()
    assert (viewer.camera.width, viewer.camera.height) == (preset.width, preset.height)
    assert viewer.viewport[2] == 2 * camera.width
    viewer.stereo.headset_size = False
    drive.settle()
    # Hiding the panel gives the eyes the whole window.
    viewer.panel.show_panel = False
    drive.settle()
    assert viewer.camera.width == PANEL_WIDTH // 2 and viewer.viewport[0] == 0
    viewer.panel.show_panel = True
    drive.settle()


def test_screenshots_and_paths_take_the_headsets_size_whatever_the_preview(open_viewer, tmp_path):
    viewer, drive = stereo_viewer(open_viewer, "sbs", width=EYE.width, height=EYE.height // 2)
    drive.settle()
    assert (viewer.camera.width, viewer.camera.height) == (EYE.width // 2, EYE.height // 2)  # previewed at half
    png, sidecar = viewer.save_screenshot()
    assert Image.open(png).size == (2 * EYE.width, EYE.height)
    assert json.loads(sidecar.read_text())["camera"]["width"] == EYE.width
    document = viewer.camera_path.document(viewer.path_scene())
    assert (document.width, document.height) == (EYE.width, EYE.height)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_each_preset_renders_each_eye_at_its_resolution(open_viewer, name):
    preset = PRESETS[name]
    viewer, drive = open_viewer(width=320, height=180, hide_panel=True,
                                stereo=StereoPreview.of(preset, on=True, headset_size=True))
    drive.frames(2)
    assert viewer.stereo.headset_preset() == preset and viewer.stereo.view().headset == preset
    assert (viewer.camera.width, viewer.camera.height) == (preset.width, preset.height)
    assert eye_sizes(viewer) == [(preset.width, preset.height)] * 2
    assert viewer.drawer.stereo.image.size == (2 * preset.width, preset.height)
    # Shown scaled to fit the window, keeping the pair's aspect ratio.
    x, y, w, h = viewer.viewport
    assert w == 320 and abs(h - round(320 * preset.height / (2 * preset.width))) <= 1


def test_panel_toggles_stereo_picks_a_layout_and_a_headset(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    viewer.stereo.headset = "custom"
    viewer.stereo.custom_size, viewer.stereo.custom_fov = [EYE.width, EYE.height], [EYE.fov_x, EYE.fov_y]
    drive.click("stereo")
    drive.frames(1)  # panel edits apply from the next frame
    assert viewer.stereo.on and viewer.shown_stereo is not None
    click_choice(drive, "layout", "anaglyph (red/cyan)")
    assert viewer.stereo.layout == "anaglyph"
    drive.settle()
    left, right = headless_eyes(viewer)
    assert_matches(composed(viewer), compose(left, right, "anaglyph"))
    assert viewer.right_settings() is None  # no split view in stereo
    index = PRESETS["index"]  # the entry shows the preset's label, eye size and field of view
    click_choice(drive, "headset", f"{index.label}: {index.width}x{index.height}, {index.fov_x:g}x{index.fov_y:g} deg")
    drive.frames(1)
    assert viewer.stereo.headset_preset() == PRESETS["index"]
    assert viewer.shown.full_camera.width == PRESETS["index"].width
    # Off again: the mono view of the window, beside the panel.
    drive.click("stereo")
    drive.settle()
    assert not viewer.stereo.on and viewer.shown_stereo is None
    assert viewer.camera.width == PANEL_WIDTH - round(viewer.panel.width)
    assert_matches(window_image(viewer), headless(viewer))


def test_a_custom_headset_out_of_range_is_a_panel_error_and_the_preview_stays(open_viewer):
    viewer, drive = stereo_viewer(open_viewer)
    drive.settle()
    viewer.stereo.headset, viewer.stereo.custom_size, viewer.stereo.custom_fov = "custom", [96, 72], [500.0, 72.0]
    drive.frames(2)
    assert viewer.panel.error.startswith("error: ") and "field of view" in viewer.panel.error
    assert viewer.shown_stereo is not None and viewer.camera.width == EYE.width
    # Mended: the error goes and the new headset is drawn.
    viewer.stereo.custom_fov = [100.0, 80.0]
    drive.frames(1)
    assert viewer.panel.error == "" and viewer.shown_stereo.headset.fov_x == 100.0


def test_frame_budget_meter_reports_both_eyes_against_each_rate(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT, stereo=StereoPreview.of(EYE, on=True))
    drive.settle()
    drive.frames(3)
    seconds = viewer.stats.gpu_seconds
    assert np.isfinite(seconds) and seconds > 0 and np.isfinite(viewer.stats.post_seconds)
    assert [bar.split(" Hz ")[0] for bar in drive.panel.labels("progress_bar")] == ["72", "90", "120"]
    # Each redraw is one reading of the eyes' timer and one of the post passes'.
    draws = viewer.stats.draws
    viewer.stereo.rig = replace(viewer.stereo.rig, ipd=0.05)
    drive.settle()
    viewer.drawer.timer.flush()
    viewer.drawer.post_timer.flush()
    assert viewer.stats.draws > draws
    assert len(viewer.drawer.timer.history) == len(viewer.drawer.post_timer.history) == viewer.stats.draws


def test_the_budget_meter_says_what_it_timed_and_estimates_the_headsets_frame(open_viewer):
    quest = PRESETS["quest3"]
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT, stereo=StereoPreview.of(quest, on=True))
    drive.settle()
    drive.frames(2)
    camera, seconds = viewer.camera, viewer.stats.gpu_seconds
    texts = drive.panel.labels("text")
    assert f"both eyes at {camera.width}x{camera.height}: {seconds * 1000:6.2f} ms" in texts
    estimate = seconds * quest.width * quest.height / (camera.width * camera.height)
    assert f"at {quest.width}x{quest.height}: ~{estimate * 1000:6.2f} ms (est.)" in texts
    bars = drive.panel.labels("progress_bar")
    fraction = estimate * 72
    assert bars[0] == "72 Hz (13.9 ms): " + (f"{fraction:.1f}x over" if fraction > 1 else f"{fraction * 100:.0f} %")
    # At the headset's size the time is measured, and nothing is estimated.
    viewer.stereo.headset_size = True
    drive.settle()
    drive.frames(2)
    texts = drive.panel.labels("text")
    assert f"both eyes at {quest.width}x{quest.height}: {viewer.stats.gpu_seconds * 1000:6.2f} ms" in texts
    assert not any(text.endswith("(est.)") for text in texts)


def test_stereo_screenshot_saves_the_pair_and_each_eye_reproducibly(open_viewer, tmp_path):
    import glfw

    from raygs_viewer.capture.sidecar import load_sidecar
    from raygs_viewer.cli.main import main
    viewer, drive = stereo_viewer(open_viewer, "anaglyph", save_eyes=True, lens_preview=False,
                                  rig=StereoRig(0.07, 3.0, 0.5))
    drive.settle()
    left, right = headless_eyes(viewer)
    drive.tap(imgui.Key.f12)
    assert viewer.panel.error == ""
    saved = viewer.captures.saved
    assert [png.stem.rsplit("-", 1)[1] for png, _ in saved] == ["pair", "left", "right"]
    expected = {"pair": compose(left, right, "sbs"), "left": left, "right": right}
    for png, sidecar in saved:
        tag = png.stem.rsplit("-", 1)[1]
        shot = np.asarray(Image.open(png)).astype(int)
        assert np.abs(shot - to_rgb8(expected[tag]).astype(int)).max() <= 1
        loaded = load_sidecar(sidecar)
        assert loaded.stereo.rig == StereoRig(0.07, 3.0, 0.5)
        assert loaded.stereo.headset == EYE and loaded.stereo.lens is None
        assert loaded.stereo.layout == ("sbs" if tag == "pair" else tag)
        assert loaded.camera.width == EYE.width  # the midpoint camera, each eye's size
        assert json.loads(sidecar.read_text())["extra"]["stereo_window_layout"] == "anaglyph"
        out = tmp_path / f"again-{png.name}"
        assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
        np.testing.assert_array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(png)))
    glfw.make_context_current(viewer.window.handle)
    # Without "each eye": the pair alone; a second capture never overwrites the first.
    viewer.stereo.save_eyes = False
    first = saved[0][0].read_bytes()
    drive.tap(imgui.Key.f12)
    (png, _), = viewer.captures.saved
    assert png not in [p for p, _ in saved] and saved[0][0].read_bytes() == first
    assert Image.open(png).size == (2 * EYE.width, EYE.height)


def test_stereo_screenshot_at_scale_and_with_the_lens(open_viewer, tmp_path):
    import glfw

    from raygs_viewer.cli.main import main
    viewer, drive = stereo_viewer(open_viewer, "sbs", lens_preview=True)
    viewer.captures.options.scale = 2.0
    drive.settle()
    png, sidecar = viewer.save_screenshot()
    assert Image.open(png).size == (4 * EYE.width, 2 * EYE.height)
    scaled = replace(viewer.camera, width=2 * EYE.width, height=2 * EYE.height, fx=2 * viewer.camera.fx,
                     fy=2 * viewer.camera.fy, cx=2 * viewer.camera.cx, cy=2 * viewer.camera.cy)
    rig = viewer.stereo.view().rig
    left, right = render_stereo(viewer.scene.renderer, viewer.scene.direct_sorter, scaled, viewer.settings, rig)
    eyes = eye_cameras(scaled, rig)
    expected = compose(lens_warp_reference(left, eyes[0]), lens_warp_reference(right, eyes[1]), "sbs")
    assert np.abs(np.asarray(Image.open(png)).astype(int) - to_rgb8(expected).astype(int)).max() <= 2
    out = tmp_path / "again.png"
    assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
    np.testing.assert_array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(png)))
    glfw.make_context_current(viewer.window.handle)


def test_stereo_sliders_set_the_rig_in_its_units(open_viewer):
    from raygs_viewer.viewer.panel.stereo import CONVERGENCE_RANGE, IPD_MM_RANGE, SCENE_SCALE_RANGE
    # Tall enough for the whole panel with its Stereo section.
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=1100, stereo=StereoPreview.of(EYE, on=True))
    drive.frames(2)
    assert drive.panel.rect("scene scale (m/unit)")[3] < 1100

    def click_end(label, right):
        x0, y0, x1, y1 = drive.panel.rect(label)  # the slider's frame, then its label
        x1 -= imgui.calc_text_size(label).x + imgui.get_style().item_inner_spacing.x
        drive.click_at(x1 - 2 if right else x0 + 2, (y0 + y1) / 2)
        drive.frames(1)

    click_end("IPD (mm)", right=True)  # the slider shows millimetres; the rig takes metres
    click_end("convergence (m)", right=False)
    click_end("scene scale (m/unit)", right=True)
    rig = viewer.stereo.view().rig
    assert rig.ipd == pytest.approx(IPD_MM_RANGE[1] / 1000)
    assert rig.convergence == pytest.approx(CONVERGENCE_RANGE[0])
    assert rig.scene_scale == pytest.approx(SCENE_SCALE_RANGE[1])
    assert viewer.shown_stereo.rig == rig  # and the frame draws with it


def test_the_split_view_is_off_in_stereo_and_its_divider_cannot_be_grabbed(open_viewer):
    viewer, drive = stereo_viewer(open_viewer)
    viewer.split.on = True  # left on from the mono view
    drive.settle()
    assert viewer.right_settings() is None and viewer.overlay_rects == {}
    x, y, w, h = viewer.viewport
    drive.move_mouse(x + viewer.split.column(w), y + h / 2)  # where the divider would be
    drive.frames(1)
    drive.button(0, True)
    drive.frames(1)
    assert not viewer.input.dragging_divider
    drive.button(0, False)
    drive.frames(1)


def test_reset_view_frames_the_scene_for_the_eyes(open_viewer):
    from raygs_viewer.camera.navigation import framing_pose
    viewer, drive = stereo_viewer(open_viewer, width=400, height=100)  # a window of another shape
    drive.frames(1)
    drive.tap(imgui.Key.r)
    expected = framing_pose(viewer.view.center, viewer.view.radius, viewer.view.navigator.up, EYE.fov_y,
                            EYE.width / EYE.height)
    np.testing.assert_allclose(viewer.view.navigator.pose.position, expected.position, atol=1e-9)
