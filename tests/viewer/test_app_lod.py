"""The window on a streamed SOG (lod-meta.json): the coarsest level first and the finer
ones as they are read, keeping the view and never blanking the picture; the budget, the
fixed level and colour by level in the panel, and what they draw; a GPU too small for
the finest level; levels read again after another file's load cut them short;
screenshots (mono, mid-read, stereo) that draw the choice for their own camera and that
``render --sidecar`` draws again.

Loads are stepped through with events (a read_lod that waits after each level) and
sorts with a gate; nothing waits on time."""

from __future__ import annotations

import json
import threading
from dataclasses import replace

import numpy as np
import pytest
from appkit import GatedSorter, click_choice
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from lod_kit import random_gaussians, write_streamed_sog
from PIL import Image

from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.stereo import custom_preset
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.capture.screenshot import scaled_camera
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.stereo_frame import render_stereo_view, stereo_order
from raygs_viewer.render.gl.storage import gpu_bytes
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.edits import Operation
from raygs_viewer.scene.lod_file import load_lod, subset_scene
from raygs_viewer.scene.selection import Sphere
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import choose
from raygs_viewer.sort.worker import BackgroundSorter
from raygs_viewer.viewer.lod_window import DEFAULT_WINDOW_BUDGET, LEVEL_COLOURS, tinted_scene
from raygs_viewer.viewer.app import load_start_scene
from raygs_viewer.viewer.state import StereoPreview, ViewerOptions

WIDTH, HEIGHT = 192, 144
PANEL_WIDTH, PANEL_HEIGHT = 640, 800
#: Level 1 begins 4 units away, level 2 at 8: the leaves below draw levels 0, 1, 2, 2.
DISTANCE = 4.0
SETTINGS = RenderSettings(lod_distance=DISTANCE)
CENTRES = ((0.0, 0.0, 3.0), (0.8, 0.2, 6.0), (-1.2, -0.3, 11.0), (1.5, 0.4, 15.0))
PER_LEVEL = ((60, 0.06), (20, 0.12), (6, 0.25))  # (gaussians, scale) of each leaf at levels 0, 1, 2


@pytest.fixture(scope="module")
def streamed(tmp_path_factory):
    """(lod-meta.json, cameras.json of one camera at the origin looking along +z): four
    leaves, nearer to farther, three levels, and an environment."""
    folder = tmp_path_factory.mktemp("streamed")
    leaves = [[random_gaussians(n, centre, spread=0.3, scale=scale, seed=10 * k + level)
               for level, (n, scale) in enumerate(PER_LEVEL)] for k, centre in enumerate(CENTRES)]
    index = write_streamed_sog(folder / "scene", leaves, environment=random_gaussians(8, spread=20.0, scale=1.0,
                                                                                       seed=99))
    cameras = folder / "view.json"
    cameras.write_text(json.dumps([{"id": 0, "img_name": "front", "width": WIDTH, "height": HEIGHT,
                                    "position": [0.0, 0.0, 0.0], "rotation": np.eye(3).tolist(),
                                    "fx": 150.0, "fy": 150.0}]))
    return str(index), str(cameras)


class SteppedLod:
    """Stands in for the loader's read_lod: after each level has been handed on, waits
    until the test lets it read the next (``go(n)``); ``handed[n]`` is set once the n-th
    level (0: the first read, the coarsest) has been handed on."""

    def __init__(self, levels: int):
        self.handed = [threading.Event() for _ in range(levels)]
        self._go = [threading.Event() for _ in range(levels)]

    def __call__(self, path, *, on_level=None, **options):
        def step(lod):
            n = int(lod.loaded.sum()) - 1
            on_level(lod)
            self.handed[n].set()
            assert self._go[n].wait(60)
        return load_lod(path, on_level=step, **options)

    def wait_handed(self, n: int) -> None:
        assert self.handed[n].wait(60)

    def go(self, n: int) -> None:
        self._go[n].set()

    def release_all(self) -> None:
        for event in self._go:
            event.set()


