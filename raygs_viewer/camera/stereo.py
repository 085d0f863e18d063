"""Stereo: two eyes a headset apart, rendered the way the headset would show them.

Conventions (camera space: +x right, +y down, +z forward; the maths page, section 1):

- The given camera is the midpoint between the eyes ("cyclops"). The eyes sit at
  -/+ ipd/2 along its x axis (left eye at -x), with its rotation.
- ``scene_scale`` is metres per scene unit: an IPD of 0.063 m is 0.063 / scene_scale
  units, so a larger scale makes the scene feel smaller (the eyes are relatively
  farther apart).
- Each eye has an off-axis (asymmetric) projection: its principal point moves by
  +/- fx * (ipd/2) / convergence, so that a point on the midpoint's optical axis at
  the convergence distance lands on the same pixel in both eyes (zero disparity).
  Nearer points have crossed (positive) disparity: they sit further right in the left
  eye than in the right eye.
- One depth sort, from the midpoint, serves both eyes (culled with both eyes'
  frusta), and SH colour is evaluated from the midpoint; quads, c^2 and opacities
  are per eye (they depend on the eye's position).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from raygs_viewer.camera.lens_model import LensModel
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError, checked_number

DEFAULT_IPD = 0.063          # metres
DEFAULT_CONVERGENCE = 2.0    # metres
DEFAULT_SCENE_SCALE = 1.0    # metres per scene unit
#: Side by side (left eye on the left), cross-eyed (right eye on the left), red/cyan
#: anaglyph, or one eye alone.
LAYOUTS = ("sbs", "cross", "anaglyph", "left", "right")
#: Frame budgets a headset's refresh rates give, for the budget meter.
REFRESH_RATES = (72, 90, 120)
#: Limits of a headset preset, per eye.
MAX_EYE_SIZE = 16384
MIN_FOV, MAX_FOV = 1.0, 170.0


@dataclass(frozen=True)
class Quantity:
    """What the readers of one rig field need besides its default: the values it takes
    (a closed interval), its unit, and what it means (the command line's help and
    metavar start from it). Each StereoRig field carries one (:func:`rig_quantities`)."""

    low: float
    high: float
    unit: str
    meaning: str
    metavar: str

    def clamp(self, value: float) -> float:
        return min(max(value, self.low), self.high)


def rig_field(default: float, quantity: Quantity):
    """A StereoRig field with its default and its Quantity."""
    return field(default=default, metadata={"quantity": quantity})


@dataclass(frozen=True)
class StereoRig:
    """ipd: metres between the eyes; convergence: metres from the eyes' midpoint to
    the plane of zero disparity; scene_scale: metres per scene unit."""

    ipd: float = rig_field(DEFAULT_IPD, Quantity(0.0, 1.0, "metres", "distance between the eyes", "METRES"))
    convergence: float = rig_field(DEFAULT_CONVERGENCE, Quantity(1e-3, 1e6, "metres", "distance of zero disparity",
                                                                "METRES"))
    scene_scale: float = rig_field(DEFAULT_SCENE_SCALE, Quantity(1e-9, 1e9, "metres per unit",
                                                                "metres per scene unit", "METRES_PER_UNIT"))

    def __post_init__(self) -> None:
        for name, quantity in rig_quantities(type(self)).items():
            object.__setattr__(self, name, checked_number(getattr(self, name), quantity.low, quantity.high,
                                                          f"stereo {name.replace('_', ' ')}"))

    @property
    def half_baseline(self) -> float:
        """Half the distance between the eyes, in scene units."""
        return 0.5 * self.ipd / self.scene_scale

    @property
    def convergence_units(self) -> float:
        return self.convergence / self.scene_scale


def rig_quantities(rig_type: type[StereoRig] = StereoRig) -> dict[str, Quantity]:
    """Each field of ``rig_type`` (StereoRig or a subclass) with its Quantity; TypeError
    for a field made without :func:`rig_field`, which no reader would know."""
    missing = [declared.name for declared in fields(rig_type) if "quantity" not in declared.metadata]
    if missing:
        raise TypeError(f"{rig_type.__name__}.{missing[0]} has no Quantity: make it with rig_field()")
    return {declared.name: declared.metadata["quantity"] for declared in fields(rig_type)}


def eye_cameras(camera: Camera, rig: StereoRig) -> tuple[Camera, Camera]:
    """(left, right): ``camera`` (the midpoint) moved by -/+ half the baseline along its
    x axis, with the principal point shifted for convergence (module docstring)."""
    b = rig.half_baseline
    shift = b / rig.convergence_units

    def eye(side: float) -> Camera:
        # Moving the centre by side*b along camera x changes t by -side*b*e_x.
        t = np.asarray(camera.t, np.float64) - side * b * np.array([1.0, 0.0, 0.0])
        return replace(camera, t=t, cx=camera.cx + side * camera.fx * shift)
    return eye(-1.0), eye(+1.0)


@dataclass(frozen=True)
class HeadsetPreset:
    """Per eye: the panel's resolution and the (symmetric) field of view in degrees."""

    name: str
    label: str
    width: int
    height: int
    fov_x: float
    fov_y: float

    def __post_init__(self) -> None:
        if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_EYE_SIZE
                   for v in (self.width, self.height)):
            raise UserError(f"headset resolution must be 1..{MAX_EYE_SIZE} per side, "
                            f"got {self.width!r}x{self.height!r}")
        for axis, value in (("horizontal", self.fov_x), ("vertical", self.fov_y)):
            object.__setattr__(self, f"fov_{axis[0]}", checked_number(value, MIN_FOV, MAX_FOV,
                                                                    f"headset {axis} field of view (degrees)"))

    def camera(self, pose: Camera) -> Camera:
        """The midpoint camera at this preset's per-eye resolution and field of view,
        with ``pose``'s rotation and position."""
        fx = self.width / (2.0 * math.tan(math.radians(self.fov_x) / 2.0))
        fy = self.height / (2.0 * math.tan(math.radians(self.fov_y) / 2.0))
        return Camera(self.width, self.height, fx, fy, self.width / 2.0, self.height / 2.0,
                      np.asarray(pose.R, np.float64), np.asarray(pose.t, np.float64))


