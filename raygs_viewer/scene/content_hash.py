"""The SHA-256 that names a scene's content (screenshot sidecars and path files record
it, and check a scene against it): of its file's bytes, of every file of an unbundled
SOG scene, or of the arrays of a scene that has no file (the demo)."""

from __future__ import annotations

import hashlib
import os
import threading
from collections.abc import Callable

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.progress import ProgressCallback
from raygs_viewer.scene.lod_file import lod_scene_files
from raygs_viewer.scene.sog_file import scene_files as sog_scene_files

#: The file hash reads this many bytes at a time (one reused buffer): hashing a
#: multi-GB scene never holds more than this of it.
HASH_CHUNK_BYTES = 1 << 20

# How often a load that has read its scene reports the hash it still waits for.
_HASH_POLL_SECONDS = 0.05

_ARRAYS = ("positions", "rotations", "scales", "opacities", "sh")


def arrays_sha256(scene: Scene) -> str:
    """Hex SHA-256 of the scene's positions, rotations, scales, opacities and sh, in that
    order, as C-contiguous float32 bytes (for the demo, where there is no file to hash)."""
    digest = hashlib.sha256()
    for name in _ARRAYS:
        digest.update(np.ascontiguousarray(getattr(scene, name), dtype=np.float32).tobytes())
    return digest.hexdigest()


def file_sha256(path: str | os.PathLike, progress: ProgressCallback | None = None,
                cancel: threading.Event | None = None, *, chunk_bytes: int | None = None) -> str:
    """Hex SHA-256 of a scene file, read HASH_CHUNK_BYTES (or ``chunk_bytes``) at a time into one buffer.

    A scene of several files (an unbundled SOG: its meta.json, or the folder holding it;
    a streamed SOG: its lod-meta.json and every unit's files) hashes each of them in turn
    (sog_file.scene_files, lod_file.lod_scene_files), every file's bytes preceded by its
    name and size, so that no file of the scene can change unseen; a one-file scene's
    digest is its file's plain SHA-256.

    ``progress(fraction, "hashing")`` follows each read; a set ``cancel`` stops it with
    ``UserError("loading cancelled")``. Read failures are a one-line UserError naming the file.
    """
    shown = os.fspath(path)
    digest = hashlib.sha256()
    buffer = bytearray(max(1, HASH_CHUNK_BYTES if chunk_bytes is None else chunk_bytes))
    view = memoryview(buffer)
    try:
        files = lod_scene_files(path) or sog_scene_files(path)
        several = files is not None
        files = files if several else [path]
        total = sum(os.path.getsize(file) for file in files)
        done = 0
        for file in files:
            with open(file, "rb") as f:
                if several:
                    digest.update(f"{os.path.basename(file)}\0{os.fstat(f.fileno()).st_size}\0".encode())
                while True:
                    if cancel is not None and cancel.is_set():
                        raise UserError("loading cancelled")
                    got = f.readinto(buffer)
                    if not got:
                        break
                    digest.update(view[:got])
                    done += got
                    if progress is not None:
                        progress(min(1.0, done / total) if total else 1.0, "hashing")
    except FileNotFoundError:
        raise UserError(f"{shown}: no such file") from None
    except IsADirectoryError:
        raise UserError(f"{shown}: is a folder, expected a scene file") from None
    except OSError as exc:
        raise UserError(f"{shown}: cannot read: {exc.strerror or exc}") from None
    return digest.hexdigest()


class FileHash:
    """:func:`file_sha256` of a file on a thread of its own, started beside the scene's
    read: the two overlap (hashlib and numpy release the GIL), so a multi-GB scene costs
    about the longer of the two instead of their sum, and the file, read twice, comes
    from the disk once. ``stop`` ends it at its next chunk."""

    def __init__(self, path: str | os.PathLike, cancel: threading.Event | None) -> None:
        self.stop = threading.Event()
        self.fraction = 0.0
        self.digest: str | None = None
        self.error: BaseException | None = None
        self._cancel = cancel
        self._thread = threading.Thread(target=self._run, args=(path,), name="raygs-hash", daemon=True)
        self._thread.start()

    def _run(self, path) -> None:
        try:
            self.digest = file_sha256(path, self._progress, self.stop)
        except BaseException as exc:  # handed to the loading thread, which raises it
            self.error = exc

    def _progress(self, fraction: float, stage: str) -> None:
        self.fraction = fraction
        if self._cancel is not None and self._cancel.is_set():
            self.stop.set()

    def result(self, report: Callable[[float], None]) -> str:
        """Waits for the digest, calling ``report(fraction)`` a few times a second (a
        cancel point: it may raise); raises what the hash raised."""
        while True:
            self._thread.join(_HASH_POLL_SECONDS)
            done = not self._thread.is_alive()
            report(1.0 if done and self.error is None else self.fraction)
            if done:
                break
        if self.error is not None:
            raise self.error
        return self.digest
