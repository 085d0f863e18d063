"""Writing rendered images: atomically, and never over a file the user already has."""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from raygs_viewer.errors import UserError

IMAGE_SUFFIXES = (".png", ".npy")


def to_rgb8(image: np.ndarray) -> np.ndarray:
    """(H, W, >=3) float image -> (H, W, 3) uint8, clamped to [0, 1] and rounded."""
    return np.round(np.clip(image[..., :3], 0.0, 1.0) * 255.0).astype(np.uint8)


def encode_image(image: np.ndarray, suffix: str) -> bytes:
    """PNG: 8-bit RGB of the composited colour. NPY: float32 (H, W, 4), RGB over the
    background and accumulated alpha, before any rounding."""
    buffer = io.BytesIO()
    if suffix == ".npy":
        np.save(buffer, np.ascontiguousarray(image, dtype=np.float32))
    elif suffix == ".png":
        return encode_png(to_rgb8(image))
    else:
        raise UserError(f"unsupported image type '{suffix}' (use {' or '.join(IMAGE_SUFFIXES)})")
    return buffer.getvalue()


def encode_png(rgb8: np.ndarray) -> bytes:
    """(H, W, 3) uint8 -> PNG bytes: what every saved PNG (screenshots, ``render``,
    video frame folders) goes through, so equal pixels give equal files."""
    buffer = io.BytesIO()
    Image.fromarray(rgb8, "RGB").save(buffer, format="PNG")
    return buffer.getvalue()


def check_output_path(path: str | Path, overwrite: bool = False, suffixes: tuple[str, ...] = IMAGE_SUFFIXES) -> Path:
    """Validates an output path before any work is done: one of ``suffixes``, an
    existing folder, and no existing file unless ``overwrite``."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise UserError(f"{path}: output must end in {' or '.join(suffixes)}")
    if not path.parent.is_dir():
        raise UserError(f"{path}: folder '{path.parent}' does not exist")
    if path.is_dir():
        raise UserError(f"{path}: is a folder")
    if path.exists() and not overwrite:
        raise UserError(f"{path}: already exists (pass --overwrite to replace it)")
    return path


def write_atomically(path: str | Path, data: bytes, overwrite: bool = False) -> None:
    """Writes ``data`` to a temporary file beside ``path`` and moves it into place, so a
    reader never sees half a file. Without ``overwrite`` an existing file is never
    replaced, even one that appears while writing."""
    path = Path(path)
    try:
        handle, temporary = temporary_beside(path)
        try:
            with os.fdopen(handle, "wb") as stream:
                stream.write(data)
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


def save_image(path: str | Path, image: np.ndarray, overwrite: bool = False) -> Path:
    path = check_output_path(path, overwrite)
    write_atomically(path, encode_image(image, path.suffix.lower()), overwrite)
    return path
