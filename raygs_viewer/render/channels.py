"""The outputs a render gives beside colour (docs/geometry.md): what they are, how a
renderer's accumulated sums become them, and how they are stacked for a file.

Both renderers (GL and the float64 reference) accumulate, per sample, in blend order
with weight w_i (the opacity the fragment composites with) and transmittance T_i before
it:

- alpha = sum w_i T_i;
- depth_sum = sum w_i T_i z_i, normal_sum = sum w_i T_i n_i, where z_i is the camera-space
  z of the fragment's peak point (EWA: of the gaussian's centre) and n_i the gaussian's
  shortest axis in camera space (OpenCV axes) turned to face the sample's ray (n.ray < 0);
- median: z_i of the first fragment after which the accumulated alpha reaches 0.5, and
  found: 1 where there is one, 0 where there is none (its z is then 0).

Supersampling averages every one of these over a pixel's k x k samples (``median`` as the
mean of median * found, so a pixel's median is the mean over the samples that have one).
:func:`finish` divides them out. Nothing here knows OpenGL.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError

#: Every channel a render can write, in the order a help text lists them.
CHANNELS = ("rgb", "alpha", "depth", "median_depth", "normal")
#: Values per pixel of each channel.
CHANNEL_WIDTHS = {"rgb": 3, "alpha": 1, "depth": 1, "median_depth": 1, "normal": 3}
#: What ``render`` writes when no channels are asked for (colour and alpha, as always).
DEFAULT_CHANNELS = ("rgb", "alpha")
#: The channels that need the geometry outputs (a dearer render variant).
GEOMETRY_CHANNELS = ("depth", "median_depth", "normal")
#: Where normals are expressed: the camera's OpenCV axes, or the scene's world axes.
NORMAL_SPACES = ("camera", "world")
#: The accumulated alpha at which the median depth is taken.
MEDIAN_ALPHA = 0.5
#: What a render draws: colour alone; the geometry outputs beside it; or those with the
#: median depth too (it costs an ordered walk of each pixel's fragments).
Outputs = Literal["color", "geometry", "median"]
OUTPUTS: tuple[Outputs, ...] = ("color", "geometry", "median")


def parse_channels(text: str) -> tuple[str, ...]:
    """The channels of a comma-separated list such as "alpha,depth,normal", in its order;
    UserError for an unknown, repeated or empty entry."""
    names = tuple(part.strip() for part in str(text).split(","))
    for name in names:
        if name not in CHANNELS:
            raise UserError(f"unknown channel {name!r}: choose from {', '.join(CHANNELS)}")
    if len(set(names)) != len(names):
        raise UserError(f"channel listed twice in {text!r}")
    return names


def needs_geometry(channels: Sequence[str]) -> bool:
    return any(name in GEOMETRY_CHANNELS for name in channels)


@dataclass(frozen=True)
class ChannelImage:
    """A finished render, every array float32 and top row first.

    rgb: (H, W, 3) colour over the background. alpha: (H, W). depth, median_depth:
    (H, W) camera-space z (0 where undefined: no coverage, or alpha never reaches 0.5);
    median_depth is None when the render was not asked for it (it costs an ordered walk
    of each pixel's fragments). normal: (H, W, 3) unit vectors, 0 where alpha is 0;
    camera space (OpenCV axes) unless ``normal_space`` is "world".
    """

    rgb: np.ndarray
    alpha: np.ndarray
    depth: np.ndarray
    median_depth: np.ndarray | None
    normal: np.ndarray
    normal_space: str = "camera"

    def channel(self, name: str) -> np.ndarray:
        """(H, W, width) of one channel."""
        value = getattr(self, name)
        if value is None:
            raise ValueError(f"this render has no {name}: ask the renderer for it")
        return value[..., None] if value.ndim == 2 else value

    def stack(self, channels: Sequence[str]) -> np.ndarray:
        """(H, W, C) float32: the channels in the order given (rgb and normal 3 each)."""
        return np.concatenate([self.channel(name) for name in channels], axis=-1).astype(np.float32)

    def in_space(self, space: str, camera: Camera) -> "ChannelImage":
        """This image with its normals in ``space`` ("camera" or "world") of ``camera``."""
        if space not in NORMAL_SPACES:
            raise UserError(f"normal space must be one of {', '.join(NORMAL_SPACES)}, got {space!r}")
        if space == self.normal_space:
            return self
        rotation = np.asarray(camera.R, np.float64)  # world -> camera
        if space == "world":  # n_world = R^T n_camera, as row vectors n_camera R
            normal = self.normal.astype(np.float64) @ rotation
        else:
            normal = self.normal.astype(np.float64) @ rotation.T
        return ChannelImage(self.rgb, self.alpha, self.depth, self.median_depth,
                            normal.astype(np.float32), space)


def finish(color: np.ndarray, sums: np.ndarray, median: np.ndarray | None) -> ChannelImage:
    """The channels from a renderer's accumulated (and sample-averaged) outputs.

    color: (H, W, 4) RGB over the background and alpha. sums: (H, W, 4) depth_sum and
    normal_sum (x, y, z). median: (H, W, 2) mean of median * found, and mean of found;
    None where it was not computed. Computed in float64 whatever the inputs, returned as
    float32."""
    color = np.asarray(color, np.float64)
    sums = np.asarray(sums, np.float64)
    alpha = color[..., 3]
    covered = alpha > 0
    depth = np.where(covered, sums[..., 0] / np.where(covered, alpha, 1.0), 0.0)
    length = np.sqrt(np.einsum("...i,...i->...", sums[..., 1:4], sums[..., 1:4]))
    facing = covered & (length > 0)
    normal = np.where(facing[..., None], sums[..., 1:4] / np.where(facing, length, 1.0)[..., None], 0.0)
    median_depth = None
    if median is not None:
        median = np.asarray(median, np.float64)
        found = median[..., 1] > 0
        median_depth = np.where(found, median[..., 0] / np.where(found, median[..., 1], 1.0), 0.0).astype(np.float32)
    return ChannelImage(color[..., :3].astype(np.float32), alpha.astype(np.float32), depth.astype(np.float32),
                        median_depth, normal.astype(np.float32))
