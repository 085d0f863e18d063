"""Pictures of one output channel, for the eye: the window's view modes and ``render
--channels ... --out X.png``.

Depth (expected or median) goes through viridis, a perceptually uniform colour map,
near bright and far dark, over a stated range; normals show as 0.5 + 0.5 n; alpha as
grey. Pixels where a channel is undefined (no coverage; no median) are black, and so
are, in the geometry pictures (depth, median depth, normal), pixels whose alpha is below
the view's alpha threshold: expected depth and normals are defined wherever alpha > 0,
so without the mask near-transparent haze paints at full strength and the picture shows
a bloated object the colour view does not (docs/geometry.md, "Masking haze").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.render.channels import CHANNELS, NORMAL_SPACES, ChannelImage

#: The channels a picture can show (every channel: rgb is the colour itself).
PICTURE_CHANNELS = CHANNELS
#: Percentiles of the defined depths that span an automatic range (robust to a few
#: far-off floaters).
AUTO_PERCENTILES = (1.0, 99.0)
#: At most about this many pixels are sampled for an automatic range: a regular grid, the
#: same whether the window's GPU pass or a file's picture takes them, so the range does
#: not need the whole image read back.
AUTO_SAMPLES = 1 << 16
COLOR_MAP = "viridis"
#: The geometry pictures' default alpha threshold, measured (docs/geometry_threshold.py):
#: the painted area that best matches what the colour view visibly shows.
ALPHA_THRESHOLD = 0.05


@dataclass(frozen=True)
class ChannelView:
    """What a picture shows: ``channel`` (one of PICTURE_CHANNELS), the depth range
    (near, far) in scene units, None for automatic, the space normals are shown in, and
    ``alpha_threshold`` (0..1): the geometry pictures leave pixels whose alpha is below it
    black, as undefined (0: the mask is off; the alpha and colour pictures ignore it)."""

    channel: str = "rgb"
    depth_range: tuple[float, float] | None = None
    normal_space: str = "camera"
    alpha_threshold: float = ALPHA_THRESHOLD

    def __post_init__(self) -> None:
        if self.channel not in PICTURE_CHANNELS:
            raise UserError(f"unknown view channel {self.channel!r}: choose from {', '.join(PICTURE_CHANNELS)}")
        if self.normal_space not in NORMAL_SPACES:
            raise UserError(f"normal space must be one of {', '.join(NORMAL_SPACES)}, got {self.normal_space!r}")
        if self.depth_range is not None:
            near, far = (float(v) for v in self.depth_range)
            if not (np.isfinite(near) and np.isfinite(far) and far > near):
                raise UserError(f"depth range must be two finite numbers, near < far, got {self.depth_range!r}")
            object.__setattr__(self, "depth_range", (near, far))
        threshold = float(self.alpha_threshold)
        if not 0.0 <= threshold <= 1.0:  # also refuses NaN
            raise UserError(f"alpha threshold must be a number from 0 to 1, got {self.alpha_threshold!r}")
        object.__setattr__(self, "alpha_threshold", threshold)

    @property
    def is_geometry(self) -> bool:
        return self.channel in ("depth", "median_depth", "normal")


def shown(alpha: np.ndarray, threshold: float) -> np.ndarray:
    """(H, W) bool: the pixels a geometry picture may paint, alpha at least ``threshold``.
    Compared in float32, as glsl/channel_picture.frag compares the float32 texel with its
    float32 uniform, so both twins mask the same pixels."""
    return np.asarray(alpha, np.float32) >= np.float32(threshold)


def sample_step(height: int, width: int) -> int:
    """Every how many rows and columns :func:`depth_samples` takes a pixel."""
    return max(1, math.ceil(math.sqrt(height * width / AUTO_SAMPLES)))


def depth_samples(depth: np.ndarray) -> np.ndarray:
    """The pixels of an (H, W) depth image an automatic range is taken from: every
    :func:`sample_step`-th pixel of every such row, from the top-left."""
    step = sample_step(*depth.shape)
    return depth[::step, ::step]


@lru_cache(maxsize=1)
def color_table() -> np.ndarray:
    """(256, 3) float32 viridis, from matplotlib's colour-map data (imported once)."""
    from matplotlib import colormaps  # late: matplotlib costs a window ~0.3 s; only depth pictures need it
    return colormaps[COLOR_MAP](np.linspace(0.0, 1.0, 256))[:, :3].astype(np.float32)


def automatic_range(depth: np.ndarray) -> tuple[float, float] | None:
    """(near, far) spanning the defined (> 0) values of ``depth`` (an (H, W) image) at
    its :func:`depth_samples` between the AUTO_PERCENTILES, or None where nothing is
    defined."""
    return range_of_samples(depth_samples(depth))


def range_of_samples(samples: np.ndarray) -> tuple[float, float] | None:
    """:func:`automatic_range` from its samples (any shape)."""
    values = samples[samples > 0]
    if values.size == 0:
        return None
    near, far = (float(v) for v in np.percentile(values, AUTO_PERCENTILES))
    if not far > near:
        far = near + max(abs(near) * 1e-3, 1e-6)
    return near, far


def depth_picture(depth: np.ndarray, depth_range: tuple[float, float] | None) -> tuple[np.ndarray, tuple | None]:
    """((H, W, 3) float32 picture, the range used): viridis, near bright, far dark,
    values outside the range clamped, black where depth is 0 (undefined)."""
    used = depth_range if depth_range is not None else automatic_range(depth)
    picture = np.zeros(depth.shape + (3,), np.float32)
    if used is None:
        return picture, None
    near, far = used
    position = np.clip((far - depth.astype(np.float64)) / (far - near), 0.0, 1.0)
    table = color_table()
    picture[:] = table[np.rint(position * (len(table) - 1)).astype(np.int64)]
    picture[depth <= 0] = 0.0
    return picture, used


def channel_picture(image: ChannelImage, view: ChannelView) -> tuple[np.ndarray, tuple | None]:
    """((H, W, 3) float32 in 0..1, the depth range used or None) showing ``view.channel``
    of ``image`` (whose normals must already be in ``view.normal_space``)."""
    if view.channel == "rgb":
        return np.clip(image.rgb, 0.0, 1.0).astype(np.float32), None
    if view.channel == "alpha":
        return np.repeat(np.clip(image.alpha, 0.0, 1.0)[..., None], 3, axis=-1).astype(np.float32), None
    kept = shown(image.alpha, view.alpha_threshold)
    if view.channel == "normal":
        normal = image.normal
        painted = kept[..., None] & np.any(normal != 0, axis=-1, keepdims=True)
        return np.where(painted, 0.5 + 0.5 * normal, 0.0).astype(np.float32), None
    # Masked depths read as undefined (0), so the automatic range ignores them too.
    return depth_picture(np.where(kept, getattr(image, view.channel), 0.0).astype(np.float32), view.depth_range)
