"""Decoding a WebP image into RGBA pixels, its size checked from its header before any
pixel is decoded.

Pillow decodes (already a dependency; its wheels bundle libwebp): lossless WebP comes
back exactly, RGB under a zero alpha included. Pillow allocates the whole canvas on
opening, so the caller's size check runs on the header's width and height first.
"""

from __future__ import annotations

import io
import warnings
from collections.abc import Callable

import numpy as np

from raygs_viewer.scene.reading import file_error, shown_token


def webp_size(shown: str, data: bytes) -> tuple[int, int]:
    """Width and height from a WebP file's first bytes (the RIFF container's first chunk:
    lossless VP8L, extended VP8X or lossy VP8), before anything is decoded."""
    if len(data) < 30 or data[:4] != b"RIFF" or data[8:12] != b"WEBP":
        raise file_error(shown, "not a WebP image")
    kind = data[12:16]
    if kind == b"VP8L" and data[20] == 0x2F:
        bits = int.from_bytes(data[21:25], "little")
        return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    if kind == b"VP8X":
        if data[20] & 0x02:
            raise file_error(shown, "animated WebP: a SOG image has one frame")
        return int.from_bytes(data[24:27], "little") + 1, int.from_bytes(data[27:30], "little") + 1
    if kind == b"VP8 " and data[23:26] == b"\x9d\x01\x2a":
        return int.from_bytes(data[26:28], "little") & 0x3FFF, int.from_bytes(data[28:30], "little") & 0x3FFF
    raise file_error(shown, "not a WebP image (unknown or corrupt first chunk)")


def decode_webp(shown: str, data: bytes, pixels_ok: Callable[[int, int], bool], need: str,
                width: int | None = None) -> np.ndarray:
    """(H * W, 4) uint8 RGBA pixels, row-major. The header's size is checked with
    ``pixels_ok(w, h)`` (and ``width``) before Pillow decodes anything; ``need`` says
    in the message what size was expected."""
    # Pillow is imported here, not at module level: only SOG reading needs it, and a
    # viewer that opens PLY files never pays for importing it.
    from PIL import Image, features

    w, h = webp_size(shown, data)
    if (width is not None and w != width) or not pixels_ok(w, h):
        raise file_error(shown, f"image is {w}x{h}; {need}")
    if not features.check_module("webp"):
        raise file_error(shown, "this Pillow was built without WebP support: cannot decode SOG images")
    try:
        with warnings.catch_warnings():
            # Sizes were bounded above; Pillow's own, global, bomb limit is not ours to apply twice.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data), formats=["WEBP"]) as image:
                if getattr(image, "n_frames", 1) != 1:
                    raise file_error(shown, "animated WebP: a SOG image has one frame")
                if image.size != (w, h):
                    raise file_error(shown, f"WebP header says {w}x{h} but the image is "
                                            f"{image.size[0]}x{image.size[1]} (corrupt image)")
                image.load()
                rgba = image if image.mode == "RGBA" else image.convert("RGBA")
                pixels = np.asarray(rgba, dtype=np.uint8)
    except (OSError, SyntaxError, ValueError, EOFError, Image.DecompressionBombError) as exc:
        detail = " ".join(str(exc).split()) or type(exc).__name__
        raise file_error(shown, f"cannot decode the WebP image ({shown_token(detail, 80)[1:-1]})") from None
    if pixels.shape != (h, w, 4):
        raise file_error(shown, "image decoded to an unexpected shape (corrupt image)")
    return pixels.reshape(h * w, 4)
