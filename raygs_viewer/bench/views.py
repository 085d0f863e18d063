"""The view classes of the benchmarks, each built from a scene's "training-like" camera:
``training`` (that camera at the benchmark resolution), ``far`` (pulled back to twice
its distance from the scene's centre, at a quarter of the resolution: details shrink
about 8 times in pixels, where aliasing shows) and ``close`` (moved forward along its
optical axis to about 5 % of its distance to the gaussians at the image centre, where
EWA splatting shows spikes).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.render.settings import DEFAULT_P_MIN
from raygs_viewer.scene.model import Scene

VIEW_CLASSES = ("training", "far", "close")
VIEW_TITLES = {"training": "training-like", "far": "far away, 1/4 resolution", "close": "very close"}

#: The far view: FAR_DISTANCE_FACTOR times the training camera's distance from the
#: scene's centre, at 1/FAR_RESOLUTION_DIVISOR of its resolution (per axis).
FAR_DISTANCE_FACTOR, FAR_RESOLUTION_DIVISOR = 2.0, 4

#: The close view ends this fraction of the way short of the central gaussians ...
CLOSE_FRACTION = 0.05
#: ... "central" meaning projected within this fraction of the image size of its centre
#: (per axis, either side) ...
CLOSE_CENTRAL_WINDOW = 0.1
#: ... and their depth being this percentile of the central gaussians' depths (robust to
#: a few stray specks in front of the cluster).
CLOSE_DEPTH_PERCENTILE = 10.0
#: The camera must stay outside every gaussian's support with a margin: c^2 >
#: CLOSE_SUPPORT_MARGIN * kappa (a camera just outside a support sees an unboundedly
#: large quad, a robustness case rather than a view). Where it would not, it backs off
#: by the factor CLOSE_BACKOFF at a time.
CLOSE_SUPPORT_MARGIN, CLOSE_BACKOFF = 2.0, 1.25


def scene_centre(scene: Scene) -> np.ndarray:
    """The median of the finite gaussian centres, (3,) float64 (the origin for none)."""
    positions = scene.positions[np.all(np.isfinite(scene.positions), axis=1)].astype(np.float64)
    return np.median(positions, axis=0) if positions.shape[0] else np.zeros(3)


def with_width(camera: Camera, width: int) -> Camera:
    """``camera`` resized to ``width`` pixels across, keeping its aspect ratio."""
    height = max(1, round(width * camera.height / camera.width))
    return camera.resized(int(width), int(height))


def moved_to(camera: Camera, eye: np.ndarray) -> Camera:
    """The same orientation and intrinsics with its centre at ``eye``."""
    return replace(camera, t=-camera.R @ np.asarray(eye, dtype=np.float64))


def turned(camera: Camera, degrees: float) -> Camera:
    """``camera`` turned in place about its own vertical axis (its centre and intrinsics kept)."""
    angle = math.radians(degrees)
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]) @ camera.R
    return replace(camera, R=R, t=-R @ camera.center)


def flown(camera: Camera, distance: float) -> Camera:
    """``camera`` moved ``distance`` forward along its optical axis."""
    return moved_to(camera, camera.center + camera.R[2] * distance)


def training_view(camera: Camera, width: int) -> Camera:
    """The training-like view: a training camera at the benchmark width (aspect kept)."""
    return with_width(camera, width)


def far_view(camera: Camera, centre: np.ndarray, factor: float = FAR_DISTANCE_FACTOR,
             divisor: int = FAR_RESOLUTION_DIVISOR) -> Camera:
    """``camera`` pulled back along its optical axis until its distance from ``centre``
    is ``factor`` times what it was, at 1/``divisor`` of its resolution (fx, fy, cx, cy
    scaled with it): the scene's details shrink about factor * divisor times in pixels.

    Moving back by s along the axis f from C, with v = C - centre and d = |v|:
    |v - s f|^2 = factor^2 d^2 gives s = v.f + sqrt((v.f)^2 + (factor^2 - 1) d^2)."""
    forward = camera.R[2]
    offset = camera.center - np.asarray(centre, dtype=np.float64)
    distance, along = float(np.linalg.norm(offset)), float(offset @ forward)
    back = along + math.sqrt(along * along + (factor * factor - 1.0) * distance * distance)
    moved = moved_to(camera, camera.center - back * forward)
    return moved.resized(max(1, camera.width // divisor), max(1, camera.height // divisor))


def inside_support(scene: Scene, point: np.ndarray, p_min: float, margin: float = 1.0) -> np.ndarray:
    """(N,) bool: gaussians whose support (enlarged: c^2 <= margin * kappa, kappa =
    -2 ln(p_min / o)) contains ``point``; computed in float64 in each gaussian's frame."""
    rotations = quaternion_to_matrix(scene.rotations.astype(np.float64))
    offsets = np.asarray(point, dtype=np.float64) - scene.positions.astype(np.float64)
    local = np.einsum("nji,nj->ni", rotations, offsets) / scene.scales.astype(np.float64)
    c2 = np.einsum("ni,ni->n", local, local)
    with np.errstate(divide="ignore"):
        kappa = -2.0 * np.log(p_min / scene.opacities.astype(np.float64))
    return (kappa > 0) & (c2 <= margin * kappa)


