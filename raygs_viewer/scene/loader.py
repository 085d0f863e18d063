"""Loading a scene with everything the window shows about it: the gaussians, the
training cameras found beside it, a content hash, and warnings.

:func:`load_now` does it synchronously (the scene named on the command line, so a
bad file fails before a window opens); :class:`SceneLoader` does it on a daemon
thread while the window keeps drawing, reporting progress and discarding a load
that a newer one replaced. The hash is :mod:`~raygs_viewer.scene.content_hash`'s; a
progress line on a terminal is the command line's (``capture/progress.py``).

A streamed SOG (``lod-meta.json``) is read level by level, coarsest first
(:func:`~raygs_viewer.scene.lod_file.load_lod`), and each level read is handed on at
once (``on_level``; the background loader delivers it like a finished load, marked
``refines``), so the window shows the coarsest level while the finer ones are read.
"""

from __future__ import annotations

import fnmatch
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import Camera, load_cameras
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import read_json_file
from raygs_viewer.scene.content_hash import FileHash, arrays_sha256, file_sha256
from raygs_viewer.scene.demo import DEMO_VIEW_NAMES, demo_cameras, demo_scene
from raygs_viewer.scene.io import dropped_summary, load_scene
from raygs_viewer.scene.lod_file import Fits, LodScene, load_lod, lod_index_file
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.progress import ProgressCallback, Reporter
from raygs_viewer.scene.source import SceneSource

#: ``read_scene(source, *, progress, cancel) -> Scene``: what reads the scene
#: file (:func:`~raygs_viewer.scene.io.load_scene`; tests hand in a steered one).
SceneReader = Callable[..., Scene]
#: ``read_lod(path, *, levels, fits, progress, cancel, on_level) -> LodScene``: what reads
#: a streamed SOG (:func:`~raygs_viewer.scene.lod_file.load_lod`; tests step through it).
LodReader = Callable[..., LodScene]

__all__ = [
    "LoadedScene",
    "LodReader",
    "SceneLoader",
    "SceneReader",
    "find_training_cameras",
    "load_now",
]

# Shares of the whole job in load_now's progress: reading and activating the scene
# dominates; the hash runs beside it, and what is left of it once the scene is read
# takes the next share.
_SCENE_END = 0.85
_HASH_END = 0.98


def find_training_cameras(scene_path: str | os.PathLike) -> Path | None:
    """cameras.json beside the scene file, or in the INRIA model folder when the scene is
    MODEL/point_cloud/iteration_*/point_cloud.ply (MODEL/cameras.json). None if neither exists.

    The file beside the scene wins when both exist. Any file name inside the
    ``iteration_*`` folder counts (trainers differ in what they write there).
    """
    scene_path = Path(scene_path)
    beside = scene_path.parent / "cameras.json"
    if beside.is_file():
        return beside
    # abspath, not resolve(): a symlinked scene keeps the folder it was opened from,
    # and a bare "point_cloud.ply" still knows its parents.
    iteration = Path(os.path.abspath(scene_path)).parent
    if fnmatch.fnmatchcase(iteration.name, "iteration_*") and iteration.parent.name == "point_cloud":
        model = iteration.parent.parent / "cameras.json"
        if model.is_file():
            return model
    return None


@dataclass(frozen=True)
class LoadedScene:
    """A loaded scene and what the window shows about it.

    scene:        the gaussians (see :class:`raygs_viewer.scene.model.Scene`).
    source:       what was read (its ``path`` as given, or "demo").
    sha256:       hex SHA-256 of the file's bytes; for the demo, :func:`arrays_sha256`.
    cameras:      training cameras (the demo: ``demo_cameras()``), [] if none.
    cameras_path: the cameras.json they came from (None for none, and for the demo's own).
    camera_names: one per camera: its ``img_name`` when present, else "camera i";
                  the demo: ``DEMO_VIEW_NAMES``.
    warnings:     one-line warnings without a "warning:" prefix: the dropped-gaussian
                  summary, and why a discovered cameras.json was skipped.
    lod:          a streamed SOG's levels read so far (``scene`` is ``lod.scene``); None
                  for any other scene.
    refines:      a finer reading of the scene delivered before it by the same load (a
                  level read since), not a new scene: the window keeps its view.
                  ``sha256`` is "" while the files are still being hashed.
    """

    scene: Scene
    source: SceneSource
    sha256: str
    cameras: list[Camera]
    cameras_path: str | None
    camera_names: list[str]
    warnings: list[str]
    lod: LodScene | None = None
    refines: bool = False

    @property
    def path(self) -> str:
        """The scene path as given, or "demo"."""
        return self.source.path

    @cached_property
    def content_sha256(self) -> str:
        """``sha256``, or, while a streamed SOG's files are still being hashed beside its
        reading, their hash taken now: what a saved document (a screenshot's sidecar, a
        path or measurements file) must record."""
        return self.sha256 or file_sha256(self.path)

    @property
    def framed(self) -> np.ndarray:
        """(N, 3) the positions a view that frames the scene should see: a streamed
        SOG's without its environment (its first rows), which surrounds the scene from afar."""
        return self.scene.positions[0 if self.lod is None else self.lod.environment[1]:]


