"""Where a rendered flight goes: an H.264 MP4 (PyAV), a folder of numbered PNGs, or (for
``render-path --channels``) a folder of numbered EXRs of a render's channels.

Both are :class:`FrameSink`\\ s: frames are written one at a time as they are rendered,
and the output appears only when it is complete (:meth:`FrameSink.finish`), or, when
the render stops early (Ctrl-C, an error), as a truncated but usable output
(:meth:`FrameSink.abort`): an MP4 whose encoder was flushed and whose container was
closed, or the PNGs written so far. Neither ever replaces a user's file without
``overwrite``, and an MP4 is never left half written: it is encoded into a hidden
temporary file beside the target and moved into place whole.
"""

from __future__ import annotations

import os
import re
from fractions import Fraction
from pathlib import Path

import numpy as np

from raygs_viewer.capture.channel_io import write_exr
from raygs_viewer.capture.image_io import encode_png
from raygs_viewer.errors import UserError
from raygs_viewer.files import check_writable_folder, move_into_place, temporary_beside, write_atomically
from raygs_viewer.render.channels import ChannelImage

VIDEO_SUFFIX = ".mp4"
#: Suffixes that name a file format we do not write: refused rather than taken for a
#: folder name, which would surprise (``--out fly.mov`` making a folder of PNGs).
REFUSED_SUFFIXES = (".mov", ".mkv", ".avi", ".webm", ".gif", ".m4v", ".mpg", ".mpeg", ".wmv", ".flv", ".ogv",
                    ".apng", ".webp", ".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".exr", ".npy", ".json")
SUPPORTED = "an .mp4 file or a folder for PNG frames"
#: H.264 encoding: crf 18 is visually lossless for most content; "medium" is x264's
#: own default trade of speed against size.
CRF = 18
PRESET = "medium"
FRAME_PREFIX = "frame_"


def even_size(width: int, height: int) -> tuple[int, int]:
    """The size H.264 with 4:2:0 chroma gets: each side padded up to even."""
    return width + width % 2, height + height % 2


def frame_rate(fps: float | Fraction) -> Fraction:
    """``fps`` as an exact fraction: a float as the simplest fraction with a denominator
    of at most 1001 (29.97002997... -> 30000/1001, 25.0 -> 25)."""
    rate = fps if isinstance(fps, Fraction) else Fraction(fps).limit_denominator(1001)
    if not rate > 0:
        raise UserError(f"frame rate must be positive, got {fps}")
    return rate


def check_video_output(out: str | Path, overwrite: bool = False) -> Path:
    """Validates ``--out`` before any slow work: ``.mp4`` names a file (its folder must
    exist and be writable; an existing file needs ``overwrite``), the suffixes of other
    formats are refused, and anything else names a folder for PNG frames (an existing
    non-empty one needs ``overwrite``; a new one's parent must exist and be writable)."""
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix in REFUSED_SUFFIXES:
        raise UserError(f"{out}: cannot write '{suffix}' (the output is {SUPPORTED})")
    if suffix == VIDEO_SUFFIX:
        check_writable_folder(out, out.parent)
        if out.is_dir():
            raise UserError(f"{out}: is a folder")
        if os.path.lexists(out) and not overwrite:
            raise UserError(f"{out}: already exists (pass --overwrite to replace it)")
        return out
    if os.path.lexists(out) and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder (the output is {SUPPORTED})")
    if out.is_dir():
        check_writable_folder(out, out)
        if not overwrite and any(out.iterdir()):
            raise UserError(f"{out}: folder is not empty (pass --overwrite to replace its frames)")
    else:
        check_writable_folder(out, out.parent)
    return out


def open_sink(out: str | Path, width: int, height: int, fps: float | Fraction, *, overwrite: bool = False,
              frames: int | None = None) -> "FrameSink":
    """An :class:`Mp4Sink` for a ``.mp4`` ``out``, else a :class:`PngFolderSink`;
    ``out`` is checked as :func:`check_video_output` does. ``frames``: how many will
    come, if known (a PNG folder names them with enough digits to sort)."""
    out = check_video_output(out, overwrite)
    if out.suffix.lower() == VIDEO_SUFFIX:
        return Mp4Sink(out, width, height, fps, overwrite)
    return PngFolderSink(out, width, height, overwrite, frames)


class FrameSink:
    """Takes a flight's frames in order. ``path``: the final output; ``frames_written``;
    ``note``: a one-line remark for the user (e.g. the padding of an odd size) or None."""

    path: Path
    frames_written: int = 0
    note: str | None = None

    def __init__(self, path: Path, width: int, height: int) -> None:
        if not (isinstance(width, int) and isinstance(height, int) and width >= 1 and height >= 1):
            raise ValueError(f"frame size must be positive integers, got {width!r}x{height!r}")
        self.path, self.width, self.height = path, width, height
        self.frames_written = 0
        self.note = None
        self._closed = False

    def write(self, frame: np.ndarray) -> None:
        """Appends ``frame``: (height, width, 3) uint8, top row first."""
        if self._closed:
            raise RuntimeError(f"{self.path}: write after finish or abort")
        self._check(frame)
        self._write(frame)
        self.frames_written += 1

    def _check(self, frame: np.ndarray) -> None:
        if frame.shape != (self.height, self.width, 3) or frame.dtype != np.uint8:
            raise ValueError(f"a frame must be ({self.height}, {self.width}, 3) uint8, "
                             f"got {frame.shape} {frame.dtype}")

    def finish(self) -> Path:
        """Completes the output and returns its path."""
        raise NotImplementedError

    def abort(self) -> Path | None:
        """Stops early: the truncated output's path, or None when nothing is left."""
        raise NotImplementedError

    def _write(self, frame: np.ndarray) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        if self._closed:
            raise RuntimeError(f"{self.path}: already finished or aborted")
        self._closed = True


class Mp4Sink(FrameSink):
    """H.264 (libx264, yuv420p, crf :data:`CRF`) in an MP4, at an exact frame rate.

    4:2:0 chroma needs even sides: an odd width or height is padded by one column or row
    that repeats the edge (``note`` says so). RGB is converted with the BT.709 matrix
    into limited range, and the stream is tagged so, as players expect of video."""

    def __init__(self, path: Path, width: int, height: int, fps: float | Fraction, overwrite: bool = False) -> None:
        # Imported here, not at the top: PyAV loads FFmpeg's libraries (~0.1 s), which
        # only writing a video needs (PNG folders, the window, `render` never do).
        import av

        super().__init__(path, width, height)
        self._av = av
        self._container = None
        self.overwrite = overwrite
        self.rate = frame_rate(fps)
        self.encoded_size = even_size(width, height)
        if self.encoded_size != (width, height):
            self.note = f"{width}x{height} padded to {self.encoded_size[0]}x{self.encoded_size[1]} for H.264"
        try:
            handle, self._temporary = temporary_beside(path)
        except OSError as exc:
            raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None
        os.close(handle)  # PyAV opens the file by name
        try:
            self._container = av.open(self._temporary, mode="w", format="mp4")
            stream = self._container.add_stream("libx264", rate=self.rate)
            stream.width, stream.height = self.encoded_size
            stream.pix_fmt = "yuv420p"
            stream.codec_context.time_base = 1 / self.rate
            stream.options = {"crf": str(CRF), "preset": PRESET,
                              "x264-params": "colorprim=bt709:transfer=bt709:colormatrix=bt709:range=tv"}
            self._stream = stream
        except BaseException as exc:
            self._closed = True
            self._discard()
            if isinstance(exc, av.error.FFmpegError):  # e.g. an FFmpeg build without libx264
                raise UserError(f"{path}: cannot start the H.264 encoder: {exc}") from None
            raise

    def _write(self, frame: np.ndarray) -> None:
        av = self._av
        if self.encoded_size != (self.width, self.height):
            pad_x, pad_y = self.encoded_size[0] - self.width, self.encoded_size[1] - self.height
            frame = np.pad(frame, ((0, pad_y), (0, pad_x), (0, 0)), mode="edge")
        picture = av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
        picture = picture.reformat(format="yuv420p", src_colorspace="itu709", dst_colorspace="itu709")
        picture.pts = self.frames_written
        try:
            self._mux(self._stream.encode(picture))
        except av.error.FFmpegError as exc:
            raise UserError(f"{self.path}: cannot encode frame {self.frames_written}: {exc}") from None

    def finish(self) -> Path:
        """Flushes the encoder, closes the file and moves it into place. With no frame
        written there is no video: UserError, and nothing is left."""
        if self.frames_written == 0:
            self._close()
            self._discard()
            raise UserError(f"{self.path}: no frames to write")
        return self._complete()

    def abort(self) -> Path | None:
        """With frames written: the truncated video, playable, moved into place. Without,
        or if completing it fails: nothing is left (a failure's error is raised; an
        interrupt while completing propagates too)."""
        if self._closed:
            return None
        if self.frames_written == 0:
            self._close()
            self._discard()
            return None
        return self._complete()

    def _complete(self) -> Path:
        self._close()
        try:
            self._mux(self._stream.encode(None))  # the frames the encoder still holds
            self._container.close()
            with open(self._temporary, "rb") as stream:
                os.fsync(stream.fileno())
            move_into_place(self._temporary, self.path, self.overwrite)
        except FileExistsError:
            self._discard()
            raise UserError(f"{self.path}: already exists (pass --overwrite to replace it)") from None
        except (self._av.error.FFmpegError, OSError) as exc:
            self._discard()
            raise UserError(f"{self.path}: cannot write the video: {getattr(exc, 'strerror', None) or exc}") from None
        except BaseException:
            self._discard()
            raise
        return self.path

    def _mux(self, packets) -> None:
        for packet in packets:
            self._container.mux(packet)

    def _discard(self) -> None:
        """Closes the container, if open, and removes the temporary file."""
        if self._container is not None:
            try:
                self._container.close()
            except Exception:  # already failing, or closed: the file goes anyway
                pass
        try:
            os.unlink(self._temporary)
        except FileNotFoundError:
            pass

    def __del__(self) -> None:
        # A sink dropped without finish or abort (a bug, or an exception between) must
        # not leave its hidden temporary file behind.
        if not getattr(self, "_closed", True) and hasattr(self, "_temporary"):
            self._closed = True
            self._discard()


class FolderSink(FrameSink):
    """frame_00000.SUFFIX, frame_00001.SUFFIX, ... in ``path`` (created if missing), each
    written atomically (subclasses say how).

    With ``overwrite``, frames already in the folder are replaced, and at the end those
    of this suffix beyond the new count are removed (other files stay)."""

    suffix = ""

    def __init__(self, path: Path, width: int, height: int, overwrite: bool = False,
                 frames: int | None = None) -> None:
        super().__init__(path, width, height)
        self.overwrite = overwrite
        self.digits = max(5, len(str(max(frames or 0, 1) - 1)))
        self._created = False
        try:
            path.mkdir()
            self._created = True
        except FileExistsError:
            if not path.is_dir():
                raise UserError(f"{path}: exists and is not a folder") from None
            if not overwrite and any(path.iterdir()):
                raise UserError(f"{path}: folder is not empty (pass --overwrite to replace its frames)") from None
        except OSError as exc:
            raise UserError(f"{path}: cannot create the folder: {exc.strerror or exc}") from None

    def frame_path(self, index: int) -> Path:
        return self.path / f"{FRAME_PREFIX}{index:0{self.digits}d}{self.suffix}"

    def finish(self) -> Path:
        self._close()
        if self.frames_written == 0:
            self._remove_if_created()
            raise UserError(f"{self.path}: no frames to write")
        self._remove_stale()
        return self.path

    def abort(self) -> Path | None:
        """Keeps the frames written so far (a shorter sequence); None if there are none."""
        if self._closed:
            return None
        self._close()
        self._remove_stale()
        if self.frames_written == 0:
            self._remove_if_created()
            return None
        return self.path

    def _remove_stale(self) -> None:
        """Removes frame_*.png of an earlier render that this one did not write, so the
        folder holds one sequence."""
        if not self.overwrite:
            return
        written = {self.frame_path(i).name for i in range(self.frames_written)}
        frame_name = re.compile(rf"{FRAME_PREFIX}\d+{re.escape(self.suffix)}")
        for entry in self.path.iterdir():
            if frame_name.fullmatch(entry.name) and entry.name not in written and entry.is_file():
                try:
                    entry.unlink()
                except FileNotFoundError:
                    pass

    def _remove_if_created(self) -> None:
        if self._created:
            try:
                self.path.rmdir()
            except OSError:  # something else was put there meanwhile: leave it
                pass


class PngFolderSink(FolderSink):
    """The frames as PNGs, each encoded as ``render --out x.png`` encodes it."""

    suffix = ".png"

    def _write(self, frame: np.ndarray) -> None:
        write_atomically(self.frame_path(self.frames_written), encode_png(frame), self.overwrite)


class ExrFolderSink(FolderSink):
    """The frames as EXRs of ``channels`` (:func:`write_exr`): each frame a ChannelImage
    (its normals already in the space wanted), not 8-bit RGB."""

    suffix = ".exr"

    def __init__(self, path: Path, width: int, height: int, channels: tuple[str, ...], *, overwrite: bool = False,
                 frames: int | None = None) -> None:
        super().__init__(path, width, height, overwrite, frames)
        self.channels = tuple(channels)

    def _check(self, frame: ChannelImage) -> None:
        if not isinstance(frame, ChannelImage) or frame.alpha.shape != (self.height, self.width):
            raise ValueError(f"a frame must be a ({self.height}, {self.width}) ChannelImage, got {frame!r:.80}")

    def _write(self, frame: ChannelImage) -> None:
        write_exr(self.frame_path(self.frames_written), frame, self.channels, self.overwrite)
