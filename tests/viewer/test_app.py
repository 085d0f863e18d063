"""The real application loop, in-process, with no X server: GLFW's null platform with
an EGL context, imgui-bundle's GLFW and OpenGL backends, and synthetic imgui input
queued where the backends would put real input."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from appkit import (
    HEIGHT,
    PANEL_HEIGHT,
    PANEL_WIDTH,
    WIDTH,
    RecordingSorter,
    click_choice,
    gated_viewer,
    headless,
    presented,
    project,
    right_image,
    split_expected,
    window_image,
)
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from PIL import Image
from testkit import assert_differs, assert_matches

from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.render.settings import RenderSettings, apply_preset
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.viewer.app import Viewer
from raygs_viewer.viewer.state import NavigationChoices, ViewerOptions


# -- the window shows the right image ---------------------------------------------------
def test_window_image_is_the_headless_render_of_its_camera(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.settle()
    camera = viewer.camera
    assert (camera.width, camera.height) == (WIDTH, HEIGHT)
    assert_matches(window_image(viewer), headless(viewer))
    # and the start view is the demo's default view, filling the window
    from raygs_viewer.scene.demo import demo_camera
    np.testing.assert_allclose(camera.center, demo_camera().center, atol=1e-9)
    np.testing.assert_allclose(camera.R, demo_camera().R, atol=1e-9)


# -- keys and mouse move the camera as documented ------------------------------------------
@pytest.mark.parametrize("key_name, axis, sign", [("w", 2, +1), ("s", 2, -1), ("d", 0, +1), ("a", 0, -1)])
def test_keys_move_the_camera(open_viewer, key_name, axis, sign):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    before = viewer.camera
    drive.key(getattr(imgui.Key, key_name), True)
    drive.frames(1)
    drive.key(getattr(imgui.Key, key_name), False)
    drive.frames(1)
    after = viewer.camera
    # The displacement in the old camera's axes (x right, y down, z forward).
    step = before.R @ (after.center - before.center)
    expected = viewer.view.navigator.speed * 0.1
    assert step[axis] == pytest.approx(sign * expected, rel=1e-6)
    assert np.abs(np.delete(step, axis)).max() < 1e-9 * expected
    np.testing.assert_array_equal(after.R, before.R)


@pytest.mark.parametrize("key_name, sign", [("e", +1), ("q", -1)])
@pytest.mark.parametrize("up_axis", ["-y", "+z"])
def test_e_and_q_move_along_the_world_up_axis(open_viewer, key_name, sign, up_axis):
    from raygs_viewer.camera.navigation import up_vector
    viewer, drive = open_viewer(hide_panel=True, navigation=NavigationChoices(up_axis=up_axis))
    drive.frames(1)
    before = viewer.camera.center
    drive.key(getattr(imgui.Key, key_name), True)
    drive.frames(1)
    drive.key(getattr(imgui.Key, key_name), False)
    drive.frames(1)
    np.testing.assert_allclose(viewer.camera.center - before,
                               sign * up_vector(up_axis) * viewer.view.navigator.speed * 0.1,
                               atol=1e-9)


def test_shift_moves_faster_and_wheel_changes_speed(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    speed = viewer.view.navigator.speed
    drive.move_mouse(WIDTH / 2, HEIGHT / 2)
    drive.wheel(2)
    drive.frames(2)
    assert viewer.view.navigator.speed == pytest.approx(speed * 1.25 ** 2)
    before = viewer.camera.center
    drive.key(imgui.Key.mod_shift, True)  # what the GLFW backend sends with left_shift
    drive.key(imgui.Key.w, True)
    drive.frames(1)
    drive.key(imgui.Key.w, False)
    drive.key(imgui.Key.mod_shift, False)
    drive.frames(1)
    assert np.linalg.norm(viewer.camera.center - before) == pytest.approx(4 * viewer.view.navigator.speed * 0.1,
                                                                          rel=1e-6)


def test_mouse_drag_looks_around_in_fly_mode(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.move_mouse(WIDTH / 2, HEIGHT / 2)
    drive.frames(2)
    camera = viewer.camera
    ahead = camera.center + 5.0 * camera.R[2]  # a point at the image centre
    drive.button(0, True)
    drive.frames(1)
    drive.move_mouse(WIDTH / 2 + 40, HEIGHT / 2)
    drive.frames(1)
    drive.button(0, False)
    drive.frames(1)
    u, v, _ = project(viewer.camera, ahead)
    assert u < viewer.camera.cx - 10  # turned right: what was ahead is now left of centre
    assert abs(v - viewer.camera.cy) < 1.0
    np.testing.assert_allclose(viewer.camera.center, camera.center)  # looking does not move


def test_orbit_mode_drag_keeps_the_target_centred(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.move_mouse(WIDTH / 2, HEIGHT / 2)
    drive.frames(1)
    drive.tap(imgui.Key.tab)
    assert viewer.view.navigator.mode == "orbit"
    target, distance = viewer.view.navigator.target.copy(), viewer.view.navigator.distance
    drive.button(0, True)
    drive.frames(1)
    drive.move_mouse(WIDTH / 2 + 30, HEIGHT / 2 + 10)
    drive.frames(1)
    drive.button(0, False)
    drive.frames(1)
    camera = viewer.camera
    u, v, z = project(camera, target)
    assert (u, v) == pytest.approx((camera.cx, camera.cy), abs=1e-6)
    assert np.linalg.norm(camera.center - target) == pytest.approx(distance, rel=1e-9)
    assert camera.R[0] @ (camera.center - viewer.view.navigator.target) != 0
    # the wheel zooms towards the target
    drive.wheel(1)
    drive.frames(2)
    assert viewer.view.navigator.distance == pytest.approx(distance * 0.85, rel=1e-9)


def test_mouse_over_the_panel_does_not_move_the_camera(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    x0, y0, x1, y1 = drive.panel.rect("Reset view (R)")
    drive.move_mouse(x0 - 2, y0)  # on the panel, beside the button
    drive.frames(1)
    pose = viewer.camera
    drive.button(0, True)
    drive.frames(1)
    drive.move_mouse(x0 + 30, y0 + 5)
    drive.frames(1)
    drive.button(0, False)
    drive.frames(1)
    np.testing.assert_array_equal(viewer.camera.R, pose.R)


# -- the panel changes settings and the image ---------------------------------------------
def test_panel_click_changes_the_setting_and_the_image(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.settle()
    before = window_image(viewer).copy()
    drive.click("white")
    assert list(viewer.settings.background) == [1.0, 1.0, 1.0]
    drive.settle()
    after = window_image(viewer)
    assert np.abs(after - before).max() > 0.5
    assert_matches(after, headless(viewer, RenderSettings(viewer.settings.p_min, (1.0, 1.0, 1.0), 3)))

    # Dragging the SH degree slider to its left end evaluates band 0 only.
    drive.click_left_end("SH degree")
    assert viewer.settings.sh_degree == 0
    drive.settle()
    degree0 = window_image(viewer)
    assert np.abs(degree0 - after).max() > 0.05  # the demo's sphere is view-dependent
    assert_matches(degree0, headless(viewer, RenderSettings(viewer.settings.p_min, (1.0, 1.0, 1.0), 0)))


def test_panel_accuracy_controls_change_the_settings_and_the_image(open_viewer):
    """Every accuracy control of the panel reaches Viewer.settings and redraws the window
    with exactly those settings; controls that do not apply to the mode are greyed out."""
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.settle()
    expected = RenderSettings(sh_degree=3)
    image = window_image(viewer).copy()

    def check(changed: bool | None = True) -> None:
        """The panel's settings are ``expected`` and the window shows them; ``changed``:
        the image must differ from the previous step's (None: not checked)."""
        nonlocal image
        assert viewer.settings == expected
        drive.settle()
        now = window_image(viewer).copy()
        assert_matches(now, headless(viewer, expected))
        if changed:
            assert_differs(now, image)
        elif changed is False:
            np.testing.assert_array_equal(now, image)
        image = now

    click_choice(drive, "mode", "GS (EWA)")
    expected = replace(expected, mode="gs")
    check()
    drive.click("MIP filter")          # greyed out in GS mode
    drive.click("opacity modulation")
    check(changed=False)
    drive.click("GS compensation")
    expected = replace(expected, gs_compensation=True)
    check()
    click_choice(drive, "mode", "RayGS")
    expected = replace(expected, mode="raygs")
    check()
    drive.click("GS compensation")     # greyed out in RayGS mode
    drive.click("opacity modulation")  # ... and so is the modulation while MIP is off
    check(changed=False)
    drive.click("MIP filter")
    expected = replace(expected, mip=True)
    check()
    drive.click("opacity modulation")
    expected = replace(expected, mip_modulation=False)
    check()
    click_choice(drive, "mode", "RayGS exact MIP")
    expected = replace(expected, mode="raygs-exact-mip")
    check(changed=None)  # close to the pixel-invariant filter at this scale
    drive.click("MIP filter")          # always on in exact MIP mode: greyed out, the RayGS choice kept
    assert viewer.settings.mip
    # sigma^2 slider: a press at its left end gives 0 px^2
    drive.click_left_end("sigma^2 (px^2)")
    expected = replace(expected, mip_sigma2=0.0)
    check()
    click_choice(drive, "mode", "RayGS")
    click_choice(drive, "supersampling", "2\u00d72")
    expected = replace(expected, mode="raygs", supersample=2)
    check()
    click_choice(drive, "blend", "8-bit")
    expected = replace(expected, precision="8bit")
    check()
    drive.click("alpha clamp 0.99")
    expected = replace(expected, alpha_clamp=True)
    check()
    if viewer.scene.renderer.supports(RenderSettings(transmittance_cutoff=True)) is None:
        drive.click("transmittance cut-off 1e-4")
        expected = replace(expected, transmittance_cutoff=True)
        check()


