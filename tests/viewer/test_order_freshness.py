"""The drawn order's freshness in the panel: its age in frames and milliseconds, and how
far the camera has turned and moved since the view it was sorted for."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from appkit import gated_viewer, headless, window_image
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from testkit import assert_matches

from raygs_viewer.bench.views import turned
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import Order, SortResult
from raygs_viewer.viewer.drawing import DrawReport, SortAsked
from raygs_viewer.viewer.frame import Frame, Framing
from raygs_viewer.viewer.stats import (
    FrameStats,
    order_freshness,
    turned_degrees,
)


def _frame(index, camera) -> Frame:
    return Frame.make(index, Framing(camera, (0, 0, camera.width, camera.height), None), stereo=None,
                      settings=RenderSettings(), right=None, lod=None)


def _result(camera, requested_at) -> SortResult:
    request = _frame(1, camera).sort
    return SortResult(request, {"depth": Order(np.arange(5), "depth", request)}, times={"sort": 0.01}, serial=1,
                      requested_at=requested_at)


def test_turned_degrees_is_the_rotation_angle():
    camera = look_at((0.0, 0.0, -3.0), (0.0, 0.0, 0.0))
    for degrees in (0.0, 0.5, 30.0, 179.0):
        assert turned_degrees(camera.R, turned(camera, degrees).R) == pytest.approx(degrees, abs=1e-6)


def test_a_stale_order_reports_its_age_turn_and_move():
    sorted_for = look_at((0.0, 0.0, -3.0), (0.0, 0.0, 0.0))
    now = replace(turned(sorted_for, 12.0))
    now = replace(now, t=now.t - now.R @ np.array([0.0, 0.3, 0.4]))  # and moved 0.5 units
    stats = FrameStats()
    result = _result(sorted_for, requested_at=100.0)
    stats.record(DrawReport(_frame(3, sorted_for), SortAsked(1, True), None, False, 100.0))  # frame 3 asks
    stats.record(DrawReport(_frame(7, now), SortAsked(2, True), result, True, 100.25))
    assert stats.order_age == 4 and stats.order_age_ms == pytest.approx(250.0)
    assert stats.order_turned_degrees == pytest.approx(12.0) and stats.order_moved == pytest.approx(0.5)
    assert order_freshness(stats) == "4 frames old (250 ms, turned 12.0°, moved 0.5)"
    # Up to date: the same view asked again.
    stats.record(DrawReport(_frame(8, sorted_for), SortAsked(3, False), result, True, 101.0))
    assert (stats.order_age, stats.order_age_ms, stats.order_turned_degrees, stats.order_moved) == (0, 0, 0, 0)
    assert order_freshness(stats) == "up to date"


def test_the_window_measures_how_far_the_camera_went_while_a_sort_ran(open_viewer):
    viewer, drive, gate = gated_viewer(open_viewer, free=1, hide_panel=True)  # the first view sorts at once
    drive.settle()
    sorted_for = viewer.scene.sorter.latest().request.camera
    drive.key(imgui.Key.w, True)
    drive.frames(6)
    drive.key(imgui.Key.w, False)
    drive.frames(1)
    stats = viewer.stats
    assert stats.order_age >= 6 and stats.order_age_ms > 0
    assert stats.order_moved == pytest.approx(np.linalg.norm(viewer.camera.center - sorted_for.center), rel=1e-9)
    assert stats.order_moved > 0 and stats.order_turned_degrees == pytest.approx(0.0, abs=1e-6)  # flew straight
    gate.release.set()
    drive.settle()
    assert viewer.stats.order_age == 0 and viewer.stats.order_moved == 0.0
    assert_matches(window_image(viewer), headless(viewer))