def gate_factory(release: threading.Event):
    """A sorter_factory whose every sort waits for ``release`` (set: sorts run at once)."""
    def factory(sorter):
        gate = GatedSorter(sorter)
        gate.release = release
        return BackgroundSorter(gate)
    return factory


def drawn_alone(viewer, scene, camera, settings) -> np.ndarray:
    """``scene`` rendered by a renderer of its own, on the window's context."""
    renderer = GLRenderer(viewer.ctx, scene)
    try:
        with DepthSorter(scene) as sorter:
            return renderer.render(camera, settings, exact_order(sorter, camera, settings))
    finally:
        renderer.release()


def expected(viewer, lod, **choice) -> np.ndarray:
    """The window's view drawn headlessly from the rows ``choose`` picks (alone in a scene)."""
    picked = choose(lod, viewer.camera, **choice)
    return drawn_alone(viewer, lod.subset(picked.spans), viewer.camera, viewer.settings)


def texts(drive) -> list[str]:
    return [w.label for w in drive.panel.widgets if w.kind in ("text", "text_wrapped")]


def line(drive, start: str) -> str:
    found = [text for text in texts(drive) if text.startswith(start)]
    assert len(found) == 1, (start, texts(drive))
    return found[0]


def open_streamed(open_viewer, streamed, **options):
    """A viewer on ``streamed`` from its camera, every level read."""
    index, cameras = streamed
    options.setdefault("settings", SETTINGS)
    viewer, drive = open_viewer(index, camera=cameras, width=PANEL_WIDTH, height=PANEL_HEIGHT, **options)
    drive.move_mouse(PANEL_WIDTH - 5, PANEL_HEIGHT - 5)
    drive.frames(1)  # starts reading the finer levels
    drive.wait_for_load()
    assert viewer.loaded.lod.loaded.all()
    drive.settle()
    return viewer, drive


def rendered_again(viewer, sidecar, out) -> np.ndarray:
    """``render --sidecar``'s PNG (8-bit RGB); the window's context current again after it."""
    from raygs_viewer.cli.main import main
    assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
    viewer.window.make_current()
    return np.asarray(Image.open(out))


def test_coarsest_level_first_then_each_finer_one_keeping_the_view(open_viewer, streamed, tmp_path):
    index, _ = streamed
    release = threading.Event()
    release.set()
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT, settings=SETTINGS,
                                sorter_factory=gate_factory(release))
    stepped = SteppedLod(3)
    viewer.scenes.loader.read_lod = stepped
    try:
        viewer.panel.open_path = index
        drive.frames(1)
        drive.click("Open")
        stepped.wait_handed(0)
        drive.frames(1)
        lod = viewer.loaded.lod
        assert lod.loaded.tolist() == [False, False, True] and viewer.scenes.loader.busy
        assert viewer.settings.lod_budget == DEFAULT_WINDOW_BUDGET and viewer.settings.lod_distance == DISTANCE
        # A view of the leaves from the origin, as the finer levels will be seen.
        viewer.view.navigator.set_pose(Pose(np.zeros(3), np.eye(3)))
        drive.settle()
        assert line(drive, "levels read") == "levels read: 2 of 0..2 (0 the finest)"
        assert any(label.startswith("reading finer levels") for label in drive.panel.labels("progress_bar"))
        coarse = viewer.drawer.mono.left.read()
        assert viewer.scene.lod.choice.levels.tolist() == [2, 2, 2, 2]
        np.testing.assert_allclose(coarse, expected(viewer, lod, distance=DISTANCE), atol=1e-5)
        assert coarse[..., 3].max() > 0.5
        # A screenshot now records the levels read, and renders again from them alone.
        png, sidecar = viewer.save_screenshot()
        assert json.loads(sidecar.read_text())["scene"]["lod_levels"] == [2]
        np.testing.assert_array_equal(rendered_again(viewer, sidecar, tmp_path / "coarse.png"),
                                      np.asarray(Image.open(png)))

        # Level 1 arrives while the sort is held: the frame draws the last order, not a blank.
        release.clear()
        stepped.go(0)
        stepped.wait_handed(1)
        drive.frames(1)
        assert viewer.loaded.lod.loaded.tolist() == [False, True, True]
        assert viewer.view.navigator.pose.position.tolist() == [0.0, 0.0, 0.0]
        np.testing.assert_array_equal(viewer.drawer.mono.left.read(), coarse)
        drive.frames(1)  # the panel shows the age the frame before noted
        assert line(drive, "choice").startswith("choice ") and line(drive, "choice") != "choice up to date"
        np.testing.assert_array_equal(viewer.drawer.mono.left.read(), coarse)
        release.set()
        drive.settle()
        assert viewer.scene.lod.choice.levels.tolist() == [1, 1, 2, 2]
        middle = viewer.drawer.mono.left.read()
        np.testing.assert_allclose(middle, expected(viewer, viewer.loaded.lod, distance=DISTANCE), atol=1e-5)
        assert np.abs(middle - coarse).max() > 0.1

        stepped.go(1)
        stepped.go(2)
        drive.wait_for_load()
        assert viewer.loaded.lod.loaded.all() and viewer.loaded.sha256
        assert viewer.view.navigator.pose.position.tolist() == [0.0, 0.0, 0.0]
        drive.settle()
        assert viewer.scene.lod.choice.levels.tolist() == [0, 1, 2, 2]
        assert line(drive, "levels read") == "levels read: 2, 1, 0 of 0..2 (0 the finest)"
        np.testing.assert_allclose(viewer.drawer.mono.left.read(),
                                   expected(viewer, viewer.loaded.lod, distance=DISTANCE), atol=1e-5)
    finally:
        stepped.release_all()
        release.set()


