"""How far one scene's gaussians are from another's, attribute by attribute: what a
lossy format (``.splat``, ``.spz``, SOG, compressed PLY) does to a scene, measured on
the activated values every renderer uses.

The two scenes must hold the same gaussians in the same order (a scene and the same
scene written and read back): :func:`attribute_errors` compares them row by row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sh import C0

# Chunks keep the float64 temporaries of a multi-million-gaussian scene small.
_CHUNK_ROWS = 1 << 18


@dataclass(frozen=True)
class AttributeErrors:
    """The largest differences of ``other`` from ``reference`` over ``count`` gaussians.

    position_max / position_mean: |p_other - p_ref| (Euclidean, world units).
    extent: the diagonal of the reference's bounding box; position_relative is
        position_max / extent (None for a scene with no extent).
    scale_relative: max over axes of |s_other / s_ref - 1|.
    colour_max: the DC term as RGB ``0.5 + C0 * f_dc`` (0..1 for a displayable colour),
        max absolute difference over the channels, unclipped; colour_max_clipped the
        same with both colours clipped to 0..1 first (what a format that stores 0..1
        bytes can hold).
    sh_rest_max: max absolute difference of the SH coefficients beyond the DC term that
        both scenes hold (0 when either has degree 0: see the degrees for what is lost).
    opacity_max: max absolute difference of the opacities (0..1).
    rotation_degrees: max angle of the rotation between the two quaternions (q and -q
        are the same rotation: 0).
    reference_sh_degree / other_sh_degree: the SH degree of each.
    """

    count: int
    position_max: float
    position_mean: float
    extent: float
    position_relative: float | None
    scale_relative: float
    colour_max: float
    colour_max_clipped: float
    sh_rest_max: float
    opacity_max: float
    rotation_degrees: float
    reference_sh_degree: int
    other_sh_degree: int

    @property
    def sh_degree_lost(self) -> bool:
        return self.other_sh_degree < self.reference_sh_degree


def attribute_errors(reference: Scene, other: Scene) -> AttributeErrors:
    """The per-attribute errors of ``other`` against ``reference`` (see
    :class:`AttributeErrors`). ValueError unless both hold the same number of gaussians
    (compared in order)."""
    n = reference.count
    if other.count != n:
        raise ValueError(f"cannot compare scenes of {n} and {other.count} gaussians")
    common = sh_coefficient_count(min(reference.sh_degree, other.sh_degree))
    worst = dict.fromkeys(("position", "scale", "colour", "clipped", "rest", "opacity", "rotation"), 0.0)
    position_sum = 0.0
    for start in range(0, n, _CHUNK_ROWS):
        rows = slice(start, start + _CHUNK_ROWS)
        distance = _distance(reference.positions[rows], other.positions[rows])
        position_sum += float(distance.sum())
        ref_scale = reference.scales[rows].astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.abs(other.scales[rows] / ref_scale - 1.0)
        ref_rgb = 0.5 + C0 * reference.sh[rows, 0, :].astype(np.float64)
        rgb = 0.5 + C0 * other.sh[rows, 0, :].astype(np.float64)
        rest = np.abs(other.sh[rows, 1:common, :].astype(np.float64) - reference.sh[rows, 1:common, :])
        opacity = np.abs(other.opacities[rows].astype(np.float64) - reference.opacities[rows])
        for name, values in (("position", distance), ("scale", scale), ("colour", np.abs(rgb - ref_rgb)),
                             ("clipped", np.abs(np.clip(rgb, 0, 1) - np.clip(ref_rgb, 0, 1))),
                             ("rest", rest), ("opacity", opacity),
                             ("rotation", rotation_angles(reference.rotations[rows], other.rotations[rows]))):
            if values.size:
                worst[name] = max(worst[name], float(np.max(values)))
    extent = _extent(reference.positions)
    return AttributeErrors(
        count=n,
        position_max=worst["position"],
        position_mean=position_sum / n if n else 0.0,
        extent=extent,
        position_relative=worst["position"] / extent if extent > 0 else None,
        scale_relative=worst["scale"],
        colour_max=worst["colour"],
        colour_max_clipped=worst["clipped"],
        sh_rest_max=worst["rest"],
        opacity_max=worst["opacity"],
        rotation_degrees=float(np.degrees(worst["rotation"])),
        reference_sh_degree=reference.sh_degree,
        other_sh_degree=other.sh_degree,
    )


def rotation_angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) angles in radians of the rotations taking quaternions ``a`` to ``b`` (N, 4),
    normalised first; q and -q give 0.

    From the chord between the nearer of b and -b and a on the unit 3-sphere, 2 asin(c/2)
    is the half-angle between them: accurate for tiny angles, where 2 acos|a.b| is not.
    """
    a = _unit(a.astype(np.float64))
    b = _unit(b.astype(np.float64))
    sign = np.where(np.sum(a * b, axis=1) < 0.0, -1.0, 1.0)
    chord = np.linalg.norm(a - sign[:, None] * b, axis=1)
    return 4.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0))


def _unit(q: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    return q / np.where(norm > 0.0, norm, 1.0)


def _distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(b.astype(np.float64) - a.astype(np.float64), axis=1)


def _extent(positions: np.ndarray) -> float:
    if positions.shape[0] == 0:
        return 0.0
    low = positions.min(axis=0).astype(np.float64)
    high = positions.max(axis=0).astype(np.float64)
    return float(np.linalg.norm(high - low))


def format_errors(errors: AttributeErrors) -> list[str]:
    """One line per attribute, for the ``convert`` command, e.g.
    ``  rotation   max 0.417 degrees``."""
    relative = "" if errors.position_relative is None else \
        f" ({_number(errors.position_relative)} of the scene's extent {_number(errors.extent)})"
    lines = [
        f"  position   max {_number(errors.position_max)}{relative}, mean {_number(errors.position_mean)}",
        f"  scale      max relative {_number(errors.scale_relative)}",
        f"  colour     max {_number(errors.colour_max)} (base colour as RGB 0..1; "
        f"{_number(errors.colour_max_clipped)} with both clipped to 0..1)",
    ]
    if errors.sh_degree_lost:
        kept = "" if errors.other_sh_degree == 0 else \
            f", max {_number(errors.sh_rest_max)} on the coefficients kept"
        lines.append(f"  SH rest    degree {errors.reference_sh_degree} -> {errors.other_sh_degree}: lost{kept}")
    elif errors.reference_sh_degree > 0:
        lines.append(f"  SH rest    max {_number(errors.sh_rest_max)}")
    lines += [
        f"  opacity    max {_number(errors.opacity_max)}",
        f"  rotation   max {_number(errors.rotation_degrees)} degrees",
    ]
    return lines


def _number(value: float) -> str:
    return "0" if value == 0 else f"{value:.3g}"
