"""Camera paths: keyframes, and the smooth, evenly paced flight through them.

A :class:`CameraPath` is immutable; every edit returns a new one (the window's panel
replaces its path whole, like the render settings). Times are seconds from the start.

The flight (kernels in :mod:`raygs_viewer.camera.spline`):

- position: a centripetal Catmull-Rom spline through the keyframes (Kochanek-Bartels
  tension), reflected at open ends so it starts and ends on the first and last keyframe;
- pacing: each segment gets time in proportion to its arc length plus its turn and zoom
  (rho * radians, rho = path length / 4 pi), between the keyframes that have explicit
  times; within a segment the camera covers equal arc length in equal time, so a path
  without turns is flown at one even speed;
- orientation: squad on the keyframes' quaternions with tangents continuous in time,
  then turned about its own forward to a roll (about the up axis) interpolated from the
  keyframes' rolls, so roll-free keyframes give a roll-free flight;
- field of view: linear in log(tan(fov / 2)) along each segment (an even-looking zoom).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from raygs_viewer.camera import spline
from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.pinhole import Camera, intrinsics_from_fov
from raygs_viewer.camera.rotation import align_signs, matrix_to_quaternion, qconj, qmul, quaternion_to_matrix
from raygs_viewer.errors import UserError, checked_number, finite_number

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
    start, or None: placed by the path's pacing (between the keyframes that have times,
    in proportion to arc length plus turn and zoom)."""

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
    tension: 0 (Catmull-Rom) to 1 (straight segments and plain slerp, corners at the
    keyframes; the pacing keeps the speed even either way).
    loop: the path returns from the last keyframe to the first, and repeats.
    up: the world's up axis, (3,) unit vector (any finite nonzero vector is normalised);
    the camera keeps it (no roll unless a keyframe has roll).
    UserError (one line) for values out of range."""

    alpha: float = 0.5
    tension: float = 0.0
    loop: bool = False
    up: tuple[float, float, float] = (0.0, -1.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "alpha", checked_number(self.alpha, 0.0, 1.0, "interpolation alpha"))
        object.__setattr__(self, "tension", checked_number(self.tension, 0.0, 1.0, "interpolation tension"))
        if not isinstance(self.loop, (bool, np.bool_)):
            raise UserError(f"interpolation loop must be true or false, got {self.loop!r}")
        object.__setattr__(self, "loop", bool(self.loop))
        object.__setattr__(self, "up", tuple(float(v) for v in _direction(self.up, "interpolation up")))


def _direction(value, what: str) -> np.ndarray:
    """(3,) unit float64 vector of a finite nonzero 3-vector, else UserError."""
    try:
        vector = np.array(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        vector = np.zeros(0)
    with np.errstate(over="ignore", invalid="ignore"):
        norm = float(np.linalg.norm(vector)) if vector.shape == (3,) else 0.0
    if vector.shape != (3,) or not math.isfinite(norm) or norm == 0.0:
        raise UserError(f"{what} must be a finite nonzero 3-vector, got {value!r}")
    return vector / norm


@dataclass(frozen=True)
class PathPose:
    """The camera of a path at one time: pose, vertical field of view (degrees)."""

    pose: Pose
    fov_y_degrees: float

    def camera(self, width: int, height: int) -> Camera:
        """Square pixels, centred principal point."""
        fx, fy, cx, cy = intrinsics_from_fov(width, height, self.fov_y_degrees)
        return self.pose.camera(width, height, fx=fx, fy=fy, cx=cx, cy=cy)


@dataclass(frozen=True)
class PathSamples:
    """A path sampled at M times: positions (M, 3), world-to-camera rotations R
    (M, 3, 3) and vertical fields of view in degrees (M,), all float64."""

    positions: np.ndarray
    rotations: np.ndarray
    fov_y_degrees: np.ndarray

    def pose(self, index: int) -> PathPose:
        return PathPose(Pose(self.positions[index], self.rotations[index]), float(self.fov_y_degrees[index]))


@dataclass(frozen=True)
class _Plan:
    """Everything pose_at needs, built once per path (arrays over the N nodes = keyframes,
    plus keyframe 0 again at the end of a loop, and the S = N - 1 segments)."""

    node_times: np.ndarray     # (N,) seconds, non-decreasing
    durations: np.ndarray      # (S,)
    lengths: np.ndarray        # (S,) arc lengths
    curve: np.ndarray          # (S, 4, 3) position polynomials
    arc: np.ndarray            # (S, C + 1) arc-length tables
    arc_slopes: np.ndarray     # (S, C, 2)
    quaternions: np.ndarray    # (N, 4) hemisphere-aligned
    out: np.ndarray            # (N, 4) squad controls leaving each node
    into: np.ndarray           # (N, 4) squad controls arriving
    roll: np.ndarray           # (N,) radians, unwrapped along the path
    roll_rates: np.ndarray     # (S, 2) radians per second at each segment's ends
    roll_weight: np.ndarray    # (N,) how far each keyframe's forward is from the pole band (0..1)
    log_tan: np.ndarray        # (N,) log(tan(fov / 2))


@dataclass(frozen=True)
class CameraPath:
    """keyframes: in flight order. duration: seconds for the whole path (a loop: one
    lap). fps: frames per second of playback and video.

    Validated on construction (and so on every edit): UserError, one line, for a duration
    outside (0, MAX_DURATION], fps outside FPS_RANGE, more than MAX_FRAMES frames or
    MAX_KEYFRAMES keyframes, a keyframe fov outside FOV_RANGE, or explicit keyframe times
    outside [0, duration] or out of order.

    Timing: keyframes with a ``time`` are anchors; the first keyframe is at 0 and the end
    (the last keyframe, or a loop's return to keyframe 0, one lap after it) at
    ``duration`` unless they have times of their own. Keyframes without a time are placed
    between their anchors in proportion to arc length plus turn and zoom. Before the first
    anchor and after the end the camera holds still; a loop wraps time modulo duration.
    Two keyframes at the same time are a cut: the path shows the later one from then on."""

    keyframes: tuple[Keyframe, ...] = ()
    duration: float = 10.0
    fps: float = 30.0
    interpolation: Interpolation = Interpolation()

    def __post_init__(self) -> None:
        keys = tuple(self.keyframes)
        if not all(isinstance(k, Keyframe) for k in keys):
            raise TypeError("CameraPath keyframes must be Keyframe objects")
        if not isinstance(self.interpolation, Interpolation):
            raise TypeError("CameraPath interpolation must be an Interpolation")
        object.__setattr__(self, "keyframes", keys)
        duration = finite_number(self.duration)
        if duration is None or not 0.0 < duration <= MAX_DURATION:
            raise UserError(f"path duration must be a number of seconds in (0, {MAX_DURATION:g}], "
                            f"got {self.duration!r}")
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "fps", checked_number(self.fps, *FPS_RANGE, "path fps"))
        if round(duration * self.fps) > MAX_FRAMES:
            raise UserError(f"path has {round(duration * self.fps)} frames (duration x fps); "
                            f"at most {MAX_FRAMES} are allowed")
        if len(keys) > MAX_KEYFRAMES:
            raise UserError(f"path has {len(keys)} keyframes; at most {MAX_KEYFRAMES} are allowed")
        previous = None
        for i, key in enumerate(keys):
            checked_number(key.fov_y_degrees, *FOV_RANGE, f"keyframe {i} fov_y_degrees")
            if key.time is None:
                continue
            time = checked_number(key.time, 0.0, duration, f"keyframe {i} time")
            if previous is not None and time < previous[1]:
                raise UserError(f"keyframe {i} time {time:g} s is before keyframe {previous[0]}'s "
                                f"{previous[1]:g} s; keyframe times must not decrease")
            previous = (i, time)

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
        time, else its place by the pacing). A loop's are modulo duration (with keyframe
        0 timed after 0, the last ones may wrap round to the lap's start)."""
        if not self.keyframes:
            return np.zeros(0)
        times = self._plan.node_times[:len(self.keyframes)].copy()
        return np.mod(times, self.duration) if self.interpolation.loop else times

    @property
    def length(self) -> float:
        """Arc length of the flight (one lap of a loop), scene units."""
        return float(self._plan.lengths.sum()) if self.keyframes else 0.0

    # -- sampling --------------------------------------------------------------------
    def pose_at(self, time: float) -> PathPose:
        """The camera at ``time`` seconds (held still outside the path; a loop wraps)."""
        if not self.keyframes:
            raise ValueError("the path has no keyframes")
        return self.sample(np.array([float(time)])).pose(0)

    def sample(self, times) -> PathSamples:
        """The path at ``times`` (M,) seconds, vectorised: what pose_at gives, for many."""
        times = np.asarray(times, dtype=np.float64).reshape(-1)
        if not self.keyframes:
            raise ValueError("the path has no keyframes")
        plan = self._plan
        if len(plan.durations) == 0:
            key = self.keyframes[0]
            count = len(times)
            return PathSamples(np.tile(key.pose.position, (count, 1)), np.tile(key.pose.R, (count, 1, 1)),
                               np.full(count, float(key.fov_y_degrees)))
        segment, s = self._locate(times)
        return self._at(segment, s)

    def cameras(self, width: int, height: int) -> list[Camera]:
        """One camera per frame (frame_times), square pixels, centred principal point;
        each equals ``pose_at(t).camera(width, height)``."""
        if not self.keyframes:
            return []
        samples = self.sample(self.frame_times())
        return [samples.pose(i).camera(width, height) for i in range(len(samples.positions))]

    def polyline(self, samples_per_segment: int = 16) -> np.ndarray:
        """(M, 3) float64 points along the flight, for drawing it: each segment at
        ``samples_per_segment`` even steps of arc length, and the end (a loop: back at the
        start). One keyframe: that one point; none: (0, 3)."""
        if not self.keyframes:
            return np.zeros((0, 3))
        plan = self._plan
        segments = len(plan.durations)
        if segments == 0:
            return self.keyframes[0].pose.position[None].copy()
        steps = max(1, int(samples_per_segment))
        segment = np.append(np.repeat(np.arange(segments), steps), segments - 1)
        s = np.append(np.tile(np.arange(steps) / steps, segments), 1.0)
        return self._positions(segment, s)

    # -- the maths -------------------------------------------------------------------
    @functools.cached_property
    def _plan(self) -> _Plan:
        return _plan(self)

    def _locate(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Segment (M,) and segment fraction s in [0, 1] (M,) of each time."""
        plan = self._plan
        nodes = plan.node_times
        if self.interpolation.loop:
            with np.errstate(invalid="ignore"):    # a non-finite time: some keyframe, not an error
                times = nodes[0] + np.mod(times - nodes[0], self.duration)
        segment = np.clip(np.searchsorted(nodes, times, side="right") - 1, 0, len(plan.durations) - 1)
        start, span = nodes[segment], plan.durations[segment]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(span > 0, (times - start) / span, np.where(times >= start, 1.0, 0.0))
        return segment, np.clip(np.nan_to_num(s), 0.0, 1.0)

    def _positions(self, segment: np.ndarray, s: np.ndarray) -> np.ndarray:
        plan = self._plan
        u = spline.invert_arc(plan.arc, plan.arc_slopes, segment, s, plan.curve)
        return spline.polynomial(plan.curve, segment, u)

    def _at(self, segment: np.ndarray, s: np.ndarray) -> PathSamples:
        plan = self._plan
        positions = self._positions(segment, s)
        q = spline.squad(plan.quaternions[segment], plan.quaternions[segment + 1],
                         plan.out[segment], plan.into[segment + 1], s)
        roll = spline.hermite(plan.roll[segment], plan.roll[segment + 1], s, start_rate=plan.roll_rates[segment, 0],
                              end_rate=plan.roll_rates[segment, 1], duration=plan.durations[segment])
        # A keyframe near the pole holds its own roll; the up-keeping roll takes over along
        # the segment (not just within the pole band, where it would whip round).
        ease = s * s * (3.0 - 2.0 * s)
        weight = (1.0 - ease) * plan.roll_weight[segment] + ease * plan.roll_weight[segment + 1]
        rotations = spline.with_roll(quaternion_to_matrix(q), roll, np.array(self.interpolation.up), weight)
        log_tan = (1.0 - s) * plan.log_tan[segment] + s * plan.log_tan[segment + 1]
        return PathSamples(positions, rotations, np.degrees(2.0 * np.arctan(np.exp(log_tan))))

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
        """The keyframe at ``index`` moved to position ``to`` in the flight order
        (UserError if that puts explicit times out of order)."""
        keys = list(self.keyframes)
        keys.insert(to, keys.pop(index))
        return replace(self, keyframes=tuple(keys))

    def with_keyframe_changed(self, index: int, **changes) -> "CameraPath":
        """Keyframe ``index`` with fields replaced (pose, fov_y_degrees, time)."""
        keys = list(self.keyframes)
        keys[index] = replace(keys[index], **changes)
        return replace(self, keyframes=tuple(keys))


def _node_times(path: CameraPath, weights: np.ndarray, loop: bool) -> np.ndarray:
    """(N,) seconds of the nodes: anchors where keyframes have times (and at the ends),
    the rest placed between them in proportion to ``weights`` (S,)."""
    keys = path.keyframes
    count = len(weights) + 1
    anchors = np.full(count, np.nan)
    for i, key in enumerate(keys[:count]):
        if key.time is not None:
            anchors[i] = float(key.time)
    if np.isnan(anchors[0]):
        anchors[0] = 0.0
    if loop:
        anchors[-1] = anchors[0] + path.duration
    elif np.isnan(anchors[-1]):
        anchors[-1] = path.duration
    times = anchors.copy()
    fixed = np.flatnonzero(~np.isnan(anchors))
    for a, b in zip(fixed[:-1], fixed[1:]):
        w = weights[a:b]
        total = float(w.sum())
        share = np.cumsum(w) / total if total > 0 else np.arange(1, b - a + 1) / (b - a)
        times[a + 1:b] = anchors[a] + (anchors[b] - anchors[a]) * share[:-1]
    return times


def _plan(path: CameraPath) -> _Plan:
    keys = path.keyframes
    interp = path.interpolation
    loop = interp.loop and len(keys) > 1
    up = np.array(interp.up)
    points = np.array([k.pose.position for k in keys])
    rotations = np.array([k.pose.R for k in keys])
    fov = np.radians(np.array([float(k.fov_y_degrees) for k in keys]))
    node = np.append(np.arange(len(keys)), 0) if loop else np.arange(len(keys))

    curve = spline.catmull_rom(points, interp.alpha, interp.tension, loop)
    arc, arc_slopes = spline.arc_tables(curve)
    lengths = arc[:, -1]

    # Pacing: arc length plus the turn and zoom in radians, worth rho scene units each.
    quaternions = align_signs(np.array([matrix_to_quaternion(R) for R in rotations])[node])
    relative = qmul(qconj(quaternions[:-1]), quaternions[1:])
    turn = 2.0 * np.arctan2(np.linalg.norm(relative[:, 1:], axis=1), np.abs(relative[:, 0]))
    turn += np.abs(np.diff(fov[node]))
    total = float(lengths.sum())
    rho = total / (4.0 * math.pi) if total > 0 else 1.0
    node_times = _node_times(path, lengths + rho * turn, loop)
    durations = np.diff(node_times)
    out, into = spline.squad_controls(quaternions, durations, interp.tension, loop)

    # Roll about up: undefined with forward along up, where the nearest defined one stands in.
    roll, sine = spline.roll_of(rotations, up)
    defined = np.flatnonzero(sine >= math.sin(spline.POLE_KEEP))
    if len(defined) == 0:
        roll[:] = 0.0
    elif len(defined) < len(keys):
        index = np.arange(len(keys))
        after = np.minimum(np.searchsorted(defined, index), len(defined) - 1)
        before = np.maximum(after - 1, 0)
        nearer = np.where(np.abs(defined[before] - index) <= np.abs(defined[after] - index), before, after)
        roll = roll[defined[nearer]]
    steps = spline.wrap(np.diff(roll[node]))
    node_roll = roll[0] + np.concatenate([[0.0], np.cumsum(steps)])
    ahead = np.append(steps, steps[0] if loop else 0.0)
    behind = np.concatenate([[steps[-1] if loop else 0.0], steps])
    ahead_time = np.append(durations, durations[0] if loop else 0.0)
    behind_time = np.concatenate([[durations[-1] if loop else 0.0], durations])
    rate = spline.time_tangents(ahead, behind, ahead_time, behind_time)
    with np.errstate(divide="ignore", invalid="ignore"):
        secant = np.where(durations > 0, steps / durations, 0.0)
    t = interp.tension
    roll_rates = np.stack([(1 - t) * rate[:-1] + t * secant, (1 - t) * rate[1:] + t * secant], axis=1)

    return _Plan(node_times, durations, lengths, curve, arc, arc_slopes, quaternions, out, into,
                 node_roll, roll_rates, spline.pole_weight(sine)[node], np.log(np.tan(fov[node] / 2.0)))


def path_through_cameras(cameras: list[Camera], duration: float = 10.0, fps: float = 30.0,
                         interpolation: Interpolation = Interpolation()) -> CameraPath:
    """A path through ``cameras`` in their order (e.g. a scene's training cameras); each
    keyframe's fov is its camera's vertical one (from fy)."""
    return CameraPath(tuple(Keyframe.of_camera(c) for c in cameras), duration, fps, interpolation)


#: Keyframes of an orbit: the Catmull-Rom curve through 12 even points of a circle stays
#: within 0.2% of its radius (10: 0.35%, 8: 0.85%).
ORBIT_KEYFRAMES = 12


def _level(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(forward, right), forward])


def orbit_path(center: np.ndarray, radius: float, up: np.ndarray, *, start: Pose | None = None,
               elevation_degrees: float = 20.0, keyframes: int = ORBIT_KEYFRAMES, duration: float = 10.0,
               fps: float = 30.0, fov_y_degrees: float = 60.0) -> CameraPath:
    """A turntable loop: the camera ``radius`` from ``center``, ``elevation_degrees`` above
    the horizon of ``up`` (so on a circle of radius radius * cos(elevation) about the up
    axis through the centre), looking at the centre without roll, moving to its right.
    Starts looking along ``start``'s heading when given (else along +z, or +y when up is
    about z, like the default view). UserError for bad numbers."""
    center = np.asarray(center, dtype=np.float64).reshape(-1)
    if center.shape != (3,) or not np.all(np.isfinite(center)):
        raise UserError(f"orbit centre must be a finite 3-vector, got {center!r}")
    radius = finite_number(radius)
    if radius is None or radius <= 0:
        raise UserError("orbit radius must be a positive number")
    up = _direction(up, "orbit up")
    elevation = math.radians(checked_number(elevation_degrees, -89.0, 89.0, "orbit elevation_degrees"))
    if isinstance(keyframes, bool) or not isinstance(keyframes, (int, np.integer)) or not 3 <= keyframes <= 360:
        raise UserError(f"orbit keyframes must be an integer in [3, 360], got {keyframes!r}")

    heading = None
    for candidate in ([start.forward, center - start.position] if start is not None else []):
        flat = candidate - np.dot(candidate, up) * up
        if np.linalg.norm(flat) > 1e-9 * max(1.0, float(np.linalg.norm(candidate))):
            heading = flat / np.linalg.norm(flat)
            break
    if heading is None:
        heading = np.array([0.0, 1.0, 0.0]) if abs(up[2]) > 0.5 else np.array([0.0, 0.0, 1.0])
        heading = heading - np.dot(heading, up) * up
        heading /= np.linalg.norm(heading)
    side = np.cross(up, -heading)   # where -heading (centre to camera) turns as the camera moves right

    keys = []
    for k in range(int(keyframes)):
        phi = 2.0 * math.pi * k / int(keyframes)
        outward = math.cos(phi) * -heading + math.sin(phi) * side
        offset = radius * (math.cos(elevation) * outward + math.sin(elevation) * up)
        keys.append(Keyframe(Pose(center + offset, _level(-offset / radius, up)), fov_y_degrees))
    return CameraPath(tuple(keys), duration, fps, Interpolation(loop=True, up=tuple(up)))


def dolly_path(start: Pose, distance: float, *, duration: float = 5.0, fps: float = 30.0,
               fov_y_degrees: float = 60.0, up: np.ndarray | None = None) -> CameraPath:
    """A straight move of ``distance`` scene units along ``start``'s view direction
    (negative: backwards), at one speed, keeping ``start``'s orientation. ``up``: the
    path's up axis for later edits (default: Interpolation's)."""
    distance = finite_number(distance)
    if distance is None:
        raise UserError("dolly distance must be a finite number")
    end = Pose(start.position + distance * start.forward, start.R)
    interpolation = Interpolation() if up is None else Interpolation(up=tuple(_direction(up, "dolly up")))
    return CameraPath((Keyframe(start, fov_y_degrees), Keyframe(end, fov_y_degrees)), duration, fps, interpolation)
