"""Input as a person's hands give it, at a few frames a second: a quick move and a click
arrive in one frame and are not a drag; a click into a text field and the letters typed
at once are the field's, not shortcuts; the Open field selects its text when clicked;
the Open… button's file dialog, or the line saying there is none."""

from __future__ import annotations

import numpy as np
import pytest
from appkit import HEIGHT, PANEL_HEIGHT, PANEL_WIDTH, WIDTH
from imgui_bundle import imgui


def _pose(viewer) -> tuple[np.ndarray, np.ndarray]:
    return viewer.camera.R.copy(), viewer.camera.t.copy()


@pytest.mark.parametrize("mode", ["fly", "orbit"])
@pytest.mark.parametrize("button", [0, 1])
def test_a_quick_move_then_a_click_leaves_the_camera_where_it_was(open_viewer, mode, button):
    """xdotool mousemove 1100 650; mousemove 700 300 click 1: the move and the press reach
    one frame; its pointer delta is the move, made with no button down."""
    viewer, drive = open_viewer(hide_panel=True)
    drive.move_mouse(WIDTH - 5, HEIGHT - 5)
    drive.frames(2)
    if mode == "orbit":
        drive.tap(imgui.Key.tab)
        assert viewer.view.navigator.mode == "orbit"
    before = _pose(viewer)
    drive.move_mouse(WIDTH / 3, HEIGHT / 3)
    drive.button(button, True)
    drive.frames(1)
    drive.button(button, False)
    drive.frames(2)
    after = _pose(viewer)
    np.testing.assert_array_equal(after[0], before[0])
    np.testing.assert_array_equal(after[1], before[1])
    # ... while a drag from there still turns the view, from where the press was.
    drive.button(button, True)
    drive.frames(1)
    drive.move_mouse(WIDTH / 3 + 20, HEIGHT / 3)
    drive.frames(1)
    drive.button(button, False)
    drive.frames(1)
    moved = _pose(viewer)  # turned (fly, orbit's left button) or panned (orbit's right)
    assert not (np.array_equal(moved[0], before[0]) and np.array_equal(moved[1], before[1]))


def test_letters_typed_with_the_click_into_a_field_are_the_field_s(open_viewer):
    """The click that focuses the Open field and the letters typed at once arrive in one
    frame: "h" would hide the panel, "k" add a path keyframe, "w" fly."""
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    x0, y0, x1, y1 = drive.panel.rect("##open")
    before, keyframes = _pose(viewer), len(viewer.camera_path.path.keyframes)
    drive.move_mouse((x0 + x1) / 2, (y0 + y1) / 2)
    drive.frames(1)
    drive.button(0, True)
    for letter in "hkw":
        key = getattr(imgui.Key, letter)
        drive._queued.append(lambda io, key=key: io.add_key_event(key, True))
        drive._queued.append(lambda io, letter=letter: io.add_input_character(ord(letter)))
        drive._queued.append(lambda io, key=key: io.add_key_event(key, False))
    drive.frames(1)
    drive.button(0, False)
    drive.frames(6)  # imgui hands the queued events out over frames (one change of a key a frame)
    assert viewer.panel.show_panel
    assert len(viewer.camera_path.path.keyframes) == keyframes
    np.testing.assert_array_equal(viewer.camera.t, before[1])
    assert "hkw" in viewer.panel.open_path


