"""The view area: the window minus the panel (viewer.layout), the panel resized by hand
and remembered from one run to the next (viewer.remembered)."""

from __future__ import annotations

import json

import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, headless, window_image
from imgui_bundle import imgui
from testkit import assert_matches

from raygs_viewer.viewer.layout import MIN_PANEL_WIDTH, MIN_VIEW_SHARE, PANEL_WIDTH as DEFAULT_PANEL, view_area
from raygs_viewer.viewer.remembered import Remembered, remembered_path


def test_the_view_area_is_the_window_beside_the_panel():
    assert view_area((1280, 720), None) == (0, 0, 1280, 720)
    assert view_area((1280, 720), 360.0) == (360, 0, 920, 720)
    assert view_area((2560, 1440), 360.0, scale=2.0) == (720, 0, 1840, 1440)  # screen units to pixels
    # Too narrow for both: the view keeps the whole window rather than a sliver beside the panel.
    assert view_area((500, 400), 360.0) == (0, 0, 500, 400)
    assert view_area((0, 0), None) == (0, 0, 1, 1)


def drag(drive, start, end, steps=4):
    drive.move_mouse(*start)
    drive.frames(2)
    drive.button(0, True)
    drive.frames(1)
    for i in range(1, steps + 1):
        drive.move_mouse(start[0] + (end[0] - start[0]) * i / steps, start[1] + (end[1] - start[1]) * i / steps)
        drive.frames(1)
    drive.button(0, False)
    drive.frames(2)


def test_the_view_is_laid_out_beside_the_panel_and_takes_the_window_without_it(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    viewer.frustums.show = False  # the window's image is compared with the scene alone
    drive.settle()
    panel = round(viewer.panel.width)
    assert panel == DEFAULT_PANEL
    assert viewer.viewport == (panel, 0, PANEL_WIDTH - panel, PANEL_HEIGHT)
    assert (viewer.camera.width, viewer.camera.height) == (PANEL_WIDTH - panel, PANEL_HEIGHT)
    viewer.captures.keep_next = True
    drive.frames(1)
    assert_matches(window_image(viewer), headless(viewer))
    shown = viewer.captures.window.astype(int)
    assert (abs(shown[:, panel:] - (window_image(viewer)[..., :3].clip(0, 1) * 255).round()).max()) <= 1
    # The split view's divider and labels lie in the view, none under the panel.
    viewer.split.on = True
    drive.settle()
    assert viewer.overlay_rects and all(x0 >= panel for x0, _, _, _ in viewer.overlay_rects.values())
    viewer.split.on = False
    # Hidden (H, the pointer over the view): the whole window.
    drive.move_mouse(PANEL_WIDTH - 5, PANEL_HEIGHT - 5)
    drive.tap(imgui.Key.h)
    drive.settle()
    assert not viewer.panel.show_panel and viewer.viewport == (0, 0, PANEL_WIDTH, PANEL_HEIGHT)


def test_the_panel_resized_by_hand_moves_the_view_and_is_remembered(open_viewer, config_home, capsys):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.settle()
    before = viewer.panel.width
    # Its right edge dragged 30 px to the left, and then far past its narrowest.
    drag(drive, (before - 1, PANEL_HEIGHT / 2), (before - 31, PANEL_HEIGHT / 2))
    assert viewer.panel.width == pytest.approx(before - 30, abs=2)
    width = round(viewer.panel.width)
    assert viewer.viewport == (width, 0, PANEL_WIDTH - width, PANEL_HEIGHT)
    drag(drive, (viewer.panel.width - 1, PANEL_HEIGHT / 2), (100, PANEL_HEIGHT / 2))
    assert viewer.panel.width == MIN_PANEL_WIDTH
    width = round(viewer.panel.width)
    assert viewer.viewport == (width, 0, PANEL_WIDTH - width, PANEL_HEIGHT)
    assert json.loads(remembered_path().read_text()) == {"panel_width": round(viewer.panel.width, 1)}
    assert remembered_path().is_relative_to(config_home)
    # The next window opens with it.
    remembered_width = viewer.panel.width
    viewer.close()
    again, drive_again = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive_again.frames(2)
    assert again.panel.width == pytest.approx(remembered_width, abs=0.1)
    assert again.viewport[0] == width
    assert capsys.readouterr().err == ""
    # Never wider than leaves the view its share of the window.
    drag(drive_again, (again.panel.width - 1, PANEL_HEIGHT / 2), (PANEL_WIDTH - 10, PANEL_HEIGHT / 2))
    assert again.panel.width == pytest.approx((1 - MIN_VIEW_SHARE) * PANEL_WIDTH, abs=1)
    assert again.viewport[0] == round(again.panel.width)
    assert json.loads(remembered_path().read_text()) == {"panel_width": round(again.panel.width, 1)}
    # A smaller window clamps the width it opens with, and the remembered one stays.
    again.close()
    small, drive_small = open_viewer(width=PANEL_WIDTH // 2, height=PANEL_HEIGHT)
    drive_small.frames(3)
    assert small.panel.width < again.panel.width
    assert json.loads(remembered_path().read_text()) == {"panel_width": round(again.panel.width, 1)}


@pytest.mark.parametrize("content", ["not json", '{"panel_width": "wide"}', '{"panel_width": 1e9}', "[]"])
def test_a_remembered_layout_that_cannot_be_used_is_said_once_and_the_default_taken(config_home, capsys, content):
    path = remembered_path()
    path.parent.mkdir(parents=True)
    path.write_text(content)
    remembered = Remembered()
    assert remembered.panel_width == DEFAULT_PANEL
    err = capsys.readouterr().err
    assert err.startswith("warning: the window's remembered layout is not used: ") and err.count("\n") == 1
    # Another width is written over it (the file is ours to keep).
    remembered.keep(MIN_PANEL_WIDTH + 10)
    assert json.loads(path.read_text()) == {"panel_width": MIN_PANEL_WIDTH + 10}


def test_a_folder_that_cannot_be_written_is_said_once(config_home, capsys):
    (config_home / "raygs-viewer").write_text("a file where the folder goes")
    remembered = Remembered()
    remembered.keep(400.0)
    remembered.keep(410.0)
    err = capsys.readouterr().err
    assert err.startswith("warning: the panel's width is not remembered: ") and err.count("\n") == 1
    assert remembered.panel_width == DEFAULT_PANEL
