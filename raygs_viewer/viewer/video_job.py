"""Render video in the background: the window writes its path document to a fresh pair
of names in the videos folder (``raygs-YYYYmmdd-HHMMSS.json`` and ``.mp4``), then runs
``raygs-viewer render-path`` on it as a subprocess (:class:`VideoJob`) and reads its
progress. :class:`VideoRender` is the path widget's part that does this: the folder,
the size, and the job under way.

The command prints the JSON lines of :mod:`raygs_viewer.capture.progress` on stdout
(``--progress json``): a frame's progress while it renders, then the render's end,
done or interrupted after a SIGINT (it then leaves a playable truncated file, or none);
a failure ends with an ``error: ...`` line on stderr and exit status 2. The window
polls the job once a frame and never waits on it, except briefly when it closes.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass, replace
from datetime import datetime
from pathlib import Path
from typing import Callable

from raygs_viewer.capture.path_file import PathDocument, save_path_document
from raygs_viewer.capture.progress import FrameProgress, RenderDone, RenderInterrupted, read_progress_line
from raygs_viewer.errors import UserError

VIDEO_PREFIX = "raygs-"
_MAX_NAME_ATTEMPTS = 1000
#: How long closing the window waits for a cancelled job to leave its truncated file.
CLOSE_WAIT_S = 5.0
#: Render video's sizes besides the view's own ("view"), "WxH" -> (width, height) per
#: frame (per eye in the stereo preview).
VIDEO_SIZES = {"1280x720": (1280, 720), "1920x1080": (1920, 1080), "3840x2160": (3840, 2160)}


def render_path_command(scene: str, document: Path, out: Path) -> list[str]:
    """The command line that renders ``document`` (a path JSON) of ``scene`` ("demo" or
    a path) to ``out``, reporting progress as JSON lines."""
    return [sys.executable, "-m", "raygs_viewer", "render-path", scene, str(document), "--out", str(out),
            "--progress", "json"]


def _video_folder(folder: str | Path) -> Path:
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{folder}: cannot create the video folder: {exc.strerror or exc}") from None
    if not folder.is_dir():
        raise UserError(f"{folder}: cannot save videos there: not a folder")
    return folder


def write_video_document(document: PathDocument, folder: str | Path, now: datetime | None = None
                         ) -> tuple[Path, Path]:
    """Saves ``document`` as ``folder/raygs-<time>.json`` (``-2``, ``-3``, ... when that
    JSON or its ``.mp4`` exists; the folder is created if missing) and returns (json,
    mp4): the video's name is free, the JSON written. Nothing is ever replaced."""
    folder = _video_folder(folder)
    stem = VIDEO_PREFIX + (now or datetime.now()).strftime("%Y%m%d-%H%M%S")
    for n in range(1, _MAX_NAME_ATTEMPTS + 1):
        name = stem if n == 1 else f"{stem}-{n}"
        json_path, video = folder / f"{name}.json", folder / f"{name}.mp4"
        if os.path.lexists(json_path) or os.path.lexists(video):
            continue
        try:
            return save_path_document(document, json_path), video
        except UserError:
            if os.path.lexists(json_path):  # another writer took the name meanwhile
                continue
            raise
    raise UserError(f"{folder}: no free video name from {stem} on")


def progress_text(progress: FrameProgress | None) -> str:
    """The progress bar's text, e.g. "frame 12 / 300, 4.1 fps, 70 s left" (None: the
    command has said nothing yet)."""
    if progress is None:
        return "frame 0 / ?"
    text = f"frame {progress.frame} / {progress.frames}"
    if progress.fps is not None:
        text += f", {progress.fps:.3g} fps"
    if progress.eta_s is not None:
        text += f", {progress.eta_s:.0f} s left"
    return text


@dataclass(frozen=True)
class JobResult:
    """How a job ended: ``kind`` "done", "interrupted" or "error", and the panel's line."""

    kind: str
    message: str


