"""Render settings shared by the GL renderer, the reference renderer and the CLI."""

from __future__ import annotations

import math
from dataclasses import dataclass

from raygs_viewer.errors import UserError

DEFAULT_P_MIN = 1.0 / 255.0


@dataclass(frozen=True)
class RenderSettings:
    """p_min: opacity below which a fragment is discarded; it sets the support
    kappa = -2 ln(p_min / o) of every gaussian (Eq. 3). background: linear RGB
    the image is composited over. sh_degree: highest spherical-harmonics band
    evaluated, capped at the scene's; None uses all the scene has."""

    p_min: float = DEFAULT_P_MIN
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sh_degree: int | None = None

    def effective_sh_degree(self, scene_degree: int) -> int:
        return scene_degree if self.sh_degree is None else min(self.sh_degree, scene_degree)

    def __post_init__(self) -> None:
        if not (isinstance(self.p_min, (int, float)) and 0.0 < self.p_min < 1.0):
            raise UserError(f"p_min must be a number in (0, 1), got {self.p_min!r}")
        if len(self.background) != 3 or not all(math.isfinite(c) for c in self.background):
            raise UserError(f"background must be three finite numbers, got {self.background!r}")
        object.__setattr__(self, "background", tuple(float(c) for c in self.background))
        if self.sh_degree is not None and (isinstance(self.sh_degree, bool) or self.sh_degree not in (0, 1, 2, 3)):
            raise UserError(f"sh_degree must be 0, 1, 2 or 3, got {self.sh_degree!r}")
