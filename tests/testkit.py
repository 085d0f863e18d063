"""What the tests share: generated scenes, the image comparison, the one-line-error check."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from raygs_viewer.errors import UserError

from raygs_viewer.scene import Scene, sh_coefficient_count

SHARED_SCENES = Path(__file__).resolve().parents[2] / "shared" / "scenes"


def random_rotation(rng):
    """A uniformly random proper rotation (det +1), float64."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def unit_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    return (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)


def make_scene(positions, scales, rotations=None, opacities=None, colors=None, sh=None, degree=0):
    """A Scene from plain arrays; colours are RGB (SH DC chosen to give them head-on)."""
    positions = np.asarray(positions, np.float32).reshape(-1, 3)
    n = positions.shape[0]
    scales = np.broadcast_to(np.asarray(scales, np.float32), (n, 3)).copy()
    rotations = (np.tile(np.float32([1, 0, 0, 0]), (n, 1)) if rotations is None
                 else np.asarray(rotations, np.float32).reshape(n, 4))
    opacities = np.broadcast_to(np.asarray(0.8 if opacities is None else opacities, np.float32), (n,)).copy()
    if sh is None:
        sh = np.zeros((n, sh_coefficient_count(degree), 3), np.float32)
        rgb = np.broadcast_to(np.asarray((0.8, 0.6, 0.4) if colors is None else colors, np.float32), (n, 3))
        sh[:, 0] = (rgb - 0.5) / 0.28209479177387814
    return Scene(positions, rotations, scales, opacities, np.asarray(sh, np.float32), degree)


def random_scene(n=300, seed=0, degree=3, spread=1.0, log_scale=(-4.0, -1.5), anisotropy=1.0):
    """Random blobs of every shape and colour around the origin, SH of ``degree``."""
    rng = np.random.default_rng(seed)
    coeffs = sh_coefficient_count(degree)
    sh = np.zeros((n, coeffs, 3), np.float32)
    sh[:, 0] = rng.normal(size=(n, 3))
    sh[:, 1:] = rng.normal(size=(n, coeffs - 1, 3)) * 0.3
    log_scales = rng.uniform(*log_scale, size=(n, 3))
    log_scales[:, 0] += rng.uniform(-anisotropy, anisotropy, n)
    return Scene(
        rng.uniform(-spread, spread, (n, 3)).astype(np.float32),
        unit_quaternions(rng, n),
        np.exp(log_scales).astype(np.float32),
        rng.uniform(0.05, 1.0, n).astype(np.float32),
        sh, degree,
    )


def compare(image, reference):
    """Error statistics of a float image against the float64 reference, all channels."""
    error = np.abs(np.asarray(image, np.float64) - reference)
    return {
        "max": float(error.max()),
        "p999": float(np.quantile(error, 0.999)),
        "mean": float(error.mean()),
        "over_1e-3": float((error.max(axis=-1) > 1e-3).mean()),  # fraction of pixels
    }


def assert_matches(image, reference, max_error=8e-3, pixel_fraction=0.002, p999=2e-4):
    """GL-vs-reference agreement. Float32 and float64 agree to ~1e-5 per pixel, but a
    pixel where some gaussian's opacity lies within float32 rounding of p_min keeps or
    drops that fragment (seen: 1.1e-5 relative from p_min on a shared scene), which moves
    it by up to p_min * colour; so a few pixels may reach ``max_error`` (2 p_min by
    default), while at most ``pixel_fraction`` of pixels may differ by over 1e-3."""
    stats = compare(image, reference)
    assert np.all(np.isfinite(image)), "NaN or Inf in the image"
    assert stats["max"] <= max_error and stats["over_1e-3"] <= pixel_fraction and stats["p999"] <= p999, stats
    return stats


def assert_differs(image, reference, **tolerances):
    """The negative control: ``image`` must fail :func:`assert_matches`."""
    try:
        assert_matches(image, reference, **tolerances)
    except AssertionError:
        return
    raise AssertionError(f"expected a visible difference, got {compare(image, reference)}")


def assert_user_error(call, path, *fragments):
    """``call()`` raises UserError with a one-line message naming ``path`` and every fragment."""
    with pytest.raises(UserError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message and "\r" not in message, message
    assert Path(path).name in message, message
    for fragment in fragments:
        assert fragment in message, message
    return message
