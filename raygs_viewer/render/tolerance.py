"""How far a GL image may be from the float64 reference: the tolerances the tests hold
the renderer to (``tests/testkit.py``'s ``assert_matches``, the precision and hard-case
tests) and ``raygs-viewer doctor`` judges each of its rows by, in one home.

Float32 and float64 agree to about 1e-6 a pixel; a fragment whose opacity lies within
float32 rounding of p_min is kept by one renderer and dropped by the other, which moves
that pixel by up to p_min times its colour. So a few pixels may reach twice the default
p_min (:data:`MATCH`), while at most :data:`PIXEL_FRACTION` of the pixels differ by
over :data:`OVER` and the 99.9th percentile stays under :data:`P999`
(docs/robustness.md). The per-pixel order may composite two fragments whose t* agree
to float32 precision either way round (:data:`PER_RAY`); a narrower blend rounds every
step (:data:`BLENDS`: the accuracy study's bounds, ``render.gl.profile``'s too).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from raygs_viewer.render.gl.profile import BLEND_ERROR_BOUNDS

#: A pixel differs when some channel differs by more than this.
OVER = 1e-3
#: The share of pixels that may differ by over OVER.
PIXEL_FRACTION = 0.002
#: The 99.9th percentile of the error over pixels and channels.
P999 = 2e-4
#: ... where a case's drawn-or-skipped decision lies within float32 rounding and the
#: reference takes GL's decision from a gaussian moved a relative 1e-6 (hard cases).
AMBIGUOUS_P999 = 1e-3
#: Twice the default p_min (1/255), rounded up.
MAX_ERROR = 8e-3
#: The largest error at a pixel where two gaussians' t* agree to float32 precision
#: (seen: a relative gap of 5e-8 on a shared scene): alpha_1 alpha_2 |c_1 - c_2| at most.
PER_RAY_TIE_ERROR = 0.25
#: The mean error a narrower blend may add (colours within 0..1; measured at most 1.3e-3
#: for float16 and 2.7e-3 for 8-bit on the test scenes).
BLEND_MEAN_ERROR = {"float16": 2.5e-3, "8bit": 5e-3}


@dataclass(frozen=True)
class Tolerance:
    """The largest error over pixels and channels; the share of pixels over OVER and
    the 99.9th percentile where given (None: not held); the mean where given; with
    ``clipped`` both images are clipped to 0..1 first (as they are shown and saved)."""

    max_error: float
    pixel_fraction: float | None = PIXEL_FRACTION
    p999: float | None = P999
    mean: float | None = None
    clipped: bool = False

    def words(self) -> str:
        """``max 0.008, ≤ 0.2 % px over 0.001, p99.9 ≤ 0.0002`` (what is held)."""
        parts = [f"max {self.max_error:.3g}"]
        if self.pixel_fraction is not None:
            parts.append(f"≤ {100 * self.pixel_fraction:g} % px over {OVER:g}")
        if self.p999 is not None:
            parts.append(f"p99.9 ≤ {self.p999:g}")
        if self.mean is not None:
            parts.append(f"mean ≤ {self.mean:g}")
        return ", ".join(parts) + (" (0..1)" if self.clipped else "")


MATCH = Tolerance(MAX_ERROR)
PER_RAY = replace(MATCH, max_error=PER_RAY_TIE_ERROR)
BLENDS = {precision: Tolerance(bound, None, None, BLEND_MEAN_ERROR[precision], True)
          for precision, bound in BLEND_ERROR_BOUNDS.items()}


@dataclass(frozen=True)
class Agreement:
    """An image against its reference: the largest, mean and 99.9th-percentile error
    over pixels and channels, the share of pixels over OVER, the non-finite pixels."""

    max: float
    mean: float
    p999: float
    over: float
    non_finite: int

    def failures(self, tolerance: Tolerance) -> list[str]:
        """What exceeds ``tolerance``, one phrase each (none: it agrees)."""
        failed = []
        if self.non_finite:
            failed.append(f"{self.non_finite} non-finite pixels")
        if not self.max <= tolerance.max_error:
            failed.append(f"max error {self.max:.2g} > {tolerance.max_error:g}")
        if tolerance.pixel_fraction is not None and not self.over <= tolerance.pixel_fraction:
            failed.append(f"{100 * self.over:.2g} % of pixels over {OVER:g} > {100 * tolerance.pixel_fraction:g} %")
        if tolerance.p999 is not None and not self.p999 <= tolerance.p999:
            failed.append(f"p99.9 error {self.p999:.2g} > {tolerance.p999:g}")
        if tolerance.mean is not None and not self.mean <= tolerance.mean:
            failed.append(f"mean error {self.mean:.2g} > {tolerance.mean:g}")
        return failed


def agreement(image: np.ndarray, reference: np.ndarray, clipped: bool = False) -> Agreement:
    """``image`` (H, W, 4) against ``reference``, in float64 (a non-finite value counts
    as an error of 9); ``clipped``: both clipped to 0..1 first."""
    image = np.asarray(image, np.float64)
    reference = np.asarray(reference, np.float64)
    non_finite = int((~np.isfinite(image)).any(axis=-1).sum())
    image = np.nan_to_num(image, nan=9.0, posinf=9.0, neginf=-9.0)
    if clipped:
        image, reference = np.clip(image, 0.0, 1.0), np.clip(reference, 0.0, 1.0)
    error = np.abs(image - reference)
    return Agreement(float(error.max()), float(error.mean()), float(np.quantile(error, 0.999)),
                     float((error.max(axis=-1) > OVER).mean()), non_finite)
