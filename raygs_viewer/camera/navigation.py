"""Camera navigation for the interactive window, in plain float64 numpy.

The window calls a :class:`Navigator` every frame with the held keys and the mouse
deltas; it keeps the view pose, the fly speed and the orbit target.
:class:`~raygs_viewer.camera.lens.Lens` turns that pose and the window size into a
:class:`~raygs_viewer.camera.pinhole.Camera`; the rotation maths is
:mod:`raygs_viewer.camera.rotation`.

Axes are OpenCV's (+x right, +y down, +z forward), as in
:mod:`raygs_viewer.camera.pinhole`: a pose's ``R`` maps world to camera, so its rows
are the camera's right, down and forward axes in world coordinates. "Up" is a property
of the scene, not of the camera, and is picked from :data:`UP_AXES`.

Nothing here imports GL, GLFW or imgui, so all of it is tested headless.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import level_rotation, orthonormalize, yaw_pitch

# "-y" is the COLMAP/INRIA convention (default), "+z" is common for Blender and
# photogrammetry exports.
UP_AXES: dict[str, tuple[float, float, float]] = {
    "-y": (0.0, -1.0, 0.0),
    "+y": (0.0, 1.0, 0.0),
    "+z": (0.0, 0.0, 1.0),
    "-z": (0.0, 0.0, -1.0),
    "+x": (1.0, 0.0, 0.0),
    "-x": (-1.0, 0.0, 0.0),
}

MODES = ("fly", "orbit")

LOOK_RADIANS_PER_PIXEL = 0.003
MAX_DT = 0.1              # seconds; a stalled frame must not teleport the camera
SPEED_STEP = 1.25         # per wheel tick, fly mode
SPEED_RANGE = (1e-4, 1e4)  # times the default speed
ZOOM_STEP = 0.85          # distance factor per wheel tick, orbit mode
MIN_DISTANCE = 1e-6       # times the scene radius
MAX_DISTANCE = 1e6        # times the scene radius
FAST, SLOW = 4.0, 0.25
AIM_SECONDS = 0.3         # the glide of a double-click's aim (SuperSplat's is about as quick)
# Pixel deltas beyond this are input garbage (a warped cursor, a broken driver); they
# are clamped so one event cannot throw the camera out to 1e300.
MAX_PIXELS = 1e6


def up_vector(up: str) -> np.ndarray:
    """(3,) float64 unit vector of an :data:`UP_AXES` name; ValueError for other names."""
    if up not in UP_AXES:
        raise ValueError(f"unknown up axis {up!r}; expected one of {', '.join(UP_AXES)}")
    return np.array(UP_AXES[up], dtype=np.float64)


# --------------------------------------------------------------------------- rotations


def _quiet(method):
    """Silences numpy's overflow warnings: absurd input may overflow mid-way, and the
    result is then dropped (see Navigator._set) rather than worth a warning per frame."""
    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        with np.errstate(over="ignore", invalid="ignore"):
            return method(*args, **kwargs)
    return wrapper


def finite(*values: float) -> bool:
    try:
        return all(math.isfinite(float(v)) for v in values)
    except (TypeError, ValueError, OverflowError):
        return False


def _mouse_pixels(dx: float, dy: float) -> tuple[float, float] | None:
    """A mouse delta clamped to +-MAX_PIXELS, or None when it is not finite or zero
    (nothing to do, and a running flight goes on)."""
    if not finite(dx, dy) or (dx == 0 and dy == 0):
        return None
    return max(-MAX_PIXELS, min(MAX_PIXELS, float(dx))), max(-MAX_PIXELS, min(MAX_PIXELS, float(dy)))


def _smoothstep(s: float) -> float:
    s = max(0.0, min(1.0, s))
    return s * s * (3.0 - 2.0 * s)


def _slerped(start: np.ndarray, end: np.ndarray, fraction: float) -> np.ndarray:
    """(3, 3) rotation ``fraction`` of the way from ``start`` to ``end`` (3, 3) along the
    shortest arc: scipy's slerp (only a flight's in-between poses use it; where it
    lands is the end pose itself)."""
    # scipy.spatial takes half a second to import, and only a flight needs it.
    from scipy.spatial.transform import Rotation, Slerp
    return Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([start, end])))(fraction).as_matrix()


# --------------------------------------------------------------------------- pose and lens


@dataclass(frozen=True, eq=False)
class Pose:
    """position: (3,) float64 camera centre in world space; R: (3, 3) float64
    world-to-camera rotation (rows = camera right, down, forward in world coordinates).

    Both are copied and made read-only, so a pose handed out never changes under its
    holder. ValueError for wrong shapes, non-finite values or an R that is not a rotation
    (R within 1e-3 of one is snapped onto it, as JSON round-trips leave ~1e-7 of drift).
    """

    position: np.ndarray
    R: np.ndarray

    def __post_init__(self) -> None:
        position = np.array(self.position, dtype=np.float64).reshape(-1)
        R = np.array(self.R, dtype=np.float64)
        if position.shape != (3,) or R.shape != (3, 3):
            raise ValueError("a pose needs a (3,) position and a (3, 3) rotation")
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(R))):
            raise ValueError("a pose must be finite")
        error = np.abs(R @ R.T - np.eye(3)).max()
        if error > 1e-3 or np.linalg.det(R) < 0:
            raise ValueError("pose R is not a rotation matrix")
        if error > 1e-12:
            u, _, vt = np.linalg.svd(R)
            R = u @ vt
        position.flags.writeable = False
        R.flags.writeable = False
        object.__setattr__(self, "position", position)
        object.__setattr__(self, "R", R)

    @classmethod
    def from_camera(cls, camera: Camera) -> "Pose":
        return cls(camera.center, camera.R)

    @property
    def forward(self) -> np.ndarray:
        """(3,) viewing direction in world space."""
        return self.R[2].copy()

    def camera(self, width: int, height: int, *, fx: float, fy: float, cx: float, cy: float) -> Camera:
        """The camera of this pose with these intrinsics (pixels)."""
        R = np.array(self.R)
        return Camera(int(width), int(height), float(fx), float(fy), float(cx), float(cy), R, -R @ self.position)


# --------------------------------------------------------------------------- framing


@_quiet
def scene_bounds(positions: np.ndarray) -> tuple[np.ndarray, float]:
    """Robust centre and radius (1st..99th percentile box of finite positions, like
    pinhole.frame_points); radius >= 1e-6; (0,0,0), 1.0 for an empty scene.

    positions: (N, 3), any float dtype. Returns a (3,) float64 centre and a float radius.
    """
    points = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    finite = points[np.all(np.isfinite(points), axis=1)]
    if finite.shape[0] == 0:
        return np.zeros(3), 1.0
    # Working on halved coordinates (exact in binary) gives frame_points' numbers bit for
    # bit, yet a cloud spanning +-1e308 no longer overflows in the differences.
    low, high = np.percentile(finite * 0.5, [1, 99], axis=0)
    center = low + high
    half = high - low
    radius = float(np.linalg.norm(half))
    if not math.isfinite(radius):
        radius = float(np.abs(half).max() * math.sqrt(3.0))
    return center, min(max(radius, 1e-6), 1e300)


def _default_forward(up: np.ndarray) -> np.ndarray:
    # +z, like frame_points, unless that is the up axis; then +y, which for "+z" up is
    # Blender's front view (camera on -y, x to the right).
    return np.array([0.0, 1.0, 0.0]) if abs(up[2]) > 0.5 else np.array([0.0, 0.0, 1.0])


def framing_pose(center, radius: float, up: str, fov_y_degrees: float, aspect: float) -> Pose:
    """A pose looking at center from a horizontal direction (perpendicular to up), far
    enough that the sphere fits the view; for up "-y" it looks along +z like
    pinhole.frame_points, so reset-view of a scene without cameras matches the CLI's
    default view.

    center: (3,); radius > 0 (smaller or non-finite values become 1e-6 / 1.0); aspect =
    width / height of the view (non-positive or non-finite is taken as 1).
    """
    up_vec = up_vector(up)
    center = np.asarray(center, dtype=np.float64).reshape(3)
    forward = _default_forward(up_vec)
    return Pose(center - framing_distance(radius, fov_y_degrees, aspect) * forward, level_rotation(forward, up_vec))


def framing_distance(radius: float, fov_y_degrees: float, aspect: float) -> float:
    """How far from a sphere of ``radius`` a camera of that vertical field of view and
    aspect (width / height) must be for the sphere to fit its view; the same fallbacks
    as :func:`framing_pose` for bad numbers."""
    radius = max(float(radius) if finite(radius) else 1.0, 1e-6)
    aspect = float(aspect) if finite(aspect) and float(aspect) > 0 else 1.0
    fov = float(fov_y_degrees) if finite(fov_y_degrees) else 60.0
    half_y = math.radians(min(179.0, max(1e-3, fov))) / 2
    # The narrower of the two half-angles decides: the sphere's cone must fit both ways.
    half = min(half_y, math.atan(math.tan(half_y) * aspect))
    return radius / math.sin(half)


# --------------------------------------------------------------------------- aiming at a point


def centred_on(pose: Pose, point, up: np.ndarray) -> tuple[Pose, float] | None:
    """Orbit mode's aim, as SuperSplat's double-click and Blender's "center view to
    mouse" do: the view keeps its direction and slides so that ``point`` (3,) sits on the
    image centre at the distance it has now. (pose, that distance), or None when the
    point is not finite or is the camera centre."""
    distance = _distance_to(pose, point)
    if distance is None:
        return None
    return Pose(np.asarray(point, np.float64) - distance * pose.R[2], pose.R), distance


def facing(pose: Pose, point, up: np.ndarray) -> tuple[Pose, float] | None:
    """Fly mode's aim: the view stays where it is and turns, level about ``up``, to look
    at ``point``. (pose, its distance), or None as for :func:`centred_on`."""
    distance = _distance_to(pose, point)
    if distance is None:
        return None
    forward = np.asarray(point, np.float64) - pose.position
    return Pose(pose.position, level_rotation(forward, up, pose.R[0])), distance


def _distance_to(pose: Pose, point) -> float | None:
    point = np.asarray(point, np.float64).reshape(-1)
    if point.shape != (3,) or not np.all(np.isfinite(point)):
        return None
    distance = float(np.linalg.norm(point - pose.position))
    return distance if math.isfinite(distance) and distance > 0 else None


# --------------------------------------------------------------------------- navigator


class Navigator:
    """Holds the view pose and navigation state. Modes: "fly" and "orbit".

    Fly: ``move(dt, right, up, forward)`` moves along camera x (right, +1 = D key, -1 = A),
    world up (+1 = E, -1 = Q) and camera z (forward, +1 = W, -1 = S); the direction's
    length is capped at 1 so diagonals are not faster. ``speed`` (scene units per second)
    starts at 0.5 * scene radius; ``scale(ticks)`` (mouse wheel) multiplies it by
    1.25**ticks, clamped to 1e-4..1e4 times the default; ``fast`` (Shift) multiplies by 4
    and ``slow`` (Ctrl) by 0.25 for that move. dt is clamped to 0.1 s.
    ``look(dx, dy)`` from mouse pixels: 0.003 rad per pixel; dx > 0 turns the view right
    (yaw about the world up axis), dy > 0 tilts it down (pitch about the camera x axis).
    Forward stays at least 1 degree from the up axis and its opposite. Yaw and pitch both
    keep the camera x axis's angle to up, so a training camera's roll neither grows nor
    vanishes.

    Orbit: a target point on the forward axis at ``distance``. ``rotate(dx, dy)`` turns
    the camera about the target like look() turns it about itself, so the scene follows
    the mouse (drag right: camera moves left around the up axis through the target;
    drag down: it moves up over the target), and the target stays on the image centre.
    ``pan(dx, dy, focal_px)`` slides camera and target in the camera plane so the target
    follows the mouse pixel for pixel. ``zoom(ticks)``: distance *= 0.85**ticks (ticks > 0
    = closer), within 1e-6..1e6 scene radii.

    The target is always ``position + distance * forward``, so switching fly -> orbit
    puts it on the forward axis at the current orbit distance, and orbit -> fly keeps
    the pose. The first orbit distance is the scene centre's depth when the centre lies
    in front (more than 0.1 radius), else the scene radius.

    All methods take any mode. Calls with a non-finite argument are ignored, and calls
    that do nothing (zero keys, zero mouse delta) leave a :meth:`fly_to` animation
    running, so the window can call move() every frame; calls that do move the view
    cancel it, keeping the in-between pose.
    """

    def __init__(self, pose: Pose, center: np.ndarray, radius: float, up: str = "-y", mode: str = "fly") -> None:
        """pose: the start view; center (3,), radius: the scene's bounds (scene_bounds);
        up: an UP_AXES name; mode: "fly" or "orbit". ValueError for bad names or
        non-finite bounds."""
        center = np.array(center, dtype=np.float64).reshape(-1)
        if center.shape != (3,) or not np.all(np.isfinite(center)):
            raise ValueError("scene centre must be 3 finite numbers")
        if not finite(radius):
            raise ValueError("scene radius must be finite")
        self._check_mode(mode)
        self._up = up
        self._up_vec = up_vector(up)
        self.center = center
        self.radius = min(max(float(radius), 1e-6), 1e300)
        self.default_speed = 0.5 * self.radius
        self._mode = mode
        self._animation: tuple[Pose, Pose, float, float] | None = None
        self._set(pose.position, pose.R)
        self.speed = self.default_speed
        self._distance = self._initial_distance()

    # ----------------------------------------------------------------- state

    @property
    def pose(self) -> Pose:
        return Pose(self._position, self._R)

    @property
    def mode(self) -> str:
        return self._mode

    @property
    def up(self) -> str:
        return self._up

    @property
    def up_vector(self) -> np.ndarray:
        """(3,) world up as a unit vector."""
        return self._up_vec.copy()

    @property
    def distance(self) -> float:
        """Orbit distance: camera centre to target."""
        return self._distance

    @property
    def target(self) -> np.ndarray:
        """(3,) orbit target, world space; on the forward axis at ``distance``."""
        return self._position + self._distance * self._R[2]

    @property
    def animating(self) -> bool:
        return self._animation is not None

    @staticmethod
    def _check_mode(mode: str) -> None:
        if mode not in MODES:
            raise ValueError(f"unknown navigation mode {mode!r}; expected 'fly' or 'orbit'")

    def _set(self, position: np.ndarray, R: np.ndarray) -> None:
        """Commits a new pose, or keeps the old one when overflow made it non-finite.

        R must already be orthonormal (every rotation path re-orthonormalises; poses
        from outside are checked by Pose), so a set_pose keeps a training camera's bits.
        """
        R = np.array(R, dtype=np.float64)
        position = np.array(position, dtype=np.float64)
        if np.all(np.isfinite(position)) and np.all(np.isfinite(R)):
            self._position, self._R = position, R

    def _initial_distance(self) -> float:
        depth = float(np.dot(self.center - self._position, self._R[2]))
        return depth if math.isfinite(depth) and depth > 0.1 * self.radius else self.radius

    def _distance_limits(self) -> tuple[float, float]:
        return MIN_DISTANCE * self.radius, MAX_DISTANCE * self.radius

    def _cancel(self) -> None:
        self._animation = None

    def set_mode(self, mode: str) -> None:
        self._check_mode(mode)
        self._mode = mode

    @_quiet
    def set_up(self, up: str) -> None:
        """Changes the world up axis and re-levels the view to it (keeps position and,
        unless it is within 1 degree of the new pole, forward). ValueError for unknown names."""
        up_vec = up_vector(up)
        self._cancel()
        self._up, self._up_vec = up, up_vec
        self._set(self._position, level_rotation(self._R[2], up_vec, self._R[0]))

    # ----------------------------------------------------------------- fly

    @_quiet
    def move(self, dt: float, right: float, up: float, forward: float, *,
             fast: bool = False, slow: bool = False) -> None:
        if not finite(dt, right, up, forward) or dt <= 0:
            return
        direction = np.array([right, up, forward], dtype=np.float64)
        length = float(np.linalg.norm(direction))
        if length == 0:
            return
        if length > 1:
            direction /= length
        factor = (FAST if fast else 1.0) * (SLOW if slow else 1.0)
        step = self.speed * factor * min(float(dt), MAX_DT)
        offset = direction[0] * self._R[0] + direction[1] * self._up_vec + direction[2] * self._R[2]
        self._cancel()
        self._set(self._position + step * offset, self._R)

    def scale(self, ticks: float) -> None:
        """Fly speed *= 1.25**ticks, clamped (worked in logs: 1.25**1e6 overflows)."""
        if not finite(ticks):
            return
        low, high = (math.log(self.default_speed * k) for k in SPEED_RANGE)
        log_speed = math.log(self.speed) + float(ticks) * math.log(SPEED_STEP)
        self.speed = math.exp(max(low, min(high, log_speed)))

    @_quiet
    def look(self, dx: float, dy: float) -> None:
        self._turn(dx, dy, about_target=False)

    # ----------------------------------------------------------------- orbit

    @_quiet
    def rotate(self, dx: float, dy: float) -> None:
        self._turn(dx, dy, about_target=True)

    def _turn(self, dx: float, dy: float, about_target: bool) -> None:
        """Yaw ``dx`` and pitch ``dy`` pixels, about the camera itself (look) or about the
        orbit target, which then stays on the image centre (rotate)."""
        pixels = _mouse_pixels(dx, dy)
        if pixels is None:
            return
        self._cancel()
        target = self.target
        R = yaw_pitch(self._R, self._up_vec, LOOK_RADIANS_PER_PIXEL * pixels[0],
                      -LOOK_RADIANS_PER_PIXEL * pixels[1])  # dy > 0: view tilts down
        self._set(target - self._distance * R[2] if about_target else self._position, R)

    @_quiet
    def pan(self, dx: float, dy: float, focal_px: float) -> None:
        pixels = _mouse_pixels(dx, dy)
        if pixels is None or not finite(focal_px) or focal_px <= 0:
            return
        dx, dy = pixels
        # At the target's depth one pixel spans distance / focal world units; the camera
        # moves against the mouse so the scene follows it.
        scale = self._distance / float(focal_px)
        self._cancel()
        self._set(self._position - scale * (dx * self._R[0] + dy * self._R[1]), self._R)

    @_quiet
    def zoom(self, ticks: float) -> None:
        if not finite(ticks) or ticks == 0:
            return
        low, high = self._distance_limits()
        # Never pull an already-farther camera in just because it is past the limit.
        high = max(high, self._distance)
        low = min(low, self._distance)
        log_d = math.log(self._distance) + float(ticks) * math.log(ZOOM_STEP)
        distance = math.exp(max(math.log(low), min(math.log(high), log_d)))
        target = self.target
        self._cancel()
        self._distance = distance
        self._set(target - distance * self._R[2], self._R)

    # ----------------------------------------------------------------- jumps and animation

    @_quiet
    def set_pose(self, pose: Pose) -> None:
        self._cancel()
        self._set(pose.position, pose.R)

    @_quiet
    def aim_at(self, point, duration: float = AIM_SECONDS) -> bool:
        """Glides to :func:`centred_on` ``point`` (orbit mode) or :func:`facing` it (fly);
        the orbit distance becomes its distance. False, nothing done, for a bad point."""
        aimed = (centred_on if self._mode == "orbit" else facing)(self.pose, point, self._up_vec)
        if aimed is not None:
            self.fly_to(aimed[0], duration)
            self._distance = aimed[1]
        return aimed is not None

    def reset(self, pose: Pose) -> None:
        self.set_pose(pose)
        self.speed = self.default_speed
        self._distance = self._initial_distance()

    @_quiet
    def fly_to(self, pose: Pose, duration: float = 0.6) -> None:
        """Moves smoothly to ``pose`` over ``duration`` seconds of :meth:`advance`:
        position smoothstep-interpolated, rotation slerped along the shortest arc. A
        non-positive or non-finite duration jumps at once."""
        if not finite(duration) or duration <= 0:
            self.set_pose(pose)
            return
        self._animation = (self.pose, pose, float(duration), 0.0)

    @_quiet
    def advance(self, dt: float) -> None:
        if self._animation is None or not finite(dt) or dt <= 0:
            return
        start, end, duration, elapsed = self._animation
        elapsed = min(duration, elapsed + float(dt))
        if elapsed >= duration:
            self._animation = None
            self._set(end.position, end.R)  # exactly the requested pose, not the slerp's rounding of it
            return
        self._animation = (start, end, duration, elapsed)
        w = _smoothstep(elapsed / duration)
        rotation = orthonormalize(_slerped(start.R, end.R, w))
        self._set(start.position + w * (end.position - start.position), rotation)
