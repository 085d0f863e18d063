"""Window robustness (issue 6, part 5): the real frame loop driven the way a careless or
unlucky user drives it. Corrupt files opened, screenshot folders that cannot be written,
absurd camera input and frame times, a window resized to nothing, loads that overlap.

Each test checks what the user would see afterwards (the panel's one-line error, the
image in the window) and that the viewer still works: a good file still loads, a
screenshot still saves, a key still moves the camera."""

from __future__ import annotations

import errno
import math
import os
import threading
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from appkit import (
    HEIGHT,
    PANEL_HEIGHT,
    PANEL_WIDTH,
    WIDTH,
    headless,
    presented,
    window_image,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from PIL import Image
from testkit import assert_matches, gaussian_columns, ply_bytes, write_ply

from raygs_viewer.camera.navigation import (
    MAX_DISTANCE,
    MAX_DT,
    MIN_DISTANCE,
    SPEED_RANGE,
    framing_pose,
)
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.spz_file import spz_bytes
from raygs_viewer.viewer.state import done

NAN, INF = float("nan"), float("inf")


# -- helpers ----------------------------------------------------------------------------------
def good_ply(path: Path, n: int = 50, seed: int = 3) -> Path:
    return write_ply(path, gaussian_columns(n=n, degree=1, seed=seed))


def assert_one_line_error(viewer, *fragments: str) -> None:
    error = viewer.panel.error
    assert error.startswith("error: "), repr(error)
    assert "\n" not in error and "\r" not in error, repr(error)
    for fragment in fragments:
        assert fragment in error, repr(error)


class Shown:
    """What the window shows now: the scene object, the camera and the pixels."""

    def __init__(self, viewer):
        self.loaded = viewer.loaded
        self.renderer = viewer.scene.renderer
        self.R, self.t = viewer.camera.R.copy(), viewer.camera.t.copy()
        self.image = window_image(viewer).copy()
        self.window = presented(viewer)

    def assert_still_shown(self, viewer) -> None:
        assert viewer.loaded is self.loaded and viewer.scene.renderer is self.renderer
        np.testing.assert_array_equal(viewer.camera.R, self.R)
        np.testing.assert_array_equal(viewer.camera.t, self.t)
        np.testing.assert_array_equal(window_image(viewer), self.image)
        np.testing.assert_array_equal(presented(viewer), self.window)


def assert_sane(viewer) -> None:
    """The invariants no input may break: a finite proper pose, finite navigation state,
    and a finite image in the window."""
    camera = viewer.camera
    assert np.all(np.isfinite(camera.R)) and np.all(np.isfinite(camera.t)), (camera.R, camera.t)
    assert np.abs(camera.R @ camera.R.T - np.eye(3)).max() < 1e-6
    assert np.linalg.det(camera.R) > 0
    nav = viewer.view.navigator
    assert math.isfinite(nav.speed) and nav.speed > 0
    assert math.isfinite(nav.distance) and nav.distance > 0
    assert np.all(np.isfinite(nav.target))
    assert np.all(np.isfinite(window_image(viewer))), "NaN or Inf in the window's image"


def run_checked(drive, count: int = 1) -> None:
    """``count`` frames, each one completing and leaving the viewer sane."""
    for _ in range(count):
        index = drive.viewer.frame_index
        drive.frames(1)
        assert drive.viewer.frame_index == index + 1
        assert_sane(drive.viewer)


def _drag_through(drive, button: int, positions, modifier=None) -> None:
    """Holds ``button`` (and ``modifier``) down while the mouse visits ``positions``,
    each frame checked."""
    if modifier is not None:
        drive.key(modifier, True)
    drive.button(button, True)
    run_checked(drive)
    for position in positions:
        drive.move_mouse(*position)
        run_checked(drive)
    drive.button(button, False)
    if modifier is not None:
        drive.key(modifier, False)
    run_checked(drive)


def drain_input(drive) -> None:
    """Checked frames until imgui has applied every queued event. It trickles them: a wheel
    event queued after a mouse move (the driver sends the position every frame) waits for
    the next frame, so a burst of input takes a few frames to arrive."""
    for _ in range(200):
        run_checked(drive)
        if imgui.get_current_context().input_events_queue.size() == 0:
            return
    raise AssertionError("imgui's input queue never drained")


def assert_w_moves_at_default_speed(viewer, drive) -> None:
    """One frame of W at dt 0.1 moves the camera straight ahead by the default speed's step:
    the view is not stuck."""
    drive.clock.step = 0.1
    drive.frames(1)  # the clock at 0.1 s a frame (after a huge one it starts again: a frame of no time)
    before = viewer.camera
    drive.key(imgui.Key.w, True)
    drive.frames(1)
    drive.key(imgui.Key.w, False)
    drive.frames(1)
    after = viewer.camera
    step = before.R @ (after.center - before.center)
    expected = viewer.view.navigator.default_speed * 0.1
    assert step[2] == pytest.approx(expected, rel=1e-6)
    assert np.abs(step[:2]).max() < 1e-6 * expected
    np.testing.assert_array_equal(after.R, before.R)


# -- 1. a corrupt file opened leaves the current scene -------------------------------------
def _truncated(tmp: Path) -> Path:
    data = good_ply(tmp / "whole.ply").read_bytes()
    path = tmp / "truncated.ply"
    path.write_bytes(data[:-37])
    return path


def _noise(name: str, size: int):
    def make(tmp: Path) -> Path:
        path = tmp / name
        path.write_bytes(np.random.default_rng(7).bytes(size))
        return path
    return make


def _absurd_count(tmp: Path) -> Path:
    path = tmp / "absurd-count.ply"
    path.write_bytes(ply_bytes(gaussian_columns(n=5, seed=1), count=10 ** 15))
    return path


def _empty(name: str):
    def make(tmp: Path) -> Path:
        path = tmp / name
        path.write_bytes(b"")
        return path
    return make


def _folder(tmp: Path) -> Path:
    path = tmp / "folder.ply"
    path.mkdir()
    return path


def _all_nan(tmp: Path) -> Path:
    columns = gaussian_columns(n=20, seed=2)
    columns["x"] = np.full(20, np.nan)  # scene_io drops every one: an empty scene
    return write_ply(tmp / "all-nan.ply", columns)


def _garbage_header(tmp: Path) -> Path:
    path = tmp / "garbage-header.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\n\xff\xfe\x00\nend_header\n" + bytes(99))
    return path


