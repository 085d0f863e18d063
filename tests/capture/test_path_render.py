"""Rendering a camera path into a sink: every frame with its own exact sort, equal bit
for bit to ``render --camera`` of that frame's entry in the cameras.json written for
it; interrupts leave a usable truncated output; stereo frames are ``render --stereo``'s."""

from __future__ import annotations

import json

import av
import numpy as np
import pytest
from PIL import Image
from testkit import assert_user_error, run_cli

from raygs_viewer.camera.path import path_through_cameras
from raygs_viewer.camera.pinhole import (
    Camera,
    camera_from_json,
    camera_to_json,
    load_cameras,
)
from raygs_viewer.camera.stereo import StereoRig, StereoView
from raygs_viewer.capture.image_io import to_rgb8
from raygs_viewer.capture.path_render import (
    frame_camera_entries,
    frame_cameras,
    frame_size,
    render_frames,
    write_cameras_json,
)
from raygs_viewer.capture.progress import FrameProgress, Progress, RenderDone, RenderInterrupted, read_progress_line
from raygs_viewer.capture.screenshot import render_tiled
from raygs_viewer.capture.video import open_sink
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.demo import demo_cameras
from raygs_viewer.sort.depth import DepthSorter

WIDTH, HEIGHT = 64, 48
FRAMES = 5
#: Not the defaults, so a frame rendered with other settings shows.
SETTINGS = RenderSettings(p_min=0.02, background=(0.1, 0.2, 0.3))


def demo_path(frames=FRAMES):
    return path_through_cameras(demo_cameras()[:3], duration=1.0, fps=frames)


def read_png(path):
    with Image.open(path) as image:
        return np.asarray(image)


def assert_bit_identical(a: Camera, b: Camera):
    assert (a.width, a.height) == (b.width, b.height)
    for name in ("fx", "fy", "cx", "cy"):
        assert float(getattr(a, name)).hex() == float(getattr(b, name)).hex(), name
    assert a.R.tobytes() == b.R.tobytes() and a.t.tobytes() == b.t.tobytes()


class Interrupting:
    """A renderer that raises KeyboardInterrupt on its ``at``-th render call (0-based),
    as Ctrl-C does in the middle of a frame; everything else is the real renderer's."""

    def __init__(self, renderer, at):
        self.renderer, self.at, self.calls = renderer, at, 0

    def __getattr__(self, name):
        return getattr(self.renderer, name)

    def render(self, *args, **kwargs):
        if self.calls == self.at:
            raise KeyboardInterrupt
        self.calls += 1
        return self.renderer.render(*args, **kwargs)


def tiled(renderer, camera, settings=SETTINGS, levels=None):
    """render_tiled of ``camera``'s exact order (what a screenshot of it saves)."""
    with DepthSorter(renderer.scene) as sorter:
        order = exact_order(sorter, camera, settings, levels=levels)
        return render_tiled(renderer, sorter, order, camera, settings)


def render_path(renderer, out, cameras, progress=None, stereo=None, overwrite=False, lod=None):
    """What render-path does with a sink: render, finish; on Ctrl-C abort and report."""
    width, height = frame_size(cameras[0].width, cameras[0].height, stereo)
    sink = open_sink(out, width, height, 30, overwrite=overwrite, frames=len(cameras))
    with renderer.ctx, DepthSorter(renderer.scene) as sorter:
        try:
            render_frames(renderer, sorter, cameras, SETTINGS, sink, stereo=stereo, progress=progress, lod=lod)
        except KeyboardInterrupt:
            kept = sink.abort()
            if progress is not None:
                progress.interrupted(sink.frames_written, kept)
            return sink, kept
    return sink, sink.finish()


# --------------------------------------------------------------------------- cameras


