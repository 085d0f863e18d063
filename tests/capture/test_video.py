"""Frame sinks (an H.264 MP4 through PyAV, a PNG folder), the output checks made before
any rendering.

The MP4's frames are compared with the rendered frames they encode. H.264 at crf 18 is
not lossless, and 4:2:0 chroma (one colour sample per 2x2 pixels) alone costs these
tiny, colourful demo frames most of their PSNR: measured at 64x48, RGB through
yuv420p and back without any compression 28-30 dB; after encoding 26-28 dB RGB, and
34-40 dB on luma against the same conversion of the source. A frame out of order
scores 12-16 dB, a transposed one about 9 dB. The bounds below sit between.
"""

from __future__ import annotations

import gc
import os
from fractions import Fraction
from pathlib import Path

import av
import numpy as np
import pytest
from PIL import Image
from testkit import assert_user_error

import raygs_viewer.capture.video as video
from raygs_viewer.camera.path import path_through_cameras
from raygs_viewer.capture.image_io import encode_image, to_rgb8
from raygs_viewer.capture.path_render import frame_cameras, render_frame
from raygs_viewer.capture.video import check_video_output, even_size, open_sink
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.demo import demo_cameras
from raygs_viewer.sort.depth import DepthSorter

#: Bounds of the MP4 against its source frames (module docstring for the measurements).
MIN_RGB_PSNR = 23.0
MIN_LUMA_PSNR = 31.0
FRAMES = 6


@pytest.fixture(scope="module")
def demo_frames(demo_renderer):
    """{(width, height): [(H, W, 3) uint8 frames]} of a short flight through the demo."""
    path = path_through_cameras(demo_cameras()[:3], duration=1.0, fps=FRAMES)
    assert path.frame_count == FRAMES
    frames = {}
    with demo_renderer.ctx, DepthSorter(demo_renderer.scene) as sorter:
        for size in ((64, 48), (65, 49)):
            frames[size] = [to_rgb8(render_frame(demo_renderer, sorter, camera, RenderSettings(), None))
                            for camera in frame_cameras(path, *size)]
    return frames


def write_all(out, frames, fps=30, overwrite=False):
    height, width = frames[0].shape[:2]
    sink = open_sink(out, width, height, fps, overwrite=overwrite, frames=len(frames))
    for frame in frames:
        sink.write(frame)
    return sink, sink.finish()


def decode(path):
    """(RGB frames, luma planes, the video stream's facts)."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        rgb, luma, times = [], [], []
        for frame in container.decode(stream):
            rgb.append(frame.reformat(format="rgb24", src_colorspace="itu709").to_ndarray())
            luma.append(plane(frame, 0))
            times.append(frame.time)
        facts = {"codec": stream.codec_context.name, "pix_fmt": stream.codec_context.pix_fmt,
                 "size": (stream.codec_context.width, stream.codec_context.height), "rate": stream.average_rate,
                 "frames": stream.frames, "times": times, "colorspace": stream.codec_context.colorspace}
    return rgb, luma, facts


def plane(frame, index):
    data = frame.planes[index]
    return np.frombuffer(bytes(data), np.uint8).reshape(data.height, data.line_size)[:, :data.width]


def source_luma(frame):
    """The luma the encoder was given: the frame padded and converted as Mp4Sink does, uncompressed."""
    height, width = frame.shape[:2]
    padded = np.pad(frame, ((0, even_size(width, height)[1] - height), (0, even_size(width, height)[0] - width),
                            (0, 0)), mode="edge")
    converted = av.VideoFrame.from_ndarray(padded, format="rgb24").reformat(
        format="yuv420p", src_colorspace="itu709", dst_colorspace="itu709")
    return plane(converted, 0)


def psnr(a, b):
    error = np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2)
    return np.inf if error == 0 else 10 * np.log10(255.0 ** 2 / error)


def assert_encodes(decoded_rgb, decoded_luma, sources):
    """Each decoded frame is its source within H.264's error, in order."""
    assert len(decoded_rgb) == len(sources)
    for k, (rgb, luma, source) in enumerate(zip(decoded_rgb, decoded_luma, sources)):
        height, width = source.shape[:2]
        assert psnr(rgb[:height, :width], source) >= MIN_RGB_PSNR, k
        assert psnr(luma, source_luma(source)) >= MIN_LUMA_PSNR, k


