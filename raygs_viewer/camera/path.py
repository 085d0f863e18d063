"""Camera paths: keyframes, and the smooth, evenly paced flight through them.

A :class:`CameraPath` is immutable; every edit returns a new one (the window's panel
replaces its path whole, like the render settings). Times are seconds from the start.

NOTE: a first, simple interpolation (linear position, slerp, time by keyframe index);
the smooth interpolation replaces the bodies, not the interface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.pinhole import Camera, intrinsics_from_fov
from raygs_viewer.camera.rotation import matrix_to_quaternion, quaternion_to_matrix, slerp

#: Limits of the numbers a path holds (a path file outside them is refused).
FOV_RANGE = (1.0, 179.0)           # degrees, vertical
FPS_RANGE = (1.0, 240.0)
MAX_DURATION = 24 * 3600.0          # seconds
MAX_KEYFRAMES = 100_000
MAX_FRAMES = 1_000_000


@dataclass(frozen=True, eq=False)
class Keyframe:
    """One keyframe. pose: where the camera is and where it looks (world-to-camera R,
    OpenCV axes). fov_y_degrees: vertical field of view. time: seconds from the path's
    start, or None: placed by the path's pacing (even speed between its neighbours)."""

    pose: Pose
    fov_y_degrees: float = 60.0
    time: float | None = None

    @classmethod
    def of_camera(cls, camera: Camera, time: float | None = None) -> "Keyframe":
        """The camera's pose and its vertical field of view (a principal point off centre is not kept)."""
        return cls(Pose.from_camera(camera), math.degrees(2.0 * math.atan(0.5 * camera.height / camera.fy)), time)


@dataclass(frozen=True)
class Interpolation:
    """How the path runs between keyframes.

    alpha: the Catmull-Rom knot exponent (0 uniform, 0.5 centripetal, 1 chordal).
    tension: 0 (Catmull-Rom) to 1 (straight segments with stops at the keyframes).
    loop: the path returns from the last keyframe to the first, and repeats.
    up: the world's up axis, (3,) unit vector; the camera keeps it (no roll unless a
    keyframe has roll)."""

    alpha: float = 0.5
    tension: float = 0.0
    loop: bool = False
    up: tuple[float, float, float] = (0.0, -1.0, 0.0)


@dataclass(frozen=True)
class PathPose:
    """The camera of a path at one time: pose, vertical field of view (degrees)."""

    pose: Pose
    fov_y_degrees: float

    def camera(self, width: int, height: int) -> Camera:
        """Square pixels, centred principal point."""
        fx, fy, cx, cy = intrinsics_from_fov(width, height, self.fov_y_degrees)
        return self.pose.camera(width, height, fx, fy, cx, cy)


