"""The window's camera path: keyframes by key and panel, playback along the path, the
path drawn over the view, its file, and Render video as a background job (with stand-in
commands for render-path)."""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import av
import numpy as np
import pytest
from appkit import PANEL_HEIGHT, PANEL_WIDTH, WIDTH, click_choice, project
from imgui_bundle import imgui  # before glfw (see raygs_viewer.viewer.window)
from PIL import Image

from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.path import CameraPath, Keyframe
from raygs_viewer.capture.path_file import load_path_document, save_path_document
from raygs_viewer.capture.progress import FrameProgress, RenderDone, RenderInterrupted, progress_line
from raygs_viewer.cli.main import main
from raygs_viewer.viewer.path_overlay import frustum_lines, screen_segments
from raygs_viewer.viewer.video_job import (
    VIDEO_SIZES,
    VideoJob,
    progress_text,
    render_path_command,
    write_video_document,
)

PATH_PANEL = {"width": PANEL_WIDTH, "height": PANEL_HEIGHT}


def click(drive, label: str) -> None:
    """Clicks the panel's widget ``label`` (appkit.Panel's names: the label as the panel
    passes it to imgui), scrolling the panel to it first."""
    drive.frames(1)  # the panel as it is now (an edit may have moved the widgets)
    drive.reveal(label)
    drive.click(label)


def same_pose(a: Pose, b: Pose) -> bool:
    return np.array_equal(a.position, b.position) and np.array_equal(a.R, b.R)


def keyframe_ahead(camera, distance: float, right: float = 0.0, fov: float = 50.0) -> Keyframe:
    """A keyframe ``distance`` ahead of ``camera`` (and ``right`` to its right), looking the same way."""
    return Keyframe(Pose(camera.center + distance * camera.R[2] + right * camera.R[0], camera.R), fov)


def shows_pose_at(viewer, time_s: float) -> None:
    """The frame's camera is the path's camera at ``time_s``, bit for bit."""
    camera = viewer.camera
    expected = viewer.camera_path.path.pose_at(time_s).camera(camera.width, camera.height)
    np.testing.assert_array_equal(camera.R, expected.R)
    np.testing.assert_array_equal(camera.t, expected.t)
    assert (camera.fx, camera.fy, camera.cx, camera.cy) == (expected.fx, expected.fy, expected.cx, expected.cy)


