"""Cleaning a scene in the window, through real input in the window loop: a rectangle, a
brush and a lasso drawn with the mouse, a histogram range dragged, a box crop, Delete,
Ctrl+Z / Ctrl+Y, and the export; each against a numpy truth on a scene made for the test.
The picture the window draws after a delete is the scene without those gaussians, the
selection is tinted in it, and a screenshot of an edited scene re-renders from its
sidecar to the same image."""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, click_choice, window_image
from edit_kit import chord, drag, on_view, rectangle_tool, rich_rows, weighed, write_rows
from imgui_bundle import imgui
from PIL import Image
from plyfile import PlyData
from testkit import assert_matches, run_cli

from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.edits import Operation, replay
from raygs_viewer.scene.filters import CropBox, KeepValues
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.viewer.edit_export import edit_document

Key = imgui.Key


@pytest.fixture
def scene_file(tmp_path):
    rows = rich_rows(n=600, seed=21, filter_3d=False, invalid=())
    rows["opacity"] = np.abs(rows["opacity"]) + 1.0  # opaque enough that every deletion shows
    for a in range(3):
        rows[f"scale_{a}"] = np.log(np.random.default_rng(a).uniform(0.02, 0.08, rows.size))
    return write_rows(tmp_path / "room.ply", rows), rows


def pixels_of(viewer, points):
    """Screen points as the drawn camera's continuous pixels (the framebuffer scale is 1)."""
    camera, (vx, vy, vw, vh) = viewer.camera, viewer.viewport
    return np.array([((x - vx) / vw * camera.width, (y - vy) / vh * camera.height) for x, y in points])


def projected(viewer):
    """(N, 2) pixel positions of the centres, (N,) in front: written here, not taken from the tool."""
    camera, positions = viewer.camera, viewer.loaded.scene.positions.astype(np.float64)
    mu = positions @ camera.R.T + camera.t
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = np.stack([camera.fx * mu[:, 0] / mu[:, 2] + camera.cx, camera.fy * mu[:, 1] / mu[:, 2] + camera.cy], 1)
    return uv, mu[:, 2] > 0


def without(viewer, deleted):
    """The window's view drawn from a scene that never held the ``deleted`` gaussians."""
    scene = viewer.loaded.scene.rows(~deleted)
    renderer = GLRenderer(viewer.ctx, scene)
    try:
        return renderer.render(viewer.camera, viewer.settings, exact_order(DepthSorter(scene), viewer.camera,
                                                                          viewer.settings)).copy()
    finally:
        renderer.release()


def test_a_rectangle_selects_the_centres_inside_and_delete_undo_redo_act_on_them(open_viewer, scene_file):
    viewer, drive = open_viewer(str(scene_file[0]), hide_panel=True)
    drive.settle()
    before = window_image(viewer).copy()
    viewer.edit_tool.tool = "rectangle"
    corners = on_view(viewer, (0.38, 0.35), (0.5, 0.45), (0.62, 0.6))
    drag(drive, corners)
    (u0, v0), (u1, v1) = pixels_of(viewer, [corners[0], corners[-1]])
    uv, front = projected(viewer)
    truth = front & (uv[:, 0] >= u0) & (uv[:, 0] <= u1) & (uv[:, 1] >= v0) & (uv[:, 1] <= v1)
    assert 40 < truth.sum() < 500
    np.testing.assert_array_equal(viewer.edit_tool.edits.selection, truth)
    drive.settle()
    assert np.abs(window_image(viewer) - before).max() > 0.1  # the selection is tinted in the picture

    drive.tap(Key.delete)
    drive.settle()
    np.testing.assert_array_equal(viewer.edit_tool.edits.deleted, truth)
    assert viewer.edit_tool.selection_count() == 0
    gone = window_image(viewer).copy()
    assert_matches(gone, without(viewer, truth))
    assert np.abs(gone - before).max() > 0.1

    chord(drive, Key.mod_ctrl, Key.z)  # undo the delete: the selection is back, tinted
    drive.settle()
    assert not viewer.edit_tool.edits.deleted.any()
    np.testing.assert_array_equal(viewer.edit_tool.edits.selection, truth)
    chord(drive, Key.mod_ctrl, Key.z)  # undo the selection: the picture as it was
    drive.settle()
    assert_matches(window_image(viewer), before)
    chord(drive, Key.mod_ctrl, Key.y)
    chord(drive, Key.mod_ctrl, Key.mod_shift, Key.z)
    drive.settle()
    np.testing.assert_array_equal(viewer.edit_tool.edits.deleted, truth)
    assert_matches(window_image(viewer), gone)