#: Common headsets, per eye (approximate public figures; "class" presets, not exact
#: optics). "custom" is built from the user's numbers by :func:`custom_preset`.
PRESETS: dict[str, HeadsetPreset] = {
    preset.name: preset for preset in (
        HeadsetPreset("quest3", "Quest 3 class", 2064, 2208, 110.0, 96.0),
        HeadsetPreset("index", "Valve Index class", 1440, 1600, 108.0, 104.0),
        HeadsetPreset("generic90", "generic 90°", 1440, 1440, 90.0, 90.0),
    )
}


def frame_budget(seconds: float) -> list[tuple[int, float, float]]:
    """(rate in Hz, budget in seconds, fraction of it used) for each of REFRESH_RATES:
    how ``seconds`` of GPU time for both eyes compares with a headset's frame time."""
    return [(rate, 1.0 / rate, seconds * rate) for rate in REFRESH_RATES]


def at_headset_size(seconds: float, drawn: tuple[int, int], headset: tuple[int, int]) -> float:
    """The GPU time of both eyes at the headset's per-eye size (``headset``: width,
    height), estimated from ``seconds`` measured at ``drawn``: a frame of splats is
    bound by fill, and the same view's fill grows with its pixels."""
    return seconds * (headset[0] * headset[1]) / max(1, drawn[0] * drawn[1])


def custom_preset(width: int, height: int, fov_x: float, fov_y: float) -> HeadsetPreset:
    return HeadsetPreset("custom", "custom", width, height, fov_x, fov_y)


DEFAULT_HEADSET = "quest3"


def check_layout(layout: str) -> str:
    """``layout`` if it is one of LAYOUTS, else UserError."""
    if layout not in LAYOUTS:
        raise UserError(f"stereo layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    return layout


def composed_size(width: int, height: int, layout: str) -> tuple[int, int]:
    """(width, height) of ``layout``'s image of two width x height eyes."""
    return (2 * width, height) if check_layout(layout) in ("sbs", "cross") else (width, height)


def preview_camera(camera: Camera, width: int, height: int, layout: str) -> Camera:
    """``camera`` (the midpoint at the headset's per-eye size) scaled down, its aspect
    kept, until ``layout``'s image of two such eyes fits ``width`` x ``height`` pixels:
    a window previews the eyes at the size it can show, never larger than the headset's."""
    shown_width, shown_height = composed_size(camera.width, camera.height, layout)
    scale = min(1.0, width / shown_width, height / shown_height)
    if scale >= 1.0:
        return camera
    return camera.resized(max(1, round(camera.width * scale)), max(1, round(camera.height * scale)))


@dataclass(frozen=True)
class StereoView:
    """What makes a stereo image besides its midpoint camera and render settings.

    layout: one of LAYOUTS. lens: the lens preview's model (None: off). headset: the
    preset the camera was sized for (a record for the sidecar and the panel; the
    camera itself carries the size and field of view)."""

    rig: StereoRig = StereoRig()
    layout: str = "sbs"
    lens: LensModel | None = None
    headset: HeadsetPreset | None = None

    def __post_init__(self) -> None:
        check_layout(self.layout)


def compose(left: np.ndarray, right: np.ndarray, layout: str) -> np.ndarray:
    """One image of a stereo pair (H, W, C each): "sbs" (left eye left), "cross" (right
    eye left, for cross-eyed free viewing), "anaglyph" (red from the left eye, green and
    blue from the right, for red/cyan glasses), "left" or "right" alone."""
    if check_layout(layout) == "sbs":
        return np.concatenate([left, right], axis=1)
    if layout == "cross":
        return np.concatenate([right, left], axis=1)
    if layout == "anaglyph":
        image = right.copy()
        image[..., 0] = left[..., 0]
        return image
    return left.copy() if layout == "left" else right.copy()
