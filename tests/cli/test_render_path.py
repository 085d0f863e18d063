"""``raygs-viewer render-path``: a path file (the window's, or nerfstudio's) to an MP4 or
PNG frames, each frame with an exact sort, options over what the file recorded, Ctrl-C
and bad input."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import av
import numpy as np
import pytest
from PIL import Image

from raygs_viewer.camera.navigation import scene_bounds
from raygs_viewer.camera.path import path_through_cameras
from raygs_viewer.camera.pinhole import load_cameras
from raygs_viewer.camera.stereo import StereoRig, StereoView
from raygs_viewer.capture import path_render
from raygs_viewer.capture.path_file import PathDocument, export_nerfstudio, save_path_document
from raygs_viewer.capture.progress import FrameProgress, RenderDone, RenderInterrupted, read_progress_line
from raygs_viewer.capture.edit_file import EditDocument, edit_document_json
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.capture.sidecar import demo_sha256
from raygs_viewer.cli import path as path_command
from raygs_viewer.cli.main import main
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.demo import demo_cameras, demo_scene
from raygs_viewer.scene.edits import Edits, Operation
from raygs_viewer.scene.selection import Box

BACKGROUND = (0.2, 0.3, 0.4)


def demo_document(**changes) -> PathDocument:
    """Four frames (0.5 s at 8 fps) through three demo views at 48x32, recorded with a
    background that is not the default (so the tests see whether recorded settings apply)."""
    path = path_through_cameras(demo_cameras()[:3], duration=0.5, fps=8)
    document = PathDocument(path, 48, 32, RenderSettings(background=BACKGROUND), None, "demo", demo_sha256())
    return replace(document, **changes)


@pytest.fixture
def path_file(tmp_path) -> Path:
    return save_path_document(demo_document(), tmp_path / "fly.json")


def png(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


def frames_of(folder: Path) -> list[np.ndarray]:
    return [png(p) for p in sorted(folder.glob("frame_*.png"))]


def decoded(video: Path) -> tuple[list[np.ndarray], av.video.stream.VideoStream]:
    with av.open(str(video)) as container:
        stream = container.streams.video[0]
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]
        return frames, (stream.codec_context.name, stream.average_rate, stream.codec_context.pix_fmt)


def run(*argv: str) -> int:
    return main(["render-path", *argv, "--progress", "none"])


def test_each_png_frame_is_render_of_its_camera_bit_for_bit(tmp_path, path_file, capsys):
    frames, cameras = tmp_path / "frames", tmp_path / "cams.json"
    assert run("demo", str(path_file), "--out", str(frames), "--cameras-out", str(cameras)) == 0
    images = frames_of(frames)
    assert len(images) == 4 and images[0].shape == (32, 48, 3)
    assert len(json.loads(cameras.read_text())) == 4
    for k in (0, 3):
        out = tmp_path / f"render{k}.png"
        assert main(["render", "demo", "--camera", str(cameras), "--camera-index", str(k), "--out", str(out),
                     "--background", ",".join(map(str, BACKGROUND))]) == 0
        np.testing.assert_array_equal(images[k], png(out))
    # The frames move: a path rendered as one still would pass the comparison above.
    assert np.abs(images[0].astype(int) - images[3]).mean() > 2
    assert "4 frames, 48x32 at 8 fps" in capsys.readouterr().out


def test_mp4_has_the_frames_size_and_rate_of_the_path(tmp_path, path_file):
    video = tmp_path / "fly.mp4"
    assert run("demo", str(path_file), "--out", str(video)) == 0
    frames, (codec, rate, pix_fmt) = decoded(video)
    assert len(frames) == 4 and frames[0].shape == (32, 48, 3)
    assert (codec, rate, pix_fmt) == ("h264", 8, "yuv420p")
    pngs = tmp_path / "frames"
    assert run("demo", str(path_file), "--out", str(pngs)) == 0
    for frame, reference in zip(frames, frames_of(pngs)):  # each frame in its place, within H.264's error
        error = np.mean((frame.astype(float) - reference) ** 2)
        assert 10 * np.log10(255.0 ** 2 / error) > 23


def test_options_replace_what_the_path_recorded(tmp_path, path_file):
    frames, cameras = tmp_path / "frames", tmp_path / "cams.json"
    assert run("demo", str(path_file), "--out", str(frames), "--fps", "16", "--size", "40x30",
               "--background", "0,0,0", "--cameras-out", str(cameras)) == 0
    images = frames_of(frames)
    assert len(images) == 8 and images[0].shape == (30, 40, 3)   # 0.5 s at 16 fps
    out = tmp_path / "render.png"
    assert main(["render", "demo", "--camera", str(cameras), "--camera-index", "7", "--out", str(out)]) == 0
    np.testing.assert_array_equal(images[7], png(out))            # the default black background, not the recorded


def test_orbit_is_a_turntable_around_the_scene_centre(tmp_path):
    cameras = tmp_path / "cams.json"
    assert run("demo", "orbit", "--out", str(tmp_path / "f"), "--size", "40x30", "--duration", "1", "--fps", "4",
               "--cameras-out", str(cameras)) == 0
    assert len(frames_of(tmp_path / "f")) == 4
    views = load_cameras(cameras)
    centre, _ = scene_bounds(demo_scene().positions)
    offsets = np.array([c.center - centre for c in views])
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=1), np.linalg.norm(offsets[0]), rtol=1e-3)
    for camera, offset in zip(views, offsets):   # each looks at the centre, level (no roll about -y)
        np.testing.assert_allclose(camera.R[2], -offset / np.linalg.norm(offset), atol=1e-9)
        assert abs(camera.R[0] @ [0.0, -1.0, 0.0]) < 1e-9
    up = np.array([0.0, -1.0, 0.0])
    flat = offsets - np.outer(offsets @ up, up)
    turns = [np.degrees(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b))) for a, b in zip(flat, flat[1:])]
    np.testing.assert_allclose(turns, 90.0, atol=0.5)   # a lap of 4 frames: a quarter turn each


def test_duration_retimes_a_path_and_up_axis_is_only_for_orbit(tmp_path, path_file, capsys):
    assert run("demo", str(path_file), "--out", str(tmp_path / "f"), "--duration", "1") == 0
    assert len(frames_of(tmp_path / "f")) == 8   # 1 s at the path's 8 fps
    assert run("demo", str(path_file), "--out", str(tmp_path / "g"), "--up-axis", "+z") == 2
    assert "--up-axis is for 'orbit'" in capsys.readouterr().err
    assert not (tmp_path / "g").exists()


def test_the_demo_flight_in_assets_renders_without_a_warning(tmp_path, capsys):
    asset = Path(__file__).parents[2] / "assets" / "demo-flight.json"   # the README's example
    assert run("demo", str(asset), "--out", str(tmp_path / "f"), "--size", "32x18", "--fps", "1") == 0
    assert len(frames_of(tmp_path / "f")) == 12 and capsys.readouterr().err == ""


def test_stereo_from_the_file_or_the_options_is_side_by_side(tmp_path):
    document = demo_document(stereo=StereoView(StereoRig(), "sbs", None))
    stereo_path = save_path_document(document, tmp_path / "stereo.json")
    assert run("demo", str(stereo_path), "--out", str(tmp_path / "a")) == 0
    assert frames_of(tmp_path / "a")[0].shape == (32, 96, 3)
    mono_path = save_path_document(demo_document(), tmp_path / "mono.json")
    assert run("demo", str(mono_path), "--out", str(tmp_path / "b"), "--stereo", "--layout", "anaglyph") == 0
    assert frames_of(tmp_path / "b")[0].shape == (32, 48, 3)


def test_a_nerfstudio_camera_path_renders_the_same_frames(tmp_path, path_file):
    nerfstudio = export_nerfstudio(demo_document(), tmp_path / "camera_path.json")
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    assert run("demo", str(path_file), "--out", str(ours)) == 0
    # nerfstudio files carry no render settings: give the background the path file recorded.
    assert run("demo", str(nerfstudio), "--out", str(theirs), "--background", ",".join(map(str, BACKGROUND))) == 0
    a, b = frames_of(ours), frames_of(theirs)
    assert len(a) == len(b) == 4
    for x, y in zip(a, b):  # the same cameras to ~1e-12: at most a rounding step at a few pixels
        difference = np.abs(x.astype(int) - y)
        assert difference.max() <= 1 and np.count_nonzero(difference) <= 5


def test_ctrl_c_leaves_a_playable_truncated_video(tmp_path, path_file, monkeypatch, capsys):
    def interrupted_after_two(renderer, sorter, cameras, *args, **kwargs):
        path_render.render_frames(renderer, sorter, cameras[:2], *args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(path_command, "render_frames", interrupted_after_two)
    video = tmp_path / "fly.mp4"
    assert run("demo", str(path_file), "--out", str(video)) == 130
    assert len(decoded(video)[0]) == 2
    assert "holds the first 2 of 4 frames" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fly.json", "fly.mp4"]  # no temporary file left


def test_ctrl_c_before_any_frame_leaves_no_file(tmp_path, path_file, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(path_command, "render_frames", interrupted)
    assert run("demo", str(path_file), "--out", str(tmp_path / "fly.mp4")) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fly.json"]


def test_json_progress_lines(tmp_path, path_file, capsys):
    assert main(["render-path", "demo", str(path_file), "--out", str(tmp_path / "f"), "--progress", "json"]) == 0
    records = [read_progress_line(line) for line in capsys.readouterr().out.splitlines()]
    assert all(isinstance(r, FrameProgress) for r in records[:-1])   # nothing but progress lines on stdout
    assert [r.frame for r in records[:-1]] == [1, 2, 3, 4]
    assert records[-1] == RenderDone(str(tmp_path / "f"), 4)


def test_a_path_recorded_on_another_scene_renders_with_a_warning(tmp_path, capsys):
    other = save_path_document(demo_document(scene_sha256="0" * 64), tmp_path / "other.json")
    assert run("demo", str(other), "--out", str(tmp_path / "f")) == 0
    warning = capsys.readouterr().err.strip().splitlines()
    assert len(warning) == 1 and warning[0].startswith("warning: ")


def refuse_to_render(monkeypatch):
    def no_scene(*args, **kwargs):
        raise AssertionError("the scene was loaded before the arguments were checked")

    monkeypatch.setattr(path_command, "load_now", no_scene)


@pytest.mark.parametrize("case", ["missing path", "not json", "existing mp4", "gif", "cameras clash", "gs per-pixel",
                                  "no folder", "duration cuts a keyframe"])
def test_bad_input_is_one_line_before_any_rendering_and_loses_nothing(tmp_path, path_file, monkeypatch, capsys,
                                                                     case):
    existing = tmp_path / "fly.mp4"
    existing.write_bytes(b"the user's video")
    (tmp_path / "bad.json").write_text("{not json")
    timed = export_nerfstudio(demo_document(), tmp_path / "timed.json")   # every keyframe has its time
    argv = {
        "missing path": ["demo", str(tmp_path / "nope.json"), "--out", str(tmp_path / "a.mp4")],
        "not json": ["demo", str(tmp_path / "bad.json"), "--out", str(tmp_path / "a.mp4")],
        "existing mp4": ["demo", str(path_file), "--out", str(existing)],
        "gif": ["demo", str(path_file), "--out", str(tmp_path / "fly.gif")],
        "cameras clash": ["demo", str(path_file), "--out", str(tmp_path / "x.mp4"),
                          "--cameras-out", str(existing)],
        "gs per-pixel": ["demo", str(path_file), "--out", str(tmp_path / "a.mp4"), "--mode", "gs",
                         "--order", "per-pixel"],
        "no folder": ["demo", str(path_file), "--out", str(tmp_path / "missing" / "a.mp4")],
        "duration cuts a keyframe": ["demo", str(timed), "--out", str(tmp_path / "a.mp4"), "--duration", "0.2"],
    }[case]
    refuse_to_render(monkeypatch)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert run(*argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
    assert existing.read_bytes() == b"the user's video"
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_real_sigint_mid_render_leaves_a_playable_video(tmp_path):
    """What the window's Cancel button and a terminal's Ctrl-C send, to a real process;
    one started as a script's background job is, which inherits SIGINT ignored."""
    long = demo_document(path=path_through_cameras(demo_cameras()[:3], duration=20, fps=10))  # 200 frames
    path_file = save_path_document(long, tmp_path / "long.json")
    video = tmp_path / "fly.mp4"
    process = subprocess.Popen([sys.executable, "-m", "raygs_viewer", "render-path", "demo", str(path_file),
                                "--out", str(video), "--progress", "json"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        first = read_progress_line(process.stdout.readline())   # a frame is done: the encoder holds some
        for _ in range(2):
            process.stdout.readline()
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert first == FrameProgress(1, 200, first.fps, first.eta_s)
    assert process.returncode == 130
    interrupted = read_progress_line(out.splitlines()[-1])
    assert isinstance(interrupted, RenderInterrupted) and interrupted.out == str(video)
    assert 3 <= interrupted.frames < 200
    assert len(decoded(video)[0]) == interrupted.frames
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fly.mp4", "long.json"]
    assert err.strip().splitlines()[-1].startswith("interrupted: ")


def test_a_path_recorded_on_an_edited_scene_leaves_the_deleted_gaussians_out(tmp_path, gl_render, capsys):
    """The window's path file carries its edit document: every frame is the scene
    without the deleted gaussians, to the bit; edits of another scene are refused."""
    scene = demo_scene()
    edits = Edits(scene.count)
    edits.apply(scene, Operation("select", Box((-5.0, -5.0, -5.0), (0.0, 5.0, 5.0))))
    edits.apply(scene, Operation("delete"))
    assert 0 < edits.deleted.sum() < scene.count
    entry = edit_document_json(EditDocument("demo", demo_sha256(), scene.count, tuple(edits.operations)))
    path_file = save_path_document(demo_document(edits=entry), tmp_path / "edited.json")
    assert json.loads(path_file.read_text())["version"] == 2
    frames, cameras = tmp_path / "frames", tmp_path / "cams.json"
    assert run("demo", str(path_file), "--out", str(frames), "--cameras-out", str(cameras)) == 0
    images = frames_of(frames)
    kept = scene.rows(~edits.deleted)
    for k in (0, 3):
        camera = load_cameras(cameras)[k]
        image = gl_render(kept, camera, RenderSettings(background=BACKGROUND))
        np.testing.assert_array_equal(images[k], to_rgb8(image)[..., :3])
    whole = tmp_path / "whole"
    assert run("demo", str(save_path_document(demo_document(), tmp_path / "plain.json")), "--out", str(whole)) == 0
    assert np.abs(frames_of(whole)[0].astype(int) - images[0]).max() > 20  # the deletion shows
    capsys.readouterr()
    other = save_path_document(demo_document(edits={**entry, "scene": {**entry["scene"], "sha256": "0" * 64}}),
                               tmp_path / "other.json")
    assert run("demo", str(other), "--out", str(tmp_path / "never")) == 2
    err = capsys.readouterr().err
    assert "is not the scene these edits were made on" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "never").exists()