def test_frame_cameras_are_what_their_cameras_json_loads_to(tmp_path):
    path = demo_path()
    entries = frame_camera_entries(path, WIDTH, HEIGHT)
    cameras = frame_cameras(path, WIDTH, HEIGHT)
    assert len(entries) == len(cameras) == path.frame_count == FRAMES
    assert [e["img_name"] for e in entries] == [f"frame_{k:05d}" for k in range(FRAMES)]
    assert [e["id"] for e in entries] == list(range(FRAMES))
    file = write_cameras_json(entries, tmp_path / "cams.json")
    for camera, loaded in zip(cameras, load_cameras(file)):
        assert_bit_identical(camera, loaded)
    # The canonicalisation is not a no-op: the path's own cameras differ in the last bits,
    # and so would cameras written again (hence the file is written from the entries).
    raw = path.cameras(WIDTH, HEIGHT)
    assert any(c.R.tobytes() != r.R.tobytes() or c.t.tobytes() != r.t.tobytes() for c, r in zip(cameras, raw))
    again = [camera_from_json(camera_to_json(c), "again") for c in cameras]
    assert any(c.R.tobytes() != a.R.tobytes() or c.t.tobytes() != a.t.tobytes() for c, a in zip(cameras, again))
    for c, r in zip(cameras, raw):
        np.testing.assert_allclose(c.t, r.t, atol=1e-12)
    with pytest.raises(TypeError):
        write_cameras_json(cameras, tmp_path / "cameras.json")


def test_cameras_json_is_written_atomically_and_never_clobbers(tmp_path):
    entries = frame_camera_entries(demo_path(), WIDTH, HEIGHT)
    file = tmp_path / "cams.json"
    file.write_text("mine")
    assert_user_error(lambda: write_cameras_json(entries, file), file, "already exists")
    assert file.read_text() == "mine"
    write_cameras_json(entries, file, overwrite=True)
    assert json.loads(file.read_text()) == entries
    assert_user_error(lambda: write_cameras_json(entries, tmp_path / "cams.txt"), "cams.txt", ".json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cams.json"]


# --------------------------------------------------------------------------- frames


def test_every_png_frame_is_render_of_its_camera_bit_for_bit(capsys, tmp_path, demo_renderer):
    """Each frame equals `render --camera cams.json --camera-index k` with the same
    settings, byte for byte; and frames with other frames' sorts would not."""
    path = demo_path()
    entries = frame_camera_entries(path, WIDTH, HEIGHT)
    cams = write_cameras_json(entries, tmp_path / "cams.json")
    out = tmp_path / "frames"
    sink, folder = render_path(demo_renderer, out, frame_cameras(path, WIDTH, HEIGHT))
    assert folder == out and sink.frames_written == FRAMES
    frames = sorted(out.iterdir())
    assert [p.name for p in frames] == [f"frame_{k:05d}.png" for k in range(FRAMES)]
    for k, frame in enumerate(frames):
        single = tmp_path / f"single_{k}.png"
        code, _, err = run_cli(capsys, "render", "demo", "--camera", cams, "--camera-index", k, "--width", WIDTH,
                               "--height", HEIGHT, "--p-min", "0.02", "--background", "0.1,0.2,0.3", "--out", single)
        assert code == 0, err
        assert frame.read_bytes() == single.read_bytes(), k
    # The frames differ from one another (a flight, not one picture repeated).
    assert len({p.read_bytes() for p in frames}) == FRAMES


def test_each_frame_has_its_own_exact_sort(tmp_path, demo_renderer):
    """A stale order (the first frame's, reused) changes the later frames: the sort
    matters on this flight, so the frames above prove it is redone each frame."""
    cameras = frame_cameras(demo_path(), WIDTH, HEIGHT)
    with demo_renderer.ctx:
        exact = [to_rgb8(tiled(demo_renderer, c)) for c in cameras]
        with DepthSorter(demo_renderer.scene) as sorter:
            stale_order = exact_order(sorter, cameras[0], SETTINGS)
        stale = [to_rgb8(demo_renderer.render(c, SETTINGS, stale_order)) for c in cameras]
    render_path(demo_renderer, tmp_path / "frames", cameras)
    written = [read_png(p) for p in sorted((tmp_path / "frames").iterdir())]
    for k in range(FRAMES):
        np.testing.assert_array_equal(written[k], exact[k])
    assert any(not np.array_equal(e, s) for e, s in zip(exact[1:], stale[1:]))