def leftovers(folder):
    """Hidden temporary files a sink may have left."""
    return [p.name for p in Path(folder).iterdir() if p.name.startswith(".")]


# --------------------------------------------------------------------------- MP4


def test_mp4_decodes_to_the_frames(tmp_path, demo_frames):
    frames = demo_frames[(64, 48)]
    sink, out = write_all(tmp_path / "fly.mp4", frames, fps=24)
    assert out == tmp_path / "fly.mp4" and sink.note is None and sink.frames_written == FRAMES
    rgb, luma, facts = decode(out)
    assert facts["codec"] == "h264" and facts["pix_fmt"] == "yuv420p"
    assert facts["size"] == (64, 48) and facts["rate"] == 24 and facts["frames"] == FRAMES
    assert facts["colorspace"] == 1  # tagged BT.709, the matrix the frames were converted with
    np.testing.assert_allclose(facts["times"], np.arange(FRAMES) / 24)
    assert_encodes(rgb, luma, frames)
    assert leftovers(tmp_path) == []


def test_the_psnr_bound_catches_a_wrong_order_or_a_transposed_image(tmp_path, demo_frames):
    """Negative controls for :func:`assert_encodes`: the same video against its frames
    shifted by one, reversed, or transposed (a square crop, so the shapes still fit)."""
    frames = demo_frames[(64, 48)]
    rgb, luma, _ = decode(write_all(tmp_path / "fly.mp4", frames)[1])
    for wrong in (frames[1:] + frames[:1], frames[::-1]):
        with pytest.raises(AssertionError):
            assert_encodes(rgb, luma, wrong)
    decoded = [(rgb_frame[:48, :48], luma_frame[:48, :48]) for rgb_frame, luma_frame in zip(rgb, luma)]
    for (rgb_frame, luma_frame), source in zip(decoded, frames):
        assert psnr(rgb_frame, source[:48, :48]) >= MIN_RGB_PSNR  # the crop itself passes
        assert psnr(rgb_frame.transpose(1, 0, 2), source[:48, :48]) < MIN_RGB_PSNR
        assert psnr(luma_frame.T, source_luma(source)[:48, :48]) < MIN_LUMA_PSNR


@pytest.mark.parametrize("fps, rate", [(30000 / 1001, Fraction(30000, 1001)), (Fraction(24000, 1001),
                                                                             Fraction(24000, 1001)), (12.5, 12.5)])
def test_mp4_fractional_frame_rates_are_exact(tmp_path, demo_frames, fps, rate):
    frames = demo_frames[(64, 48)][:3]
    _, luma, facts = decode(write_all(tmp_path / "fly.mp4", frames, fps=fps)[1])
    assert facts["rate"] == rate and len(luma) == 3
    np.testing.assert_allclose(facts["times"], np.arange(3) / float(rate), rtol=0, atol=1e-4)


def test_odd_sizes_are_padded_with_a_note(tmp_path, demo_frames):
    frames = demo_frames[(65, 49)]
    sink, out = write_all(tmp_path / "odd.mp4", frames)
    assert sink.note == "65x49 padded to 66x50 for H.264"
    rgb, luma, facts = decode(out)
    assert facts["size"] == (66, 50) == even_size(65, 49)
    assert_encodes(rgb, luma, frames)
    # The padding repeats the last column and row (not black, not wrapped around).
    for decoded, source in zip(rgb, frames):
        assert np.abs(decoded[:49, 65].astype(int) - source[:, 64]).mean() < 8
        assert np.abs(decoded[49, :65].astype(int) - source[48]).mean() < 8
    assert even_size(64, 48) == (64, 48) and even_size(1279, 719) == (1280, 720)


@pytest.mark.parametrize("written", [0, 1, 4])
def test_mp4_abort_leaves_a_playable_truncated_video_or_nothing(tmp_path, demo_frames, written):
    frames = demo_frames[(64, 48)]
    out = tmp_path / "fly.mp4"
    sink = open_sink(out, 64, 48, 30)
    assert len(leftovers(tmp_path)) == 1  # the hidden temporary file the video is encoded into
    for frame in frames[:written]:
        sink.write(frame)
    kept = sink.abort()
    assert leftovers(tmp_path) == []
    if written == 0:
        assert kept is None and not out.exists()
        return
    assert kept == out
    rgb, luma, facts = decode(out)
    assert facts["frames"] == written
    assert_encodes(rgb, luma, frames[:written])