def test_controls_this_gpu_cannot_render_are_greyed_out(open_viewer, monkeypatch):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    monkeypatch.setattr(viewer.scene.renderer, "supports",
                        lambda settings, geometry=False: "no framebuffer fetch" if settings.transmittance_cutoff else None)
    drive.frames(2)
    drive.click("transmittance cut-off 1e-4")
    assert not viewer.settings.transmittance_cutoff and viewer.panel.error == ""


def test_settings_the_renderer_refuses_show_an_error_and_keep_running(open_viewer, monkeypatch):
    from raygs_viewer.errors import UserError
    viewer, drive = open_viewer(hide_panel=True)
    render_into = viewer.scene.renderer.render_into

    def refusing(target, camera, settings, order, *args, **kwargs):
        if settings.transmittance_cutoff:
            raise UserError("the transmittance cut-off needs GL_EXT_shader_framebuffer_fetch")
        return render_into(target, camera, settings, order, *args, **kwargs)

    monkeypatch.setattr(viewer.scene.renderer, "render_into", refusing)
    drive.settle()
    viewer.settings = replace(viewer.settings, transmittance_cutoff=True)
    drive.frames(2)
    assert viewer.panel.error.startswith("error: the transmittance cut-off") and "\n" not in viewer.panel.error
    viewer.settings = replace(viewer.settings, transmittance_cutoff=False)
    drive.settle()
    assert viewer.panel.error == ""
    assert_matches(window_image(viewer), headless(viewer))