class VideoJob:
    """One running ``command`` (see :func:`render_path_command`) writing ``out``: its
    stdout's progress lines and its stderr's ``error:`` line are read on threads;
    :meth:`poll` returns the result once, when it has ended."""

    def __init__(self, command: list[str], out: Path, document: Path):
        self.command, self.out, self.document = list(command), Path(out), Path(document)
        self._lock = threading.Lock()
        self._progress: FrameProgress | None = None
        self._final: RenderDone | RenderInterrupted | None = None
        self._errors: list[str] = []         # stderr's lines (the last few)
        self.cancelled = False
        self._reported = False
        try:
            self.process = subprocess.Popen(self.command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                            stderr=subprocess.PIPE, text=True, encoding="utf-8", errors="replace",
                                            bufsize=1)
        except OSError as exc:
            raise UserError(f"cannot start the video render: {exc.strerror or exc}") from None
        self._readers = [threading.Thread(target=self._read_stdout, daemon=True, name="video-progress"),
                         threading.Thread(target=self._read_stderr, daemon=True, name="video-errors")]
        for reader in self._readers:
            reader.start()

    # -- reader threads -----------------------------------------------------------------
    def _read_stdout(self) -> None:
        for line in self.process.stdout:
            record = read_progress_line(line)
            if record is None:
                continue  # not a progress line of ours: nothing the window shows
            with self._lock:
                if isinstance(record, FrameProgress):
                    self._progress = record
                else:
                    self._final = record

    def _read_stderr(self) -> None:
        for line in self.process.stderr:
            line = line.strip()
            if line:
                with self._lock:
                    self._errors = (self._errors + [line])[-20:]

    # -- what the window calls ----------------------------------------------------------
    @property
    def running(self) -> bool:
        return self.process.poll() is None or any(reader.is_alive() for reader in self._readers)

    @property
    def progress(self) -> FrameProgress | None:
        """The last progress line; None before the first."""
        with self._lock:
            return self._progress

    def cancel(self) -> None:
        """Asks the command to stop (SIGINT, as Ctrl-C would): it leaves a playable
        truncated video, or none."""
        if self.process.poll() is None:
            self.cancelled = True
            try:
                self.process.send_signal(signal.SIGINT)
            except OSError:
                pass  # it has just ended

    def poll(self) -> JobResult | None:
        """The result once the command has ended and its output is read; None before, and
        after the result has been returned once."""
        if self._reported or self.running:
            return None
        self._reported = True
        return self.result()

    def result(self) -> JobResult:
        status = self.process.returncode
        with self._lock:
            final, errors, progress = self._final, list(self._errors), self._progress
        if isinstance(final, RenderDone) and status == 0:
            return JobResult("done", f"saved {final.out} ({final.frames} frames; path {self.document})")
        if isinstance(final, RenderInterrupted) or (self.cancelled and status in (130, -signal.SIGINT)):
            done = final.frames if final else progress.frame if progress else 0
            kept = final.out if final else None
            if kept is None and self.out.exists():
                kept = str(self.out)
            where = f"{kept} holds the first {done} frames" if kept else "no video was written"
            return JobResult("interrupted", f"video cancelled: {where}")
        error = next((line for line in reversed(errors) if line.startswith("error:")), None)
        if error is None:
            error = f"error: the video render failed (exit status {status})" + (f": {errors[-1]}" if errors else "")
        return JobResult("error", error)

    def close(self, timeout: float = CLOSE_WAIT_S) -> None:
        """Cancels the job if it runs, waits up to ``timeout`` seconds for it to leave
        its truncated file, then kills it."""
        self.cancel()
        try:
            self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        for reader in self._readers:
            reader.join(timeout=1.0)


class VideoRender:
    """Render video's part of the path widget: ``folder`` the videos go to, ``size``
    ("view": the document's own, or a VIDEO_SIZES key), ``command(scene, document,
    out)`` that renders one (tests run stand-ins), and ``job``, the render under way
    (None: none)."""

    def __init__(self) -> None:
        self.folder = "videos"
        self.size = "view"
        self.command: Callable[[str, Path, Path], list[str]] = render_path_command
        self.job: VideoJob | None = None

    @property
    def running(self) -> bool:
        return self.job is not None and self.job.running

    def start(self, document: PathDocument, scene: str) -> Path:
        """Saves ``document`` (at the chosen size) into the folder and starts rendering
        ``scene`` ("demo" or an absolute path) along it; returns the video's path.
        UserError when the document cannot be saved or the command not started."""
        if self.size in VIDEO_SIZES:
            width, height = VIDEO_SIZES[self.size]
            document = replace(document, width=width, height=height)
        saved, out = write_video_document(document, self.folder)
        self.job = VideoJob(self.command(scene, saved, out), out, saved)
        return out

    def cancel(self) -> None:
        if self.job is not None:
            self.job.cancel()

    def poll(self) -> JobResult | None:
        """The job's result once it has ended (the job is then forgotten); else None."""
        result = None if self.job is None else self.job.poll()
        if result is not None:
            self.job = None
        return result

    def close(self) -> None:
        """Stops a render still under way: it would outlive the window."""
        if self.job is not None:
            self.job.close()