def test_a_failed_or_interrupted_finish_leaves_no_file(tmp_path, demo_frames, monkeypatch):
    frames = demo_frames[(64, 48)]
    for failure in (KeyboardInterrupt, OSError(28, "No space left on device")):
        out = tmp_path / f"{type(failure).__name__}.mp4"
        sink = open_sink(out, 64, 48, 30)
        for frame in frames[:3]:
            sink.write(frame)

        def fail(*_):
            raise failure
        monkeypatch.setattr(video, "move_into_place", fail)
        if failure is KeyboardInterrupt:
            with pytest.raises(KeyboardInterrupt):
                sink.abort()
        else:
            assert_user_error(sink.finish, out, "No space left on device")
        monkeypatch.undo()
        assert not out.exists() and leftovers(tmp_path) == []


def test_mp4_never_clobbers_without_overwrite(tmp_path, demo_frames):
    frames = demo_frames[(64, 48)][:2]
    out = tmp_path / "fly.mp4"
    out.write_bytes(b"mine")
    assert_user_error(lambda: check_video_output(out), out, "already exists", "--overwrite")
    assert_user_error(lambda: open_sink(out, 64, 48, 30), out, "already exists")
    assert out.read_bytes() == b"mine" and leftovers(tmp_path) == []
    # A file that appears while the video is encoded is not replaced either.
    other = tmp_path / "other.mp4"
    sink = open_sink(other, 64, 48, 30)
    sink.write(frames[0])
    other.write_bytes(b"theirs")
    assert_user_error(sink.finish, other, "already exists")
    assert other.read_bytes() == b"theirs" and leftovers(tmp_path) == []
    # With overwrite it is replaced by the video.
    write_all(out, frames, overwrite=True)
    assert decode(out)[2]["frames"] == 2 and leftovers(tmp_path) == []


def test_finish_without_frames_is_an_error_and_leaves_nothing(tmp_path):
    out = tmp_path / "empty.mp4"
    assert_user_error(open_sink(out, 64, 48, 30).finish, out, "no frames")
    assert list(tmp_path.iterdir()) == []


def test_a_sink_checks_frames_and_order_of_calls(tmp_path, demo_frames):
    sink = open_sink(tmp_path / "fly.mp4", 64, 48, 30)
    with pytest.raises(ValueError):
        sink.write(demo_frames[(65, 49)][0])
    with pytest.raises(ValueError):
        sink.write(demo_frames[(64, 48)][0].astype(np.float32))
    sink.write(demo_frames[(64, 48)][0])
    sink.finish()
    with pytest.raises(RuntimeError):
        sink.write(demo_frames[(64, 48)][0])
    assert sink.abort() is None  # after finish: nothing more to do, the video stays
    assert decode(tmp_path / "fly.mp4")[2]["frames"] == 1


def test_a_dropped_sink_leaves_no_temporary_file(tmp_path, demo_frames):
    """A sink lost without finish or abort (an exception the caller did not expect)."""
    sink = open_sink(tmp_path / "fly.mp4", 64, 48, 30)
    sink.write(demo_frames[(64, 48)][0])
    del sink
    gc.collect()
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- PNG folder


def read_png(path):
    with Image.open(path) as image:
        assert image.mode == "RGB"
        return np.asarray(image)


def test_png_folder_holds_the_exact_frames(tmp_path, demo_frames, demo_renderer):
    frames = demo_frames[(64, 48)]
    out = tmp_path / "frames"
    sink, folder = write_all(out, frames)
    assert folder == out and sink.note is None
    names = sorted(p.name for p in out.iterdir())
    assert names == [f"frame_{k:05d}.png" for k in range(FRAMES)]
    for name, frame in zip(names, frames):
        np.testing.assert_array_equal(read_png(out / name), frame)
    # Encoded as `render --out x.png` encodes a float image.
    path = path_through_cameras(demo_cameras()[:3], duration=1.0, fps=FRAMES)
    with demo_renderer.ctx, DepthSorter(demo_renderer.scene) as sorter:
        image = render_frame(demo_renderer, sorter, frame_cameras(path, 64, 48)[2], RenderSettings(), None)
    assert (out / names[2]).read_bytes() == encode_image(image, ".png")


