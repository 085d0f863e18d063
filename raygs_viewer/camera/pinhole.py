"""Pinhole cameras in OpenCV axes (+x right, +y down, +z forward), as section 1 defines.

A camera is intrinsics (pixels) plus a world-to-camera pose: ``mu = R @ p + t``.
Pixel (u, v) has its centre at (u + 0.5, v + 0.5) and its ray is
``((u + 0.5 - cx) / fx, (v + 0.5 - cy) / fy, 1)``; the GL projection is built
from the same numbers so the two renderers sample the same rays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from raygs_viewer.camera.rotation import is_rotation
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import nested_numbers, read_json_file, typed


#: The largest camera coordinate taken from a file: far beyond any scene, and far enough
#: below float64's range that the translation -R p cannot overflow.
MAX_COORDINATE = 1e300


@dataclass(frozen=True)
class Camera:
    """width, height: pixels; fx, fy, cx, cy: pixels; R: (3, 3) float64 world-to-camera
    rotation; t: (3,) float64 translation."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    R: np.ndarray
    t: np.ndarray

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world space, (3,) float64."""
        return -self.R.T @ self.t

    def resized(self, width: int, height: int) -> "Camera":
        """The same view at another resolution: fx, cx scale with width, fy, cy with height."""
        sx, sy = width / self.width, height / self.height
        return replace(self, width=int(width), height=int(height),
                       fx=self.fx * sx, fy=self.fy * sy, cx=self.cx * sx, cy=self.cy * sy)

    def pixel_rays(self) -> np.ndarray:
        """(H, W, 3) float64 camera-space rays through pixel centres, z = 1."""
        u = (np.arange(self.width) + 0.5 - self.cx) / self.fx
        v = (np.arange(self.height) + 0.5 - self.cy) / self.fy
        rays = np.empty((self.height, self.width, 3))
        rays[..., 0] = u[None, :]
        rays[..., 1] = v[:, None]
        rays[..., 2] = 1.0
        return rays

    def gl_projection(self, near: float = 0.01, far: float = 1000.0) -> np.ndarray:
        """(4, 4) float64 matrix taking OpenCV camera-space points straight to GL clip space.

        Window x equals u + 0.5 exactly where the ray of pixel u passes, and window y
        runs upwards, so image row v is framebuffer row H - 1 - v. near/far only set the
        depth range: the renderer draws with depth clamp, so nothing is clipped by them.
        """
        w, h = self.width, self.height
        # Built for GL eye space (x right, y up, looking down -z), then composed with
        # diag(1, -1, -1) so it takes OpenCV camera coordinates directly.
        proj = np.array([
            [2 * self.fx / w, 0.0, 1.0 - 2 * self.cx / w, 0.0],
            [0.0, 2 * self.fy / h, 2 * self.cy / h - 1.0, 0.0],
            [0.0, 0.0, -(far + near) / (far - near), -2 * far * near / (far - near)],
            [0.0, 0.0, -1.0, 0.0],
        ])
        return proj @ np.diag([1.0, -1.0, -1.0, 1.0])


def camera_key(camera: Camera) -> tuple:
    """Everything that defines ``camera``'s view, as exact, hashable values: equal keys
    render equal images (for caches that skip work when the view has not changed)."""
    return (camera.width, camera.height, float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy),
            np.asarray(camera.R, np.float64).tobytes(), np.asarray(camera.t, np.float64).tobytes())


def intrinsics_from_fov(width: int, height: int, fov_y_degrees: float) -> tuple[float, float, float, float]:
    """fx, fy, cx, cy for square pixels, a vertical field of view and a centred principal point."""
    f = 0.5 * height / math.tan(math.radians(fov_y_degrees) / 2)
    return f, f, width / 2, height / 2


def look_at(eye, target, up=(0.0, -1.0, 0.0), *, width: int = 640, height: int = 480,
            fov_y_degrees: float = 60.0, fx: float | None = None, fy: float | None = None) -> Camera:
    """A camera at ``eye`` looking at ``target``; ``up`` is world "up" (default -y,
    the OpenCV/COLMAP convention where +y points down)."""
    eye, target, up = (np.asarray(a, dtype=np.float64) for a in (eye, target, up))
    forward = target - eye
    if not np.all(np.isfinite(forward)) or np.linalg.norm(forward) == 0:
        raise UserError("look_at: eye and target must be distinct finite points")
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)  # camera +x, given that camera +y (down) is -up
    if np.linalg.norm(right) < 1e-9:
        # Looking along the up axis: any right vector perpendicular to forward works.
        right = np.cross(forward, [1.0, 0.0, 0.0] if abs(forward[0]) < 0.9 else [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    R = np.stack([right, down, forward])  # rows: camera axes in world coordinates
    f, f2, cx, cy = intrinsics_from_fov(width, height, fov_y_degrees)
    return Camera(int(width), int(height), fx if fx is not None else f, fy if fy is not None else f2,
                  cx, cy, R, -R @ eye)


def camera_from_json(entry, where: str) -> Camera:
    """One INRIA cameras.json object -> Camera. ``position`` is the centre, ``rotation``
    camera-to-world; optional ``cx``/``cy`` override the image centre."""
    if not isinstance(entry, dict):
        raise UserError(f"{where}: a camera must be a JSON object")
    for key in ("width", "height", "position", "rotation", "fx", "fy"):
        if key not in entry:
            raise UserError(f"{where}: missing '{key}'")
    width, height = (typed(entry[k], float, f"{where}: '{k}'") for k in ("width", "height"))
    if width != int(width) or height != int(height) or not (1 <= width <= 65536 and 1 <= height <= 65536):
        raise UserError(f"{where}: width and height must be whole numbers from 1 to 65536")
    fx, fy = (typed(entry[k], float, f"{where}: '{k}'") for k in ("fx", "fy"))
    if fx <= 0 or fy <= 0:
        raise UserError(f"{where}: fx and fy must be positive")
    if not (nested_numbers(entry["position"], 1) and nested_numbers(entry["rotation"], 2)):
        raise UserError(f"{where}: 'position' and 'rotation' must be arrays of numbers")
    try:
        position = np.array(entry["position"], dtype=np.float64)
        rotation = np.array(entry["rotation"], dtype=np.float64)
    except (TypeError, ValueError):  # ragged nesting
        raise UserError(f"{where}: 'position' and 'rotation' must be arrays of numbers") from None
    except OverflowError:  # an integer beyond float range
        raise UserError(f"{where}: 'position' and 'rotation' must be finite") from None
    if position.shape != (3,) or rotation.shape != (3, 3):
        raise UserError(f"{where}: 'position' must have 3 numbers and 'rotation' be 3x3")
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(rotation))):
        raise UserError(f"{where}: 'position' and 'rotation' must be finite")
    if not is_rotation(rotation, 1e-3):
        raise UserError(f"{where}: 'rotation' is not a rotation matrix")
    if np.abs(position).max() > MAX_COORDINATE:  # t = -R p would overflow
        raise UserError(f"{where}: 'position' is beyond {MAX_COORDINATE:g} in magnitude")
    # Re-orthonormalise: JSON round-trips leave ~1e-7 drift.
    u, _, vt = np.linalg.svd(rotation)
    R = (u @ vt).T
    cx = typed(entry["cx"], float, f"{where}: 'cx'") if "cx" in entry else width / 2
    cy = typed(entry["cy"], float, f"{where}: 'cy'") if "cy" in entry else height / 2
    return Camera(int(width), int(height), fx, fy, cx, cy, R, -R @ position)


def load_cameras(path: str | Path) -> list[Camera]:
    """Cameras from an INRIA ``cameras.json``: a list of camera objects, or one object."""
    path = Path(path)
    data = read_json_file(path, "a cameras.json file")
    entries = data if isinstance(data, list) else [data]
    if not entries:
        raise UserError(f"{path}: contains no cameras")
    return [camera_from_json(e, f"{path}: camera {i}") for i, e in enumerate(entries)]


def load_camera(path: str | Path, index: int = 0) -> Camera:
    """Camera ``index`` of :func:`load_cameras`. Counting from the end (Python's -1) is
    refused: a typo would otherwise render some other camera without a word."""
    cameras = load_cameras(path)
    if not 0 <= index < len(cameras):
        raise UserError(f"{path}: --camera-index must be 0..{len(cameras) - 1}, got {index} "
                        f"(out of range: the file has {len(cameras)} camera{'s' if len(cameras) != 1 else ''})")
    return cameras[index]


def camera_to_json(camera: Camera, index: int = 0, name: str = "") -> dict:
    """The inverse of :func:`camera_from_json` (cx, cy written only when off-centre)."""
    entry = {
        "id": index, "img_name": name, "width": camera.width, "height": camera.height,
        "position": camera.center.tolist(), "rotation": camera.R.T.tolist(),
        "fx": camera.fx, "fy": camera.fy,
    }
    if camera.cx != camera.width / 2 or camera.cy != camera.height / 2:
        entry["cx"], entry["cy"] = camera.cx, camera.cy
    return entry


def frame_points(points: np.ndarray, width: int = 640, height: int = 480, fov_y_degrees: float = 60.0) -> Camera:
    """A camera looking along world +z at the bulk of ``points`` (1st..99th percentile
    box), far enough back that the box fills most of the view; for scenes without
    cameras of their own."""
    finite = points[np.all(np.isfinite(points), axis=1)].astype(np.float64)
    if finite.shape[0] == 0:
        return look_at([0.0, 0.0, -5.0], [0.0, 0.0, 0.0], width=width, height=height, fov_y_degrees=fov_y_degrees)
    low, high = np.percentile(finite, [1, 99], axis=0)
    center = (low + high) / 2
    radius = max(float(np.linalg.norm(high - low)) / 2, 1e-6)
    half_y = math.radians(fov_y_degrees) / 2
    fov = 2 * min(half_y, math.atan(math.tan(half_y) * width / height))
    distance = radius / math.sin(fov / 2)
    return look_at(center - [0.0, 0.0, distance], center, width=width, height=height, fov_y_degrees=fov_y_degrees)