def test_stereo_frames_are_render_stereo(capsys, tmp_path, demo_renderer):
    path = demo_path(3)
    cams = write_cameras_json(frame_camera_entries(path, WIDTH, HEIGHT), tmp_path / "cams.json")
    stereo = StereoView(StereoRig(ipd=0.3), "sbs")
    assert frame_size(WIDTH, HEIGHT, stereo) == (2 * WIDTH, HEIGHT)
    assert frame_size(WIDTH, HEIGHT, StereoView(layout="anaglyph")) == (WIDTH, HEIGHT)
    _, folder = render_path(demo_renderer, tmp_path / "frames", frame_cameras(path, WIDTH, HEIGHT), stereo=stereo)
    frames = sorted(folder.iterdir())
    assert len(frames) == 3 and read_png(frames[0]).shape == (HEIGHT, 2 * WIDTH, 3)
    k = 2
    single = tmp_path / "single.png"
    code, _, err = run_cli(capsys, "render", "demo", "--camera", cams, "--camera-index", k, "--width", WIDTH,
                           "--height", HEIGHT, "--p-min", "0.02", "--background", "0.1,0.2,0.3",
                           "--stereo", "--ipd", "0.3", "--layout", "sbs", "--out", single)
    assert code == 0, err
    assert frames[k].read_bytes() == single.read_bytes()
    left, right = np.split(read_png(frames[k]), 2, axis=1)
    assert not np.array_equal(left, right)  # two eyes, not one image twice


# --------------------------------------------------------------------------- interrupts


def decoded_frames(path):
    with av.open(str(path)) as container:
        return [frame.reformat(format="rgb24", src_colorspace="itu709").to_ndarray()
                for frame in container.decode(video=0)]


@pytest.mark.parametrize("at", [0, 1, 3])
def test_an_interrupt_leaves_a_playable_truncated_mp4_or_nothing(tmp_path, demo_renderer, at):
    cameras = frame_cameras(demo_path(), WIDTH, HEIGHT)
    lines = JsonLines()
    progress = Progress(len(cameras), "json", lines)
    sink, kept = render_path(Interrupting(demo_renderer, at), tmp_path / "fly.mp4", cameras, progress)
    assert sink.frames_written == at
    assert sorted(p.name for p in tmp_path.iterdir()) == ([] if at == 0 else ["fly.mp4"])  # no temporary files
    assert lines.records[-1] == RenderInterrupted(at, None if at == 0 else str(kept))
    assert [r.frame for r in lines.records[:-1]] == list(range(1, at + 1))
    if at == 0:
        assert kept is None
        return
    assert kept == tmp_path / "fly.mp4"
    decoded = decoded_frames(kept)
    assert len(decoded) == at
    with demo_renderer.ctx:
        expected = [to_rgb8(tiled(demo_renderer, c)) for c in cameras[:at]]
    for got, want in zip(decoded, expected):
        error = np.mean((got.astype(float) - want) ** 2)
        assert 10 * np.log10(255 ** 2 / error) > 23.0  # the bound of test_video.py


def test_an_interrupt_keeps_the_png_frames_written(tmp_path, demo_renderer):
    cameras = frame_cameras(demo_path(), WIDTH, HEIGHT)
    sink, kept = render_path(Interrupting(demo_renderer, 2), tmp_path / "frames", cameras)
    assert kept == tmp_path / "frames"
    assert sorted(p.name for p in kept.iterdir()) == ["frame_00000.png", "frame_00001.png"]
    with demo_renderer.ctx:
        np.testing.assert_array_equal(read_png(kept / "frame_00001.png"),
                                      to_rgb8(tiled(demo_renderer, cameras[1])))