def _camera_names(path: Path, count: int) -> list[str]:
    """img_name of each camera in an already validated cameras.json, else "camera i"."""
    try:
        data = read_json_file(path, "a cameras.json file")
    except UserError:
        data = None  # it parsed a moment ago; if it changed since, fall back to numbers
    entries = data if isinstance(data, list) else [data]
    names = []
    for i in range(count):
        entry = entries[i] if i < len(entries) else None
        name = entry.get("img_name") if isinstance(entry, dict) else None
        # One line for the panel's list, whatever the JSON holds.
        name = " ".join(name.split()) if isinstance(name, str) else ""
        names.append(name or f"camera {i}")
    return names


def _scaled(progress: ProgressCallback | None, start: float, end: float,
            then: str) -> ProgressCallback | None:
    """A step's progress mapped into [start, end] of the whole job; the step's own
    "done" is renamed ``then`` (the next stage), so "done" comes once, at the end."""
    if progress is None:
        return None
    return lambda fraction, stage: progress(start + (end - start) * fraction, then if stage == "done" else stage)


def load_now(source: SceneSource, progress: ProgressCallback | None = None, *,
             cancel: threading.Event | None = None, read_scene: SceneReader = load_scene,
             fits: Fits | None = None, on_level: Callable[[LoadedScene], None] | None = None,
             read_lod: LodReader = load_lod) -> LoadedScene:
    """Loads ``source`` (a scene file, or the demo) with its training cameras, synchronously.

    ``source.cameras``: an explicit cameras.json; a bad one is a UserError. Without it
    the file found by :func:`find_training_cameras` is used, and a bad one only adds a
    warning (the scene still loads, with no cameras). For the demo, ``cameras``
    replaces its built-in views.

    ``progress(fraction, stage)``: non-decreasing fractions in [0, 1], ending with
    ``(1.0, "done")``. ``cancel``: when set, stops at the next progress point with
    ``UserError("loading cancelled")``. Every failure is a one-line UserError.
    ``read_scene`` reads the scene file (:func:`load_scene`), with the source's options.

    A streamed SOG is read by ``read_lod`` (:func:`load_lod`): ``source.levels`` (None:
    every level) while they ``fit``; ``on_level`` gets the scene so far after each level
    (from this thread, its ``sha256`` "" until the hash is done), and the result holds
    every level read (``LoadedScene.lod``).
    """
    report = Reporter(progress, cancel)
    try:
        if source.is_demo:
            report(0.0, "building")
            scene = demo_scene()
            report(_SCENE_END, "hashing")
            digest = arrays_sha256(scene)
        elif lod_index_file(source.path) is not None:
            return _read_levels(source, progress, report, cancel, read_lod, fits=fits, on_level=on_level)
        else:
            scene, digest = _read_and_hash(source, progress, report, cancel, read_scene)
        warnings = dropped_summary(scene)
        report(_HASH_END, "cameras")
        found, names, cameras_path = _training_cameras(source, warnings)
        report(1.0, "done")
    except (OSError, MemoryError) as exc:
        raise source.read_error(exc) from None
    return LoadedScene(scene, source, digest, found, cameras_path, names, warnings)


def _read_and_hash(source: SceneSource, progress: ProgressCallback | None, report: Reporter,
                   cancel: threading.Event | None, read_scene: SceneReader) -> tuple[Scene, str]:
    """The scene file read and hashed side by side; a failed read stops the hash."""
    hashing = FileHash(source.path, cancel)
    try:
        scene = read_scene(source, progress=_scaled(progress, 0.0, _SCENE_END, "hashing"), cancel=cancel)
        digest = hashing.result(lambda f: report(_SCENE_END + (_HASH_END - _SCENE_END) * f, "hashing"))
    finally:
        hashing.stop.set()  # a failed or cancelled load leaves no hash running
    return scene, digest


