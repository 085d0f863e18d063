"""What a headset's panel shows of an eye image: the compositor's lens pre-distortion.

A headset lens has pincushion distortion and lateral chromatic aberration, so the
compositor pre-warps each eye image with the inverse: barrel distortion, with a slightly
different scale per colour channel. The preview applies that warp to show the panel
image; :func:`lens_warp_reference` is the float64 definition the GL pass
(``glsl/lens.frag``) is tested against.

The mapping (pixel coordinates, the image's top-left origin, y down):

- The lens centre is the eye camera's principal point c = (cx, cy), its optical axis.
- R = max(cx, W - cx): the distance from c to the farther left/right edge.
- Output pixel (x, y) has its centre P = (x + 0.5, y + 0.5); p = (P - c) / R,
  r2 = |p|^2, D(r2) = 1 + k1 r2 + k2 r2^2 and F = D(1) = 1 + k1 + k2, so the farther
  horizontal edge maps to itself and the centre is magnified F times.
- Channel c with scale s_c (red, 1, blue) samples q_c = c + (P - c) D(r2) / F s_c.
- A channel whose q_c lies outside [0, W] x [0, H] is 0 (black on the panel); otherwise
  it is the bilinear sample at q_c (texel centres at i + 0.5, indices clamped to the
  image). Alpha is 1 where the green sample is inside, else 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import checked_number


@dataclass(frozen=True)
class LensModel:
    """The pre-distortion a headset compositor applies so that the lens's pincushion
    distortion and chromatic aberration cancel: barrel distortion with per-channel scales.

    The defaults are typical of the distortion meshes early consumer headsets published:
    a class of lens, not one headset's calibration. A channel with a larger scale samples
    farther from the centre, so its content lands nearer the centre on the panel: blue is
    pulled in and red pushed out, undoing a lens that magnifies blue more than red."""

    k1: float = 0.22
    k2: float = 0.24
    chroma_red: float = 0.996
    chroma_blue: float = 1.014

    def __post_init__(self) -> None:
        for name, low, high in (("k1", 0.0, 10.0), ("k2", 0.0, 10.0),
                                ("chroma_red", 0.5, 2.0), ("chroma_blue", 0.5, 2.0)):
            object.__setattr__(self, name, checked_number(getattr(self, name), low, high,
                                                          f"lens {name.replace('_', ' ')}"))

    @property
    def edge_gain(self) -> float:
        """F = D(1): dividing by it keeps the farther horizontal edge in place."""
        return 1.0 + self.k1 + self.k2

    @property
    def channel_scales(self) -> tuple[float, float, float]:
        return (self.chroma_red, 1.0, self.chroma_blue)


DEFAULT_LENS = LensModel()


def lens_radius(camera: Camera) -> float:
    """R: pixels from the lens centre to the farther left/right image edge."""
    return max(float(camera.cx), float(camera.width) - float(camera.cx))


def source_point(camera: Camera, model: LensModel, x, y, channel_scale: float = 1.0):
    """(qx, qy) float64: where the panel point (x, y) samples the eye image, for a channel
    of ``channel_scale``. x, y are pixel coordinates (not indices: pixel (i, j) has its
    centre at (i + 0.5, j + 0.5)); scalars or arrays that broadcast."""
    cx, cy, radius = float(camera.cx), float(camera.cy), lens_radius(camera)
    dx = np.asarray(x, np.float64) - cx
    dy = np.asarray(y, np.float64) - cy
    r2 = (dx * dx + dy * dy) / (radius * radius)
    # (P - c) times a gain rather than p * R: with the identity lens the gain is exactly
    # 1 and pixel centres map exactly onto themselves.
    gain = (1.0 + r2 * (model.k1 + model.k2 * r2)) / model.edge_gain * channel_scale
    return cx + dx * gain, cy + dy * gain


def _bilinear(channel: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    height, width = channel.shape
    ux, uy = qx - 0.5, qy - 0.5
    x0, y0 = np.floor(ux), np.floor(uy)
    fx, fy = ux - x0, uy - y0
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    xa, xb = np.clip(x0, 0, width - 1), np.clip(x0 + 1, 0, width - 1)
    ya, yb = np.clip(y0, 0, height - 1), np.clip(y0 + 1, 0, height - 1)
    top = (1.0 - fx) * channel[ya, xa] + fx * channel[ya, xb]
    bottom = (1.0 - fx) * channel[yb, xa] + fx * channel[yb, xb]
    return (1.0 - fy) * top + fy * bottom


def lens_warp_reference(image: np.ndarray, camera: Camera, model: LensModel = DEFAULT_LENS) -> np.ndarray:
    """The panel image of one eye: ``image`` (H, W, C >= 3, top row first, the eye
    ``camera``'s size) warped as the module docstring defines. float32 (H, W, 4)."""
    image = np.asarray(image, np.float64)
    if image.ndim != 3 or image.shape[2] < 3 or image.shape[:2] != (camera.height, camera.width):
        raise ValueError(f"expected an ({camera.height}, {camera.width}, C>=3) image, got {image.shape}")
    height, width = camera.height, camera.width
    x = (np.arange(width, dtype=np.float64) + 0.5)[None, :]
    y = (np.arange(height, dtype=np.float64) + 0.5)[:, None]
    out = np.zeros((height, width, 4), np.float64)
    for c, scale in enumerate(model.channel_scales):
        qx, qy = source_point(camera, model, x, y, scale)
        inside = (qx >= 0.0) & (qx <= width) & (qy >= 0.0) & (qy <= height)
        out[..., c] = np.where(inside, _bilinear(image[..., c], qx, qy), 0.0)
        if c == 1:
            out[..., 3] = inside
    return out.astype(np.float32)
