"""Panel text is never silently cut at the panel's edge: every line of text the panel
draws ends inside its window (long ones wrap), in the states that make the longest lines."""

from __future__ import annotations

import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, text_past_the_panel

from raygs_viewer.viewer import app as viewer_app
from raygs_viewer.viewer.layout import MIN_PANEL_WIDTH
from raygs_viewer.viewer.panel.widgets import labelled_progress
from raygs_viewer.viewer.panel_sections import quiet
from raygs_viewer.viewer.state import failed, note


def test_no_panel_text_runs_past_the_panel(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(3)
    # The longest lines: an order while the view turns, a long message and error.
    viewer.panel.say(note("saved /a/rather/long/folder/name/that/people/have/screenshots/raygs-20261128-000000.png"),
                     failed("nothing to pick there: that pixel's alpha never reaches 0.5 along its ray "
                            "(the scene is too faint or absent there)"))
    drive.move_mouse(PANEL_WIDTH - 20, PANEL_HEIGHT / 2)
    drive.button(0, True)
    drive.frames(1)
    for step in range(3):
        drive.move_mouse(PANEL_WIDTH - 20 - 10 * (step + 1), PANEL_HEIGHT / 2)
        drive.frames(1)
    cut = text_past_the_panel(drive)
    assert cut == [], "\n".join(cut)
    drive.button(0, False)
    drive.frames(1)


@pytest.mark.parametrize("mode", ["stereo", "split"])
def test_nothing_is_cut_in_every_section_of_the_narrowest_panel(open_viewer, monkeypatch, mode):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=3 * PANEL_HEIGHT)
    viewer.panel.width = MIN_PANEL_WIDTH  # the width it opens with (remembered)
    viewer.stereo.on = mode == "stereo"
    viewer.split.on = mode == "split"
    viewer.measure.on = True
    drive.frames(2)
    for closed in ("Measure", "Training cameras (6)###training"):
        drive.click(closed)
    # A progress bar with a load's longest stage, as the Scene and Level of detail sections show one.
    sections = viewer_app.panel_sections
    monkeypatch.setattr(viewer_app, "panel_sections", lambda window, draft: sections(window, draft) + [
        quiet(lambda: labelled_progress(0.25, "reading level 3 of 5: 1,234,567 of 2,345,678 gaussians"))])
    drive.frames(3)
    assert viewer.panel.width == MIN_PANEL_WIDTH
    assert "replace file##measure" in drive.panel and ("Stereo" in drive.panel or mode != "stereo")
    assert "25 %" in drive.panel.labels("progress_bar")  # the label above the bar, which says how far
    cut = text_past_the_panel(drive)
    assert cut == [], "\n".join(cut)


def test_a_choice_cut_in_its_box_is_named_whole_on_hover(open_viewer, monkeypatch):
    from imgui_bundle import imgui

    from raygs_viewer.camera.stereo import PRESETS
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=2 * PANEL_HEIGHT)
    viewer.panel.width = MIN_PANEL_WIDTH
    viewer.stereo.on = True
    drive.frames(2)
    tips = []
    set_tooltip = imgui.set_tooltip
    monkeypatch.setattr(imgui, "set_tooltip", lambda text: (tips.append(text), set_tooltip(text)))
    quest = PRESETS["quest3"]
    whole = f"{quest.label}: {quest.width}x{quest.height}, {quest.fov_x:g}x{quest.fov_y:g} deg"
    x0, y0, x1, y1 = drive.panel.rect("headset")
    drive.move_mouse(x0 + 10, (y0 + y1) / 2)
    drive.frames(2)
    assert whole in tips
    # A choice that fits is not named again (the combo's own help is still shown).
    tips.clear()
    x0, y0, x1, y1 = drive.panel.rect("order")
    drive.move_mouse(x0 + 10, (y0 + y1) / 2)
    drive.frames(2)
    assert tips and "depth" not in tips
