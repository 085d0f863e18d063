"""Writing rendered images: atomically, and never over a file the user already has
(:mod:`raygs_viewer.files`, which every written file goes through)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from PIL import Image
from PIL.PngImagePlugin import PngInfo

from raygs_viewer.errors import UserError
from raygs_viewer.files import check_writable_folder, write_atomically

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


def encode_png(rgb8: np.ndarray, text: dict[str, str] | None = None) -> bytes:
    """(H, W, 3) uint8 -> PNG bytes: what every saved PNG (screenshots, ``render``,
    video frame folders) goes through, so equal pixels give equal files. ``text``: tEXt
    entries (e.g. a depth picture's range); without it the file is as it always was."""
    buffer = io.BytesIO()
    info = None
    if text:
        info = PngInfo()
        for key, value in text.items():
            info.add_text(key, value)
    Image.fromarray(rgb8, "RGB").save(buffer, format="PNG", pnginfo=info)
    return buffer.getvalue()


def check_output_path(path: str | Path, overwrite: bool = False, suffixes: tuple[str, ...] = IMAGE_SUFFIXES) -> Path:
    """Validates an output path before any work is done: one of ``suffixes``, an
    existing folder this user may write in, and no existing file unless ``overwrite``."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise UserError(f"{path}: output must end in {' or '.join(suffixes)}")
    check_writable_folder(path, path.parent)
    if path.is_dir():
        raise UserError(f"{path}: is a folder")
    if path.exists() and not overwrite:
        raise UserError(f"{path}: already exists (pass --overwrite to replace it)")
    return path


def save_image(path: str | Path, image: np.ndarray, overwrite: bool = False) -> Path:
    path = check_output_path(path, overwrite)
    write_atomically(path, encode_image(image, path.suffix.lower()), overwrite)
    return path