BAD_FILES = {
    "truncated PLY": _truncated,
    "random bytes .ply": _noise("noise.ply", 4096),
    "random bytes .splat": _noise("noise.splat", 32 * 100 + 7),
    "absurd vertex count": _absurd_count,
    "garbage header": _garbage_header,
    "empty .ply": _empty("empty.ply"),
    "empty .splat": _empty("empty.splat"),       # scene_io: a valid scene of 0 gaussians
    "directory": _folder,
    "missing path": lambda tmp: tmp / "missing.ply",
    "every gaussian invalid": _all_nan,           # scene_io: 0 gaussians left, a warning
    "random bytes .spz": _noise("noise.spz", 4096),
    "random bytes .sog": _noise("noise.sog", 4096),
    "truncated .spz": lambda tmp: _cut(tmp / "cut.spz", spz_bytes(load_scene(good_ply(tmp / "whole.ply")))),
}


def _cut(path: Path, data: bytes) -> Path:
    path.write_bytes(data[: len(data) // 2])
    return path


@pytest.mark.parametrize("kind", list(BAD_FILES))
def test_a_corrupt_file_opened_leaves_the_scene_camera_and_image(open_viewer, tmp_path, kind):
    viewer, drive = open_viewer()  # panel open: it must draw the error line
    drive.settle()
    shown = Shown(viewer)
    bad = BAD_FILES[kind](tmp_path)
    for route in ("path field", "drop"):
        viewer.panel.say(done(""))
        if route == "drop":
            viewer.drop([str(bad)])
        else:
            viewer.open_scene(str(bad))
        drive.wait_for_load()
        assert_one_line_error(viewer, bad.name)
        drive.frames(3)  # the loop keeps running...
        drive.settle()   # ...and sorting
        shown.assert_still_shown(viewer)
        assert viewer.window.handle is not None and not viewer.window.should_close
    # A good file opened afterwards still loads.
    good = good_ply(tmp_path / "good.ply")
    viewer.open_scene(str(good))
    drive.wait_for_load()
    assert viewer.panel.error == ""
    assert viewer.loaded.path == str(good) and viewer.loaded.scene.count == 50
    drive.settle()
    assert_matches(window_image(viewer), headless(viewer))


def test_a_dropped_spz_opens_like_a_ply(open_viewer, tmp_path):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    spz = tmp_path / "scene.spz"
    spz.write_bytes(spz_bytes(load_scene(good_ply(tmp_path / "scene.ply"))))
    viewer.drop([str(spz)])
    drive.wait_for_load()
    assert viewer.panel.error == "" and viewer.loaded.path == str(spz)
    assert (viewer.loaded.scene.format, viewer.loaded.scene.count) == ("spz v3", 50)
    drive.settle()
    assert_matches(window_image(viewer), headless(viewer))


# sorting.py's cull radius overflows float32 for the absurd scales this noise decodes to
# (a RuntimeWarning); what the window makes of it is what this test checks.
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_random_bytes_that_happen_to_be_whole_splat_rows_load_without_breaking_the_view(open_viewer, tmp_path):
    """A .splat has no header to reject: noise of a multiple of 32 bytes decodes to
    gaussians with absurd positions and scales (some dropped). The viewer must show
    what decoded, say what it dropped, and stay navigable."""
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    path = tmp_path / "noise-rows.splat"
    path.write_bytes(np.random.default_rng(1).bytes(32 * 1000))
    viewer.open_scene(str(path))
    drive.wait_for_load()
    assert viewer.panel.error == "" and viewer.loaded.path == str(path)
    assert "dropped" in viewer.panel.message and "\n" not in viewer.panel.message
    drive.settle()
    assert_sane(viewer)
    assert_matches(window_image(viewer), headless(viewer))
    drive.tap(imgui.Key.r)
    assert_sane(viewer)
    assert_w_moves_at_default_speed(viewer, drive)
    assert_sane(viewer)


# -- 2. screenshots that cannot be written ------------------------------------------------------
def _files(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (hidden and partial ones too) with its bytes."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _assert_later_screenshots_work(viewer, drive, folder: Path) -> None:
    viewer.captures.options.folder = str(folder)
    drive.tap(imgui.Key.f12)
    assert viewer.panel.error == ""
    png, sidecar = viewer.captures.last
    assert png.parent == folder and png.is_file() and sidecar.is_file()
    assert Image.open(png).size == (viewer.camera.width, viewer.camera.height)


@pytest.mark.parametrize("kind", ["folder under a regular file", "folder is a regular file"])
def test_a_screenshot_folder_that_cannot_be_made_reports_and_keeps_running(open_viewer, tmp_path, kind):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(2)
    blocker = tmp_path / "blocker"
    blocker.write_bytes(b"precious")
    folder = blocker / "shots" if kind == "folder under a regular file" else blocker
    viewer.captures.options.folder = str(folder)
    before = _files(tmp_path)
    drive.tap(imgui.Key.f12)
    assert_one_line_error(viewer, "screenshot not saved", str(folder))
    assert viewer.captures.last is None
    assert _files(tmp_path) == before  # nothing written, nothing replaced
    run_checked(drive, 3)
    _assert_later_screenshots_work(viewer, drive, tmp_path / "good")


class _FullDisk:
    """Stands in for imageio's ``os``: the ``fail_on``-th file opened for writing takes
    half its bytes and then reports a full disk, as a real write(2) would."""

    def __init__(self, fail_on: int):
        self.fail_on = fail_on
        self.opened = 0

    def __getattr__(self, name):
        return getattr(os, name)

    def fdopen(self, fd, mode="r", *args, **kwargs):
        stream = os.fdopen(fd, mode, *args, **kwargs)
        self.opened += 1
        return _HalfWriter(stream) if self.opened == self.fail_on else stream


class _HalfWriter:
    def __init__(self, stream):
        self.stream = stream

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.stream.close()

    def write(self, data):
        self.stream.write(data[:len(data) // 2])
        self.stream.flush()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def __getattr__(self, name):
        return getattr(self.stream, name)


class _Frozen(datetime):
    """A clock stopped at one second, so the screenshot names are known in advance."""

    @classmethod
    def now(cls, tz=None):
        return cls(2030, 1, 2, 3, 4, 5)


@pytest.mark.parametrize("failing", ["png", "sidecar"])
def test_a_full_disk_during_a_screenshot_leaves_no_partial_files(open_viewer, tmp_path, monkeypatch, failing):
    import raygs_viewer.capture.screenshot
    import raygs_viewer.files
    monkeypatch.setattr(raygs_viewer.capture.screenshot, "datetime", _Frozen)
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(2)
    folder = tmp_path / "shots"
    folder.mkdir()
    # The name this second's capture would take is already someone's file.
    (folder / "raygs-20300102-030405.png").write_bytes(b"an older screenshot")
    (folder / "notes.txt").write_text("keep me")
    viewer.captures.options.folder = str(folder)
    before = _files(folder)
    disk = _FullDisk(fail_on=1 if failing == "png" else 2)
    monkeypatch.setattr(raygs_viewer.files, "os", disk)
    drive.tap(imgui.Key.f12)
    assert disk.opened == (1 if failing == "png" else 2)  # the failure did happen where meant
    monkeypatch.setattr(raygs_viewer.files, "os", os)
    assert_one_line_error(viewer, "screenshot not saved", os.strerror(errno.ENOSPC), "raygs-20300102-030405-2.")
    assert viewer.captures.last is None
    assert _files(folder) == before  # no half PNG, no PNG without sidecar, no temp file, nothing replaced
    run_checked(drive, 3)
    _assert_later_screenshots_work(viewer, drive, folder)
    assert viewer.captures.last[0].name == "raygs-20300102-030405-2.png"
    assert (folder / "raygs-20300102-030405.png").read_bytes() == b"an older screenshot"


# -- 3. extreme camera moves ------------------------------------------------------------------------
def _reference_reset_view(open_viewer):
    """(R, centre) of a fresh viewer's view after R (reset view)."""
    fresh, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    drive.tap(imgui.Key.r)
    R, center = fresh.camera.R.copy(), fresh.camera.center.copy()
    fresh.close()  # one window at a time
    return R, center


def test_extreme_moves_never_break_the_pose_the_image_or_the_controls(open_viewer):
    from raygs_viewer.scene.demo import demo_cameras
    reset_R, reset_center = _reference_reset_view(open_viewer)
    viewer, drive = open_viewer(hide_panel=True)
    nav = viewer.view.navigator
    drive.move_mouse(WIDTH / 2, HEIGHT / 2)
    run_checked(drive, 2)
    default = nav.default_speed

    # The wheel many notches up (one notch a frame, then thousands at once): the speed clamp.
    for _ in range(20):
        drive.wheel(1)
        run_checked(drive)
    drain_input(drive)
    assert nav.speed == pytest.approx(default * 1.25 ** 20)
    drive.wheel(5000)
    drain_input(drive)
    assert nav.speed == pytest.approx(default * SPEED_RANGE[1])
    for ticks in (1e30, INF, NAN, -INF):  # the infinite and NaN ones are ignored
        drive.wheel(ticks)
        drain_input(drive)
    assert nav.speed == pytest.approx(default * SPEED_RANGE[1])

    # Fly at the top speed with Shift and absurd frame times, far out and back through
    # the scene: every frame moves exactly the clamped step.
    drive.key(imgui.Key.mod_shift, True)
    for dt, key in ((1e6, imgui.Key.w), (1e30, imgui.Key.s)):
        drive.clock.step = dt
        drive.key(key, True)
        for _ in range(15):
            before = viewer.camera.center
            run_checked(drive)
            step = np.linalg.norm(viewer.camera.center - before)
            assert step == pytest.approx(4 * nav.speed * MAX_DT, rel=1e-6)
        drive.key(key, False)
        run_checked(drive)
    drive.key(imgui.Key.mod_shift, False)

    # Into and through the dense centre at the default speed, frame by frame.
    drive.tap(imgui.Key.r)
    assert nav.speed == default
    drive.clock.step = 1e30
    drive.key(imgui.Key.w, True)
    travelled, beyond = 0.0, 2 * np.linalg.norm(viewer.view.center - viewer.camera.center) + viewer.view.radius
    while travelled < beyond:
        before = viewer.camera.center
        run_checked(drive)
        travelled += np.linalg.norm(viewer.camera.center - before)
    drive.key(imgui.Key.w, False)
    drive.settle()
    assert_sane(viewer)

    # The wheel at its extremes the other way.
    drive.wheel(-1e30)
    drain_input(drive)
    assert nav.speed == pytest.approx(default * SPEED_RANGE[0])

    # Mouse looks with huge, overflowing, infinite and NaN positions (hence deltas).
    garbage = [(1e6, 0), (-1e6, 1e6), (2e9, -2e9), (1e30, 1e30), (-3.4e38, 3.4e38), (INF, -INF), (NAN, NAN),
               (NAN, 5.0), (WIDTH / 2, HEIGHT / 2)]
    for button in (0, 1):
        _drag_through(drive, button, garbage)

    # Orbit: thousands of notches in, to the target, and out; pan and rotate wildly.
    drive.tap(imgui.Key.tab)
    assert nav.mode == "orbit"
    target = nav.target.copy()
    drive.wheel(5000)
    drain_input(drive)
    assert nav.distance == pytest.approx(MIN_DISTANCE * viewer.view.radius)
    np.testing.assert_allclose(nav.target, target, atol=1e-9 * viewer.view.radius)
    for _ in range(10):
        drive.wheel(-500)
        run_checked(drive)
    drain_input(drive)
    assert nav.distance == pytest.approx(MAX_DISTANCE * viewer.view.radius)
    for button, modifier in ((1, None), (2, None), (0, imgui.Key.mod_shift), (0, None)):
        _drag_through(drive, button, garbage, modifier)
    drive.wheel(3000)
    drain_input(drive)
    drive.tap(imgui.Key.tab)
    assert nav.mode == "fly"

    # Flying to training cameras while moving: each key press starts a flight that the
    # held key interrupts; once the key is up the next flight arrives exactly.
    drive.key(imgui.Key.d, True)
    for _ in range(3):
        drive.key(imgui.Key.n, True)
        run_checked(drive)
        drive.key(imgui.Key.n, False)
        run_checked(drive, 2)
    drive.key(imgui.Key.d, False)
    drive.tap(imgui.Key.n)
    run_checked(drive, 6)  # a flight's 0.6 s in frames of at most MAX_DT
    assert viewer.view.training_index == 3 and not viewer.view.navigator.animating
    goal = demo_cameras()[3]
    np.testing.assert_allclose(viewer.camera.center, goal.center, atol=1e-9)
    np.testing.assert_allclose(viewer.camera.R, goal.R, atol=1e-9)

    # Reset view: the framing view of a fresh viewer, and W moves the camera again.
    drive.tap(imgui.Key.r)
    drive.settle()
    assert_sane(viewer)
    np.testing.assert_allclose(viewer.camera.R, reset_R, atol=1e-12)
    np.testing.assert_allclose(viewer.camera.center, reset_center, atol=1e-9 * viewer.view.radius)
    assert nav.speed == default
    assert_matches(window_image(viewer), headless(viewer))
    assert_w_moves_at_default_speed(viewer, drive)


def test_mouse_garbage_over_the_open_panel_is_harmless(open_viewer):
    """Huge, infinite and NaN mouse positions with buttons and the wheel, while the panel
    is open under the cursor: imgui's hit tests see them too."""
    viewer, drive = open_viewer()
    drive.settle()
    settings_before = viewer.settings
    for position in [(10, 10), (1e30, -1e30), (INF, INF), (NAN, NAN), (-2e9, 2e9), (10, 10)]:
        drive.move_mouse(*position)
        drive.wheel(1e30)
        drive.button(0, True)
        run_checked(drive)
        drive.button(0, False)
        run_checked(drive)
    assert viewer.panel.error == ""
    assert viewer.settings == settings_before


def test_tab_switches_navigation_with_the_panel_open_and_the_keys_keep_steering(open_viewer):
    """Tab is the fly/orbit key. With the panel open (the default) imgui tabbed into the
    panel as well, and the slider it landed on became a text field that took every key
    after it: a second Tab, WASD and R no longer reached the camera."""
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.move_mouse(PANEL_WIDTH - 5, PANEL_HEIGHT - 5)  # over the scene, not the panel
    drive.frames(2)
    settings_before, open_path = viewer.settings, viewer.panel.open_path
    for expected in ("orbit", "fly", "orbit", "fly"):
        drive.tap(imgui.Key.tab)
        assert viewer.view.navigator.mode == expected
        assert not imgui.get_io().want_capture_keyboard
    for chord in ((imgui.Key.mod_shift, imgui.Key.tab), (imgui.Key.mod_ctrl, imgui.Key.tab), (imgui.Key.left_alt,),
                  (imgui.Key.space,), (imgui.Key.enter,), (imgui.Key.down_arrow,)):
        mode = viewer.view.navigator.mode
        for key in chord:
            drive.key(key, True)
        drive.frames(1)
        for key in chord:
            drive.key(key, False)
        drive.frames(1)
        assert not imgui.get_io().want_capture_keyboard, chord
        assert viewer.view.navigator.mode == (mode if imgui.Key.tab not in chord
                                              else {"fly": "orbit", "orbit": "fly"}[mode])
    assert_w_moves_at_default_speed(viewer, drive)
    drive.tap(imgui.Key.r)
    _, _, w, h = viewer.viewport  # framed for the view beside the panel
    expected = framing_pose(viewer.view.center, viewer.view.radius, viewer.view.navigator.up,
                            viewer.view.lens.fov_y_degrees, w / h)
    np.testing.assert_allclose(viewer.camera.R, expected.R, atol=1e-12)
    np.testing.assert_allclose(viewer.camera.center, expected.position, atol=1e-9 * viewer.view.radius)
    assert viewer.settings == settings_before and viewer.panel.open_path == open_path


_KEYS = [imgui.Key.w, imgui.Key.a, imgui.Key.s, imgui.Key.d, imgui.Key.q, imgui.Key.e, imgui.Key.n, imgui.Key.p,
         imgui.Key.r, imgui.Key.home, imgui.Key.tab, imgui.Key.mod_shift, imgui.Key.mod_ctrl]
_coordinate = st.one_of(st.sampled_from([0.0, WIDTH / 2, 1e6, -1e6, 2e9, -2e9, 1e30, -1e30, 3.4e38, INF, -INF, NAN]),
                        st.floats(-300, 500))
_frame = st.tuples(
    st.sampled_from([0.0, 1e-9, 1 / 60, 0.1, 1e6, 1e30, INF, NAN]),                        # frame time
    st.lists(st.tuples(st.sampled_from(_KEYS), st.booleans()), max_size=3),                 # key events
    st.one_of(st.none(), st.sampled_from([1.0, -1.0, 1e3, -1e3, 1e30, -1e30, INF, NAN]),
              st.floats(-50, 50)),                                                          # wheel
    st.one_of(st.none(), st.tuples(_coordinate, _coordinate)),                              # mouse position
    st.lists(st.tuples(st.integers(0, 2), st.booleans()), max_size=2),                      # buttons
    st.one_of(st.none(), st.sampled_from([(1, 1), (0, 0), (1, 300), (WIDTH, HEIGHT)])),     # window size
)


@settings(max_examples=4, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                 HealthCheck.data_too_large, HealthCheck.large_base_example])
@given(st.lists(_frame, min_size=50, max_size=50))
def test_any_sequence_of_extreme_input_keeps_the_viewer_sane_and_usable(open_viewer, frames):
    import glfw
    viewer, drive = open_viewer(hide_panel=True)
    try:
        drive.frames(1)
        for dt, keys, wheel, mouse, buttons, size in frames:
            drive.clock.step = dt
            for key, down in keys:
                drive.key(key, down)
            if wheel is not None:
                drive.wheel(wheel)
            if mouse is not None:
                drive.move_mouse(*mouse)
            for button, down in buttons:
                drive.button(button, down)
            if size is not None:
                glfw.set_window_size(viewer.window.handle, *size)
            run_checked(drive)
        # Let go of everything, back to the normal size: the loop draws the right image...
        glfw.set_window_size(viewer.window.handle, WIDTH, HEIGHT)
        for key in _KEYS:
            drive.key(key, False)
        for button in range(3):
            drive.button(button, False)
        drive.move_mouse(WIDTH / 2, HEIGHT / 2)
        drive.clock.step = 0.1
        drain_input(drive)
        drive.settle()
        assert_sane(viewer)
        assert_matches(window_image(viewer), headless(viewer))
        # ...reset view frames the scene as documented, and W still moves the camera.
        drive.tap(imgui.Key.r)
        expected = framing_pose(viewer.view.center, viewer.view.radius, viewer.view.navigator.up,
                                viewer.view.lens.fov_y_degrees, WIDTH / HEIGHT)
        np.testing.assert_allclose(viewer.camera.R, expected.R, atol=1e-12)
        np.testing.assert_allclose(viewer.camera.center, expected.position, atol=1e-9 * viewer.view.radius)
        assert_w_moves_at_default_speed(viewer, drive)
        assert_sane(viewer)
    finally:
        viewer.close()  # one window at a time: the next example opens its own


# -- 4. what else a demanding user does -----------------------------------------------------------
def test_resizing_to_one_pixel_and_minimising_and_back(open_viewer, tmp_path):
    import glfw
    viewer, drive = open_viewer(hide_panel=True)
    drive.settle()
    for size in [(1, 1), (1, 300), (300, 1), (WIDTH, HEIGHT)]:
        glfw.set_window_size(viewer.window.handle, *size)
        drive.settle()
        assert_sane(viewer)
        assert (viewer.camera.width, viewer.camera.height) == size and viewer.viewport == (0, 0, *size)
        assert_matches(window_image(viewer), headless(viewer))
    # A training camera's letterboxed lens at 1x1 and at extreme aspects.
    drive.tap(imgui.Key.n)
    for size in [(1, 1), (1, 300), (300, 1)]:
        glfw.set_window_size(viewer.window.handle, *size)
        drive.settle()
        assert_sane(viewer)
        x, y, w, h = viewer.viewport
        assert w >= 1 and h >= 1 and 0 <= x and x + w <= size[0] and 0 <= y and y + h <= size[1]
        assert_matches(window_image(viewer), headless(viewer))
    # A screenshot of a 1x1 window is a 1x1 PNG.
    glfw.set_window_size(viewer.window.handle, 1, 1)
    drive.settle()
    drive.tap(imgui.Key.f12)
    assert viewer.panel.error == "" and Image.open(viewer.captures.last[0]).size == (1, 1)
    # Minimised with W held and F12 pressed: nothing moves or draws until it is back, and
    # the screenshot then saves the restored view.
    glfw.set_window_size(viewer.window.handle, WIDTH, HEIGHT)
    drive.settle()
    pose, draws, shots = viewer.camera, viewer.stats.draws, viewer.captures.last
    glfw.set_window_size(viewer.window.handle, 0, 0)
    viewer.captures.requested = True
    drive.key(imgui.Key.w, True)
    drive.frames(3)
    assert viewer.stats.draws == draws and viewer.camera is pose and viewer.captures.last == shots
    drive.key(imgui.Key.w, False)
    glfw.set_window_size(viewer.window.handle, WIDTH, HEIGHT)
    drive.frames(1)
    assert viewer.captures.last != shots and viewer.panel.error == ""
    assert Image.open(viewer.captures.last[0]).size == (WIDTH, HEIGHT)
    drive.settle()
    assert_sane(viewer)
    assert_matches(window_image(viewer), headless(viewer))


class _Gate:
    """Holds back the background reads of files whose name starts with "slow" until
    ``release`` is set; the rest read as usual. Installed as the loader's reader."""

    def __init__(self, loader):
        self.entered = threading.Event()
        self.release = threading.Event()
        real = loader.read_scene

        def gated(source, *args, **kwargs):
            if Path(source.path).name.startswith("slow"):
                self.entered.set()
                self.release.wait(60)
            return real(source, *args, **kwargs)

        loader.read_scene = gated


@pytest.mark.parametrize("second", ["good", "bad"])
def test_opening_a_file_while_another_loads_replaces_that_load(open_viewer, tmp_path, second):
    viewer, drive = open_viewer(hide_panel=True)
    gate = _Gate(viewer.scenes.loader)
    drive.settle()
    shown = Shown(viewer)
    slow = good_ply(tmp_path / "slow.ply", n=30, seed=1)
    viewer.open_scene(str(slow))
    assert gate.entered.wait(30)
    run_checked(drive, 5)  # the loop never waits for the load; the scene stays meanwhile
    assert viewer.scenes.loader.busy and viewer.loaded is shown.loaded
    path = good_ply(tmp_path / "good.ply") if second == "good" else _noise("noise.ply", 999)(tmp_path)
    viewer.open_scene(str(path))
    drive.wait_for_load()
    if second == "good":
        assert viewer.panel.error == "" and viewer.loaded.path == str(path)
    else:
        assert_one_line_error(viewer, path.name)
        assert viewer.loaded is shown.loaded
    current = viewer.loaded
    gate.release.set()  # the first load now finishes (cancelled): it must never show up
    assert viewer.scenes.loader.join(timeout=60)
    run_checked(drive, 3)
    assert viewer.loaded is current and viewer.scenes.loader.discarded >= 1
    drive.settle()
    if second == "good":
        assert viewer.panel.error == ""
    else:
        shown.assert_still_shown(viewer)
        assert_one_line_error(viewer, path.name)  # the cancelled load did not clear it
    assert_matches(window_image(viewer), headless(viewer))


def test_dropping_several_files_opens_the_first(open_viewer, tmp_path):
    viewer, drive = open_viewer(hide_panel=True)
    drive.settle()
    good = good_ply(tmp_path / "good.ply")
    bad = _noise("noise.ply", 999)(tmp_path)
    viewer.drop([str(good), str(bad), str(tmp_path / "missing.ply")])
    assert "3 files" in viewer.panel.message
    drive.wait_for_load()
    assert viewer.panel.error == "" and viewer.loaded.path == str(good)
    drive.settle()
    shown = Shown(viewer)
    viewer.drop([str(bad), str(good)])
    drive.wait_for_load()
    assert_one_line_error(viewer, bad.name)
    drive.settle()
    shown.assert_still_shown(viewer)
    started = viewer.scenes.loader.started
    viewer.drop([])  # e.g. a drop of something that is no file
    run_checked(drive, 2)
    assert viewer.scenes.loader.started == started and viewer.loaded is shown.loaded


def test_a_load_that_finishes_while_minimised_is_shown_when_restored(open_viewer, tmp_path):
    import glfw
    viewer, drive = open_viewer(hide_panel=True)
    drive.settle()
    glfw.set_window_size(viewer.window.handle, 0, 0)
    drive.frames(1)
    good = good_ply(tmp_path / "good.ply")
    viewer.open_scene(str(good))
    drive.wait_for_load()
    assert viewer.panel.error == "" and viewer.loaded.path == str(good)
    glfw.set_window_size(viewer.window.handle, WIDTH, HEIGHT)
    drive.settle()
    assert_sane(viewer)
    assert_matches(window_image(viewer), headless(viewer))