def test_the_drag_draws_instead_of_turning_the_camera_and_modifiers_combine(open_viewer, scene_file):
    viewer, drive = open_viewer(str(scene_file[0]), hide_panel=True)
    drive.settle()
    camera = viewer.camera
    x, y, w, h = viewer.viewport
    viewer.edit_tool.tool = "brush"
    viewer.edit_tool.brush_radius = 12.0
    stroke = on_view(viewer, (0.2, 0.5), (0.5, 0.55), (0.8, 0.5))
    drag(drive, stroke)
    assert np.array_equal(viewer.camera.R, camera.R) and np.array_equal(viewer.camera.t, camera.t)
    uv, front = projected(viewer)
    line = pixels_of(viewer, stroke)
    radius = 12.0 * camera.width / w

    def near(a, b):
        d = b - a
        t = np.clip(((uv - a) @ d) / (d @ d), 0, 1)
        return np.linalg.norm(uv - (a + t[:, None] * d), axis=1) <= radius

    brushed = front & (near(line[0], line[1]) | near(line[1], line[2]))
    assert 20 < brushed.sum() < 400
    np.testing.assert_array_equal(viewer.edit_tool.edits.selection, brushed)

    viewer.edit_tool.tool = "lasso"
    triangle = on_view(viewer, (0.1, 0.1), (0.6, 0.1), (0.1, 0.9))
    drag(drive, triangle, Key.mod_ctrl)  # Ctrl: subtract
    (a, b, c) = pixels_of(viewer, triangle)
    # Inside the right triangle a-b-c: right of a's column, below a's row, left of the hypotenuse b-c.
    cross = (c[0] - b[0]) * (uv[:, 1] - b[1]) - (c[1] - b[1]) * (uv[:, 0] - b[0])
    inside = front & (uv[:, 0] > a[0]) & (uv[:, 1] > a[1]) & (cross > 0)
    assert (brushed & inside).any() and (brushed & ~inside).any()
    np.testing.assert_array_equal(viewer.edit_tool.edits.selection, brushed & ~inside)


