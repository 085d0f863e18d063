"""Writing files atomically, and never over a file the user already has.

Every file the project writes (images, sidecars, camera paths, videos, scenes, the
benchmarks' generated scenes) goes through here: it is written to a hidden temporary
beside the target and moved into place whole, so a reader never sees half a file and
an interrupted write leaves nothing behind. Without ``overwrite`` an existing file is
never replaced, even one that appears while writing. It sits below ``scene/`` so that
writing a scene and saving a screenshot share one mechanism.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

from raygs_viewer.errors import UserError


def check_writable_folder(out: str | os.PathLike, folder: str | os.PathLike) -> None:
    """UserError unless ``folder``, where ``out`` will be written, exists and this user
    may create files in it: checked before any slow work, so that a long run does not
    end in "permission denied" with nothing saved."""
    folder = Path(folder)
    if not folder.is_dir():
        kind = " (it is a file)" if folder.exists() else ""
        raise UserError(f"{out}: folder '{folder}' does not exist{kind}")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UserError(f"{out}: folder '{folder}' is not writable")


def config_file(name: str) -> Path:
    """Where the viewer keeps ``name`` between runs: ``$XDG_CONFIG_HOME/raygs-viewer/``
    (``~/.config`` where that is unset); the folder may not exist yet."""
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "raygs-viewer" / name


@contextmanager
def atomic_writer(path: str | os.PathLike, overwrite: bool = False) -> Iterator[BinaryIO]:
    """A binary stream into a temporary beside ``path``, moved into place when the
    block ends without an exception (and removed when it ends with one). UserError
    "already exists" for an existing ``path`` without ``overwrite``, and for any OS
    error, one line naming ``path``."""
    path = Path(path)
    try:
        handle, temporary = temporary_beside(path)
        try:
            with os.fdopen(handle, "wb") as stream:
                yield stream
                stream.flush()
                os.fsync(stream.fileno())
            move_into_place(temporary, path, overwrite)
        except BaseException:
            if os.path.exists(temporary):
                os.unlink(temporary)
            raise
    except FileExistsError:
        raise UserError(f"{path}: already exists (pass --overwrite to replace it)") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None


def write_atomically(path: str | os.PathLike, data: bytes, overwrite: bool = False) -> None:
    """Writes ``data`` to ``path`` through :func:`atomic_writer`."""
    with atomic_writer(path, overwrite) as stream:
        stream.write(data)


def temporary_beside(path: Path) -> tuple[int, str]:
    """(open descriptor, name) of a new hidden ``.NAME.*.partial`` file in ``path``'s
    folder, with an ordinary file's permissions; OSError if the folder refuses it."""
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        os.fchmod(handle, 0o666 & ~_umask())  # mkstemp makes 0600; a saved file is an ordinary file
    except BaseException:
        os.close(handle)
        os.unlink(temporary)
        raise
    return handle, temporary


def move_into_place(temporary: str, path: Path, overwrite: bool) -> None:
    """Renames a finished ``temporary`` (from :func:`temporary_beside`) to ``path``:
    replacing it only with ``overwrite``; without, FileExistsError if ``path`` exists,
    even one that appeared while writing."""
    if overwrite:
        os.replace(temporary, path)
    else:
        _move_without_replacing(temporary, path)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _move_without_replacing(source: str, target: Path) -> None:
    try:
        os.link(source, target)  # atomic, and fails if target exists: no clobbering race
    except FileExistsError:
        raise
    except OSError:  # a filesystem without hard links: claim the name, then replace it
        os.close(os.open(target, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        os.replace(source, target)
    else:
        os.unlink(source)
