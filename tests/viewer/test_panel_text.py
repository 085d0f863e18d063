"""Panel text is never silently cut at the panel's edge: every line of text the panel
draws ends inside its window (long ones wrap), in the states that make the longest lines."""

from __future__ import annotations

from appkit import PANEL_HEIGHT, PANEL_WIDTH, text_past_the_panel


def test_no_panel_text_runs_past_the_panel(open_viewer):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(3)
    # The longest lines: an order while the view turns, a long message and error.
    viewer.panel.message = "saved /a/rather/long/folder/name/that/people/have/screenshots/raygs-20261128-000000.png"
    viewer.panel.error = ("error: nothing to pick there: that pixel's alpha never reaches 0.5 along its ray "
                          "(the scene is too faint or absent there)")
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
