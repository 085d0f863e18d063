"""The window's Headset section against a real runtime (Monado: null compositor,
simulated headset, ``xr_kit``): the window enters the headset through the section's
buttons, mirrors the eyes on the desktop, leaves, and draws its own view again as it
was; an Enter that fails leaves the desktop drawing and says why in the panel, in one
line (in this process: no session is made).

Each session runs in a child process (``xr_kit.run_child``: this Monado closes file
descriptor 0), a window on GLFW's null platform with an EGL context (no X server). The
child drives the real viewer loop with the tests' panel driver (``appkit``: it clicks
the section's buttons where the panel drew them) and prints one JSON line that the
tests read.

The known answers: Monado's null compositor recommends 320x240 per eye (its README in
``../shared/openxr``), so the resolution scales 0.5 and 0.25 give 160x120 and 80x60
eyes; the mirror of both eyes side by side is 4:1.5 (8:3), which letterboxes into the
320x240 window as 320x120 starting at row 60, and the left eye alone (4:3) fills it.
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
import xr_kit
from appkit import (
    PANEL_HEIGHT,
    PANEL_WIDTH,
    click_choice,
    presented,
    text_past_the_panel,
)

from raygs_viewer.viewer.layout import MIN_PANEL_WIDTH
from raygs_viewer.viewer.state import HeadsetChoices

#: The tests that open a session (in a child): skipped where no runtime can run.
needs_runtime = pytest.mark.skipif(xr_kit.skip_reason() is not None, reason=str(xr_kit.skip_reason()))

#: What each child starts with: the panel driver (appkit), a 320x240 window on the demo
#: scene, and what the tests compare before and after the headset.
PRELUDE = r"""
import json, sys
from pathlib import Path

import numpy as np

sys.path.insert(0, "tests")
from appkit import click_choice, open_viewer_factory, presented

open_, close_all = open_viewer_factory(Path(sys.argv[1]))
viewer, drive = open_(width=320, height=240)
headset = viewer.headset

def desktop():
    camera = viewer.camera
    return dict(camera=[camera.R.tolist(), camera.t.tolist(), camera.fx, camera.fy, camera.cx, camera.cy,
                        camera.width, camera.height],
                settings=repr(viewer.settings), viewport=list(viewer.viewport))

def frames_until(done, limit=300):
    for _ in range(limit):
        if done():
            return True
        drive.frames(1)
    return done()

def spread(image):
    # How much a picture varies: a uniform grey (nothing drawn) has none.
    return float(np.asarray(image, float).std())
"""

#: Two rounds of Enter headset, headset frames, Leave headset: each with its own
#: resolution scale (set before Enter, as the section's slider sets it); the second
#: presses Recentre (the headset's own method, counted) and switches the mirror to the
#: left eye through the section's combo while in the headset.
ROUNDS = PRELUDE + r"""
rounds = []
try:
    drive.frames(3)
    drive.reveal("Headset")
    drive.click("Headset")  # the section starts closed
    drive.reveal("Enter headset")
    drive.settle()
    for scale, mirror in ((0.5, None), (0.25, "left eye")):
        before, image_before, draws_before = desktop(), presented(viewer), viewer.stats.draws
        headset.choices.scale = scale
        drive.click("Enter headset")
        entered = dict(message=viewer.panel.message, error=viewer.panel.error)
        running = frames_until(lambda: headset.running and headset.stats.ended >= 2)
        stats = headset.stats
        mirrored = dict(submitted=stats.ended, layered=stats.layered,
                        sizes=[list(size) for size in headset.session.sizes], viewport=list(viewer.viewport),
                        mirror_size=list(viewer.drawer.mono.stereo_image.size),
                        desktop_draws=viewer.stats.draws - draws_before,
                        spread=spread(presented(viewer)), labels=drive.panel.labels(),
                        differs=not np.array_equal(presented(viewer), image_before))
        if mirror is not None:
            recentred = []
            recentre = headset.recentre
            headset.recentre = lambda: (recentred.append(headset.stats.ended), recentre())
            drive.click("Recentre")
            mirrored.update(recentred=recentred)
            click_choice(drive, "mirror", mirror)
            ended = headset.stats.ended
            frames_until(lambda: headset.stats.ended >= ended + 2)
            mirrored.update(switched_viewport=list(viewer.viewport),
                            switched_mirror_size=list(viewer.drawer.mono.stereo_image.size))
        drive.click("Leave headset")
        left = frames_until(lambda: not headset.active)
        draws_left = viewer.stats.draws
        drive.settle()
        image_after = presented(viewer)
        rounds.append(dict(
            entered=entered, running=running, mirrored=mirrored,
            left=left, message_left=viewer.panel.message, error_left=viewer.panel.error,
            draws_after=viewer.stats.draws - draws_left, mirror_gone=viewer.drawer.mono.stereo_image is None,
            before=before, after=desktop(), same_image=bool(np.array_equal(image_before, image_after)),
            spread_after=spread(image_after), labels_after=drive.panel.labels()))
finally:
    close_all()