# -- keyframes ---------------------------------------------------------------------------
def test_k_adds_the_current_view_after_the_selected_keyframe(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    drive.tap(imgui.Key.k)
    first = viewer.camera_path.path.keyframes
    assert len(first) == 1 and viewer.camera_path.selected == 0
    assert same_pose(first[0].pose, viewer.view.navigator.pose)
    np.testing.assert_allclose(first[0].pose.position, viewer.camera.center, atol=1e-12)
    np.testing.assert_array_equal(first[0].pose.R, viewer.camera.R)
    assert first[0].fov_y_degrees == viewer.view.lens.fov_y_degrees
    assert Keyframe.of_camera(viewer.camera).fov_y_degrees == pytest.approx(first[0].fov_y_degrees, abs=1e-9)

    drive.key(imgui.Key.w, True)
    drive.frames(1)
    drive.key(imgui.Key.w, False)
    drive.tap(imgui.Key.k)          # appended after the selected (last) one
    second = viewer.view.navigator.pose
    viewer.camera_path.select(0)
    drive.key(imgui.Key.d, True)
    drive.frames(1)
    drive.key(imgui.Key.d, False)
    drive.tap(imgui.Key.k)          # inserted after keyframe 0
    third = viewer.view.navigator.pose
    poses = [k.pose for k in viewer.camera_path.path.keyframes]
    assert [same_pose(p, q) for p, q in zip(poses, [first[0].pose, third, second])] == [True] * 3
    assert viewer.camera_path.selected == 1
    up = tuple(viewer.view.navigator.up_vector)
    assert viewer.camera_path.path.interpolation.up == up


def test_panel_buttons_add_select_reorder_delete_and_retime(open_viewer):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(2)
    click(drive, "Add view (K)")
    a = viewer.view.navigator.pose
    drive.move_mouse(PANEL_WIDTH - 10, PANEL_HEIGHT - 10)  # over the view: letters fly there, not on the panel
    drive.key(imgui.Key.w, True)
    drive.frames(1)
    drive.key(imgui.Key.w, False)
    drive.frames(1)
    click(drive, "Add view (K)")
    b = viewer.view.navigator.pose
    path = viewer.camera_path.path
    assert len(path.keyframes) == 2 and same_pose(path.keyframes[0].pose, a) and same_pose(path.keyframes[1].pose, b)

    drive.reveal("Go to##keyframe")  # the list just above it: a list box scrolled out of sight draws no entries
    click(drive, "##keyframe0")
    assert viewer.camera_path.selected == 0
    click(drive, "Down##keyframe")
    assert [same_pose(k.pose, p) for k, p in zip(viewer.camera_path.path.keyframes, (b, a))] == [True, True]
    assert viewer.camera_path.selected == 1  # the moved keyframe stays selected
    click(drive, "Up##keyframe")
    assert same_pose(viewer.camera_path.path.keyframes[0].pose, a)

    # Retime: "auto time" off pins the keyframe at its current time; the field then sets it.
    click(drive, "##keyframe1")
    click(drive, "auto time")
    assert viewer.camera_path.path.keyframes[1].time == pytest.approx(viewer.camera_path.path.duration)
    viewer.camera_path.set_time(1, 7.5)   # what typing into the time field does
    assert viewer.camera_path.path.keyframes[1].time == 7.5
    click(drive, "auto time")
    assert viewer.camera_path.path.keyframes[1].time is None
    viewer.camera_path.set_fov(1, 35.0)  # the fov slider's callback
    assert viewer.camera_path.path.keyframes[1].fov_y_degrees == 35.0

    # An edit the path refuses stands in the error line, and the path stays.
    before = viewer.camera_path.path
    viewer.panel.say(viewer.camera_path.set_duration(-1.0))
    assert viewer.panel.error.startswith("error: ") and "duration" in viewer.panel.error
    assert viewer.camera_path.path is before
    drive.frames(1)  # drawn as a line, not raised
    viewer.panel.say(viewer.camera_path.set_fps(24.0))  # an edit that goes through mends it
    assert viewer.panel.error == "" and viewer.camera_path.path.fps == 24.0

    click(drive, "Add training cameras")  # after the selected keyframe 1: at the end
    cameras = viewer.loaded.cameras
    keys = viewer.camera_path.path.keyframes
    assert len(keys) == 2 + len(cameras)
    for keyframe, camera in zip(keys[2:], cameras):
        assert same_pose(keyframe.pose, Keyframe.of_camera(camera).pose)
        assert keyframe.fov_y_degrees == pytest.approx(Keyframe.of_camera(camera).fov_y_degrees)

    click(drive, "##keyframe0")
    click(drive, "Delete##keyframe")
    assert len(viewer.camera_path.path.keyframes) == 1 + len(cameras)
    assert same_pose(viewer.camera_path.path.keyframes[0].pose, b)
    click(drive, "Clear##path")
    assert viewer.camera_path.path.keyframes == () and viewer.camera_path.selected is None


def test_go_to_shows_the_keyframe_and_generators_replace_the_path(open_viewer):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    camera = viewer.camera
    viewer.camera_path.add([keyframe_ahead(camera, 1.0, fov=40.0), keyframe_ahead(camera, 2.0)])
    drive.frames(1)
    drive.reveal("duration (s)")  # a list box scrolled out of the panel draws no rows
    click(drive, "##keyframe0")
    click(drive, "Go to##keyframe")
    drive.frames(1)  # the panel's edits show from the next frame
    assert same_pose(viewer.view.navigator.pose, viewer.camera_path.path.keyframes[0].pose)
    assert viewer.view.lens.fov_y_degrees == 40.0
    viewer.camera_path.dolly_distance = 0.5   # what typing into the units field does
    click(drive, "Dolly")
    assert viewer.panel.error == ""
    assert len(viewer.camera_path.path.keyframes) >= 2 and viewer.camera_path.selected is None
    start, end = viewer.camera_path.path.keyframes[0].pose, viewer.camera_path.path.keyframes[-1].pose
    np.testing.assert_allclose(start.position, viewer.camera.center, atol=1e-9)
    np.testing.assert_allclose(end.position - start.position, 0.5 * viewer.camera.R[2], atol=1e-9)
    assert viewer.camera_path.path.interpolation.up == tuple(viewer.view.navigator.up_vector)
    click(drive, "Orbit")
    assert viewer.camera_path.path.interpolation.loop
    centre = viewer.view.center
    distances = [np.linalg.norm(k.pose.position - centre) for k in viewer.camera_path.path.keyframes]
    np.testing.assert_allclose(distances, distances[0], rtol=1e-6)


# -- playback ----------------------------------------------------------------------------
def test_play_follows_the_path_and_an_open_path_stops_at_its_end(open_viewer):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    camera = viewer.camera
    viewer.camera_path.add([keyframe_ahead(camera, 0.0), keyframe_ahead(camera, 1.0, 0.5, fov=40.0),
                      keyframe_ahead(camera, 2.0, fov=70.0)])
    viewer.camera_path.set_duration(0.55)
    click(drive, "Play###play")
    assert viewer.camera_path.playback.playing
    drive.frames(1)  # the panel's edits show from the next frame: its first frame of playback
    start = viewer.camera_path.playback.time
    shows_pose_at(viewer, start)
    for k in range(1, 4):
        drive.frames(1)
        assert viewer.camera_path.playback.time == pytest.approx(start + 0.1 * k)   # the frame's dt (fixed in tests)
        shows_pose_at(viewer, viewer.camera_path.playback.time)
    drive.frames(5)
    assert not viewer.camera_path.playback.playing
    assert viewer.camera_path.playback.time == 0.55
    shows_pose_at(viewer, 0.55)
    assert viewer.camera_path.playback.frame_number(viewer.camera_path.path) == viewer.camera_path.path.frame_count - 1
    # the sort follows the played view like any move
    drive.settle()
    assert viewer.stats.order_age == 0

    # Play at the end starts over; a loop wraps instead of stopping.
    viewer.camera_path.set_loop(True)
    click(drive, "Play###play")
    assert viewer.camera_path.playback.playing and viewer.camera_path.playback.time < 0.55
    drive.frames(8)
    assert viewer.camera_path.playback.playing
    assert 0.0 <= viewer.camera_path.playback.time < 0.55
    shows_pose_at(viewer, viewer.camera_path.playback.time)
    click(drive, "Pause###play")  # the same button, playing
    assert not viewer.camera_path.playback.playing


def test_user_input_pauses_playback_and_keeps_the_users_view(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    camera = viewer.camera
    viewer.camera_path.add([keyframe_ahead(camera, 0.0), keyframe_ahead(camera, 2.0)])
    viewer.camera_path.play()
    drive.frames(3)
    assert viewer.camera_path.playback.playing
    played = viewer.camera
    drive.key(imgui.Key.d, True)
    drive.frames(1)
    drive.key(imgui.Key.d, False)
    drive.frames(2)
    assert not viewer.camera_path.playback.playing
    step = played.R @ (viewer.camera.center - played.center)  # the key's move, in the camera's axes
    assert step[0] == pytest.approx(viewer.view.navigator.speed * 0.1, rel=1e-6)
    # a field of view set in the panel pauses it too
    viewer.camera_path.play()
    drive.frames(2)
    viewer.view.set_fov(33.0)
    drive.frames(1)
    assert not viewer.camera_path.playback.playing and viewer.view.lens.fov_y_degrees == 33.0


def test_scrub_and_step_show_the_path_at_that_time(open_viewer):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    camera = viewer.camera
    viewer.camera_path.add([keyframe_ahead(camera, 0.0), keyframe_ahead(camera, 1.0, fov=45.0)])
    viewer.camera_path.set_duration(1.0)
    viewer.camera_path.set_fps(10.0)
    drive.frames(1)
    drive.reveal("##scrub")
    drive.click("##scrub")  # the slider's middle: about half the duration
    drive.frames(1)
    start = viewer.camera_path.playback.time
    assert 0.2 < start < 0.8 and not viewer.camera_path.playback.playing
    shows_pose_at(viewer, start)
    frame = viewer.camera_path.playback.frame_number(viewer.camera_path.path)
    for _ in range(3):
        click(drive, "##step forward")
    drive.frames(1)
    assert viewer.camera_path.playback.frame_number(viewer.camera_path.path) == frame + 3
    # 10 frames over 1 s, the first and last on the path's ends: one each 1/9 s
    assert viewer.camera_path.playback.time == pytest.approx((frame + 3) / 9)
    shows_pose_at(viewer, viewer.camera_path.playback.time)
    click(drive, "##step back")
    drive.frames(1)
    assert viewer.camera_path.playback.frame_number(viewer.camera_path.path) == frame + 2
    shows_pose_at(viewer, viewer.camera_path.playback.time)


# -- the path over the view ---------------------------------------------------------------
def test_the_overlay_projects_keyframes_where_the_camera_sees_them_and_nothing_behind(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    camera = viewer.camera
    ahead = [keyframe_ahead(camera, 2.0, -0.3), keyframe_ahead(camera, 2.5, 0.3)]
    viewer.camera_path.add(ahead)
    drive.frames(1)
    drawn = viewer.camera_path.drawn
    assert set(drawn.keyframe_points) == {0, 1}
    for index, keyframe in enumerate(ahead):
        u, v, _ = project(viewer.camera, keyframe.pose.position)  # null platform: screen = framebuffer pixels
        assert drawn.keyframe_points[index] == pytest.approx((u, v), abs=1e-6)
    assert drawn.polyline_segments > 0 and drawn.frustum_segments > 0

    viewer.camera_path.show = False
    drive.frames(1)
    assert viewer.camera_path.drawn.segments == 0
    viewer.camera_path.show = True

    viewer.camera_path.clear()
    viewer.camera_path.add([keyframe_ahead(camera, -2.0, -0.3), keyframe_ahead(camera, -3.0, 0.3)])  # behind
    drive.frames(1)
    assert viewer.camera_path.drawn.segments == 0 and viewer.camera_path.drawn.keyframe_points == {}

    viewer.camera_path.clear()
    viewer.camera_path.add([keyframe_ahead(camera, -2.0, 0.2), keyframe_ahead(camera, 2.0, 0.2)])  # through the camera
    drive.frames(1)
    assert viewer.camera_path.drawn.polyline_segments > 0 and list(viewer.camera_path.drawn.keyframe_points) == [1]


def test_screen_segments_cut_at_the_near_plane_and_the_viewport(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    camera = viewer.camera
    rect = (0.0, 0.0, float(camera.width), float(camera.height))
    ahead, behind = camera.center + 2.0 * camera.R[2], camera.center - 2.0 * camera.R[2] + 0.1 * camera.R[0]
    (segment,) = screen_segments(camera, ahead[None], behind[None], rect, near=0.5)
    # one end is the point ahead; the other the crossing of the near plane, never the wrapped projection
    crossing = ahead + (2.0 - 0.5) / 4.0 * (behind - ahead)
    assert segment[0] == pytest.approx(project(camera, ahead)[:2], abs=1e-6)
    assert np.isfinite(segment).all()
    u, v, depth = project(camera, crossing)
    assert depth == pytest.approx(0.5)
    end = np.clip([u, v], [0, 0], [camera.width, camera.height])
    assert segment[1] == pytest.approx(end, abs=1e-6)
    assert len(screen_segments(camera, behind[None], (behind - camera.R[2])[None], rect, near=0.5)) == 0
    # a segment off to the side stays outside
    far_right = ahead + 10.0 * camera.R[0]
    assert len(screen_segments(camera, far_right[None], (far_right + camera.R[1])[None], rect, near=0.5)) == 0
    assert WIDTH == camera.width

    # A keyframe at the view itself: its frustum's rim is the image's border.
    keyframe = Keyframe(viewer.view.navigator.pose, viewer.view.lens.fov_y_degrees)
    _, ends = frustum_lines(CameraPath((keyframe,)), 0.7, camera.width / camera.height)
    corners = [project(camera, corner)[:2] for corner in ends[:4]]
    w, h = camera.width, camera.height
    np.testing.assert_allclose(corners, [(0, 0), (w, 0), (w, h), (0, h)], atol=1e-9)


# -- files -------------------------------------------------------------------------------
def test_save_and_load_through_the_panel_round_trip(open_viewer, tmp_path):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    camera = viewer.camera
    viewer.camera_path.add([keyframe_ahead(camera, 0.0), keyframe_ahead(camera, 1.0, 0.2, fov=42.0)])
    viewer.camera_path.set_duration(4.0)
    viewer.camera_path.set_loop(True)
    saved = viewer.camera_path.path
    file = tmp_path / "fly.json"
    viewer.camera_path.file = str(file)   # what typing into the file field does
    drive.frames(1)
    click(drive, "Save##path")
    assert file.exists() and viewer.panel.message == f"saved {file}"
    document = load_path_document(file)
    assert (document.width, document.height) == (viewer.camera.width, viewer.camera.height)
    assert document.settings == viewer.settings and document.stereo is None
    assert document.scene_path == "demo" and document.scene_sha256 == viewer.loaded.sha256

    click(drive, "Save##path")  # never replaces it unless asked to
    assert "already exists" in viewer.panel.error
    viewer.camera_path.set_fps(12.0)
    click(drive, "overwrite")
    click(drive, "Save##path")
    assert viewer.panel.error == "" and load_path_document(file).path.fps == 12.0
    saved = viewer.camera_path.path
    click(drive, "Clear##path")
    click(drive, "Load##path")
    loaded = viewer.camera_path.path
    assert viewer.panel.error == "" and viewer.panel.message.startswith(f"loaded {file}: 2 keyframes")
    assert (loaded.duration, loaded.fps, loaded.interpolation.loop) == (4.0, saved.fps, True)
    for got, want in zip(loaded.keyframes, saved.keyframes, strict=True):
        np.testing.assert_allclose(got.pose.position, want.pose.position, atol=1e-12)
        np.testing.assert_allclose(got.pose.R, want.pose.R, atol=1e-12)
        assert got.fov_y_degrees == pytest.approx(want.fov_y_degrees) and got.time == want.time

    # Exported for nerfstudio, the path's frames load back (the frames its camera_path holds).
    exported = tmp_path / "camera_path.json"
    viewer.camera_path.file = str(exported)
    click(drive, "Export nerfstudio")
    assert viewer.panel.message == f"saved {exported}"
    theirs = load_path_document(exported)
    assert theirs.kind == "nerfstudio" and len(theirs.path.keyframes) == loaded.frame_count
    second_frame = loaded.pose_at(loaded.frame_times()[1]).pose
    np.testing.assert_allclose(theirs.path.keyframes[1].pose.position, second_frame.position, atol=1e-12)

    # A path recorded on another scene loads, with a note.
    other = tmp_path / "other.json"
    save_path_document(replace(document, scene_path="/elsewhere/scene.ply", scene_sha256="0" * 64), other)
    viewer.camera_path.file = str(other)
    click(drive, "Load##path")
    assert len(viewer.camera_path.path.keyframes) == 2
    assert "recorded on" in viewer.panel.message and viewer.panel.error == ""


@pytest.mark.parametrize("content", ["{", '{"format": "raygs-viewer camera path", "version": 1}', None])
def test_a_bad_path_file_gives_an_error_line_and_keeps_the_path(open_viewer, tmp_path, content):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    click(drive, "Add view (K)")
    before = viewer.camera_path.path
    file = tmp_path / "bad.json"
    if content is not None:
        file.write_text(content)
    viewer.camera_path.file = str(file)
    click(drive, "Load##path")
    assert viewer.panel.error.startswith("error: path not loaded: ") and "\n" not in viewer.panel.error
    assert viewer.camera_path.path is before


# -- Render video --------------------------------------------------------------------------
def stand_in(lines: list[str], tail: str = "") -> list[str]:
    """A stand-in for render-path: prints ``lines`` (one JSON object each) with pauses, then runs ``tail``."""
    script = ("import json, sys, time\n"
              f"for line in {lines!r}:\n"
              "    print(line, flush=True)\n"
              "    time.sleep(0.05)\n" + tail)
    return [sys.executable, "-c", script]


def line(record) -> str:
    """``record`` as render-path prints it, without the newline (the stand-ins print it)."""
    return progress_line(record).rstrip("\n")


PROGRESS = [line(FrameProgress(k, 3, 5.0, (3 - k) / 5.0)) for k in (1, 2, 3)]
DONE = line(RenderDone("OUT", 3))
#: Prints one progress line, then renders "forever" until SIGINT, as render-path does on Ctrl-C.
INTERRUPTIBLE = [sys.executable, "-c", (  # as render-path --progress json: SIGINT stops it, even if inherited ignored
    "import json, signal, sys, time\n"
    "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
    "try:\n"
    f"    print({PROGRESS[0]!r}, flush=True)\n"
    "    while True:\n"
    "        time.sleep(0.02)\n"
    "except KeyboardInterrupt:\n"
    f"    print({line(RenderInterrupted(1, None))!r}, flush=True)\n"
    "    sys.exit(130)\n")]


def wait_for_progress(job: VideoJob, drive=None) -> None:
    """Until the job has reported a frame (drawing frames meanwhile when ``drive`` is given)."""
    deadline = time.monotonic() + 20
    while job.progress is None or job.progress.frame < 1:
        assert time.monotonic() < deadline, "no progress from the job"
        if drive is not None:
            drive.frames(1)
        time.sleep(0.01)


def finish(job: VideoJob, timeout: float = 20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        result = job.poll()
        if result is not None:
            return result
        time.sleep(0.01)
    job.close(timeout=1.0)
    raise AssertionError("the job did not end")


def test_render_path_command_line():
    assert render_path_command("demo", Path("v/a.json"), Path("v/a.mp4")) == [
        sys.executable, "-m", "raygs_viewer", "render-path", "demo", "v/a.json", "--out", "v/a.mp4",
        "--progress", "json"]


def test_video_job_progress_done_error_and_cancel(tmp_path):
    out, doc = tmp_path / "a.mp4", tmp_path / "a.json"
    job = VideoJob(stand_in(PROGRESS + [DONE]), out, doc)
    result = finish(job)
    assert result.kind == "done" and result.message.startswith("saved OUT (3 frames")
    assert job.progress.frame == 3 and job.progress.fraction == 1.0
    assert progress_text(job.progress) == "frame 3 / 3, 5 fps, 0 s left"
    assert job.poll() is None  # reported once

    # Lines of another version, or not progress lines at all, are passed over: the last
    # frame and the end shown are those of version 1.
    other = ['{"progress": 2, "frame": 9, "frames": 9, "fps": 1.0, "eta_s": 0.0}', "rendering...", "[1, 2]",
             '{"frame": 8, "frames": 9, "fps": 1.0, "eta_s": 1.0}', '{"progress": 1, "frame": "7", "frames": 9}']
    job = VideoJob(stand_in(PROGRESS + other + [DONE, '{"progress": 2, "done": true, "out": "NEW", "frames": 9}']),
                   out, doc)
    result = finish(job)
    assert result.kind == "done" and result.message.startswith("saved OUT (3 frames")
    assert job.progress == FrameProgress(3, 3, 5.0, 0.0)

    job = VideoJob(stand_in(PROGRESS[:1], "print('error: out.mp4: cannot write', file=sys.stderr)\nsys.exit(2)\n"),
                   out, doc)
    assert finish(job) == type(result)("error", "error: out.mp4: cannot write")

    job = VideoJob(stand_in([], "print('Traceback (most recent call last):', file=sys.stderr)\nsys.exit(1)\n"),
                   out, doc)
    result = finish(job)
    assert result.kind == "error" and "exit status 1" in result.message

    job = VideoJob(INTERRUPTIBLE, out, doc)
    wait_for_progress(job)
    job.cancel()
    result = finish(job)
    assert result.kind == "interrupted" and result.message == "video cancelled: no video was written"
    assert job.process.returncode == 130


def test_video_documents_never_clobber(open_viewer, tmp_path):
    from datetime import datetime
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    drive.tap(imgui.Key.k)
    now = datetime(2026, 11, 21, 10, 15, 0)
    folder = tmp_path / "videos"
    first = write_video_document(viewer.camera_path.document(viewer.path_scene()), folder, now)
    assert first == (folder / "raygs-20261121-101500.json", folder / "raygs-20261121-101500.mp4")
    (folder / "raygs-20261121-101500-2.mp4").write_bytes(b"taken")
    second = write_video_document(viewer.camera_path.document(viewer.path_scene()), folder, now)
    assert second[0].name == "raygs-20261121-101500-3.json" and not second[1].exists()
    assert first[0].read_bytes() != b"" and (folder / "raygs-20261121-101500-2.mp4").read_bytes() == b"taken"


def test_render_video_runs_in_the_background_while_the_window_keeps_drawing(open_viewer, tmp_path):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    camera = viewer.camera
    viewer.camera_path.add([keyframe_ahead(camera, 0.0), keyframe_ahead(camera, 1.0)])
    viewer.camera_path.video.folder = str(tmp_path / "videos")
    release = tmp_path / "release"
    calls = []

    def command(scene, document, out):
        calls.append((scene, document, out))
        return stand_in(PROGRESS[:2], f"while not __import__('os').path.exists({str(release)!r}):\n"
                                      "    time.sleep(0.01)\n"
                                      f"print({PROGRESS[2]!r}, flush=True)\n"
                                      f"print({line(RenderDone(str(out), 3))!r})\n")
    viewer.camera_path.video.command = command
    drive.frames(1)
    click(drive, "Render video")
    (scene, document, out), = calls
    assert scene == "demo" and document.parent == out.parent == tmp_path / "videos"
    assert document.suffix == ".json" and out.suffix == ".mp4" and document.stem == out.stem
    saved = load_path_document(document)
    assert len(saved.path.keyframes) == 2 and (saved.width, saved.height) == (camera.width, camera.height)
    job = viewer.camera_path.video.job
    assert job is not None and job.running
    deadline = time.monotonic() + 20
    frames = viewer.frame_index
    while (job.progress is None or job.progress.frame < 2) and time.monotonic() < deadline:
        drive.frames(1)
    drive.frames(2)
    assert job.running and viewer.frame_index >= frames + 3   # frames keep coming while it renders
    # The job waits for the release after its second frame: the bar's text stands still.
    assert drive.panel.labels("progress_bar") == [progress_text(job.progress)] and "Cancel##video" in drive.panel
    release.write_text("go")
    while viewer.camera_path.video.job is not None and time.monotonic() < deadline:
        drive.frames(1)
        time.sleep(0.01)
    assert viewer.camera_path.video.job is None and viewer.panel.error == ""
    assert viewer.panel.message.startswith(f"saved {out} (3 frames")


def test_cancel_and_closing_the_window_stop_the_job(open_viewer, tmp_path):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    click(drive, "Add view (K)")
    viewer.camera_path.video.folder = str(tmp_path / "videos")
    viewer.camera_path.video.command = lambda scene, document, out: INTERRUPTIBLE
    click(drive, "Render video")
    job = viewer.camera_path.video.job
    wait_for_progress(job, drive)
    deadline = time.monotonic() + 20
    click(drive, "Cancel##video")
    while viewer.camera_path.video.job is not None and time.monotonic() < deadline:
        drive.frames(1)
        time.sleep(0.01)
    assert viewer.panel.message == "video cancelled: no video was written"
    assert job.process.returncode == 130

    viewer.camera_path.video.command = lambda scene, document, out: stand_in(["{}"], "print('error: no such scene', "
                                                                          "file=sys.stderr)\nsys.exit(2)\n")
    click(drive, "Render video")
    viewer.camera_path.video.command = lambda scene, document, out: INTERRUPTIBLE
    while viewer.camera_path.video.job is not None and time.monotonic() < deadline:
        drive.frames(1)
        time.sleep(0.01)
    assert viewer.panel.error == "error: no such scene"

    click(drive, "Render video")
    job = viewer.camera_path.video.job
    wait_for_progress(job)
    viewer.close()
    assert job.process.returncode == 130  # it was interrupted, not killed


# -- end to end: the window's path through render-path -------------------------------------
def test_a_path_recorded_and_played_in_the_window_renders_as_it_was_shown(open_viewer, tmp_path):
    """Keyframes by key, playback paused at a frame, the path saved from the window:
    render-path's frame at that time is the window's (exact-sort) screenshot of it."""
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    drive.tap(imgui.Key.k)
    for key in (imgui.Key.w, imgui.Key.d):     # forward, then right and a turn
        drive.key(key, True)
        drive.frames(2)
        drive.key(key, False)
    drive.button(0, True)
    drive.move_mouse(WIDTH / 2 + 30, 60)
    drive.frames(1)
    drive.button(0, False)
    drive.tap(imgui.Key.k)
    widget = viewer.camera_path
    assert len(widget.path.keyframes) == 2
    widget.set_duration(0.3)                    # 9 frames at 30 fps
    k = 5
    widget.seek(widget.path.frame_times()[k])
    drive.frames(1)
    shot, _ = viewer.save_screenshot(tmp_path / "shot.png")
    saved = tmp_path / "path.json"
    widget.file = str(saved)
    viewer.panel.say(widget.save(viewer.path_scene()))
    assert viewer.panel.message == f"saved {saved}"

    frames = tmp_path / "frames"
    assert main(["render-path", "demo", str(saved), "--out", str(frames), "--progress", "none"]) == 0
    images = sorted(frames.glob("frame_*.png"))
    assert len(images) == 9
    rendered = np.asarray(Image.open(images[k]).convert("RGB")).astype(int)
    shown = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    assert rendered.shape == shown.shape == (viewer.camera.height, viewer.camera.width, 3)
    # The same view to the last bits of its pose (render-path's cameras go through cameras.json).
    difference = np.abs(rendered - shown)
    assert difference.max() <= 1 and np.count_nonzero(difference) <= 10
    neighbour = np.asarray(Image.open(images[k - 1]).convert("RGB")).astype(int)
    assert np.abs(neighbour - shown).max() > 8   # the frames differ: the comparison can tell them apart


def test_render_video_button_runs_the_real_render_path(open_viewer, tmp_path, monkeypatch):
    viewer, drive = open_viewer(**PATH_PANEL)
    drive.frames(1)
    camera = viewer.camera
    viewer.camera_path.add([keyframe_ahead(camera, 0.0), keyframe_ahead(camera, 0.5, fov=40.0)])
    viewer.camera_path.set_duration(0.3)
    viewer.camera_path.set_fps(10)
    viewer.camera_path.video.folder = str(tmp_path / "videos")
    drive.frames(1)
    drive.reveal("##video size")
    click_choice(drive, "##video size", "1280x720")
    assert viewer.camera_path.video.size == "1280x720"
    monkeypatch.setitem(VIDEO_SIZES, "1280x720", (64, 36))   # the choice, at a test's size
    click(drive, "Render video")
    deadline = time.monotonic() + 120
    while viewer.camera_path.video.job is not None and time.monotonic() < deadline:
        drive.frames(1)
        time.sleep(0.02)
    assert viewer.panel.error == "" and viewer.panel.message.startswith("saved ")
    video, = (tmp_path / "videos").glob("*.mp4")
    with av.open(str(video)) as container:
        stream = container.streams.video[0]
        frames = list(container.decode(stream))
        assert (stream.average_rate, len(frames)) == (10, 3)
        assert (frames[0].width, frames[0].height) == (64, 36)