def test_png_folder_names_sort_beyond_99999_frames(tmp_path):
    sink = open_sink(tmp_path / "many", 2, 2, 30, frames=100_001)
    assert sink.frame_path(7).name == "frame_000007.png"
    assert open_sink(tmp_path / "few", 2, 2, 30, frames=100_000).frame_path(7).name == "frame_00007.png"


def test_png_folder_overwrite_replaces_frames_and_removes_stale_ones(tmp_path, demo_frames):
    frames = demo_frames[(64, 48)]
    out = tmp_path / "frames"
    write_all(out, frames)
    (out / "notes.txt").write_text("keep me")
    assert_user_error(lambda: check_video_output(out), out, "not empty", "--overwrite")
    assert_user_error(lambda: open_sink(out, 64, 48, 30), out, "not empty")
    write_all(out, frames[::-1][:3], overwrite=True)
    names = sorted(p.name for p in out.iterdir())
    assert names == ["frame_00000.png", "frame_00001.png", "frame_00002.png", "notes.txt"]
    for k in range(3):
        np.testing.assert_array_equal(read_png(out / names[k]), frames[::-1][k])
    assert (out / "notes.txt").read_text() == "keep me" and leftovers(out) == []


def test_png_abort_keeps_the_frames_written(tmp_path, demo_frames):
    frames = demo_frames[(64, 48)]
    sink = open_sink(tmp_path / "frames", 64, 48, 30)
    for frame in frames[:2]:
        sink.write(frame)
    assert sink.abort() == tmp_path / "frames"
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == ["frame_00000.png", "frame_00001.png"]
    # None written: the folder it made is gone again.
    assert open_sink(tmp_path / "none", 64, 48, 30).abort() is None
    assert not (tmp_path / "none").exists()


# --------------------------------------------------------------------------- checks before rendering


@pytest.mark.parametrize("name", ["fly.mov", "fly.gif", "fly.MKV", "fly.png", "still.npy"])
def test_other_formats_are_refused_naming_what_is_supported(tmp_path, name):
    out = tmp_path / name
    assert_user_error(lambda: check_video_output(out), out, ".mp4", "folder")
    assert_user_error(lambda: open_sink(out, 64, 48, 30), out, ".mp4")
    assert list(tmp_path.iterdir()) == []


def test_missing_or_unusable_folders_are_refused(tmp_path, monkeypatch):
    missing = tmp_path / "nowhere" / "fly.mp4"
    assert_user_error(lambda: check_video_output(missing), missing, "does not exist")
    assert_user_error(lambda: check_video_output(tmp_path / "nowhere" / "frames"), "frames", "does not exist")
    a_file = tmp_path / "taken"
    a_file.write_text("")
    assert_user_error(lambda: check_video_output(a_file), a_file, "not a folder")
    assert_user_error(lambda: check_video_output(a_file / "fly.mp4"), "fly.mp4", "does not exist")
    folder = tmp_path / "fly.mp4"
    folder.mkdir()
    assert_user_error(lambda: check_video_output(folder, overwrite=True), folder, "is a folder")
    # An unwritable folder (simulated: these tests may run as root, whom permissions do not stop).
    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access
    monkeypatch.setattr(video.os, "access", lambda p, mode: False if Path(p) == locked else real_access(p, mode))
    for out in (locked / "fly.mp4", locked / "frames", locked):
        assert_user_error(lambda: check_video_output(out), out, "not writable")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs a user whom permissions stop")
def test_a_read_only_folder_is_refused(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    assert_user_error(lambda: check_video_output(locked / "fly.mp4"), "fly.mp4", "not writable")


def test_valid_outputs_pass_the_check(tmp_path):
    assert check_video_output(tmp_path / "fly.MP4") == tmp_path / "fly.MP4"
    assert check_video_output(tmp_path / "frames") == tmp_path / "frames"
    assert check_video_output(tmp_path / "frames.v2") == tmp_path / "frames.v2"  # an unknown suffix: a folder
    (tmp_path / "empty").mkdir()
    assert check_video_output(tmp_path / "empty") == tmp_path / "empty"
    assert list(tmp_path.iterdir()) == [tmp_path / "empty"]  # checking creates nothing
