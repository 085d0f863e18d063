"""What the view shows, weighed beside the frames, with real input through the window:
a rectangle weighed over many frames while the view goes on drawing (the camera moves
and the image changes meanwhile), selecting the float64 truth of the camera it was
drawn on; Escape cancels one with nothing changed and the window open; undo and redo
after a finished one; a new scene drops one under way."""

from __future__ import annotations

import numpy as np
import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, click_choice, window_image
from edit_kit import chord, drag, on_view, rectangle_tool, rich_rows, weighed, write_rows
from imgui_bundle import imgui

from raygs_viewer.render.contributions import max_weights
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

Key = imgui.Key
#: A slice's time so small that every slice after the first weighs one row: a selection
#: spans as many frames as its rows, whatever this machine's speed.
TINY_SLICE = 1e-9
MIN_WEIGHT = 0.05


@pytest.fixture
def crowd(tmp_path):
    """Overlapping gaussians in front of one another, filling the view."""
    rows = rich_rows(n=500, seed=8, filter_3d=False, invalid=())
    rng = np.random.default_rng(8)
    rows["x"], rows["y"], rows["z"] = (rng.uniform(-1, 1, rows.size).astype(np.float32) for _ in range(3))
    for a in range(3):
        rows[f"scale_{a}"] = np.log(rng.uniform(0.04, 0.12, rows.size))
    rows["opacity"] = rng.uniform(-1.0, 3.0, rows.size)
    return write_rows(tmp_path / "crowd.ply", rows)


def truth(viewer, shape):
    """The rows the float64 weighing selects through ``shape`` (on its own camera), and
    those within 1e-4 of the threshold (either answer is right for them)."""
    scene, settings, inside = viewer.loaded.scene, viewer.settings, shape.pixel_mask()
    order = exact_order(DepthSorter(scene), shape.camera, settings)  # the view's order
    weights = max_weights(scene, shape.camera, settings, order.indices, inside)
    return weights >= MIN_WEIGHT, np.abs(weights - MIN_WEIGHT) < 1e-4


def visible_rectangle(viewer, drive):
    rectangle_tool(drive)
    drive.reveal("selects##edit")
    click_choice(drive, "selects##edit", "what the view shows")
    viewer.edit_tool.slice_seconds = TINY_SLICE
    drive.settle()


def test_a_selection_weighs_over_many_frames_while_the_view_goes_on(open_viewer, crowd):
    viewer, drive = open_viewer(str(crowd), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    visible_rectangle(viewer, drive)
    tool = viewer.edit_tool
    drag(drive, on_view(viewer, (0.2, 0.45), (0.5, 0.5), (0.8, 0.53)))
    weighing = tool.weighing
    assert weighing is not None and not tool.edits.selection.any()  # nothing yet: it runs beside the frames
    shape = weighing.shape
    before, camera = window_image(viewer).copy(), viewer.camera
    drive.key(Key.w, True)  # fly forward while it weighs
    seen = []
    for _ in range(5):
        drive.frames(1)
        seen.append(tool.weighing is not None)
    drive.key(Key.w, False)
    drive.frames(1)
    assert all(seen) and tool.weighing is not None  # still weighing after six frames
    assert not np.allclose(viewer.camera.t, camera.t)  # the view flew on
    assert np.abs(window_image(viewer) - before).max() > 0.1  # and was drawn anew
    progress = tool.weighing.progress
    assert 0.0 < progress < 1.0
    weighed(drive, viewer, most=2000)
    assert weighing.slices > 10
    expected, band = truth(viewer, shape)  # the camera the shape was drawn on, not the one flown to
    selected = tool.edits.selection
    assert expected.sum() > 20 and not (selected ^ expected)[~band].any()

    chord(drive, Key.mod_ctrl, Key.z)
    assert not tool.edits.selection.any()
    chord(drive, Key.mod_ctrl, Key.y)
    np.testing.assert_array_equal(tool.edits.selection, selected)


def test_escape_cancels_a_selection_under_way_with_nothing_changed(open_viewer, crowd):
    viewer, drive = open_viewer(str(crowd), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    visible_rectangle(viewer, drive)
    tool = viewer.edit_tool
    drag(drive, on_view(viewer, (0.3, 0.45), (0.6, 0.5)))
    weighed(drive, viewer, most=2000)
    selected, generation, undoable = tool.edits.selection.copy(), tool.edits.generation, tool.edits.can_undo()
    drag(drive, on_view(viewer, (0.1, 0.1), (0.9, 0.9)))
    drive.frames(2)
    assert tool.weighing is not None and tool.weighing.progress < 0.5
    drive.tap(Key.escape)
    drive.frames(1)
    assert tool.weighing is None and not viewer.window.should_close  # Escape cancelled: it did not quit
    assert tool.edits.generation == generation and tool.edits.can_undo() == undoable
    np.testing.assert_array_equal(tool.edits.selection, selected)
    chord(drive, Key.mod_ctrl, Key.z)  # the undo step is the finished selection's, not the cancelled one's
    assert not tool.edits.selection.any()

    drag(drive, on_view(viewer, (0.1, 0.1), (0.9, 0.9)))
    drive.frames(2)
    drive.reveal("Cancel##weighing")
    drive.click("Cancel##weighing")
    assert tool.weighing is None and not tool.edits.selection.any()


def test_a_scene_opened_while_a_selection_weighs_drops_it_with_a_message(open_viewer, crowd):
    viewer, drive = open_viewer(str(crowd), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    visible_rectangle(viewer, drive)
    drag(drive, on_view(viewer, (0.1, 0.1), (0.9, 0.9)))
    drive.frames(1)
    assert viewer.edit_tool.weighing is not None
    viewer.drop(["demo"])  # nothing deleted: it opens at once
    drive.wait_for_load()
    assert viewer.loaded.source.is_demo and viewer.edit_tool.weighing is None
    assert "selection dropped: the scene changed" in viewer.panel.message
    assert not viewer.edit_tool.edits.selection.any()  # never applied to the new scene's rows
