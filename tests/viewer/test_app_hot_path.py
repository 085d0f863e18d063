"""The window's hot path: its GPU sort never waits for the GPU (its time comes from a
timer query read frames later), and its scene targets take the blend precision, so a
frame at float16 or 8-bit blends straight into what the window shows, with no copy pass
and the image of a headless render at that precision."""

from __future__ import annotations

import math
from dataclasses import replace

import moderngl
import numpy as np
import pytest
from appkit import headless, window_image
from test_app_stereo import headless_eyes, stereo_viewer

from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.viewer.state import NavigationChoices


def test_the_window_s_gpu_sort_never_waits_for_the_gpu(open_viewer, monkeypatch):
    """Every frame of a turntable sorts a new view on the GPU; none calls ctx.finish,
    and the sort time shown is the GPU's, from the sort's timer query, within a few
    frames."""
    viewer, drive = open_viewer(sort="gpu", hide_panel=True, navigation=NavigationChoices(turntable=5.0))
    drive.frames(1)
    finishes = []
    original = moderngl.Context.finish
    monkeypatch.setattr(moderngl.Context, "finish", lambda ctx: (finishes.append(ctx), original(ctx))[1])
    sorts = viewer.scene.sorter.finished
    drive.frames(6)
    assert viewer.scene.sorter.finished - sorts == 6 and viewer.scene.sorter.error is None  # one sort a frame
    assert finishes == []
    timer = viewer.scene.sort_timer
    assert viewer.stats.sort_timer is timer and len(timer.history) >= 3
    assert math.isfinite(viewer.stats.sort_seconds) and viewer.stats.sort_seconds == timer.seconds
    assert " sort " in viewer.summary()


def test_a_still_view_s_gpu_sort_time_is_read_frames_later(open_viewer):
    """One sort, then a still view: no later sort pushes its query out, the frames do."""
    viewer, drive = open_viewer(sort="gpu", hide_panel=True)
    drive.frames(1)
    assert viewer.scene.sorter.finished == 1
    drive.frames(viewer.scene.sort_timer.depth)
    assert viewer.scene.sorter.finished == 1 and math.isfinite(viewer.stats.sort_seconds)


#: The split view's preset that blends at each narrow precision.
PRESETS = {"float16": "RayGS, float16 blend", "8bit": "RayGS, 8-bit blend"}


def count_resolves(monkeypatch) -> list:
    """The calls of GLRenderer.resolve_samples from now on: the copy pass a narrow
    blend into a float32 target takes."""
    calls = []
    original = GLRenderer.resolve_samples
    monkeypatch.setattr(GLRenderer, "resolve_samples", lambda *args: (calls.append(args), original(*args))[1])
    return calls


@pytest.mark.parametrize("precision, dtype", [("float16", "f2"), ("8bit", "f1")])
def test_the_window_blends_at_its_precision_straight_into_what_it_shows(open_viewer, monkeypatch, precision,
                                                                        dtype):
    """No copy pass in a window frame at a narrow precision, on either side of the split
    view, and the image is the headless render's at that precision to the bit (a float16
    or 8-bit value converted to float32 is exact)."""
    settings = RenderSettings(precision=precision)
    viewer, drive = open_viewer(hide_panel=True, settings=settings)
    drive.settle()
    resolves = count_resolves(monkeypatch)
    draws = viewer.stats.draws
    viewer.settings = replace(settings, background=(0.1, 0.2, 0.3))  # a frame to draw again
    drive.settle()
    assert viewer.stats.draws > draws and resolves == []
    assert viewer.drawer.mono.left.dtypes == (dtype,)
    shown = window_image(viewer)
    expected = headless(viewer)  # into a float32 target: the copy pass
    assert len(resolves) == 1
    np.testing.assert_array_equal(shown, expected)
    assert expected[..., 3].max() > 0.5

    # The split view: a float32 left side beside the right side's preset at the precision.
    viewer.settings = replace(viewer.settings, precision="float32")
    viewer.split.on, viewer.split.preset = True, PRESETS[precision]
    draws = viewer.stats.draws
    drive.settle()
    assert viewer.stats.draws > draws and len(resolves) == 1
    assert viewer.drawer.mono.left.dtypes == ("f4",) and viewer.drawer.mono.right.dtypes == (dtype,)
    right = viewer.right_settings()
    assert right.precision == precision
    np.testing.assert_array_equal(viewer.drawer.mono.right.read(), headless(viewer, right))

def test_the_window_s_target_follows_the_precision_and_what_resolves_into_it(open_viewer):
    """A new precision makes the target anew; supersampling and a channel's picture
    write the target through a pass of their own, so it stays float32 for them."""
    viewer, drive = open_viewer(hide_panel=True)
    drive.settle()
    assert viewer.drawer.mono.left.dtypes == ("f4",)
    for settings, dtype in ((replace(viewer.settings, precision="float16"), "f2"),
                            (replace(viewer.settings, precision="float16", supersample=2), "f4"),
                            (replace(viewer.settings, precision="8bit"), "f1")):
        viewer.settings = settings
        drive.settle()
        assert viewer.drawer.mono.left.dtypes == (dtype,), settings
        np.testing.assert_array_equal(window_image(viewer), headless(viewer))


def test_the_stereo_eyes_blend_at_the_precision_with_no_copy_pass(open_viewer, monkeypatch):
    viewer, drive = stereo_viewer(open_viewer, settings=RenderSettings(precision="float16"))
    drive.settle()
    resolves = count_resolves(monkeypatch)
    viewer.settings = replace(viewer.settings, background=(0.1, 0.2, 0.3))  # a frame to draw again
    draws = viewer.stats.draws
    drive.settle()
    assert viewer.stats.draws > draws and resolves == []
    eyes = viewer.drawer.stereo.read_eyes()
    for eye, expected in zip(eyes, headless_eyes(viewer), strict=True):
        np.testing.assert_array_equal(eye, expected)