def test_the_command_line_scene_shows_its_coarsest_level_then_reads_the_rest(open_viewer, streamed):
    index, cameras = streamed
    viewer, drive = open_viewer(index, camera=cameras, settings=SETTINGS, hide_panel=True)
    assert viewer.loaded.lod.loaded.tolist() == [False, False, True]
    drive.frames(1)
    pose = viewer.view.navigator.pose
    drive.wait_for_load()
    assert viewer.loaded.lod.loaded.all()
    assert viewer.view.navigator.pose.position.tolist() == pose.position.tolist()
    drive.settle()
    assert viewer.scene.lod.choice.levels.tolist() == [0, 1, 2, 2]


def test_gaussians_deleted_stay_deleted_when_a_finer_level_arrives(open_viewer, streamed):
    """The edits grow with the scene (``Edits.grow``): rows deleted at the coarsest level
    are still left out of every sort once the finer levels are read, and the new rows are not."""
    index, cameras = streamed
    viewer, drive = open_viewer(index, camera=cameras, settings=SETTINGS, hide_panel=True)
    coarse = viewer.loaded.scene
    assert viewer.loaded.lod.loaded.tolist() == [False, False, True]
    tool = viewer.edit_tool
    tool.apply(Operation("select all"), coarse)
    tool.apply(Operation("delete"), coarse)
    drive.frames(1)  # the finer levels' reading starts
    drive.wait_for_load()
    scene = viewer.loaded.scene
    assert viewer.loaded.lod.loaded.all() and scene.count > coarse.count
    deleted = tool.edits.deleted
    assert deleted.size == scene.count and deleted[:coarse.count].all() and not deleted[coarse.count:].any()
    drive.settle()
    assert viewer.shown.sort.deleted.mask[:coarse.count].all()
    drawn = viewer.drawer.orders[viewer.settings.sort_key].indices
    assert len(drawn) and (np.asarray(drawn) >= coarse.count).all()  # no coarse gaussian came back


