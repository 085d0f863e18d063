"""The generated scene of ``bench sort`` (gaussians uniform in a cube, made in memory),
the view that sees it whole and the two motions its freshness is measured along."""

from __future__ import annotations

import math

import numpy as np

from raygs_viewer.bench.views import flown, turned
from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.scene.model import Scene

FOV_Y = 60.0
#: Half the side of the generated cube; its bounding sphere is the scene's radius.
HALF_SIDE = 1.0
SCENE_RADIUS = HALF_SIDE * math.sqrt(3.0)
TURN_DEGREES_PER_S = 90.0
FLY_RADII_PER_S = 0.5
SWEEPS = ("turn", "fly")


def generated_scene(count: int, seed: int = 0) -> Scene:
    """``count`` gaussians uniform in the cube [-1, 1]^3: random rotations, log-scales
    spread +-0.5 about half the mean spacing (neighbours overlap on screen), opacities
    0.1..0.9, random colours (SH degree 0: no view dependence, and a quarter of SH 3's memory)."""
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-HALF_SIDE, HALF_SIDE, (count, 3)).astype(np.float32)
    rotations = rng.normal(size=(count, 4)).astype(np.float32)
    rotations /= np.linalg.norm(rotations, axis=1, keepdims=True)
    spacing = 2.0 * HALF_SIDE / max(count, 1) ** (1.0 / 3.0)
    scales = np.exp(rng.uniform(-0.5, 0.5, (count, 3))).astype(np.float32)
    scales *= np.float32(0.5 * spacing)
    opacities = rng.uniform(0.1, 0.9, count).astype(np.float32)
    sh = rng.uniform(-1.5, 1.5, (count, 1, 3)).astype(np.float32)
    return Scene(positions, rotations, scales, opacities, sh, 0, source="generated")


def view_distance() -> float:
    """From this far in front of the cube's centre its bounding sphere just fills the
    vertical field of view: every gaussian is in view, none wasted."""
    return SCENE_RADIUS / math.sin(math.radians(FOV_Y) / 2)


def view_camera(width: int, height: int, distance: float | None = None) -> Camera:
    """Looking at the cube's centre from ``distance`` (default :func:`view_distance`) in front of it."""
    distance = view_distance() if distance is None else distance
    return look_at((0.0, 0.0, -distance), (0.0, 0.0, 0.0), width=width, height=height, fov_y_degrees=FOV_Y)


def moved(start: Camera, sweep: str, seconds: float) -> Camera:
    """``start`` after ``seconds`` of the motion: "turn" about its own vertical axis at
    TURN_DEGREES_PER_S (its centre fixed), "fly" forward at FLY_RADII_PER_S scene radii a second."""
    if sweep == "turn":
        return turned(start, TURN_DEGREES_PER_S * seconds)
    if sweep == "fly":
        return flown(start, FLY_RADII_PER_S * SCENE_RADIUS * seconds)
    raise ValueError(f"unknown sweep {sweep!r}")