def test_the_start_settings_come_from_the_options(open_viewer):
    options = dict(p_min=0.01, mode="gs", gs_compensation=True, supersample=2, alpha_clamp=True, mip=True,
                   mip_sigma2=0.5, mip_modulation=False)
    viewer, drive = open_viewer(hide_panel=True, settings=RenderSettings(**options))
    expected = RenderSettings(sh_degree=3, **options)
    assert viewer.settings == expected
    drive.settle()
    assert_matches(window_image(viewer), headless(viewer, expected))
    assert_differs(window_image(viewer), headless(viewer, RenderSettings(p_min=0.01)))


def test_start_settings_are_checked_before_the_window_opens(restore_gl_ctx):
    import glfw

    from raygs_viewer.errors import UserError
    from raygs_viewer.render.gl.renderer import GLRenderer
    from raygs_viewer.viewer.app import run_viewer
    with pytest.raises(UserError, match="supersample"):
        run_viewer(ViewerOptions(settings=RenderSettings(supersample=9), frames=1, platform="null"))

    class WithoutFramebufferFetch(GLRenderer):
        def supports(self, settings):
            return "needs framebuffer fetch" if settings.transmittance_cutoff else None

    with pytest.raises(UserError, match="framebuffer fetch"):
        Viewer(ViewerOptions(width=64, height=48, platform="null", settings=RenderSettings(transmittance_cutoff=True)),
               load_now(SceneSource.demo()), renderer_factory=WithoutFramebufferFetch)
    assert not glfw.get_current_context()  # the window was closed again


def test_the_sort_is_asked_with_the_cull_of_what_is_shown(open_viewer):
    viewer, drive = open_viewer(hide_panel=True, sorter_factory=RecordingSorter)
    drive.frames(1)
    asked = viewer.scene.sorter.asked
    assert asked[-1] == (1 / 255, 0.0)
    viewer.settings = replace(viewer.settings, mip=True)
    drive.frames(1)
    mip = viewer.settings.cull_dilation(viewer.camera)
    assert mip > 0 and asked[-1] == (1 / 255, mip)
    viewer.settings = replace(viewer.settings, mode="raygs-exact-mip")
    drive.frames(1)
    assert asked[-1] == (1 / 255, pytest.approx(2 * mip))
    viewer.settings = replace(viewer.settings, mode="gs")
    drive.frames(1)
    assert asked[-1] == (1 / 255, None)
    drive.settle()
    assert viewer.scene.sorter.latest().request.dilation is None  # the drawn order was culled that way
    # The split view sorts once for both sides, with the more conservative cull of the two.
    viewer.settings, viewer.split.on = replace(viewer.settings, mode="raygs", p_min=0.01), True
    viewer.split.preset = "RayGS p_min 1e-3"  # no MIP: dilation 0
    drive.frames(1)
    assert asked[-1] == (1e-3, mip)
    viewer.split.preset = "GS"
    drive.frames(1)
    assert asked[-1] == (0.01, None)
    drive.settle()
    assert viewer.stats.order_age == 0