def test_a_fixed_level_reads_that_level_alone_and_per_view_reads_the_rest(open_viewer, streamed):
    viewer, drive = open_viewer(streamed[0], camera=streamed[1], width=PANEL_WIDTH, height=PANEL_HEIGHT,
                                settings=replace(SETTINGS, lod=1))
    drive.frames(3)
    assert viewer.loaded.lod.loaded.tolist() == [False, True, False] and not viewer.scenes.loader.busy
    drive.settle()
    assert viewer.scene.lod.choice.levels.tolist() == [1, 1, 1, 1]
    np.testing.assert_allclose(viewer.drawer.mono.left.read(), expected(viewer, viewer.loaded.lod, level=1),
                               atol=1e-5)
    click_choice(drive, "level", "per view")
    assert viewer.settings.lod is None
    drive.frames(1)  # starts reading the other levels
    drive.wait_for_load()
    assert viewer.loaded.lod.loaded.all()
    drive.settle()
    assert viewer.scene.lod.choice.levels.tolist() == [0, 1, 2, 2]


def test_the_budget_changes_what_is_drawn(open_viewer, streamed):
    viewer, drive = open_streamed(open_viewer, streamed)
    lod = viewer.loaded.lod
    full = viewer.drawer.mono.left.read()
    env = lod.environment[1]
    wanted = env + 60 + 20 + 6 + 6
    assert line(drive, "drawn") == f"drawn {wanted} gaussians of a budget of {DEFAULT_WINDOW_BUDGET:,}"
    assert line(drive, "parts at each level") == "parts at each level: 0: 1, 1: 1, 2: 2"
    np.testing.assert_allclose(full, expected(viewer, lod, distance=DISTANCE), atol=1e-5)
    drawn = viewer.drawer.orders[viewer.settings.sort_key]
    np.testing.assert_array_equal(drawn.spans, viewer.scene.lod.choice.spans)  # preprocessing only those
    assert not any(text.startswith("the budget is below") for text in texts(drive))

    drive.click_left_end("##budget")  # a budget of 1: below even the coarsest level
    assert viewer.settings.lod_budget == 1
    drive.settle()
    assert line(drive, "drawn") == f"drawn {env + 4 * 6} gaussians of a budget of 1"
    assert line(drive, "parts at each level") == "parts at each level: 0: 0, 1: 0, 2: 4"
    assert line(drive, "the budget is below").startswith("the budget is below the coarsest level")
    drive.frames(1)  # the panel is drawn before the frame notes the order's age
    assert line(drive, "choice") == "choice up to date"
    coarse = viewer.drawer.mono.left.read()
    np.testing.assert_allclose(coarse, drawn_alone(viewer, lod.subset(lod.level_spans(2)), viewer.camera,
                                                   viewer.settings), atol=1e-5)
    assert np.abs(coarse - full).max() > 0.1
    np.testing.assert_array_equal(viewer.drawer.orders[viewer.settings.sort_key].spans, lod.level_spans(2))


def test_colour_by_level_tints_each_level_and_goes_back(open_viewer, streamed):
    viewer, drive = open_streamed(open_viewer, streamed)
    lod = viewer.loaded.lod
    own = viewer.drawer.mono.left.read()
    drive.click("colour by level")
    assert viewer.scene.lod.tint
    drive.settle()
    tinted = viewer.drawer.mono.left.read()
    picked = choose(lod, viewer.camera, budget=DEFAULT_WINDOW_BUDGET, distance=DISTANCE)
    np.testing.assert_allclose(tinted, drawn_alone(viewer, subset_scene(tinted_scene(lod), picked.spans, ""),
                                                   viewer.camera, viewer.settings), atol=1e-5)
    assert np.abs(tinted - own).max() > 0.1
    # A screenshot would not show the scene's own colours: refused, and said so.
    drive.tap(imgui.Key.f12)
    assert "colour by level" in viewer.panel.error and viewer.captures.last is None

    # One level everywhere: the picture is that level's colour.
    for level, entry in ((0, "level 0 (finest)"), (2, "level 2 (coarsest)")):
        click_choice(drive, "level", entry)
        drive.settle()
        image = viewer.drawer.mono.left.read()
        covered = image[..., 3] > 0.5
        colour = image[covered, :3].mean(axis=0)
        assert int(np.argmax(colour)) == int(np.argmax(LEVEL_COLOURS[level])), (level, colour)
    click_choice(drive, "level", "per view")
    drive.click("colour by level")
    assert not viewer.scene.lod.tint
    drive.settle()
    np.testing.assert_array_equal(viewer.drawer.mono.left.read(), own)