def central_depth(camera: Camera, scene: Scene, p_min: float) -> float | None:
    """Depth along the optical axis of the gaussians at the image centre: the
    CLOSE_DEPTH_PERCENTILE-th percentile of the depths of the gaussians (opacity above
    p_min, in front of the camera) whose centres project within CLOSE_CENTRAL_WINDOW of
    the image centre; with none there, of those anywhere in the image, then of all in
    front. None when no gaussian is in front of the camera."""
    mu = scene.positions.astype(np.float64) @ camera.R.T + camera.t
    x, y, z = mu[:, 0], mu[:, 1], mu[:, 2]
    candidates = (z > 0) & (scene.opacities > p_min) & np.all(np.isfinite(mu), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        du = np.abs(camera.fx * x / z + camera.cx - camera.width / 2)
        dv = np.abs(camera.fy * y / z + camera.cy - camera.height / 2)
    for window in (CLOSE_CENTRAL_WINDOW, 0.5):
        chosen = candidates & (du <= window * camera.width) & (dv <= window * camera.height)
        if chosen.any():
            return float(np.percentile(z[chosen], CLOSE_DEPTH_PERCENTILE))
    return float(np.percentile(z[candidates], CLOSE_DEPTH_PERCENTILE)) if candidates.any() else None


def close_view(camera: Camera, scene: Scene, p_min: float = DEFAULT_P_MIN,
               fraction: float = CLOSE_FRACTION) -> Camera:
    """``camera`` moved forward along its optical axis until the gaussians at the image
    centre (:func:`central_depth`, depth D) are ``fraction`` * D in front of it.

    Where that would put the camera inside (or near: c^2 <= CLOSE_SUPPORT_MARGIN * kappa)
    some gaussian's support, it backs off by CLOSE_BACKOFF at a time, at worst to the
    original position. Gaussians whose support already contains the original camera
    are ignored (moving cannot get out of them any better)."""
    depth = central_depth(camera, scene, p_min)
    if depth is None or not depth > 0:
        return camera
    already = inside_support(scene, camera.center, p_min, CLOSE_SUPPORT_MARGIN)
    forward = camera.R[2]
    remaining = fraction * depth
    while remaining < depth:
        eye = camera.center + (depth - remaining) * forward
        if not np.any(inside_support(scene, eye, p_min, CLOSE_SUPPORT_MARGIN) & ~already):
            return moved_to(camera, eye)
        remaining *= CLOSE_BACKOFF
    return camera


def view_cameras(scene: Scene, camera: Camera, width: int, p_min: float = DEFAULT_P_MIN) -> dict[str, Camera]:
    """The three view classes of ``scene`` built from its training camera ``camera``."""
    training = training_view(camera, width)
    return {"training": training,
            "far": far_view(training, scene_centre(scene)),
            "close": close_view(training, scene, p_min)}
