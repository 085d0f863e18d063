"""A render beside its photo, as pictures: the |difference| heat map, the split between
photo and render, a photo resampled to the size shown. The window's Photo view draws
them; every image here is (H, W, 3) float32 in 0..1, top row first.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from PIL import Image

#: The heat map's colour map (matplotlib's name) and the error shown at its top colour.
HEAT_MAP = "magma"
DEFAULT_HEAT_MAX = 0.25


@lru_cache(maxsize=4)
def colour_table(name: str = HEAT_MAP, entries: int = 256) -> np.ndarray:
    """(entries, 3) float32: matplotlib's colour map ``name`` sampled evenly over 0..1."""
    # matplotlib is imported here, not at the top: only the heat map needs it, and its
    # import costs a quarter of a second that the window and the CLI would pay at start.
    from matplotlib import colormaps
    return colormaps[name](np.linspace(0.0, 1.0, entries))[:, :3].astype(np.float32)


def abs_difference(render: np.ndarray, photo: np.ndarray) -> np.ndarray:
    """(H, W) float32: |render − photo| averaged over the RGB channels (both (H, W, 3))."""
    _check_pair(render, photo)
    return np.abs(render.astype(np.float32) - photo.astype(np.float32)).mean(axis=2)


def heat_map(error: np.ndarray, vmax: float = DEFAULT_HEAT_MAX, name: str = HEAT_MAP) -> np.ndarray:
    """(H, W, 3) float32: ``error`` ((H, W), >= 0) through the colour map, 0 at its
    bottom colour and ``vmax`` (or more) at its top; the nearest of 256 table entries."""
    if not (math.isfinite(vmax) and vmax > 0):
        raise ValueError(f"the heat map's top value must be positive, not {vmax}")
    table = colour_table(name)
    index = np.rint(np.clip(np.nan_to_num(error / vmax), 0.0, 1.0) * (len(table) - 1)).astype(np.intp)
    return table[index]


def difference_picture(render: np.ndarray, photo: np.ndarray, vmax: float = DEFAULT_HEAT_MAX) -> np.ndarray:
    """(H, W, 3) float32: the heat map of :func:`abs_difference`."""
    return heat_map(abs_difference(render, photo), vmax)


def split_picture(photo: np.ndarray, render: np.ndarray, fraction: float) -> np.ndarray:
    """(H, W, 3) float32: the photo left of column round(fraction * W), the render from it on."""
    _check_pair(render, photo)
    column = int(round(min(max(fraction, 0.0), 1.0) * photo.shape[1]))
    return np.concatenate([photo[:, :column], render[:, column:]], axis=1).astype(np.float32)


def _check_pair(render: np.ndarray, photo: np.ndarray) -> None:
    if render.shape != photo.shape or render.ndim != 3 or render.shape[2] != 3:
        raise ValueError(f"a render {render.shape} and a photo {photo.shape} must both be (H, W, 3)")


def resize_picture(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """(height, width, 3) float32: ``image`` ((H, W, 3) float32) resampled bicubically,
    per channel in float (no 8-bit rounding), clipped to 0..1."""
    channels = [np.asarray(Image.fromarray(np.ascontiguousarray(image[..., c], np.float32), mode="F")
                           .resize((width, height), Image.Resampling.BICUBIC)) for c in range(3)]
    return np.clip(np.stack(channels, axis=2), 0.0, 1.0).astype(np.float32)