print(json.dumps(rounds))
"""

def test_the_section_edits_the_windows_choices_and_fits_the_narrowest_panel(open_viewer):
    """In process, with no session (Enter is never pressed): this needs no runtime."""
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=3 * PANEL_HEIGHT)  # the whole panel: no scroll bar
    viewer.panel.width = MIN_PANEL_WIDTH
    drive.frames(2)
    assert "Enter headset" not in drive.panel  # closed until opened
    drive.click("Headset")
    assert "Enter headset" in drive.panel and "Recentre" not in drive.panel
    drive.click_left_end("resolution scale")
    drive.click("Depth for reprojection")
    click_choice(drive, "mirror", "left eye")
    click_choice(drive, "turning", "smooth")
    choices = viewer.headset.choices
    assert 0.1 <= choices.scale < 0.15  # the slider's lowest end: 0.1 of the recommended size
    assert (choices.depth, choices.mirror, choices.turn) == (True, "left", "smooth")
    assert viewer.options.headset == HeadsetChoices()  # the window's copy changed, never the options
    assert viewer.headset.session is None and not viewer.headset.active
    cut = text_past_the_panel(drive)
    assert cut == [], "\n".join(cut)


def run_script(script: str, tmp_path, **env) -> list[dict]:
    done = xr_kit.run_child(["-c", script, str(tmp_path)], xr_kit.runtime_env(**env))
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@needs_runtime
def test_entering_and_leaving_twice_mirrors_the_eyes_then_draws_the_desktop_as_it_was(tmp_path):
    first, second = run_script(ROUNDS, tmp_path)
    for index, (done, eye) in enumerate(((first, [160, 120]), (second, [80, 60]))):
        assert done["entered"]["error"] == "", done["entered"]
        assert done["entered"]["message"].startswith("headset: Monado"), done["entered"]
        assert done["entered"]["message"].endswith(f"{eye[0]}x{eye[1]} per eye")
        mirrored = done["mirrored"]
        assert done["running"] and mirrored["submitted"] >= 2 and mirrored["layered"] >= 1
        # The scale was taken at Enter: the runtime's 320x240 times it.
        assert mirrored["sizes"] == [eye, eye]
        # The desktop shows the mirror of both eyes side by side, letterboxed, and never
        # draws its own view meanwhile.
        assert mirrored["mirror_size"] == [2 * eye[0], eye[1]]
        assert mirrored["viewport"] == [0, 60, 320, 120]
        assert mirrored["desktop_draws"] == 0
        assert mirrored["spread"] > 5.0 and mirrored["differs"]  # the eyes, not the grey, nor the desktop's view
        labels = mirrored["labels"]
        assert "Leave headset" in labels and "Recentre" in labels and "Enter headset" not in labels
        assert "resolution scale" not in labels  # taken at Enter: not offered while in the headset
        assert any(label.startswith("Monado") for label in labels)
        assert f"{eye[0]}x{eye[1]} per eye, depth off" in labels
        assert any(label.startswith("headset frames: ") for label in labels)
        # Left: the desktop draws its own view again, the view and settings as before.
        assert done["left"] and done["message_left"] == "left the headset" and done["error_left"] == ""
        assert done["draws_after"] >= 1 and done["mirror_gone"]
        assert done["after"] == done["before"], index
        assert done["same_image"] and done["spread_after"] > 5.0
        labels = done["labels_after"]
        assert "Enter headset" in labels and "resolution scale" in labels and "Leave headset" not in labels
    # Recentre asked the headset once; the mirror switched to the left eye while in the
    # headset fills the 4:3 window.
    assert len(second["mirrored"]["recentred"]) == 1
    assert second["mirrored"]["switched_mirror_size"] == [80, 60]
    assert second["mirrored"]["switched_viewport"] == [0, 0, 320, 240]


def test_a_failing_enter_says_why_in_one_line_and_the_desktop_draws_on(open_viewer, tmp_path, monkeypatch):
    """Enter with a runtime whose library is not there, then with pyopenxr missing. No
    session is made either time (each fails before the loader is asked), so this runs
    in the test's own process and needs no runtime."""
    manifest = tmp_path / "broken_runtime.json"
    manifest.write_text(json.dumps({"file_format_version": "1.0.0",
                                    "runtime": {"library_path": str(tmp_path / "libmissing_openxr.so")}}))
    monkeypatch.setenv("XR_RUNTIME_JSON", str(manifest))
    viewer, drive = open_viewer(width=320, height=240)
    headset = viewer.headset
    drive.frames(3)
    drive.reveal("Headset")
    drive.click("Headset")  # the section starts closed
    drive.reveal("Enter headset")
    drive.settle()
    tries = []
    for blocked in (False, True):
        if blocked:
            monkeypatch.setitem(sys.modules, "xr", None)  # import xr raises ImportError: pyopenxr missing
        draws = viewer.stats.draws
        drive.click("Enter headset")
        error, active, session = viewer.panel.error, headset.active, headset.session is not None
        drive.frames(1)  # the panel draws the error line
        fx_before = viewer.camera.fx
        viewer.view.set_fov(viewer.view.lens.fov_y_degrees * 0.8)  # a new view: the desktop draws it
        drive.settle()
        tries.append({"error": error, "active": active, "session": session, "labels": drive.panel.labels(),
                      "draws": viewer.stats.draws - draws, "mirror_gone": viewer.drawer.mono.stereo_image is None,
                      "fx_before": fx_before, "fx_after": viewer.camera.fx,
                      "spread": float(np.asarray(presented(viewer), float).std())})
    missing_library, no_pyopenxr = tries
    for tried in tries:
        error = tried["error"]
        assert error.startswith("error: ") and "\n" not in error, error
        assert error in tried["labels"]  # drawn in the panel
        assert not tried["active"] and not tried["session"]
        assert "Enter headset" in tried["labels"] and "Leave headset" not in tried["labels"]
        # The desktop draws on: the narrower field of view is drawn, its own view, not a mirror.
        assert tried["draws"] >= 1 and tried["mirror_gone"] and tried["spread"] > 5.0
        assert tried["fx_after"] > tried["fx_before"]
    assert "pyopenxr" in no_pyopenxr["error"]
    assert "libmissing_openxr.so" in missing_library["error"] and "pyopenxr" not in missing_library["error"]
