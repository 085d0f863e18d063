"""Keep rules: which gaussians of a scene pass a crop or a threshold, as (N,) bool masks.

The rules read three values per gaussian (:class:`KeepValues`): its centre in the
scene's coordinates (a PLY's own), its opacity as rendered (after the sigmoid and any 3D
filter's fusion) and its largest axis as the file states it (exp of its largest
log-scale, before any 3D filter widens it). Bounds are compared in float32, the
precision the values have, so an edge written as the same decimal as a stored
coordinate is on the edge, and edges are inside: ``--crop-box 0.7,...`` keeps a centre
stored as 0.7, although float32(0.7) < 0.7.

A gaussian is kept when it passes every rule; :func:`apply_rules` applies them in turn
and says how many each removed of those the earlier ones left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np

from raygs_viewer.scene.model import Scene


@dataclass(frozen=True)
class KeepValues:
    """What the rules read, for N gaussians.

    positions:      (N, 3) float32 centres.
    opacities:      (N,) float32 opacity as rendered, in [0, 1].
    largest_scales: (N,) float32 exp of each gaussian's largest log-scale (the file's, before
                    a 3D filter's fusion).
    """

    positions: np.ndarray
    opacities: np.ndarray
    largest_scales: np.ndarray

    @classmethod
    def of_scene(cls, scene: Scene, log_scales: np.ndarray | None = None) -> "KeepValues":
        """The values of ``scene``; ``log_scales`` ((N, 3) float32, the file's own, row for
        row with the scene) where a 3D filter was fused into the scene's scales, which then
        no longer say the file's size (without them, the fused sizes are taken)."""
        if log_scales is None:
            largest = scene.scales.max(axis=1) if scene.count else np.zeros(0, np.float32)
        else:
            # The reader's own rounding: float64 exp rounded once, so a scene without a filter
            # gives the same values either way.
            largest = np.exp(log_scales.max(axis=1).astype(np.float64)).astype(np.float32)
        return cls(scene.positions, scene.opacities, largest)


class KeepRule(Protocol):
    """One rule: ``keeps(values)`` is its (N,) bool mask; ``describe()`` says it in words."""

    def keeps(self, values: KeepValues) -> np.ndarray: ...

    def describe(self) -> str: ...


def _float32(value: float) -> np.float32:
    return np.float32(value)


def _numbers(values: Sequence[float], count: int, what: str) -> tuple[float, ...]:
    numbers = tuple(float(v) for v in values)
    if len(numbers) != count or not all(math.isfinite(v) for v in numbers):
        raise ValueError(f"{what}: expected {count} finite numbers")
    return numbers


@dataclass(frozen=True)
class CropBox:
    """Centres inside the axis-aligned box ``low``..``high`` (each (x, y, z)), edges included."""

    low: tuple[float, float, float]
    high: tuple[float, float, float]

    def __post_init__(self) -> None:
        low, high = _numbers(self.low, 3, "crop box corner"), _numbers(self.high, 3, "crop box corner")
        for axis, lo, hi in zip("XYZ", low, high):
            if lo > hi:
                raise ValueError(f"{axis}0 = {lo:g} is greater than {axis}1 = {hi:g}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    def keeps(self, values: KeepValues) -> np.ndarray:
        low = np.array(self.low, np.float32)
        high = np.array(self.high, np.float32)
        return np.all((values.positions >= low) & (values.positions <= high), axis=1)

    def describe(self) -> str:
        return f"crop box {','.join(f'{v:g}' for v in self.low + self.high)}"


@dataclass(frozen=True)
class CropSphere:
    """Centres within ``radius`` of ``centre`` (on the sphere included), measured in float64."""

    centre: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", _numbers(self.centre, 3, "crop sphere centre"))
        radius = float(self.radius)
        if not (math.isfinite(radius) and radius >= 0):
            raise ValueError(f"the radius R = {radius:g} is not a finite number >= 0")
        object.__setattr__(self, "radius", radius)

    def keeps(self, values: KeepValues) -> np.ndarray:
        offsets = values.positions.astype(np.float64) - np.array(self.centre)
        return np.einsum("ij,ij->i", offsets, offsets) <= self.radius * self.radius

    def describe(self) -> str:
        return f"crop sphere {','.join(f'{v:g}' for v in self.centre)},{self.radius:g}"


@dataclass(frozen=True)
class MinOpacity:
    """Opacity as rendered at least ``opacity`` (in 0..1)."""

    opacity: float

    def __post_init__(self) -> None:
        if not 0.0 <= float(self.opacity) <= 1.0:
            raise ValueError(f"{self.opacity:g} is outside 0..1")

    def keeps(self, values: KeepValues) -> np.ndarray:
        return values.opacities >= _float32(self.opacity)

    def describe(self) -> str:
        return f"min opacity {self.opacity:g}"


@dataclass(frozen=True)
class MaxScale:
    """The largest axis (exp of the largest log-scale) at most ``scale`` (> 0, scene
    units): convert's --max-scale drops the huge splats training leaves at the edges."""

    scale: float

    def __post_init__(self) -> None:
        scale = float(self.scale)
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"{scale:g} is not a finite number > 0")

    def keeps(self, values: KeepValues) -> np.ndarray:
        return values.largest_scales <= _float32(self.scale)

    def describe(self) -> str:
        return f"max scale {self.scale:g}"


@dataclass(frozen=True)
class Removed:
    """``rule`` removed ``count`` gaussians of those the rules before it left."""

    rule: str
    count: int


def apply_rules(values: KeepValues, rules: Sequence[KeepRule], keep: np.ndarray | None = None
                ) -> tuple[np.ndarray, list[Removed]]:
    """((N,) bool: kept by every rule, and by ``keep`` where given; what each rule removed)."""
    kept = np.ones(values.positions.shape[0], bool) if keep is None else keep.copy()
    removed = []
    for rule in rules:
        before = int(np.count_nonzero(kept))
        kept &= rule.keeps(values)
        removed.append(Removed(rule.describe(), before - int(np.count_nonzero(kept))))
    return kept, removed