# -- the A/B split view ---------------------------------------------------------------------
@pytest.mark.parametrize("preset", ["GS", "RayGS + MIP", "RayGS 2x2 supersampling"])
def test_split_view_shows_a_left_and_b_right(open_viewer, preset):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    viewer.frustums.show = False  # the window as shown is compared with the scene: no training cameras over it
    drive.frames(2)
    drive.click("split view")
    assert viewer.split.on
    click_choice(drive, "##right side", preset)
    assert viewer.split.preset == preset
    drive.tap(imgui.Key.f1)  # hide the panel (F1: the pointer is on the panel, where H would type): the whole window shows the scene
    assert not viewer.panel.show_panel
    drive.settle()
    a = RenderSettings(sh_degree=3)
    b = apply_preset(a, preset)
    assert viewer.settings == a and viewer.right_settings() == b
    image_a, image_b = headless(viewer, a), headless(viewer, b)
    assert_differs(image_a, image_b)
    # Each side renders the whole viewport with its own settings.
    assert_matches(window_image(viewer), image_a)
    assert_matches(right_image(viewer), image_b)
    # The present pass shows A left of the divider and B from it on, column for column.
    x, y, w, h = viewer.viewport
    column = viewer.split.column(viewer.viewport[2])
    assert column == w // 2
    expected = split_expected(image_a, image_b, column)
    assert np.abs(presented(viewer) - expected).max() <= 1
    rgb_a, rgb_b = to_rgb8(image_a).astype(int), to_rgb8(image_b).astype(int)
    for c in (column - 1, column):  # a boundary one column off would show
        assert np.abs(rgb_a[:, c] - rgb_b[:, c]).max() > 2
    # The window as shown: the same, apart from the divider line and the side labels.
    viewer.captures.keep_next = True
    drive.frames(1)
    window = viewer.captures.window[y:y + h, x:x + w].astype(int)
    covered = np.zeros((h, w), bool)
    for name in ("divider", "left label", "right label"):
        x0, y0, x1, y1 = viewer.overlay_rects[name]
        covered[max(int(y0) - y, 0):int(math.ceil(y1)) - y + 1, max(int(x0) - x, 0):int(math.ceil(x1)) - x + 1] = True
    assert np.abs(window - expected)[~covered].max() <= 1
    x0, y0, x1, y1 = (int(v) for v in viewer.overlay_rects["divider"])
    assert np.abs(window[y0:y1, x0:x1 + 1] - expected[y0:y1, x0:x1 + 1]).max() > 50  # the line is drawn
    x0, y0, x1, y1 = (int(v) for v in viewer.overlay_rects["right label"])
    assert x0 > column and np.abs(window[y0:y1, x0:x1] - expected[y0:y1, x0:x1]).max() > 50  # so is the label
    # Switched off: the whole viewport is A again.
    viewer.split.on = False
    drive.frames(2)
    assert np.abs(presented(viewer) - to_rgb8(image_a).astype(int)).max() <= 1


@pytest.mark.parametrize("letterboxed", [False, True])
def test_dragging_the_divider_moves_the_boundary_not_the_camera(open_viewer, tmp_path, letterboxed):
    options = {}
    if letterboxed:  # a square training camera: bars left and right, the viewport starts at x = 24
        from raygs_viewer.camera.pinhole import camera_to_json, look_at
        path = tmp_path / "square.json"
        path.write_text(json.dumps([camera_to_json(look_at((0.5, -0.5, -4), (0, 0, 0), width=300, height=300))]))
        options["camera"] = str(path)
    viewer, drive = open_viewer(hide_panel=True, **options)
    viewer.split.on, viewer.split.preset = True, "GS"
    drive.settle()
    x, y, w, h = viewer.viewport
    assert x == (24 if letterboxed else 0)
    pose = viewer.camera
    a, b = headless(viewer, viewer.settings), headless(viewer, viewer.right_settings())
    divider = x + w // 2
    assert viewer.overlay_rects["divider"][0] < divider < viewer.overlay_rects["divider"][2]

    drive.move_mouse(divider + 5, HEIGHT / 2)  # within the grab distance
    drive.frames(1)
    drive.button(0, True)
    drive.frames(1)
    assert viewer.input.dragging_divider
    drive.move_mouse(x + 100, HEIGHT / 2 + 20)
    drive.frames(1)
    drive.move_mouse(x + 90, HEIGHT / 2 + 30)
    drive.frames(1)
    drive.button(0, False)
    drive.frames(1)
    assert not viewer.input.dragging_divider
    assert viewer.split.fraction == pytest.approx(90 / w) and viewer.split.column(viewer.viewport[2]) == 90
    np.testing.assert_array_equal(viewer.camera.R, pose.R)  # the drag did not turn the camera
    np.testing.assert_array_equal(viewer.camera.center, pose.center)
    drive.settle()
    assert np.abs(presented(viewer) - split_expected(a, b, 90)).max() <= 1

    def drag(start_x, end_x):
        drive.move_mouse(start_x, HEIGHT / 2)
        drive.frames(1)
        drive.button(0, True)
        drive.frames(1)
        drive.move_mouse(end_x, HEIGHT / 2)
        drive.frames(1)
        drive.button(0, False)
        drive.frames(1)

    drag(x + 90, WIDTH + 50)  # past the edge: it stops at 98 % of the width
    assert viewer.split.fraction == 0.98

    drag(x + 20, x + 50)  # started away from the divider: looks around, leaves the divider
    assert viewer.split.fraction == 0.98 and not viewer.input.dragging_divider
    assert not np.array_equal(viewer.camera.R, pose.R)