def test_a_gpu_too_small_for_the_finest_levels_opens_with_the_coarser_ones(open_viewer, streamed, monkeypatch):
    index, _ = streamed
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    lod = load_lod(index)
    coarse = lod.environment[1] + int(lod.index.counts[2])
    with_level_1 = coarse + int(lod.index.counts[1])
    # Room for the coarsest level and the environment, not for level 1 besides.
    mib = (gpu_bytes(coarse, lod.scene.sh_degree) + gpu_bytes(with_level_1, lod.scene.sh_degree)) / 2 / 0.8 / 2**20
    monkeypatch.setenv("RAYGS_GPU_MEMORY", f"{mib:.6f}")
    viewer.panel.open_path = index
    drive.frames(1)
    drive.click("Open")
    drive.wait_for_load()
    assert viewer.loaded.lod.loaded.tolist() == [False, False, True]
    message = viewer.loaded.lod.unread
    assert message.startswith("levels 0, 1 not read") and f"({with_level_1:,} gaussians)" in message
    drive.frames(2)
    assert message in texts(drive) and not viewer.scenes.loader.busy  # nothing more is read


def test_a_screenshot_draws_the_choice_for_its_camera_and_renders_again_from_its_sidecar(
        open_viewer, streamed, tmp_path):
    viewer, _ = open_streamed(open_viewer, streamed, hide_panel=True)
    drawn = viewer.drawer.orders[viewer.settings.sort_key]
    # A budget the window has not drawn yet: the screenshot makes the choice for itself.
    viewer.settings = replace(viewer.settings, lod_budget=40)
    viewer.captures.options.scale = 2.0
    png, sidecar = viewer.save_screenshot()
    assert viewer.drawer.orders[viewer.settings.sort_key] is drawn  # the window's own order stands
    recorded = json.loads(sidecar.read_text())
    assert recorded["settings"]["lod_budget"] == 40 and recorded["settings"]["lod_distance"] == DISTANCE
    assert recorded["scene"]["sha256"] == viewer.loaded.sha256 and recorded["scene"]["lod_levels"] == [0, 1, 2]
    shot = np.asarray(Image.open(png))
    lod = viewer.loaded.lod
    camera = scaled_camera(viewer.camera, 2.0)
    picked = choose(lod, camera, budget=40, distance=DISTANCE)
    assert picked.levels.tolist() != [0, 1, 2, 2]  # what the window drew
    alone = drawn_alone(viewer, lod.subset(picked.spans), camera, viewer.settings)
    assert np.abs(shot.astype(int) - to_rgb8(alone).astype(int)).max() <= 1
    np.testing.assert_array_equal(rendered_again(viewer, sidecar, tmp_path / "again.png"), shot)


def test_a_stereo_screenshot_draws_the_choice_for_its_midpoint(open_viewer, streamed, tmp_path):
    stereo = StereoPreview.of(custom_preset(96, 72, 90.0, 72.0), on=True)
    viewer, _ = open_streamed(open_viewer, streamed, hide_panel=True, stereo=stereo)
    viewer.settings = replace(viewer.settings, lod_budget=40)  # not drawn yet, as above
    png, sidecar = viewer.save_screenshot()
    shot = np.asarray(Image.open(png))
    lod, camera = viewer.loaded.lod, viewer.camera  # the eyes' midpoint
    picked = choose(lod, camera, budget=40, distance=DISTANCE)
    assert picked.levels.tolist() != viewer.scene.lod.choice.levels.tolist()
    subset = lod.subset(picked.spans)
    renderer = GLRenderer(viewer.ctx, subset)
    try:
        with DepthSorter(subset) as sorter:
            order = stereo_order(sorter, camera, viewer.settings, viewer.shown_stereo.rig)
        pair = render_stereo_view(renderer, order, camera, viewer.settings,
                                  replace(viewer.shown_stereo, layout="sbs"))[0]
    finally:
        renderer.release()
    assert np.abs(shot.astype(int) - to_rgb8(pair).astype(int)).max() <= 1
    np.testing.assert_array_equal(rendered_again(viewer, sidecar, tmp_path / "again.png"), shot)



