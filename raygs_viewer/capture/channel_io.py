"""Writing a render's channels (:mod:`raygs_viewer.render.channels`) to a file, as
``render --channels`` and ``render-path --channels`` ask:

- ``.npy``: float32 (H, W, C), the channels in the order listed (rgb and normal 3 each);
- ``.exr``: float32 named channels (:data:`EXR_NAMES`) through the OpenEXR library; EXR
  keeps channels sorted by name, so the header's ``raygsChannels`` says the listed order;
- ``.png``: a picture of one channel (:func:`channel_picture`): depth through viridis
  over a stated range, which the PNG's text metadata records, normals as 0.5 + 0.5 n.

Every file is written atomically and never over an existing file without
``overwrite`` (:mod:`raygs_viewer.files`).
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Sequence

import numpy as np

from raygs_viewer.capture.image_io import encode_png, to_rgb8
from raygs_viewer.errors import UserError
from raygs_viewer.files import move_into_place, temporary_beside, write_atomically
from raygs_viewer.render.channel_pictures import ALPHA_THRESHOLD, ChannelView, channel_picture
from raygs_viewer.render.channels import DEFAULT_CHANNELS, ChannelImage

CHANNEL_SUFFIXES = (".png", ".npy", ".exr")
#: The EXR channel names of each channel, in the conventions compositing tools read:
#: colour R, G, B, alpha A, depth Z.
EXR_NAMES = {"rgb": ("R", "G", "B"), "alpha": ("A",), "depth": ("Z",), "median_depth": ("Z.median",),
             "normal": ("N.X", "N.Y", "N.Z")}
#: EXR header attributes: the channels in the order listed, and the normals' space.
EXR_ORDER_ATTRIBUTE = "raygsChannels"
EXR_NORMAL_SPACE_ATTRIBUTE = "raygsNormalSpace"
#: PNG text keys of a channel picture.
PNG_CHANNEL_KEY = "raygs-viewer channel"
PNG_DEPTH_RANGE_KEY = "raygs-viewer depth range"
PNG_NORMAL_SPACE_KEY = "raygs-viewer normal space"
PNG_ALPHA_THRESHOLD_KEY = "raygs-viewer alpha threshold"


def colour_channels(rgba: np.ndarray) -> ChannelImage:
    """A ChannelImage of an (H, W, 4) RGBA render (float32 or float64) whose geometry
    channels were not rendered: they read as zeros but take no memory, so a colour-only
    output of a huge image costs nothing more."""
    rgba = np.asarray(rgba, np.float32)
    shape = rgba.shape[:2]
    none = np.broadcast_to(np.float32(0.0), shape)
    return ChannelImage(rgba[..., :3], rgba[..., 3], none, none, np.broadcast_to(np.float32(0.0), shape + (3,)))


def picture_view(channels: Sequence[str], suffix: str, depth_range: tuple[float, float] | None = None,
                 normal_space: str = "camera", alpha_threshold: float | None = None) -> ChannelView | None:
    """The picture a ``.png`` output shows (None for the other formats): its one
    channel, or colour for the default rgb,alpha; ``alpha_threshold`` None: the default.
    UserError for several channels, and for a depth range or an alpha threshold where no
    picture uses it (it would be silently ignored). .npy and .exr are raw data: never
    masked."""
    channels = tuple(channels)
    if suffix.lower() != ".png":
        if depth_range is not None:
            raise UserError(f"--depth-range sets a .png picture's colour map; {suffix} files keep depths as numbers")
        if alpha_threshold is not None:
            raise UserError(f"--alpha-threshold masks a .png picture; {suffix} files keep every pixel's value")
        return None
    if channels == DEFAULT_CHANNELS:
        channels = ("rgb",)
    if len(channels) != 1:
        raise UserError(f"a .png shows one channel, got {','.join(channels)} (write .npy or .exr for several)")
    view = ChannelView(channels[0], depth_range, normal_space,
                       ALPHA_THRESHOLD if alpha_threshold is None else alpha_threshold)
    if depth_range is not None and view.channel not in ("depth", "median_depth"):
        raise UserError(f"--depth-range is for a picture of depth or median_depth, not of {view.channel}")
    if alpha_threshold is not None and not view.is_geometry:
        raise UserError(f"--alpha-threshold is for a picture of depth, median_depth or normal, not of {view.channel}")
    return view


def is_plain_colour(channels: Sequence[str], suffix: str) -> bool:
    """Whether the output is what ``render`` wrote before channels existed (the default
    channels to .png or .npy), which keeps that path and its bytes."""
    return tuple(channels) == DEFAULT_CHANNELS and suffix.lower() in (".png", ".npy")


def encode_npy(image: ChannelImage, channels: Sequence[str]) -> bytes:
    """float32 (H, W, C): ``channels`` in order (:meth:`ChannelImage.stack`)."""
    buffer = io.BytesIO()
    np.save(buffer, np.ascontiguousarray(image.stack(channels)))
    return buffer.getvalue()


def encode_picture(image: ChannelImage, view: ChannelView) -> tuple[bytes, tuple[float, float] | None]:
    """(PNG bytes, the depth range used or None): the 8-bit picture of ``view`` with text
    metadata naming the channel, its depth range, its normal space and its alpha threshold."""
    picture, used = channel_picture(image, view)
    text = {PNG_CHANNEL_KEY: view.channel}
    if view.is_geometry:
        text[PNG_ALPHA_THRESHOLD_KEY] = repr(view.alpha_threshold)
    if view.channel == "normal":
        text[PNG_NORMAL_SPACE_KEY] = view.normal_space
    if view.channel in ("depth", "median_depth"):
        text[PNG_DEPTH_RANGE_KEY] = "none" if used is None else f"{used[0]!r} {used[1]!r}"
    return encode_png(to_rgb8(picture), text), used


def exr_planes(image: ChannelImage, channels: Sequence[str]) -> dict[str, np.ndarray]:
    """{EXR name: (H, W) float32} of ``channels``, in the order listed."""
    planes = {}
    for name in channels:
        values = image.channel(name)
        for index, exr_name in enumerate(EXR_NAMES[name]):
            planes[exr_name] = np.ascontiguousarray(values[..., index], dtype=np.float32)
    return planes


def write_exr(path: str | os.PathLike, image: ChannelImage, channels: Sequence[str], overwrite: bool = False) -> Path:
    """Writes ``channels`` of ``image`` as a float32 EXR (ZIP compressed), atomically:
    OpenEXR writes a hidden temporary beside ``path`` by name, which is moved into place
    whole; never over an existing file without ``overwrite``."""
    import OpenEXR  # late: its native library is only needed when an EXR is written

    path = Path(path)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              EXR_ORDER_ATTRIBUTE: ",".join(channels)}
    if "normal" in channels:
        header[EXR_NORMAL_SPACE_ATTRIBUTE] = image.normal_space
    planes = exr_planes(image, channels)
    try:
        handle, temporary = temporary_beside(path)
    except OSError as exc:
        raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None
    os.close(handle)  # OpenEXR opens the file by name
    try:
        OpenEXR.File(header, planes).write(temporary)
        with open(temporary, "rb") as stream:
            os.fsync(stream.fileno())
        move_into_place(temporary, path, overwrite)
    except FileExistsError:
        raise UserError(f"{path}: already exists (pass --overwrite to replace it)") from None
    except (OSError, RuntimeError) as exc:  # OpenEXR reports its I/O failures as RuntimeError
        raise UserError(f"{path}: cannot write: {getattr(exc, 'strerror', None) or exc}") from None
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)
    return path


def save_channels(path: str | os.PathLike, image: ChannelImage, channels: Sequence[str],
                  view: ChannelView | None = None, overwrite: bool = False) -> tuple[float, float] | None:
    """Writes ``image`` (its normals already in the space wanted) to ``path`` by its
    suffix: .npy and .exr get ``channels``, .png the picture of ``view``
    (:func:`picture_view`). Returns the depth range a depth picture used, else None."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".exr":
        write_exr(path, image, channels, overwrite)
        return None
    if suffix == ".npy":
        write_atomically(path, encode_npy(image, channels), overwrite)
        return None
    if suffix == ".png":
        data, used = encode_picture(image, view or picture_view(channels, suffix))
        write_atomically(path, data, overwrite)
        return used
    raise UserError(f"{path}: channels are written as {', '.join(CHANNEL_SUFFIXES)}")


def depth_range_line(view: ChannelView, used: tuple[float, float] | None) -> str:
    """The line ``render`` prints about a depth picture's range."""
    if used is None:
        return f"{view.channel} range: none (no pixel has one; the picture is black)"
    how = "given" if view.depth_range is not None else "automatic"
    return f"{view.channel} range {used[0]:.6g} to {used[1]:.6g} ({how}; viridis, near bright, far dark)"