@dataclass(frozen=True)
class CameraPath:
    """keyframes: in flight order. duration: seconds for the whole path (a loop: one
    lap). fps: frames per second of playback and video."""

    keyframes: tuple[Keyframe, ...] = ()
    duration: float = 10.0
    fps: float = 30.0
    interpolation: Interpolation = Interpolation()

    # -- timing ----------------------------------------------------------------------
    @property
    def frame_count(self) -> int:
        """Frames of one pass: round(duration * fps), at least 1; 0 without keyframes."""
        if not self.keyframes:
            return 0
        return max(1, round(self.duration * self.fps))

    def frame_times(self) -> np.ndarray:
        """(F,) float64 seconds of each frame: an open path shows its first and last
        keyframes (k * duration / (F - 1)); a loop stops one frame short of its start."""
        count = self.frame_count
        if count <= 1:
            return np.zeros(count)
        step = self.duration / (count if self.interpolation.loop else count - 1)
        return np.arange(count) * step

    def keyframe_times(self) -> np.ndarray:
        """(K,) float64 seconds at which the path passes each keyframe (a keyframe's own
        time, else its place by the pacing)."""
        count = len(self.keyframes)
        if count == 0:
            return np.zeros(0)
        spans = count if self.interpolation.loop else count - 1
        return np.arange(count) * (self.duration / max(spans, 1))

    # -- sampling --------------------------------------------------------------------
    def pose_at(self, time: float) -> PathPose:
        """The camera at ``time`` seconds (clamped to the path; a loop wraps)."""
        if not self.keyframes:
            raise ValueError("the path has no keyframes")
        times = self.keyframe_times()
        keys = list(self.keyframes)
        if self.interpolation.loop:
            time = float(time) % self.duration if self.duration > 0 else 0.0
            keys.append(keys[0])
            times = np.append(times, self.duration)
        else:
            time = min(max(float(time), 0.0), float(times[-1]))
        if len(keys) == 1:
            return PathPose(keys[0].pose, keys[0].fov_y_degrees)
        i = int(np.clip(np.searchsorted(times, time, side="right") - 1, 0, len(keys) - 2))
        span = times[i + 1] - times[i]
        s = 0.0 if span <= 0 else (time - times[i]) / span
        a, b = keys[i], keys[i + 1]
        position = (1 - s) * a.pose.position + s * b.pose.position
        q = slerp(matrix_to_quaternion(a.pose.R), matrix_to_quaternion(b.pose.R), s)
        fov = (1 - s) * a.fov_y_degrees + s * b.fov_y_degrees
        return PathPose(Pose(position, quaternion_to_matrix(q[None])[0]), fov)

    def cameras(self, width: int, height: int) -> list[Camera]:
        """One camera per frame (frame_times), square pixels, centred principal point."""
        return [self.pose_at(t).camera(width, height) for t in self.frame_times()]

    def polyline(self, samples_per_segment: int = 16) -> np.ndarray:
        """(M, 3) float64 points along the flight, for drawing it."""
        if not self.keyframes:
            return np.zeros((0, 3))
        times = self.keyframe_times()
        end = self.duration if self.interpolation.loop else float(times[-1])
        count = max(2, samples_per_segment * max(1, len(self.keyframes) - (0 if self.interpolation.loop else 1)) + 1)
        return np.array([self.pose_at(t).pose.position for t in np.linspace(0.0, end, count)])

    # -- edits (each returns a new path) ----------------------------------------------
    def with_keyframe(self, keyframe: Keyframe, index: int | None = None) -> "CameraPath":
        """``keyframe`` inserted before ``index`` (None: appended)."""
        keys = list(self.keyframes)
        keys.insert(len(keys) if index is None else index, keyframe)
        return replace(self, keyframes=tuple(keys))

    def without_keyframe(self, index: int) -> "CameraPath":
        keys = list(self.keyframes)
        del keys[index]
        return replace(self, keyframes=tuple(keys))

    def moved(self, index: int, to: int) -> "CameraPath":
        """The keyframe at ``index`` moved to position ``to`` in the flight order."""
        keys = list(self.keyframes)
        keys.insert(to, keys.pop(index))
        return replace(self, keyframes=tuple(keys))

    def with_keyframe_changed(self, index: int, **changes) -> "CameraPath":
        """Keyframe ``index`` with fields replaced (pose, fov_y_degrees, time)."""
        keys = list(self.keyframes)
        keys[index] = replace(keys[index], **changes)
        return replace(self, keyframes=tuple(keys))


def path_through_cameras(cameras: list[Camera], duration: float = 10.0, fps: float = 30.0,
                         interpolation: Interpolation = Interpolation()) -> CameraPath:
    """A path through ``cameras`` in their order (e.g. a scene's training cameras)."""
    return CameraPath(tuple(Keyframe.of_camera(c) for c in cameras), duration, fps, interpolation)


def orbit_path(center: np.ndarray, radius: float, up: np.ndarray, *, start: Pose | None = None,
               elevation_degrees: float = 20.0, keyframes: int = 12, duration: float = 10.0, fps: float = 30.0,
               fov_y_degrees: float = 60.0) -> CameraPath:
    """A turntable: one lap around ``center`` at ``radius``, ``elevation_degrees`` above
    the horizon of ``up``, looking at the centre; starts at ``start``'s heading when given."""
    raise NotImplementedError


def dolly_path(start: Pose, distance: float, *, duration: float = 5.0, fps: float = 30.0,
               fov_y_degrees: float = 60.0) -> CameraPath:
    """A straight move of ``distance`` scene units along ``start``'s view direction (negative: backwards)."""
    raise NotImplementedError