def test_levels_cut_short_by_another_file_are_read_again(open_viewer, streamed, tmp_path):
    index, cameras = streamed
    viewer, drive = open_viewer(index, camera=cameras, settings=SETTINGS, hide_panel=True)
    stepped = SteppedLod(3)
    viewer.scenes.loader.read_lod = stepped
    try:
        drive.frames(1)  # starts reading the finer levels
        stepped.wait_handed(0)
        viewer.open_scene(str(tmp_path / "missing.ply"))  # cancels that reading, then fails
        stepped.release_all()
        drive.wait_for_load()
        assert "missing.ply" in viewer.panel.error and viewer.loaded.path == index
        drive.frames(1)  # reads the levels again
        drive.wait_for_load()
        assert viewer.loaded.lod.loaded.all()
    finally:
        stepped.release_all()


def test_level_of_detail_options_for_another_scene_are_kept_and_said():
    loaded = load_start_scene(ViewerOptions(settings=RenderSettings(lod_budget=500, lod_distance=2.0)))
    assert loaded.lod is None
    assert loaded.warnings[-1] == ("--lod-budget, --lod-distance: not for this scene, which is not a streamed SOG "
                                   "(lod-meta.json); kept for one opened later")
    assert not load_start_scene(ViewerOptions()).warnings


def test_a_scripted_run_ends_on_every_level(restore_gl_ctx, streamed, tmp_path, capsys):
    """--frames N --screenshot: the last frame waits for the levels still being read, so
    the screenshot shows the scene as it ends up (and its sidecar says so)."""
    from raygs_viewer.cli.main import main

    index, cameras = streamed
    shot = tmp_path / "scripted.png"
    assert main(["view", str(index), "--frames", "1", "--screenshot", str(shot), "--camera", str(cameras),
                 "--width", "64", "--height", "48", "--window-platform", "null"]) == 0
    capsys.readouterr()
    assert json.loads(shot.with_suffix(".json").read_text())["scene"]["lod_levels"] == [0, 1, 2]


def test_an_edited_screenshot_of_a_streamed_sog_renders_again_from_its_sidecar(open_viewer, streamed, tmp_path,
                                                                                capsys):
    viewer, drive = open_streamed(open_viewer, streamed, hide_panel=True)
    tool = viewer.edit_tool
    positions = viewer.loaded.scene.positions
    middle = np.median(positions, axis=0)
    tool.select(Sphere(tuple(middle.tolist()), float(np.percentile(np.linalg.norm(positions - middle, axis=1), 30))),
                viewer.loaded.scene)
    tool.apply(Operation("delete"), viewer.loaded.scene)
    deleted = tool.edits.deleted.copy()
    assert 0 < deleted.sum() < deleted.size
    drive.settle()
    png, sidecar = viewer.save_screenshot()
    recorded = json.loads(sidecar.read_text())
    assert recorded["edits"]["operations"][-1] == {"op": "delete"} and recorded["scene"]["lod_levels"] == [0, 1, 2]
    shot = np.asarray(Image.open(png))
    tool.undo()
    drive.settle()
    whole, _ = viewer.save_screenshot()
    assert np.abs(np.asarray(Image.open(whole)).astype(int) - shot.astype(int)).max() > 20  # the delete shows
    capsys.readouterr()
    np.testing.assert_array_equal(rendered_again(viewer, sidecar, tmp_path / "again.png"), shot)
    assert f"({int(deleted.sum())} deleted)" in capsys.readouterr().out