def _read_levels(source: SceneSource, progress: ProgressCallback | None, report: Reporter,
                 cancel: threading.Event | None, read_lod: LodReader, *, fits: Fits | None,
                 on_level: Callable[[LoadedScene], None] | None) -> LoadedScene:
    """A streamed SOG read and hashed side by side (``source.levels`` while they ``fit``).
    The cameras come first: the coarsest level is shown with them."""
    camera_warnings: list[str] = []
    found, names, cameras_path = _training_cameras(source, camera_warnings)

    def loaded(lod: LodScene, digest: str) -> LoadedScene:
        return LoadedScene(lod.scene, source, digest, found, cameras_path, names,
                           dropped_summary(lod.scene) + camera_warnings, lod)

    hashing = FileHash(source.path, cancel)
    try:
        lod = read_lod(source.path, progress=_scaled(progress, 0.0, _SCENE_END, "hashing"), cancel=cancel,
                       on_level=None if on_level is None else lambda lod: on_level(loaded(lod, hashing.digest or "")),
                       levels=source.levels, fits=fits)
        digest = hashing.result(lambda f: report(_SCENE_END + (_HASH_END - _SCENE_END) * f, "hashing"))
    finally:
        hashing.stop.set()
    report(1.0, "done")
    return loaded(lod, digest)


def _training_cameras(source: SceneSource, warnings: list[str]) -> tuple[list[Camera], list[str], str | None]:
    """(cameras, their names, the cameras.json they came from) shown with ``source``'s
    scene: its explicit ``cameras`` file (a bad one is a UserError); else the demo's
    own views, or the cameras.json found beside a scene file (a bad one is skipped
    with a line added to ``warnings``)."""
    cameras = source.cameras
    if cameras is not None:
        found = load_cameras(cameras)
        return found, _camera_names(Path(cameras), len(found)), cameras
    if source.is_demo:
        return demo_cameras(), list(DEMO_VIEW_NAMES), None
    discovered = find_training_cameras(source.path)
    if discovered is None:
        return [], [], None
    try:
        found = load_cameras(discovered)
    except UserError as exc:
        warnings.append(f"training cameras skipped: {exc}")
        return [], [], None
    return found, _camera_names(discovered, len(found)), os.fspath(discovered)


class _Job:
    """One load on its own thread; its fields are written by that thread only."""

    def __init__(self, source: SceneSource, fits: Fits | None, refines: bool) -> None:
        self.source = source
        self.fits = fits        # load_now's
        self.refines = refines  # every result refines the scene shown
        self.delivered = False  # a result of this job has been polled
        self.cancel = threading.Event()
        self.progress = 0.0
        self.stage = "queued"
        self.done = False


