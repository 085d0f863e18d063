"""Image metrics of a render against its photo, as the 3DGS paper's evaluation reports
them (docs/evaluation.md): PSNR, SSIM, FLIP and, where its optional extra is installed,
LPIPS (VGG).

Every metric takes two (H, W, 3) float images with values in 0..1 (the reference, the
photo, first) and returns a Python float.

SSIM is the 3DGS training code's (``utils/loss_utils.py``), not scikit-image's
``structural_similarity``: an 11x11 gaussian window with sigma 1.5 (the outer product
of the normalised 1D gaussian), each channel on its own, zero padding (the window
at a border reaches into zeros, as ``conv2d(padding=5)`` does), C1 = 0.01^2,
C2 = 0.03^2, the mean over the whole map and all channels. scikit-image crops the
borders instead and gives a different number, most of all on small images.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: What the reports say SSIM is.
SSIM_KIND = "3dgs (11x11 gaussian, sigma 1.5, zero padding)"
SSIM_WINDOW = 11
SSIM_SIGMA = 1.5
SSIM_C1 = 0.01 ** 2
SSIM_C2 = 0.03 ** 2
#: What a report says when LPIPS cannot be computed because the extra is missing.
LPIPS_MISSING = "LPIPS: not installed (pip install raygs-viewer[lpips])"


def check_pair(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``a``, ``b`` as float64 (H, W, C) arrays; ValueError unless their shapes agree
    (a programming error: the evaluation resizes every photo to its camera first)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 3:
        raise ValueError(f"images must be (H, W, C) of one shape, got {a.shape} and {b.shape}")
    return a, b


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """10 log10(1 / MSE), the MSE in float64 over every pixel and channel; inf for
    identical images."""
    a, b = check_pair(a, b)
    mse = float(np.mean((a - b) ** 2))
    return math.inf if mse == 0.0 else 10.0 * math.log10(1.0 / mse)


def gaussian_taps(size: int = SSIM_WINDOW, sigma: float = SSIM_SIGMA) -> np.ndarray:
    """(size,) float64: the 3DGS code's normalised 1D gaussian, centred on size // 2."""
    x = np.arange(size, dtype=np.float64) - size // 2
    taps = np.exp(-x ** 2 / (2.0 * sigma ** 2))
    return taps / taps.sum()


def blur(image: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """(H, W, C) float64 filtered by the separable window ``taps`` x ``taps`` with zero
    padding, the same size out (a correlation, as conv2d is; the window is symmetric)."""
    half = taps.size // 2
    height, width = image.shape[:2]
    padded = np.pad(image, ((half, half), (0, 0), (0, 0)))
    rows = sum(weight * padded[k:k + height] for k, weight in enumerate(taps))
    padded = np.pad(rows, ((0, 0), (half, half), (0, 0)))
    return sum(weight * padded[:, k:k + width] for k, weight in enumerate(taps))


def ssim_map(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(H, W, C) float64: the 3DGS SSIM of every pixel and channel (see the module docstring)."""
    a, b = check_pair(a, b)
    taps = gaussian_taps()
    mu_a, mu_b = blur(a, taps), blur(b, taps)
    var_a = blur(a * a, taps) - mu_a ** 2
    var_b = blur(b * b, taps) - mu_b ** 2
    covariance = blur(a * b, taps) - mu_a * mu_b
    return ((2 * mu_a * mu_b + SSIM_C1) * (2 * covariance + SSIM_C2)) / \
        ((mu_a ** 2 + mu_b ** 2 + SSIM_C1) * (var_a + var_b + SSIM_C2))


def ssim_3dgs(a: np.ndarray, b: np.ndarray) -> float:
    """The 3DGS training code's SSIM: the mean of :func:`ssim_map`."""
    return float(np.mean(ssim_map(a, b)))


def flip(a: np.ndarray, b: np.ndarray) -> float:
    """NVIDIA's FLIP (LDR, sRGB inputs, 67 pixels per degree), ``a`` the reference: its
    mean error, 0 for identical images."""
    # Late: flip_evaluator is only needed when an evaluation runs.
    import flip_evaluator

    a, b = check_pair(a, b)
    _, mean, _ = flip_evaluator.evaluate(np.ascontiguousarray(a, np.float32), np.ascontiguousarray(b, np.float32),
                                         "LDR", applyMagma=False)
    return float(mean)


class Lpips:
    """LPIPS with the VGG network, as the 3DGS paper reports it: call with two (H, W, 3)
    images in 0..1. Built by :func:`open_lpips` only; its weights come from the
    ``lpips`` extra and torchvision's cache, never from a download."""

    def __init__(self, model, torch) -> None:
        self.model, self.torch = model, torch

    def __call__(self, a: np.ndarray, b: np.ndarray) -> float:
        a, b = check_pair(a, b)
        with self.torch.no_grad():
            # LPIPS wants (1, 3, H, W) in -1..1.
            tensors = [self.torch.from_numpy(np.ascontiguousarray(x.transpose(2, 0, 1)[None] * 2 - 1, np.float32))
                       for x in (a, b)]
            return float(self.model(*tensors).item())


def open_lpips() -> tuple[Lpips | None, str | None]:
    """(the LPIPS metric, None), or (None, the one line a report shows saying why not):
    the extra is not installed, or the VGG weights are not on this machine."""
    try:
        # Late: the optional extra (torch, lpips) is large and most installs lack it.
        import lpips
        import torch
    except ImportError:
        return None, LPIPS_MISSING
    if not _vgg_weights_cached(torch):
        return None, "LPIPS: the VGG weights are not in torch's cache (run lpips.LPIPS(net='vgg') once online)"
    try:
        model = lpips.LPIPS(net="vgg", verbose=False)
    except Exception as exc:  # a broken install must not stop the other metrics
        return None, f"LPIPS: cannot load the VGG network ({str(exc).splitlines()[0] if str(exc) else exc})"
    return Lpips(model.eval(), torch), None


def _vgg_weights_cached(torch) -> bool:
    """Whether torchvision's VGG16 weights are already downloaded (lpips would fetch them)."""
    folder = Path(torch.hub.get_dir()) / "checkpoints"
    return folder.is_dir() and any(path.name.startswith("vgg16") for path in folder.iterdir())