def test_split_view_screenshot_saves_each_side_with_its_sidecar(open_viewer, tmp_path):
    import glfw

    from raygs_viewer.capture.sidecar import load_sidecar
    from raygs_viewer.cli.main import main
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    viewer.split.on, viewer.split.preset = True, "RayGS + MIP"
    viewer.split.fraction = 0.3
    drive.move_mouse(PANEL_WIDTH - 5, PANEL_HEIGHT - 5)
    drive.settle()
    a, b = viewer.settings, viewer.right_settings()
    expected = {"left": to_rgb8(headless(viewer, a)).astype(int), "right": to_rgb8(headless(viewer, b)).astype(int)}
    drive.tap(imgui.Key.f12)
    assert viewer.panel.error == ""
    saved = viewer.captures.saved
    assert [png.stem.rsplit("-", 1)[1] for png, _ in saved] == ["left", "right"]
    assert viewer.captures.last == saved[0]
    folder = tmp_path / "shots"
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for pair in saved for p in pair)
    for png, sidecar in saved:
        assert sidecar == png.with_suffix(".json") and str(png) in viewer.panel.message
    _, _, view_width, view_height = viewer.viewport
    for (png, sidecar), side, settings in zip(saved, ("left", "right"), (a, b)):
        shot = np.asarray(Image.open(png)).astype(int)
        assert shot.shape == (view_height, view_width, 3)  # the whole view, not half of it
        assert np.abs(shot - expected[side]).max() <= 1
        loaded = load_sidecar(sidecar)
        assert loaded.settings == settings and loaded.render_mode == settings.mode
        assert loaded.raw["extra"]["split_view"]["side"] == side
    assert np.abs(expected["left"] - expected["right"]).max() > 50
    # A second capture never overwrites the first.
    first = [png.read_bytes() for png, _ in saved]
    drive.tap(imgui.Key.f12)
    second = viewer.captures.saved
    assert len(second) == 2 and not {p for pair in second for p in pair} & {p for pair in saved for p in pair}
    assert [png.read_bytes() for png, _ in saved] == first
    # Each side reproduces headlessly from its own sidecar.
    for png, sidecar in saved:
        out = tmp_path / f"again-{png.name}"
        assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
        np.testing.assert_array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(png)))
    glfw.make_context_current(viewer.window.handle)


# -- screenshots -----------------------------------------------------------------------------
def test_f12_screenshot_with_sidecar_reproduces_headlessly(open_viewer, tmp_path):
    from raygs_viewer.cli.main import main
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)  # the panel is open: the screenshot must not show it
    drive.move_mouse(PANEL_WIDTH - 5, PANEL_HEIGHT - 5)
    drive.settle()
    drive.tap(imgui.Key.f12)
    png, sidecar = viewer.captures.last
    assert png.parent == tmp_path / "shots" and sidecar == png.with_suffix(".json")
    shot = np.asarray(Image.open(png))
    x, y, w, h = viewer.viewport  # the view beside the panel
    assert (x, y, w, h) == (round(viewer.panel.width), 0, PANEL_WIDTH - round(viewer.panel.width), PANEL_HEIGHT)
    assert shot.shape == (h, w, 3)
    info = json.loads(sidecar.read_text())
    assert info["camera"]["width"] == w and info["scene"]["path"] == "demo"
    assert info["settings"]["p_min"] == viewer.settings.p_min
    # The scene alone: equal to the headless render of the window's camera.
    from raygs_viewer.capture.image_io import to_rgb8
    expected = to_rgb8(headless(viewer))
    assert np.abs(shot.astype(int) - expected).max() <= 1
    # ... and `render --sidecar` reproduces the PNG.
    out = tmp_path / "again.png"
    assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
    np.testing.assert_array_equal(np.asarray(Image.open(out)), shot)

    # A second capture never overwrites the first.
    first = png.read_bytes()
    drive.tap(imgui.Key.f12)
    second, _ = viewer.captures.last
    assert second != png and png.read_bytes() == first


def test_panel_button_saves_at_the_chosen_scale(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    viewer.captures.options.scale = 2.0
    drive.reveal("Save screenshot (F12)")
    drive.click("Save screenshot (F12)")
    png, sidecar = viewer.captures.last
    _, _, w, h = viewer.viewport
    assert Image.open(png).size == (2 * w, 2 * h)
    assert json.loads(sidecar.read_text())["image"]["scale"] == 2.0


def test_unwritable_screenshot_folder_reports_and_keeps_running(open_viewer, tmp_path):
    viewer, drive = open_viewer(hide_panel=True)
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("x")
    viewer.captures.options.folder = str(blocker / "shots")
    drive.frames(1)
    drive.tap(imgui.Key.f12)
    assert viewer.panel.error.startswith("error: ") and "\n" not in viewer.panel.error
    drive.frames(2)  # still running


# -- loading --------------------------------------------------------------------------------
def test_bad_file_dropped_in_shows_an_error_and_keeps_the_scene(open_viewer, tmp_path):
    viewer, drive = open_viewer(hide_panel=True)
    drive.settle()
    loaded, image = viewer.loaded, window_image(viewer).copy()
    bad = tmp_path / "broken.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\nend_header\n\x00")
    viewer.drop([str(bad)])
    drive.wait_for_load()
    assert viewer.panel.error.startswith("error: ") and "broken.ply" in viewer.panel.error
    assert "\n" not in viewer.panel.error
    assert viewer.loaded is loaded
    drive.settle()
    np.testing.assert_array_equal(window_image(viewer), image)


