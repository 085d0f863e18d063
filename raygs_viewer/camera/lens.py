"""How a pose and a window size become a camera: a free lens (a vertical field of view
filling the window) or a training camera's own intrinsics, letterboxed."""

from __future__ import annotations

import math
from dataclasses import dataclass

from raygs_viewer.camera.navigation import Pose, finite
from raygs_viewer.camera.pinhole import Camera, intrinsics_from_fov


def letterbox(width: int, height: int, aspect: float) -> tuple[int, int, int, int]:
    """x, y (from the top-left), w, h of the largest rectangle of ``aspect`` (w / h)
    centred in a width x height window; each of w, h at least 1."""
    width, height = max(1, int(width)), max(1, int(height))
    if width >= height * aspect:   # window wider than the image: bars left and right
        w, h = max(1, min(width, round(height * aspect))), height
    else:                          # taller: bars top and bottom
        w, h = width, max(1, min(height, round(width / aspect)))
    return (width - w) // 2, (height - h) // 2, w, h


@dataclass(frozen=True)
class Lens:
    """How pose + window size become intrinsics. Either a free lens (vertical field of view,
    centred principal point, square pixels, fills the whole window) or a training camera's
    intrinsics (fx, fy, cx, cy at its own width x height), which is shown letterboxed: the
    largest rectangle of the camera's aspect ratio that fits the window, centred, with the
    intrinsics scaled to it (Camera.resized).

    fov_y_degrees: in (0, 180), ValueError otherwise. For a training-camera lens it is that
    camera's own vertical field of view (what a panel shows); the intrinsics come from
    ``source``.
    """

    fov_y_degrees: float = 60.0
    source: Camera | None = None

    def __post_init__(self) -> None:
        if not finite(self.fov_y_degrees) or not 0.0 < float(self.fov_y_degrees) < 180.0:
            raise ValueError(f"field of view must be between 0 and 180 degrees, got {self.fov_y_degrees!r}")
        object.__setattr__(self, "fov_y_degrees", float(self.fov_y_degrees))

    @classmethod
    def of_camera(cls, camera: Camera) -> "Lens":
        return cls(math.degrees(2.0 * math.atan(0.5 * camera.height / camera.fy)), camera)

    def with_fov(self, fov_y_degrees: float) -> "Lens":
        """A free lens; the angle is clamped to 1..179 degrees (ValueError if not finite)."""
        if not finite(fov_y_degrees):
            raise ValueError(f"field of view must be finite, got {fov_y_degrees!r}")
        return Lens(min(179.0, max(1.0, float(fov_y_degrees))), None)

    def viewport(self, width: int, height: int) -> tuple[int, int, int, int]:
        """x, y (from the top-left), w, h of the image inside a width x height window, in
        pixels; each of w, h is at least 1 (a minimised window reports 0 x 0)."""
        if self.source is None:
            return 0, 0, max(1, int(width)), max(1, int(height))
        return letterbox(width, height, self.source.width / self.source.height)

    def camera(self, pose: Pose, width: int, height: int) -> Camera:
        """The camera of the viewport (size w x h from :meth:`viewport`) seen from ``pose``."""
        _, _, w, h = self.viewport(width, height)
        if self.source is None:
            fx, fy, cx, cy = intrinsics_from_fov(w, h, self.fov_y_degrees)
        elif (w, h) == (self.source.width, self.source.height):
            fx, fy, cx, cy = self.source.fx, self.source.fy, self.source.cx, self.source.cy
        else:
            scaled = self.source.resized(w, h)
            fx, fy, cx, cy = scaled.fx, scaled.fy, scaled.cx, scaled.cy
        return pose.camera(w, h, fx=fx, fy=fy, cx=cx, cy=cy)
