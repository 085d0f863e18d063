"""The image metrics against independent computations: SSIM against direct per-pixel
window sums written out from the 3DGS code's definition, PSNR against its formula."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from raygs_viewer.photos import metrics
from raygs_viewer.photos.metrics import LPIPS_MISSING, flip, open_lpips, psnr, ssim_3dgs


def brute_force_ssim(a, b, pad="zero"):
    """The 3DGS SSIM by its definition, one pixel and channel at a time: the weighted
    sums over the 11x11 window w(dy, dx) = g(dy) g(dx) / (sum g)^2, with pixels outside
    the image read as 0 (``pad`` "edge": as the nearest border pixel, a control)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    height, width, channels = a.shape
    g = [math.exp(-(k - 5) ** 2 / (2 * 1.5 ** 2)) for k in range(11)]
    total = sum(g)
    values = []
    for c in range(channels):
        for y in range(height):
            for x in range(width):
                sums = [0.0] * 5
                for dy in range(-5, 6):
                    for dx in range(-5, 6):
                        yy, xx = y + dy, x + dx
                        if pad == "edge":
                            yy, xx = min(max(yy, 0), height - 1), min(max(xx, 0), width - 1)
                        elif not (0 <= yy < height and 0 <= xx < width):
                            continue
                        w = g[dy + 5] * g[dx + 5] / total ** 2
                        p, q = a[yy, xx, c], b[yy, xx, c]
                        for i, v in enumerate((p, q, p * p, q * q, p * q)):
                            sums[i] += w * v
                mu_a, mu_b, aa, bb, ab = sums
                var_a, var_b, cov = aa - mu_a ** 2, bb - mu_b ** 2, ab - mu_a * mu_b
                values.append((2 * mu_a * mu_b + 0.01 ** 2) * (2 * cov + 0.03 ** 2)
                              / ((mu_a ** 2 + mu_b ** 2 + 0.01 ** 2) * (var_a + var_b + 0.03 ** 2)))
    return float(np.mean(values))


@pytest.fixture(scope="module")
def pair():
    rng = np.random.default_rng(3)
    photo = rng.uniform(0.2, 0.8, (9, 13, 3))
    photo[:, :6] *= 0.5  # structure, so the borders matter
    render = np.clip(photo + rng.normal(0.0, 0.05, photo.shape), 0.0, 1.0)
    return photo, render


def test_ssim_matches_the_window_sums_with_zero_padding(pair):
    photo, render = pair
    expected = brute_force_ssim(photo, render)
    assert ssim_3dgs(photo, render) == pytest.approx(expected, abs=1e-12)
    # The padding is part of the definition: reading the borders otherwise changes it.
    assert abs(brute_force_ssim(photo, render, pad="edge") - expected) > 1e-3


def test_ssim_of_identical_images_is_one_and_is_symmetric(pair):
    photo, render = pair
    assert ssim_3dgs(photo, photo) == pytest.approx(1.0, abs=1e-12)
    assert ssim_3dgs(render, photo) == pytest.approx(ssim_3dgs(photo, render), abs=1e-12)
    assert ssim_3dgs(photo, render) < 0.99


def test_ssim_window_is_the_normalised_gaussian():
    taps = metrics.gaussian_taps()
    assert taps.shape == (11,) and taps.sum() == pytest.approx(1.0)
    assert taps[5] == taps.max() and taps[0] == pytest.approx(taps[10])
    assert taps[4] / taps[5] == pytest.approx(math.exp(-1 / (2 * 1.5 ** 2)))


def test_psnr_is_ten_log_of_the_inverse_mse(pair):
    photo, render = pair
    mse = np.mean((photo.astype(np.float64) - render) ** 2)
    assert psnr(photo, render) == pytest.approx(10 * math.log10(1 / mse), abs=1e-12)
    # A uniform offset d: MSE d^2.
    assert psnr(np.full((4, 5, 3), 0.5), np.full((4, 5, 3), 0.6)) == pytest.approx(20.0, abs=1e-9)
    assert psnr(photo, photo) == math.inf


def test_metrics_refuse_images_of_different_shapes(pair):
    photo, _ = pair
    for metric in (psnr, ssim_3dgs, flip):
        with pytest.raises(ValueError, match="one shape"):
            metric(photo, photo[:, :-1])


def test_flip_is_zero_for_identical_images_and_grows_with_the_error(pair):
    photo, render = pair
    assert flip(photo, photo) == 0.0
    worse = np.clip(photo + 0.3, 0.0, 1.0)
    assert 0.0 < flip(photo, render) < flip(photo, worse) <= 1.0


def test_lpips_without_the_extra_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "lpips", None)  # import lpips then raises ImportError
    model, note = open_lpips()
    assert model is None and note == LPIPS_MISSING
    assert "pip install raygs-viewer[lpips]" in note