class SceneLoader:
    """Loads one scene at a time on a daemon thread.

    The window calls :meth:`start` and then, every frame, reads ``progress``/``stage``
    and :meth:`poll`s for the result; none of those wait for the load. Starting a new
    load cancels the one in progress: its thread stops at its next progress point
    (every few MiB) and its result, whatever it is, is never delivered.

    Counters for tests and the statistics panel: ``started``, ``delivered`` (results
    handed to poll/wait), ``discarded`` (results of loads that a newer start or
    :meth:`cancel` replaced).

    ``read_scene`` reads each scene file (:func:`load_scene`), ``read_lod`` each
    streamed SOG (:func:`load_lod`), on the load's thread. A streamed SOG's load delivers
    each level as it is read: every result after its first is marked ``refines``.
    """

    def __init__(self, read_scene: SceneReader = load_scene, read_lod: LodReader = load_lod) -> None:
        self.read_scene = read_scene
        self.read_lod = read_lod
        self._cond = threading.Condition()
        self._job: _Job | None = None
        self._result: LoadedScene | UserError | None = None
        self._running: set[threading.Thread] = set()
        self._closed = False
        self.started = 0
        self.delivered = 0
        self.discarded = 0

    def start(self, source: SceneSource, *, fits: Fits | None = None, refines: bool = False) -> None:
        """Cancels a load in progress (its result is discarded) and starts reading
        ``source`` (``fits``: as for :func:`load_now`); a finished result
        not yet polled is dropped too. ``refines``: every result, the first too, is a finer
        reading of the scene shown (the rest of a streamed SOG's levels). RuntimeError
        after :meth:`close`."""
        job = _Job(source, fits, refines)
        thread = threading.Thread(target=self._run, args=(job,), name="raygs-load", daemon=True)
        with self._cond:
            if self._closed:
                raise RuntimeError("SceneLoader.start after close()")
            self._abandon()
            self._job = job
            self._running.add(thread)
            self.started += 1
        thread.start()

    def cancel(self) -> None:
        """Cancels the load in progress, if any; poll() then returns None for it."""
        with self._cond:
            self._abandon()
            self._job = None
            self._cond.notify_all()

    @property
    def progress(self) -> float:
        """Fraction in [0, 1] of the current load (1.0 once finished; 0.0 with none)."""
        job = self._job
        return job.progress if job is not None else 0.0

    @property
    def stage(self) -> str:
        """What the current load is doing ("reading", "hashing", "done", ...; "" with none)."""
        job = self._job
        return job.stage if job is not None else ""

    @property
    def path(self) -> str:
        """The path of the current load as given ("" with none)."""
        job = self._job
        return job.source.path if job is not None else ""

    @property
    def busy(self) -> bool:
        """A load is in progress (its result not yet available)."""
        job = self._job
        return job is not None and not job.done

    def poll(self) -> LoadedScene | UserError | None:
        """Non-blocking: the finished result once (then None); a failed load gives the
        UserError object, for the window to show. While a streamed SOG is read, each
        level read is a result of its own (a newer one replaces one not yet polled)."""
        with self._cond:
            result, self._result = self._result, None
            if result is not None:
                self.delivered += 1
            if isinstance(result, LoadedScene) and self._job is not None:
                result = replace(result, refines=self._job.refines or self._job.delivered)
                self._job.delivered = True
            return result

    def wait_done(self, timeout: float | None = None) -> bool:
        """Blocks until the current load finishes, leaving its result for :meth:`poll`;
        True when it has (or there is none)."""
        with self._cond:
            return self._cond.wait_for(lambda: self._job is None or self._job.done, timeout)

    def wait(self, timeout: float | None = None) -> LoadedScene | UserError | None:
        """Blocks until the current load finishes, then returns what :meth:`poll` would.
        None when there is no load, its result was already polled, or ``timeout`` passed."""
        self.wait_done(timeout)
        return self.poll()

    def join(self, timeout: float | None = None) -> bool:
        """Waits for every load thread, cancelled ones included, to end (tests and
        scripted shutdown). True when none is left running."""
        with self._cond:
            return self._cond.wait_for(lambda: not self._running, timeout)

    def close(self) -> None:
        """Cancels the load in progress and returns without waiting for its thread."""
        with self._cond:
            self._closed = True
            self._abandon()
            self._job = None
            self._cond.notify_all()

    def __enter__(self) -> "SceneLoader":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # ------------------------------------------------------------------ internals

    def _abandon(self) -> None:
        """(Lock held.) Cancel the current job and drop an undelivered result."""
        if self._job is not None and not self._job.done:
            self._job.cancel.set()
        if self._result is not None:
            self.discarded += 1
            self._result = None

    def _run(self, job: _Job) -> None:
        def progress(fraction: float, stage: str) -> None:
            job.progress, job.stage = fraction, stage

        def level(loaded: LoadedScene) -> None:
            with self._cond:
                if job is self._job and not job.cancel.is_set():
                    self._result = loaded
                    self._cond.notify_all()

        try:
            result: LoadedScene | UserError = load_now(job.source, progress, cancel=job.cancel,
                                                       read_scene=self.read_scene, fits=job.fits,
                                                       on_level=level, read_lod=self.read_lod)
        except UserError as exc:
            result = exc
        except Exception as exc:  # a bug or an odd OS failure: still one line for the panel
            detail = " ".join(str(exc).split())
            what = type(exc).__name__ + (f": {detail}" if detail else "")
            result = UserError(f"{job.source.path}: loading failed ({what})")
        with self._cond:
            job.done = True
            if job is self._job:
                self._result = result
            else:
                self.discarded += 1
            self._running.discard(threading.current_thread())
            self._cond.notify_all()
