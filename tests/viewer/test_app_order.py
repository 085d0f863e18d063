"""The window's order per ray (issue 15): the Order section of the panel, the sort keys
the window asks for and draws with (each side of the split view its own), GS with a
per-pixel order, and the per-pixel statistics the panel and the summary show.

The renderer is a GLRenderer that records what the window drew and reports made-up
per-pixel statistics (the GL pass reports real ones; here only their way to the panel
is tested)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from appkit import (
    PANEL_HEIGHT,
    PANEL_WIDTH,
    RecordingSorter,
    click_choice,
    headless,
    right_image,
    window_image,
)
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from testkit import assert_matches

from raygs_viewer.camera.stereo import PRESETS
from raygs_viewer.render.gl.results import OrderStats
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import MAX_ORDER_K, RenderSettings, apply_preset
from raygs_viewer.render.sorting import sort_request
from raygs_viewer.sort.request import Order, SortRequest
from raygs_viewer.viewer.drawing import order_for
from raygs_viewer.viewer.panel.order import gs_fallback_note, with_mode
from raygs_viewer.viewer.state import StereoPreview
from raygs_viewer.viewer.stats import FrameStats, order_stats_lines, summary

#: What the fake per-pixel pass reports: 7 fragments per covered pixel on average.
LISTS = OrderStats(path="lists", width=8, height=4, fragments=140, max_per_pixel=19, covered_pixels=20,
                   pool_fragments=100, pool_bytes=3 * 2**20, parts=2, largest_part=70)


class RecordingRenderer(GLRenderer):
    """Records (target, settings, order) of every render_into and reports LISTS (with
    the settings' K as its width, to tell sides apart) after a per-pixel one."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.drawn: list = []

    def render_into(self, target, camera, settings, order, *args, **kwargs):
        result = super().render_into(target, camera, settings, order, *args, **kwargs)
        self.drawn.append((target, settings, order))
        return replace(result, order_stats=replace(LISTS, width=settings.order_k) if settings.per_pixel else None)


def sorted_now(viewer, p_min: float, key: str) -> np.ndarray:
    """The indices of the exact sort of the viewer's view by ``key``."""
    return viewer.scene.direct_sorter.sort(SortRequest(viewer.camera, p_min, keys=(key,))).order.indices


def drawn_into(viewer, target) -> tuple[RenderSettings, Order]:
    """The settings and the order of the last draw into ``target``."""
    for drawn_target, settings, order in reversed(viewer.scene.renderer.drawn):
        if drawn_target is target:
            return settings, order
    raise AssertionError("nothing drawn into that target")


def open_recording(open_viewer, **options):
    return open_viewer(renderer_factory=RecordingRenderer, sorter_factory=RecordingSorter, **options)


# -- the panel's Order control -----------------------------------------------------------------
def test_the_panel_sets_the_order_and_k_and_the_next_draw_uses_them(open_viewer):
    viewer, drive = open_recording(open_viewer, width=PANEL_WIDTH, height=PANEL_HEIGHT)
    drive.settle()
    assert viewer.settings.order == "depth" and viewer.scene.sorter.keys[-1] == ("depth",)
    assert "K (window)" not in drive.panel  # K is shown for per pixel only

    click_choice(drive, "order", "distance")
    assert viewer.settings == RenderSettings(sh_degree=3, order="distance")
    drive.settle()
    assert viewer.scene.sorter.keys[-1] == ("distance",)
    settings, order = drawn_into(viewer, viewer.drawer.mono.left)
    assert settings.order == "distance"
    np.testing.assert_array_equal(order.indices, sorted_now(viewer, settings.p_min, "distance"))
    assert not np.array_equal(order.indices, sorted_now(viewer, settings.p_min, "depth"))
    assert_matches(window_image(viewer), headless(viewer))
    assert viewer.stats.order_stats == (None, None)

    click_choice(drive, "order", "per pixel")
    assert viewer.settings.order == "per-pixel" and viewer.settings.order_k == 0
    drive.settle()
    key = viewer.settings.sort_key  # the global order per pixel is fed in
    assert viewer.scene.sorter.keys[-1] == (key,)
    settings, order = drawn_into(viewer, viewer.drawer.mono.left)
    assert settings.per_pixel and settings.order_k == 0
    np.testing.assert_array_equal(order.indices, sorted_now(viewer, settings.p_min, key))
    assert viewer.stats.order_stats == (replace(LISTS, width=0), None)
    drive.frames(1)
    assert "K (window)" in drive.panel
    assert all(line in drive.panel for line in order_stats_lines(replace(LISTS, width=0)))

    drive.click("K (window)")  # the middle of the slider: a window of about half the most
    k = viewer.settings.order_k
    assert 0 < k <= MAX_ORDER_K and viewer.settings.order == "per-pixel"
    drive.settle()
    settings, _ = drawn_into(viewer, viewer.drawer.mono.left)
    assert settings.order_k == k and viewer.stats.order_stats[0].width == k
    drive.click_left_end("K (window)")
    assert viewer.settings.order_k == 0
    assert_matches(window_image(viewer), headless(viewer))

    click_choice(drive, "order", "depth")
    drive.settle()
    assert viewer.scene.sorter.keys[-1] == ("depth",) and viewer.stats.order_stats == (None, None)
    assert viewer.panel.error == ""


def test_gs_with_a_per_pixel_order_switches_it_to_distance_and_says_so(open_viewer):
    viewer, drive = open_recording(open_viewer, width=PANEL_WIDTH, height=PANEL_HEIGHT,
                                   settings=RenderSettings(order="per-pixel", order_k=3))
    drive.settle()
    fallback = RenderSettings(order="per-pixel").sort_key
    click_choice(drive, "mode", "GS (EWA)")
    assert viewer.settings == RenderSettings(sh_degree=3, mode="gs", order=fallback, order_k=3)
    assert viewer.panel.message == gs_fallback_note(fallback) and viewer.panel.error == ""
    drive.settle()
    assert drawn_into(viewer, viewer.drawer.mono.left)[0].mode == "gs"
    assert_matches(window_image(viewer), headless(viewer))
    # In GS mode the per-pixel entry is greyed out: choosing it changes nothing.
    click_choice(drive, "order", "per pixel")
    assert viewer.settings.order == fallback and viewer.panel.error == ""
    assert "(per pixel needs a RayGS mode)" in drive.panel
    drive.click("order")  # the greyed-out entry left the combo open: close it
    # Back in a RayGS mode it can be chosen again.
    click_choice(drive, "mode", "RayGS")
    click_choice(drive, "order", "per pixel")
    assert viewer.settings.order == "per-pixel" and viewer.settings.mode == "raygs"


def test_with_mode_keeps_every_other_combination():
    for order in ("depth", "distance", "per-pixel"):
        for mode in ("raygs", "raygs-exact-mip", "gs"):
            settings, note = with_mode(RenderSettings(order=order, order_k=2), mode)
            assert settings.mode == mode and settings.order_k == 2
            fell_back = order == "per-pixel" and mode == "gs"
            assert settings.order == ("depth" if fell_back else order)
            assert note == (gs_fallback_note("depth") if fell_back else "")
    assert gs_fallback_note("depth") == "GS (EWA) has no per-pixel order: the order is now depth"


# -- the split view: one cull, an order per key, each side its own ----------------------------------
@pytest.mark.parametrize("left, preset, keys", [
    ("depth", "RayGS, distance order", ("depth", "distance")),
    ("distance", "RayGS, per-pixel order", ("distance", "depth")),
    ("per-pixel", "RayGS, per-pixel order K=4", ("depth",)),
    ("distance", "RayGS", ("distance", "depth")),
    ("per-pixel", "GS", ("depth",)),
])
def test_the_split_view_sorts_each_key_once_and_each_side_draws_its_own(open_viewer, left, preset, keys):
    viewer, drive = open_recording(open_viewer, hide_panel=True, settings=RenderSettings(order=left))
    viewer.split.on, viewer.split.preset = True, preset
    drive.settle()
    a, b = viewer.settings, viewer.right_settings()
    assert b == apply_preset(a, preset)
    assert sort_request(viewer.camera, a, b).keys == keys and viewer.scene.sorter.keys[-1] == keys
    result = viewer.scene.sorter.latest()
    assert result.keys == keys
    left_settings, left_order = drawn_into(viewer, viewer.drawer.mono.left)
    right_settings, right_order = drawn_into(viewer, viewer.drawer.mono.right)
    assert (left_settings, right_settings) == (a, b)
    assert left_order is result.order_for(a.sort_key) and right_order is result.order_for(b.sort_key)
    if len(keys) == 2:
        assert not np.array_equal(left_order.indices, right_order.indices)
        assert sorted(left_order.indices.tolist()) == sorted(right_order.indices.tolist())  # one cull
    assert_matches(window_image(viewer), headless(viewer, a))
    assert_matches(right_image(viewer), headless(viewer, b))
    # The statistics of each per-pixel side (the fake tells the sides apart by K).
    expected = tuple(replace(LISTS, width=side.order_k) if side.per_pixel else None for side in (a, b))
    assert viewer.stats.order_stats == expected


def test_the_split_view_panel_shows_each_per_pixel_side(open_viewer):
    viewer, drive = open_recording(open_viewer, width=PANEL_WIDTH, height=PANEL_HEIGHT,
                                   settings=RenderSettings(order="per-pixel"))
    viewer.split.on, viewer.split.preset = True, "RayGS, per-pixel order K=4"
    drive.settle()
    drive.frames(1)
    assert "left side:" in drive.panel and "right side:" in drive.panel
    assert all(line in drive.panel for side in viewer.stats.order_stats for line in order_stats_lines(side))
    viewer.split.preset = "RayGS, distance order"
    drive.settle()
    drive.frames(1)
    assert "left side:" in drive.panel and "right side:" not in drive.panel


def test_a_newly_chosen_key_draws_the_old_order_until_its_sort_is_done():
    depth = Order(np.array([2, 0, 1], np.uint32))
    assert order_for({"depth": depth}, "distance") is depth
    distance = Order(depth.indices[::-1], "distance")
    assert order_for({"depth": depth, "distance": distance}, "distance") is distance
    assert order_for({}, "depth").count == 0 and order_for({}, "depth").indices.dtype == np.uint32


# -- stereo -------------------------------------------------------------------------------------
def test_stereo_sorts_both_eyes_by_the_settings_key(open_viewer):
    eye = replace(PRESETS["generic90"], name="custom", width=64, height=48)
    stereo = StereoPreview.of(eye, on=True)
    viewer, drive = open_recording(open_viewer, hide_panel=True, width=128, height=48, stereo=stereo,
                                   settings=RenderSettings(order="per-pixel"))
    drive.settle()
    assert viewer.scene.sorter.keys[-1] == ("depth",)
    result = viewer.scene.sorter.latest()
    eye_orders = [order for _, settings, order in viewer.scene.renderer.drawn[-2:]]
    assert all(order is result.order_for("depth") for order in eye_orders)
    assert viewer.stats.order_stats == (replace(LISTS, width=0), None)
    viewer.settings = replace(viewer.settings, order="distance")
    drive.settle()
    assert viewer.scene.sorter.keys[-1] == ("distance",) and viewer.stats.order_stats == (None, None)
    assert all(order is viewer.scene.sorter.latest().order_for("distance")
               for order in [order for _, settings, order in viewer.scene.renderer.drawn[-2:]])


# -- the statistics' words -------------------------------------------------------------------------
def test_order_statistics_lines_and_summary():
    lines = order_stats_lines(LISTS)
    assert lines[0] == "fragments/px 7.0 mean, 19 max (20 px covered)"
    assert lines[1] == "pool 70 % of 100 fragments (3.0 MiB), 2 parts"
    assert lines[2].startswith("path: per-pixel fragment lists")
    fetch = order_stats_lines(replace(LISTS, path="fetch", pool_fragments=0, pool_bytes=0, parts=1))
    assert fetch[1] == "no pool, 1 part" and fetch[2].startswith("path: k-buffer")
    stats = FrameStats()
    quiet = dict(camera=None, stereo=None, gpu_times=[], post_times=[], scene_count=100, general=False)
    plain = summary(stats, 3, **quiet)
    assert "per-pixel" not in plain
    stats.order_stats = (LISTS, None)
    assert "per-pixel order 7.0 fragments/px (max 19) in 2 parts" in summary(stats, 3, **quiet)
    assert math.isclose(LISTS.pool_use, 0.7)


def test_keys_reach_the_sorter_even_without_the_panel(open_viewer):
    viewer, drive = open_recording(open_viewer, hide_panel=True)
    drive.settle()
    viewer.settings = replace(viewer.settings, order="distance")
    drive.frames(1)
    assert viewer.scene.sorter.keys[-1] == ("distance",)
    drive.settle()  # a result for the old key is not up to date: settle waits for the new one
    assert viewer.scene.sorter.latest().keys == ("distance",) and viewer.stats.order_age == 0
    assert drawn_into(viewer, viewer.drawer.mono.left)[1] is viewer.scene.sorter.latest().order_for("distance")


# -- screenshots ---------------------------------------------------------------------------------
def test_split_view_screenshots_record_each_sides_order_and_reproduce(open_viewer, tmp_path):
    import glfw
    from PIL import Image

    from raygs_viewer.capture.sidecar import load_sidecar
    from raygs_viewer.cli.main import main
    viewer, drive = open_viewer(hide_panel=True, settings=RenderSettings(order="per-pixel", order_k=2))
    viewer.split.on, viewer.split.preset = True, "RayGS, distance order"
    drive.settle()
    drive.tap(imgui.Key.f12)
    assert viewer.panel.error == ""
    saved = viewer.captures.saved
    sides = [load_sidecar(sidecar).settings for _, sidecar in saved]
    assert sides == [viewer.settings, viewer.right_settings()]
    assert [(s.order, s.order_k) for s in sides] == [("per-pixel", 2), ("distance", 0)]
    for png, sidecar in saved:
        out = tmp_path / f"again-{png.name}"
        assert main(["render", "--sidecar", str(sidecar), "--out", str(out)]) == 0
        np.testing.assert_array_equal(np.asarray(Image.open(out)), np.asarray(Image.open(png)))
    glfw.make_context_current(viewer.window.handle)


# -- the real per-pixel passes in the window ---------------------------------------------------------
@pytest.mark.parametrize("order_k, path", [(0, "lists"), (3, "fetch"), (3, "lists")])
def test_the_window_draws_per_pixel_order_as_an_offscreen_render_does(open_viewer, order_k, path):
    # Frames after swaps and a moving camera: the count and fill passes index pixels by
    # gl_FragCoord, so a draw that saw it flipped would fail their check or this image.
    def renderer(ctx, scene, **options):
        return GLRenderer(ctx, scene, order_path=path, **options)

    settings = RenderSettings(order="per-pixel", order_k=order_k)
    viewer, drive = open_viewer(hide_panel=True, renderer_factory=renderer, settings=settings)
    centres = []
    for _ in range(3):
        drive.key(imgui.Key.w, True)
        drive.frames(2)
        drive.key(imgui.Key.w, False)
        drive.settle()
        stats = viewer.stats.order_stats[0]
        assert stats is not None and stats.path == path and stats.fragments > 0
        shown = viewer.drawer.mono.left.read()
        offscreen = viewer.scene.renderer.render(viewer.camera, viewer.settings, viewer.scene.sorter.latest().order_for("depth"))
        np.testing.assert_array_equal(shown, offscreen)
        centres.append(viewer.camera.center)
    assert np.linalg.norm(centres[2] - centres[0]) > 0  # the camera moved between the draws
