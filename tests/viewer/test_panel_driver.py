"""The test-side driver's record of the panel (tests/appkit.py): how a test names a
widget, and that a name fits exactly one widget of the last frame or fails loudly."""

from __future__ import annotations

import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, Panel, Widget, label_names, open_viewer_factory
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)


def panel_of(*widgets: Widget) -> Panel:
    panel = Panel()
    panel.widgets.extend(widgets)
    return panel


def test_a_widget_answers_to_its_label_its_visible_text_and_its_id():
    assert label_names("button", "Save##path") == {"Save##path", "Save", "##path"}
    assert label_names("button", "Play###play") == {"Play###play", "Play", "###play"}
    assert label_names("slider_float", "##scrub") == {"##scrub"}
    assert label_names("button", "Open") == {"Open"}
    # Text has no id: "##" in it is text.
    assert label_names("text_disabled", "a ## b") == {"a ## b"}
    assert label_names("progress_bar", "") == set()


def test_a_name_never_drawn_or_drawn_twice_is_an_error_naming_what_was_drawn():
    panel = panel_of(Widget("button", "Save##path", (0, 0, 10, 10)),
                     Widget("button", "Save##shot", (0, 20, 10, 30)),
                     Widget("checkbox", "overwrite", (20, 0, 30, 10)))
    assert panel.rect("overwrite") == (20, 0, 30, 10)
    assert panel.rect("Save##shot") == (0, 20, 10, 30)
    with pytest.raises(KeyError, match="'Load' fits 0 widgets.*'Save##path', 'Save##shot', 'overwrite'"):
        panel.rect("Load")
    with pytest.raises(KeyError, match=r"'Save' fits 2 widgets.*\['Save##path', 'Save##shot'\]"):
        panel.rect("Save")
    assert "Save" in panel and "Load" not in panel


def test_combo_entries_are_named_within_their_combo_only():
    panel = panel_of(Widget("selectable", "RayGS", (0, 40, 50, 50), within="mode"),
                     Widget("selectable", "GS (EWA)", (0, 50, 50, 60), within="mode"),
                     Widget("begin_combo", "mode", (0, 20, 50, 30)),
                     Widget("text", "RayGS", (0, 0, 50, 10)))
    assert panel.rect("RayGS", within="mode") == (0, 40, 50, 50)
    assert panel.rect("RayGS") == (0, 0, 50, 10)  # the window's text, not the popup's entry
    assert "GS (EWA)" not in panel
    with pytest.raises(KeyError, match="'GS' fits 0 widgets drawn in the popup of 'mode'"):
        panel.rect("GS", within="mode")
    with pytest.raises(KeyError, match=r"'order' fits 0 combos open.*\['mode'\]"):
        panel.rect("depth", within="order")


def test_the_driver_records_each_frame_of_the_real_panel(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(1)
    assert "Reset view (R)" in drive.panel and "white" in drive.panel
    x0, y0, x1, y1 = drive.panel.rect("Reset view (R)")
    assert 0 <= x0 < x1 <= PANEL_WIDTH and 0 <= y0 < y1 <= PANEL_HEIGHT
    # An open combo's entries are recorded within it, and only while it is open.
    assert [w for w in drive.panel.widgets if w.within is not None] == []
    closed = drive.panel.rect("mode")
    drive.click("mode")
    drive.frames(1)
    assert [w.label for w in drive.panel.widgets if w.within == "mode"] == ["RayGS", "RayGS exact MIP", "GS (EWA)"]
    assert drive.panel.rect("mode") == closed  # open, the combo itself is still where it was
    assert "GS (EWA)" not in drive.panel
    drive.click(drive.panel.rect("GS (EWA)", within="mode"))
    assert viewer.settings.mode == "gs"
    drive.frames(1)  # the popup closes the frame after the pick
    assert [w for w in drive.panel.widgets if w.within is not None] == []
    # Only the last frame counts: a hidden panel leaves nothing to click.
    viewer.panel.show_panel = False
    drive.frames(1)
    assert drive.panel.widgets == []
    with pytest.raises(KeyError):
        drive.click("Reset view (R)")


def test_the_recording_wrappers_come_off_imgui_with_the_viewers(tmp_path):
    button, end_combo = imgui.button, imgui.end_combo
    _, close_all = open_viewer_factory(tmp_path)
    assert imgui.button is not button and imgui.end_combo is not end_combo
    close_all()
    assert imgui.button is button and imgui.end_combo is end_combo