def test_letters_typed_after_the_field_let_go_of_the_keys_are_not_shortcuts(open_viewer):
    """Enter in the Open field opens and lets go of the keyboard; the person, pointer
    still on the panel, types on: "h" must not hide the panel, "k" not add a keyframe,
    "r" not reset the view. F12 still saves (it types no text); and once the pointer is
    over the view, the letters are shortcuts again."""
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    x0, y0, x1, y1 = drive.panel.rect("##open")
    drive.click_at((x0 + x1) / 2, (y0 + y1) / 2)
    drive.tap(imgui.Key.enter)  # "Open" an empty path: an error line, the field let go
    drive.frames(1)
    keyframes = len(viewer.camera_path.path.keyframes)
    for key in (imgui.Key.h, imgui.Key.k):
        drive.tap(key)
    assert viewer.panel.show_panel and len(viewer.camera_path.path.keyframes) == keyframes
    drive.tap(imgui.Key.f12)
    drive.frames(2)
    assert viewer.captures.last is not None  # F12 types nothing: it still saves
    drive.move_mouse(PANEL_WIDTH - 10, PANEL_HEIGHT / 2)  # over the view
    drive.frames(1)
    drive.tap(imgui.Key.h)
    assert not viewer.panel.show_panel


def test_the_open_field_selects_its_old_path_when_clicked(open_viewer):
    """A click in the Open field selects what it holds: typing replaces it."""
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    viewer.panel.open_path = "/the/old/scene.ply"
    drive.frames(2)
    x0, y0, x1, y1 = drive.panel.rect("##open")
    drive.click_at((x0 + x1) / 2, (y0 + y1) / 2)
    for letter in "nex":
        drive._queued.append(lambda io, letter=letter: io.add_input_character(ord(letter)))
        drive.frames(1)
    drive.frames(2)  # characters reach the field's value a frame or two after they are queued
    assert viewer.panel.open_path.startswith("ne") and "old" not in viewer.panel.open_path


class _Dialog:
    """portable-file-dialogs' open_file, as a desktop with a dialog program answers it."""

    def __init__(self, chosen):
        self.chosen, self.asked = chosen, 0

    def __call__(self, title, folder, filters, *options):
        self.folder = folder
        return self

    def ready(self, timeout=0):
        self.asked += 1
        return self.asked > 2  # open for two frames, as a person takes time to choose

    def result(self):
        return self.chosen


def test_open_button_opens_the_file_the_dialog_chose(open_viewer, monkeypatch, tmp_path):
    from testkit import write_inria_ply

    from raygs_viewer.viewer import file_dialog

    scene = write_inria_ply(tmp_path / "chosen.ply", n=7)
    dialog = _Dialog([str(scene)])
    monkeypatch.setattr(file_dialog, "dialog_problem", lambda: None)
    monkeypatch.setattr(file_dialog.pfd, "open_file", dialog)
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.click("Open...")
    assert viewer.file_dialog.open
    drive.frames(4)
    drive.wait_for_load()
    assert viewer.loaded.scene.count == 7 and viewer.panel.open_path == str(scene)
    assert not viewer.file_dialog.open


def test_without_a_dialog_program_open_says_so_and_keeps_the_typed_path(open_viewer, monkeypatch):
    from raygs_viewer.viewer import file_dialog

    monkeypatch.setattr(file_dialog.shutil, "which", lambda program: None)
    monkeypatch.setattr(file_dialog.sys, "platform", "linux")
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    viewer.panel.open_path = "typed/so/far.ply"
    drive.frames(2)
    drive.click("Open...")
    assert viewer.panel.error == ("error: no file dialog here (it needs zenity or kdialog): type the scene's "
                                  "path and press Enter")
    assert viewer.panel.open_path == "typed/so/far.ply" and not viewer.file_dialog.open


def test_the_window_starts_at_a_screenshot_s_view(open_viewer, tmp_path):
    """view --camera SHOT.json: the view of a screenshot, to go on from."""
    import json

    from testkit import demo_sidecar, window_camera

    shot = tmp_path / "shot.json"
    camera = window_camera(64, 48)
    shot.write_text(json.dumps(demo_sidecar(camera=camera)))
    viewer, drive = open_viewer(hide_panel=True, camera=str(shot))
    drive.frames(1)
    np.testing.assert_allclose(viewer.camera.R, camera.R, atol=1e-12)
    np.testing.assert_allclose(viewer.camera.center, camera.center, atol=1e-9)