def test_a_drag_across_the_histogram_selects_that_range_of_opacity(open_viewer, scene_file):
    viewer, drive = open_viewer(str(scene_file[0]), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.reveal("Edit")
    drive.click("Edit")
    drive.frames(1)
    drive.reveal("##histogram")
    drive.frames(1)
    x0, y0, x1, y1 = drive.panel.rect("##histogram")
    start, stop = float(round(x0 + 0.4 * (x1 - x0))), float(round(x0 + 0.9 * (x1 - x0)))
    middle = float(round((y0 + y1) / 2))
    drag(drive, [(start, middle), (float(round((start + stop) / 2)), middle), (stop, middle)])
    opacity = viewer.loaded.scene.opacities.astype(np.float64)
    low, high = opacity.min(), opacity.max()
    a, b = (low + (p - x0) / (x1 - x0) * (high - low) for p in (start, stop))
    truth = (opacity >= a) & (opacity <= b)
    assert 0 < truth.sum() < opacity.size
    np.testing.assert_array_equal(viewer.edit_tool.edits.selection, truth)


def test_crop_to_the_box_and_export_write_the_kept_rows_bit_for_bit(open_viewer, scene_file, tmp_path, capsys):
    source, rows = scene_file
    viewer, drive = open_viewer(str(source), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.reveal("Edit")
    drive.click("Edit")
    drive.frames(1)
    tool = viewer.edit_tool
    tool.box = type(tool.box)((-1.0, -1.5, -2.0), (1.5, 1.0, 0.5))
    drive.reveal("Crop to box")
    drive.click("Crop to box")
    kept = CropBox((-1.0, -1.5, -2.0), (1.5, 1.0, 0.5)).keeps(KeepValues.of_scene(viewer.loaded.scene))
    assert 50 < kept.sum() < 550
    np.testing.assert_array_equal(~tool.edits.deleted, kept)
    drive.settle()
    assert_matches(window_image(viewer), without(viewer, ~kept))

    target = tmp_path / "clean.ply"
    tool.exporter.file = str(target)
    drive.reveal("Export")
    drive.click("Export")
    viewer.panel.say(tool.exporter.wait())  # written on a thread of its own
    written = PlyData.read(str(target))["vertex"].data
    assert written.tobytes() == rows[np.flatnonzero(kept)].tobytes()
    document = tmp_path / "clean.edits.json"
    assert json.loads(document.read_text())["operations"] == [
        {"op": "crop", "shape": {"kind": "box", "low": [-1.0, -1.5, -2.0], "high": [1.5, 1.0, 0.5]}}]

    first = target.read_bytes()
    tool.apply(type(tool.edits.operations[0])("undelete all"), viewer.loaded.scene)
    drive.click("Export")  # the file exists: nothing is written until Replace
    assert tool.exporter.confirm_replace == str(target) and target.read_bytes() == first
    assert f"{target} and {document} exist: replace them?" in drive.panel.labels()
    drive.reveal("Cancel##export")
    drive.click("Cancel##export")
    assert tool.exporter.confirm_replace is None and target.read_bytes() == first
    # Another format beside it shares the edit document's name: that is what the question names.
    tool.exporter.file = str(tmp_path / "clean.splat")
    drive.frames(3)  # the question's lines gone, the panel's scroll settles
    drive.reveal("Export")
    drive.click("Export")
    assert tool.exporter.confirm_replace == str(tmp_path / "clean.splat")
    assert f"{document} exists: replace it?" in drive.panel.labels()
    assert not (tmp_path / "clean.splat").exists()
    drive.reveal("Cancel##export")
    drive.click("Cancel##export")

    replayed = tmp_path / "replayed.ply"
    code, out, err = run_cli(capsys, "convert", source, replayed, "--edits", document)
    assert code == 0, err
    assert replayed.read_bytes() == first


def test_an_edited_screenshot_renders_again_from_its_sidecar(open_viewer, scene_file, tmp_path, capsys):
    viewer, drive = open_viewer(str(scene_file[0]), hide_panel=True)
    drive.settle()
    tool = viewer.edit_tool
    tool.select(type(tool.box)((-2.5, -2.5, -2.5), (0.0, 2.5, 2.5)), viewer.loaded.scene)
    tool.apply(type(tool.edits.operations[0])("delete"), viewer.loaded.scene)
    drive.settle()
    png, sidecar = viewer.save_screenshot(tmp_path / "shot.png")
    recorded = json.loads(sidecar.read_text())
    assert recorded["version"] == 5 and recorded["edits"]["operations"][1] == {"op": "delete"}
    # The path the window saves or renders a video from carries the same edits (render-path honours them).
    assert viewer.camera_path.document(viewer.path_scene()).edits["operations"] == recorded["edits"]["operations"]
    again = tmp_path / "again.png"
    code, out, err = run_cli(capsys, "render", "--sidecar", sidecar, "--out", again)
    assert code == 0, err
    assert again.read_bytes() == png.read_bytes()
    reference = tmp_path / "reference.png"  # the float64 reference leaves the same rows out
    code, out, err = run_cli(capsys, "render", "--sidecar", sidecar, "--reference", "--out", reference)
    assert code == 0, err
    assert f"({int(tool.edits.deleted.sum())} deleted)" in out
    shot, drawn = (np.asarray(Image.open(path)).astype(int) for path in (png, reference))
    assert np.abs(shot - drawn).max() <= 3
    deleted = DeletedRows(tool.edits.deleted)
    assert viewer.shown.sort.deleted.key == deleted.key  # the frame's sort leaves them out


@pytest.fixture
def occluded(tmp_path):
    """On the view's axis a wide opaque gaussian in front of a small one; four more at the
    corners frame the scene (the view looks along +z at the centre of the centres)."""
    rows = rich_rows(n=6, seed=2, filter_3d=False, invalid=())
    centres = [(0, 0, -0.5), (0, 0, 0.5), (-1.2, -0.9, 0), (1.2, -0.9, 0), (-1.2, 0.9, 0), (1.2, 0.9, 0)]
    for name, column in zip("xyz", np.array(centres, np.float32).T):
        rows[name] = column
    for a in range(3):
        rows[f"scale_{a}"] = np.log([0.25, 0.08, 0.05, 0.05, 0.05, 0.05])
    rows["opacity"] = [4.0, 2.2, 2.0, 2.0, 2.0, 2.0]  # 0.982 and 0.900 as rendered
    rows["rot_0"], rows["rot_1"], rows["rot_2"], rows["rot_3"] = 1, 0, 0, 0
    return write_rows(tmp_path / "occluded.ply", rows)


def screen_of(viewer, u, v):
    camera, (vx, vy, vw, vh) = viewer.camera, viewer.viewport
    return float(round(vx + u / camera.width * vw)), float(round(vy + v / camera.height * vh))


def test_visible_selection_and_a_click_take_what_the_view_shows_not_what_it_covers(open_viewer, occluded):
    viewer, drive = open_viewer(str(occluded), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    rectangle_tool(drive)
    drive.settle()
    uv, front = projected(viewer)
    assert front.all() and np.abs(uv[0] - uv[1]).max() < 0.5  # the two centres on one pixel
    (cu, cv) = uv[0]
    box = [screen_of(viewer, cu - 9, cv - 9), screen_of(viewer, cu, cv), screen_of(viewer, cu + 9, cv + 9)]
    drag(drive, box)
    assert np.flatnonzero(viewer.edit_tool.edits.selection).tolist() == [0, 1]  # through: both centres

    drive.reveal("selects##edit")
    click_choice(drive, "selects##edit", "what the view shows")
    assert viewer.edit_tool.selects == "visible"
    drag(drive, box)
    weighed(drive, viewer)
    # The front one gives 0.98 of the centre pixel; the one it hides at most (1 - 0.98) * 0.9.
    assert np.flatnonzero(viewer.edit_tool.edits.selection).tolist() == [0]

    click_choice(drive, "tool##edit", "click")
    drive.click_at(*screen_of(viewer, cu, cv))
    weighed(drive, viewer)
    assert np.flatnonzero(viewer.edit_tool.edits.selection).tolist() == [0]
    drive.tap(Key.delete)
    drive.settle()
    assert np.flatnonzero(viewer.edit_tool.edits.deleted).tolist() == [0]
    drive.click_at(*screen_of(viewer, cu, cv))  # the deleted one shows no more: the one behind it does
    weighed(drive, viewer)
    assert np.flatnonzero(viewer.edit_tool.edits.selection).tolist() == [1]
    operations = edit_document(viewer.loaded, viewer.edit_tool.edits).operations
    assert operations[-1].shape.to_json()["found by"] == "top"
    again = replay(viewer.loaded.scene, [Operation.from_json(json.loads(json.dumps(op.to_json())))
                                         for op in operations])
    np.testing.assert_array_equal(again.selected, viewer.edit_tool.edits.selected)
    np.testing.assert_array_equal(again.deleted, viewer.edit_tool.edits.deleted)

    chord(drive, Key.mod_ctrl, Key.z)
    chord(drive, Key.mod_ctrl, Key.z)
    assert not viewer.edit_tool.edits.deleted.any()
    assert np.flatnonzero(viewer.edit_tool.edits.selection).tolist() == [0]


def test_opening_another_scene_over_edits_not_exported_asks_first(open_viewer, scene_file, tmp_path):
    viewer, drive = open_viewer(str(scene_file[0]), hide_panel=True)
    drive.settle()
    tool = viewer.edit_tool
    tool.select(type(tool.box)((-2.5, -2.5, -2.5), (0.0, 2.5, 2.5)), viewer.loaded.scene)
    tool.apply(Operation("delete"), viewer.loaded.scene)
    deleted = tool.deleted_count()
    viewer.drop(["demo"])
    drive.frames(2)
    assert not viewer.scenes.loader.busy and viewer.loaded.path == str(scene_file[0])
    assert viewer.panel.error == (f"error: not opened: the edits of the scene shown ({deleted:,} deleted) are not "
                                  "exported; export them, or open it again to leave them")
    tool.exporter.file = str(tmp_path / "kept.ply")
    assert tool.exporter.export(tool.edits, viewer.loaded)[0].kind == "done"
    tool.exporter.wait()
    viewer.drop(["demo"])  # exported: nothing is lost, it opens at once
    drive.wait_for_load()
    assert viewer.loaded.source.is_demo and viewer.panel.error == ""
    tool.select(type(tool.box)((-9.0, -9.0, -9.0), (0.0, 9.0, 9.0)), viewer.loaded.scene)
    tool.apply(Operation("delete"), viewer.loaded.scene)
    viewer.drop([str(scene_file[0])])
    drive.frames(1)
    assert viewer.loaded.source.is_demo and viewer.panel.error.startswith("error: not opened")
    viewer.drop([str(scene_file[0])])  # asked, and asked again: it goes on
    drive.wait_for_load()
    assert viewer.loaded.path == str(scene_file[0]) and tool.deleted_count() == 0


def test_closing_the_window_over_edits_not_exported_asks_first(open_viewer, scene_file):
    viewer, drive = open_viewer(str(scene_file[0]), hide_panel=True)
    drive.settle()
    tool = viewer.edit_tool
    drive.tap(Key.escape)
    assert viewer.window.should_close and viewer.may_close()  # nothing to lose: it closes
    viewer.window.keep_open()
    tool.select(type(tool.box)((-2.5, -2.5, -2.5), (0.0, 2.5, 2.5)), viewer.loaded.scene)
    tool.apply(Operation("delete"), viewer.loaded.scene)
    drive.tap(Key.escape)
    assert viewer.window.should_close and not viewer.may_close()
    assert not viewer.window.should_close and viewer.panel.error.startswith("error: not closed: the edits")
    drive.tap(Key.escape)  # asked, and asked again: it closes
    assert viewer.window.should_close and viewer.may_close()


def test_the_export_writes_on_its_own_thread_while_the_window_goes_on(open_viewer, scene_file, tmp_path,
                                                                      monkeypatch):
    from raygs_viewer.viewer import edit_export
    release, started = threading.Event(), threading.Event()
    real = edit_export.write_kept

    def held(*args):
        started.set()
        assert release.wait(30), "the test never let the export go on"
        return real(*args)

    monkeypatch.setattr(edit_export, "write_kept", held)
    viewer, drive = open_viewer(str(scene_file[0]), width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.frames(2)
    drive.reveal("Edit")
    drive.click("Edit")
    tool = viewer.edit_tool
    tool.select(type(tool.box)((-2.5, -2.5, -2.5), (0.0, 2.5, 2.5)), viewer.loaded.scene)
    tool.apply(Operation("delete"), viewer.loaded.scene)
    kept = ~tool.edits.deleted.copy()
    tool.exporter.file = str(tmp_path / "clean.ply")
    drive.reveal("Export")
    drive.click("Export")
    assert started.wait(30)
    shown = viewer.frame_index
    drive.frames(3)  # the window draws on while the file is being written
    assert viewer.frame_index == shown + 3 and tool.exporter.writing is not None
    assert viewer.panel.message.startswith(f"exporting {int(kept.sum()):,} gaussians to ")
    tool.apply(Operation("undelete all"), viewer.loaded.scene)  # a later edit does not reach the file
    assert tool.unsaved() is None  # nothing deleted now
    viewer.panel.say(tool.exporter.export(tool.edits, viewer.loaded))
    assert viewer.panel.error.endswith("clean.ply is still being written")
    release.set()
    viewer.panel.say(tool.exporter.wait())
    assert PlyData.read(str(tmp_path / "clean.ply"))["vertex"].count == int(kept.sum())
    assert viewer.panel.message.startswith(f"exported {int(kept.sum()):,} gaussians")