def test_a_finished_render_reports_json_progress(tmp_path, demo_renderer):
    cameras = frame_cameras(demo_path(3), WIDTH, HEIGHT)
    lines = JsonLines()
    progress = Progress(len(cameras), "json", lines)
    _, out = render_path(demo_renderer, tmp_path / "fly.mp4", cameras, progress)
    progress.finish(out)
    assert [r.frame for r in lines.records[:-1]] == [1, 2, 3]
    assert all(isinstance(r, FrameProgress) and r.frames == 3 and r.fps > 0 and r.eta_s >= 0
               for r in lines.records[:-1])
    assert lines.records[-1] == RenderDone(str(out), 3)
    assert len(decoded_frames(out)) == 3


class JsonLines:
    """A stream that keeps the progress lines written to it, read back as records."""

    def __init__(self):
        self.text = ""

    def write(self, text):
        self.text += text

    def flush(self):
        pass

    @property
    def records(self):
        assert self.text.endswith("\n")
        records = [read_progress_line(line) for line in self.text.splitlines()]
        assert None not in records
        return records


def test_nothing_is_rendered_when_the_output_is_refused(tmp_path, demo_renderer):
    """open_sink checks before the first frame: a bad output costs no render."""
    calls = Interrupting(demo_renderer, at=-1)
    cameras = frame_cameras(demo_path(2), WIDTH, HEIGHT)
    for out in (tmp_path / "fly.gif", tmp_path / "missing" / "fly.mp4"):
        assert_user_error(lambda: render_path(calls, out, cameras), out)
    assert calls.calls == 0 and list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- level of detail


def test_each_frame_of_a_streamed_scene_draws_the_levels_chosen_for_its_camera(tmp_path, gl_ctx):
    """A flight towards a streamed SOG: every frame is the screenshot of its camera with
    the levels chosen for that camera, bit for bit; the first frame's choice kept for
    the whole flight, or no choice at all, would give other frames."""
    from lod_kit import random_gaussians, write_streamed_sog

    from raygs_viewer.camera.pinhole import look_at
    from raygs_viewer.render.gl.renderer import GLRenderer
    from raygs_viewer.scene.lod_file import load_lod
    from raygs_viewer.sort.lod_choice import LodRequest

    leaves = [[random_gaussians(24 >> level, centre=(1.2 * (k % 3) - 1.2, 0.8 * (k // 3) - 0.4, 2.0),
                                spread=0.3, scale=0.05 * 1.6 ** level, seed=7 * k + level) for level in range(3)]
              for k in range(6)]
    lod = load_lod(write_streamed_sog(tmp_path / "lod", leaves))
    request = LodRequest(lod, distance=1.5)
    cameras = [look_at([0.2, 0.1, 2.0 - distance], [0.0, 0.0, 2.0], width=WIDTH, height=HEIGHT)
               for distance in (9.0, 5.0, 3.0, 1.8)]
    choices = [request.choose(camera) for camera in cameras]
    assert len({choice.spans.tobytes() for choice in choices}) >= 3  # the flight takes every level
    renderer = GLRenderer(gl_ctx, lod.scene)
    try:
        render_path(renderer, tmp_path / "frames", cameras, lod=request)
        written = [read_png(p) for p in sorted((tmp_path / "frames").iterdir())]
        assert len(written) == len(cameras)
        with gl_ctx:
            for k, camera in enumerate(cameras):
                np.testing.assert_array_equal(written[k], to_rgb8(tiled(renderer, camera, levels=choices[k])))
            first_choice = [to_rgb8(tiled(renderer, camera, levels=choices[0])) for camera in cameras]
            whole = [to_rgb8(tiled(renderer, camera)) for camera in cameras]
    finally:
        renderer.release()
    assert sum(not np.array_equal(w, f) for w, f in zip(written[1:], first_choice[1:])) >= 2
    assert all(not np.array_equal(w, a) for w, a in zip(written, whole))