@pytest.mark.parametrize("route", ["drop", "path field"])
def test_good_file_opened_replaces_the_scene(open_viewer, tmp_path, route):
    from testkit import gaussian_columns, write_ply
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(1)
    path = tmp_path / "small.ply"
    write_ply(path, gaussian_columns(n=50, degree=1, seed=3))
    if route == "drop":
        viewer.drop([str(path)])
    else:  # click into the field, type the path, press Enter
        drive.click("##open")
        drive._queued.append(lambda io: io.add_input_characters_utf8(str(path)))
        drive.frames(1)
        drive.tap(imgui.Key.enter)
        assert viewer.panel.open_path == str(path)
    drive.wait_for_load()
    assert viewer.panel.error == ""
    assert viewer.loaded.path == str(path) and viewer.loaded.scene.count == 50
    drive.settle()
    assert_matches(window_image(viewer), headless(viewer))


# -- the sort never makes a frame wait ----------------------------------------------------------
def test_frames_never_wait_for_the_sort(open_viewer):
    viewer, drive, gate = gated_viewer(open_viewer, hide_panel=True)
    drive.frames(1)
    assert gate.inside.wait(timeout=30)  # the first sort is running, and stays blocked
    drive.key(imgui.Key.w, True)
    drive.frames(10)  # each moves the camera: a new request every frame
    drive.key(imgui.Key.w, False)
    drive.frames(1)
    # Twelve frames completed while the only sort ever started was still blocked.
    assert viewer.scene.sorter.started == 1 and viewer.scene.sorter.finished == 0
    assert viewer.stats.frames_with_sort_running >= 11
    assert viewer.stats.order_age >= 11 and viewer.stats.visible == 0
    assert viewer.scene.sorter.superseded >= 9  # views that went by were never sorted
    gate.release.set()
    drive.settle()
    assert viewer.stats.drawn_serial == viewer.scene.sorter.latest().serial
    assert_matches(window_image(viewer), headless(viewer))


# -- training cameras --------------------------------------------------------------------------
def test_training_camera_keys_fly_smoothly_and_use_its_intrinsics(open_viewer):
    from raygs_viewer.scene.demo import demo_cameras
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    start = viewer.camera.center.copy()
    drive.tap(imgui.Key.n)
    assert viewer.view.training_index == 0
    drive.tap(imgui.Key.n)
    assert viewer.view.training_index == 1
    target = demo_cameras()[1]
    assert not np.allclose(viewer.camera.center, target.center)  # on its way, not jumped
    drive.frames(10)
    camera = viewer.camera
    np.testing.assert_allclose(camera.center, target.center, atol=1e-9)
    np.testing.assert_allclose(camera.R, target.R, atol=1e-9)
    # 640x480 letterboxed into 192x144 is the same aspect: exactly the camera, scaled.
    assert (camera.width, camera.height) == (WIDTH, HEIGHT)
    assert camera.fx == pytest.approx(target.fx * WIDTH / target.width)
    assert camera.cy == pytest.approx(target.cy * HEIGHT / target.height)
    drive.tap(imgui.Key.p)
    assert viewer.view.training_index == 0
    assert not np.allclose(start, target.center)
    # The close-up view has a 50 degree lens where the window's own is 60.
    for _ in range(4):
        drive.tap(imgui.Key.page_down)
    close_up = demo_cameras()[4]
    assert viewer.view.training_index == 4 and close_up.fy != target.fy
    drive.frames(8)
    assert viewer.camera.fy == pytest.approx(close_up.fy * HEIGHT / close_up.height)


def test_training_camera_of_another_aspect_is_letterboxed(open_viewer, tmp_path):
    from raygs_viewer.camera.pinhole import camera_to_json, look_at
    square = look_at((0, 0, -4), (0, 0, 0), width=300, height=300, fov_y_degrees=50)
    path = tmp_path / "cameras.json"
    path.write_text(json.dumps([camera_to_json(square)]))
    viewer, drive = open_viewer(hide_panel=True, camera=str(path))
    drive.settle()
    assert viewer.viewport == ((WIDTH - HEIGHT) // 2, 0, HEIGHT, HEIGHT)
    assert (viewer.camera.width, viewer.camera.height) == (HEIGHT, HEIGHT)
    assert viewer.camera.fx == pytest.approx(square.fx * HEIGHT / 300)
    assert_matches(window_image(viewer), headless(viewer))


# -- window behaviour ------------------------------------------------------------------------------
def test_resize_and_minimise(open_viewer):
    import glfw
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    glfw.set_window_size(viewer.window.handle, 0, 0)
    draws = viewer.stats.draws
    drive.frames(3)  # minimised: no draw, no error
    assert viewer.stats.draws == draws
    glfw.set_window_size(viewer.window.handle, 240, 100)
    drive.settle()
    assert (viewer.camera.width, viewer.camera.height) == (240, 100)
    assert_matches(window_image(viewer), headless(viewer))


def test_escape_quits_the_loop(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    drive.key(imgui.Key.escape, True)
    viewer.run()  # returns once the key closes the window
    assert viewer.window.should_close


def test_reset_view_frames_the_scene(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    drive.key(imgui.Key.w, True)
    drive.frames(20)
    drive.key(imgui.Key.w, False)
    drive.tap(imgui.Key.r)
    camera = viewer.camera
    u, v, z = project(camera, viewer.view.center)
    assert z > viewer.view.radius and abs(u - camera.cx) < 1 and abs(v - camera.cy) < 1


def rolled_demo_cameras(tmp_path) -> tuple[str, list]:
    """A cameras.json of the demo's views, each turned 180 degrees about its optical axis
    (image down = -y in world space, so their up is +y), and those cameras."""
    from raygs_viewer.camera.pinhole import Camera, camera_to_json
    from raygs_viewer.scene.demo import demo_cameras
    flip = np.diag([-1.0, -1.0, 1.0])
    cameras = [Camera(c.width, c.height, c.fx, c.fy, c.width - c.cx, c.height - c.cy, flip @ c.R, flip @ c.t)
               for c in demo_cameras(160, 120)]
    path = tmp_path / "rolled.json"
    path.write_text(json.dumps([camera_to_json(c, i, f"view_{i}") for i, c in enumerate(cameras)]))
    return str(path), cameras


def up_line(drive) -> list[str]:
    return [label for label in drive.panel.labels("text_disabled") if label.startswith("up: ")]


def test_up_comes_from_the_training_cameras_so_reset_view_agrees_with_them(open_viewer, tmp_path):
    path, cameras = rolled_demo_cameras(tmp_path)
    viewer, drive = open_viewer(SceneSource.demo(path), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    assert viewer.view.navigator.up == "+y"
    assert up_line(drive) == ["up: +y (from the 6 training cameras)"]
    np.testing.assert_allclose(viewer.view.navigator.pose.R, cameras[0].R, atol=1e-12)  # the start view: the first
    drive.move_mouse(PANEL_WIDTH - 2, PANEL_HEIGHT - 2)  # off the panel: R reaches the window
    drive.tap(imgui.Key.r)
    framed = viewer.view.navigator.pose.R
    # R's framing is level about +y: its image down is the cameras' (-y), not upside down.
    assert framed[1] @ np.array([0.0, -1.0, 0.0]) > 0.99
    assert framed[1] @ cameras[0].R[1] > 0.9


def test_an_explicit_up_axis_wins_over_the_cameras(open_viewer, tmp_path):
    path, _ = rolled_demo_cameras(tmp_path)
    viewer, drive = open_viewer(SceneSource.demo(path), width=PANEL_WIDTH, height=PANEL_HEIGHT,
                                navigation=NavigationChoices(up_axis="-y"))
    drive.frames(2)
    assert viewer.view.navigator.up == "-y"
    assert up_line(drive) == ["up: -y (--up-axis)"]


def test_without_cameras_up_is_the_default_and_a_panel_choice_says_so(open_viewer, tmp_path):
    from raygs_viewer.scene.writing import write_scene
    from testkit import random_scene
    scene = tmp_path / "bare.ply"
    write_scene(random_scene(n=40, seed=1, degree=0), scene)
    viewer, drive = open_viewer(str(scene), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    assert not viewer.loaded.cameras and viewer.view.navigator.up == "-y"
    assert up_line(drive) == ["up: -y (default)"]
    click_choice(drive, "up axis", "+z")
    drive.frames(1)
    assert viewer.view.navigator.up == "+z"
    assert up_line(drive) == ["up: +z (chosen in the panel)"]
    assert viewer.view.choices() == NavigationChoices(up_axis="+z", up_source="chosen in the panel")


# -- scripted runs ------------------------------------------------------------------------------------
def test_scripted_run_saves_the_last_frame(restore_gl_ctx, tmp_path, capsys):
    from raygs_viewer.camera.pinhole import camera_to_json
    from raygs_viewer.cli.main import main
    from raygs_viewer.scene.demo import demo_cameras
    cameras = tmp_path / "cams.json"
    cameras.write_text(json.dumps([camera_to_json(c) for c in demo_cameras(160, 120)]))
    shot, window = tmp_path / "shot.png", tmp_path / "window.png"
    status = main(["view", "--frames", "2", "--screenshot", str(shot), "--camera", str(cameras),
                   "--camera-index", "2", "--width", "640", "--height", "480", "--window-platform", "null",
                   "--window-screenshot", str(window)])
    assert status == 0
    # Two frames are too few for the background sort on its own: the last frame of a
    # scripted run waits for its view's order, so right of the panel the window shows
    # the finished scene, the same as the screenshot: the 4:3 camera letterboxed in the
    # 280 x 480 view beside the 360-wide panel.
    scene, whole = (np.asarray(Image.open(p)).astype(int) for p in (shot, window))
    assert whole.shape == (480, 640, 3) and scene.shape == (210, 280, 3)
    assert scene.std() > 10  # there is something to see there
    # (The other training cameras' frustums are drawn over the window's view: thin lines.)
    same = np.abs(whole[135:345, 360:] - scene).max(axis=2) <= 1
    assert same.mean() > 0.97 and not same.all()
    sidecar = json.loads(shot.with_suffix(".json").read_text())
    assert sidecar["camera"]["position"] == pytest.approx(demo_cameras()[2].center.tolist())
    assert Image.open(shot).size == (280, 210)
    # an existing screenshot is never overwritten: refused before the window opens
    assert main(["view", "--frames", "1", "--screenshot", str(shot), "--window-platform", "null"]) == 2
    assert "already exists" in capsys.readouterr().err


@pytest.mark.parametrize("camera_size", [(200, 400), (800, 309)])
def test_window_shows_the_image_letterboxed_and_the_panel_on_top(open_viewer, tmp_path, camera_size):
    from raygs_viewer.camera.pinhole import camera_to_json, look_at
    from raygs_viewer.capture.image_io import to_rgb8
    from raygs_viewer.render.gl.mono_frame import LETTERBOX_GREY
    width, height = camera_size
    lens = look_at((0.3, -0.5, -4), (0, 0, 1), width=width, height=height, fov_y_degrees=70)
    path = tmp_path / "lens.json"
    path.write_text(json.dumps(camera_to_json(lens)))
    viewer, drive = open_viewer(camera=str(path), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    viewer.panel.show_panel = False
    viewer.frustums.show = False  # the window as shown is compared with the scene: no training cameras over it
    drive.settle()
    viewer.captures.keep_next = True
    drive.frames(1)
    window = viewer.captures.window.astype(int)
    x, y, w, h = viewer.viewport
    if width < height:  # bars left and right
        assert (w, h) == (PANEL_HEIGHT // 2, PANEL_HEIGHT) and (x, y) == ((PANEL_WIDTH - w) // 2, 0)
    else:  # bars above and below, of unequal heights: 276 above, 277 below
        assert (w, h) == (PANEL_WIDTH, 247) and (x, y) == (0, 276)
    scene = to_rgb8(window_image(viewer)).astype(int)
    # Inside the viewport: the scene, the right way up and in the right place.
    assert np.abs(window[y:y + h, x:x + w] - scene).max() <= 1
    shifted = window[y:y + h, x + 1:x + w + 1] if width < height else window[y + 1:y + h + 1, x:x + w]
    assert np.abs(shifted - scene).max() > 10  # one pixel off would show
    assert np.abs(window[y:y + h, x:x + w][::-1] - scene).max() > 10
    # Outside it: the letterbox bars.
    grey = round(LETTERBOX_GREY * 255)
    outside = np.ones(window.shape[:2], bool)
    outside[y:y + h, x:x + w] = False
    assert outside.any() and np.abs(window[outside] - grey).max() <= 1

    # With the panel the letterbox is laid out in what the panel leaves: none of it under the panel.
    viewer.panel.show_panel = True
    drive.settle()
    viewer.captures.keep_next = True
    drive.frames(1)
    with_panel = viewer.captures.window.astype(int)
    x, y, w, h = viewer.viewport
    panel = round(viewer.panel.width)
    area = PANEL_WIDTH - panel
    # 280 x 800 beside the panel: both cameras are as wide as it, with bars above and below.
    assert (x, w) == (panel, area) and abs(h - area * height / width) <= 1 and y == (PANEL_HEIGHT - h) // 2
    scene = to_rgb8(window_image(viewer)).astype(int)
    assert np.abs(with_panel[y:y + h, x:x + w] - scene).max() <= 1
    x0, y0, x1, y1 = (int(v) for v in drive.panel.rect("Reset view (R)"))
    assert x1 <= panel and np.abs(with_panel[y0:y1, x0:x1] - window[y0:y1, x0:x1]).max() > 50  # the panel is drawn
    # A screenshot shows the scene alone.
    drive.tap(imgui.Key.f12)
    shot = np.asarray(Image.open(viewer.captures.last[0])).astype(int)
    assert np.abs(shot - scene).max() <= 1


def test_turntable_turns_a_fixed_angle_per_frame(open_viewer):
    from raygs_viewer.camera.navigation import up_vector
    viewer, drive = open_viewer(hide_panel=True, navigation=NavigationChoices(turntable=5.0))
    drive.frames(1)
    target, first = viewer.view.navigator.target.copy(), viewer.camera.center.copy()
    drive.frames(6)
    up = up_vector("-y")
    def around(point):  # the horizontal direction from the target
        d = point - target
        d -= (d @ up) * up
        return d / np.linalg.norm(d)
    angle = np.degrees(np.arccos(np.clip(around(first) @ around(viewer.camera.center), -1, 1)))
    assert angle == pytest.approx(30.0, abs=1e-6)
    assert viewer.stats.draws >= 6  # every frame a new view


def test_scripted_run_prints_its_frame_statistics(restore_gl_ctx, capsys):
    from raygs_viewer.viewer.app import run_viewer
    status = run_viewer(ViewerOptions(width=96, height=72, frames=6, navigation=NavigationChoices(turntable=5.0),
                                      platform="null"))
    assert status == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert line.startswith("6 frames (6 drawn) at 96x72: median frame ") and " fps), GPU " in line


def test_no_display_refuses_an_endless_invisible_window(monkeypatch):
    from raygs_viewer.errors import UserError
    from raygs_viewer.viewer.app import run_viewer
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(UserError, match="no display"):
        run_viewer(ViewerOptions())


def test_a_scene_too_large_for_the_gpu_fails_before_the_loop_and_closes_the_window(restore_gl_ctx):
    import glfw

    from raygs_viewer.errors import UserError

    def refuse(*args, **kwargs):
        raise UserError("scene of 3914 gaussians needs 9 storage blocks")

    with pytest.raises(UserError, match="storage blocks"):
        Viewer(ViewerOptions(width=64, height=48, platform="null"), load_now(SceneSource.demo()),
               renderer_factory=refuse)
    assert not glfw.get_current_context()  # the window and GLFW were shut down
