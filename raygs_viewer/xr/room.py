"""Where a headset's room sits in the scene, and the eye cameras it gives: the one home of
the headset's conventions.

Two spaces meet here.

- The **room** is OpenXR's tracking space: right-handed, +x right, +y up, -z forward,
  in metres. OpenXR hands out poses (:class:`Pose`): an orientation quaternion in
  OpenXR's (x, y, z, w) order and a position. The orientation takes a view's local axes
  into the room; a view (an eye's camera) looks along its local -z with +y up, GL's
  camera axes.
- The **world** is the scene's space, in scene units, and its cameras are the project's
  :class:`~raygs_viewer.camera.pinhole.Camera`: OpenCV axes (+x right, +y down,
  +z forward), ``R`` world-to-camera, pixel (u, v) centred at (u + 0.5, v + 0.5).

A :class:`Room` says where the room lies in the world: ``world = origin +
units_per_metre * rotation @ room``. Moving through the scene (the controllers of
:mod:`raygs_viewer.xr.controls`) changes the room, never the scene. An eye camera is the
view's GL axes turned into OpenCV's (y and z flipped) and carried into the world by the
room's rotation; scale moves the eyes apart or together (the IPD in scene units is
``units_per_metre`` times the metres) but never turns them.

Quaternions: OpenXR orders them (x, y, z, w); :mod:`raygs_viewer.camera.rotation`, whose
maths is reused here, orders them (w, x, y, z). :func:`xyzw_to_wxyz` and
:func:`wxyz_to_xyzw` are the only crossings between the two.

A field of view (:class:`Fov`) is OpenXR's four angles in radians: the image's left
edge lies at x / (-z) = tan(left), the right at tan(right), the top at y / (-z) = tan(up),
the bottom at tan(down) (left and down usually negative). Headsets give each eye an
asymmetric one, mirrored between the eyes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import (
    is_rotation,
    matrix_to_quaternion,
    quaternion_to_matrix,
)
from raygs_viewer.errors import finite_number

#: GL camera axes (x right, y up, z back) to OpenCV ones (x right, y down, z forward),
#: and back: its own inverse.
GL_TO_OPENCV = np.diag([1.0, -1.0, -1.0])
#: Room +y, the up of the tracking space.
ROOM_UP = np.array([0.0, 1.0, 0.0])
GL_TO_OPENCV.flags.writeable = ROOM_UP.flags.writeable = False  # shared constants
#: How far a Room's rotation may be from a proper rotation (largest entry of M Mᵀ - I):
#: loose enough for rotations composed over a long session, tight enough to refuse a
#: scaled or sheared matrix.
ROTATION_TOLERANCE = 1e-6
#: A horizontal direction shorter than this (of a unit vector) is taken as none: the
#: vector points straight along the up axis, and a fallback gives the heading.
LEVEL_EPSILON = 1e-9


def xyzw_to_wxyz(quaternion: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions in OpenXR's (x, y, z, w) order -> the project's (w, x, y, z)."""
    return np.roll(np.asarray(quaternion, np.float64), 1, axis=-1)


def wxyz_to_xyzw(quaternion: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions in the project's (w, x, y, z) order -> OpenXR's (x, y, z, w)."""
    return np.roll(np.asarray(quaternion, np.float64), -1, axis=-1)


def finite_float(value, what: str) -> float:
    """``value`` (a Python or numpy number, not a bool) as a float; ValueError unless finite."""
    number = finite_number(value.item() if isinstance(value, (np.floating, np.integer)) else value)
    if number is None:
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return number


def finite_vector(values, size: int, what: str) -> np.ndarray:
    """``values`` as a fresh, read-only (size,) float64 array; ValueError unless it has
    that shape and only finite numbers."""
    array = np.array(values, dtype=np.float64)
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{what} must be {size} finite numbers, got {values!r}")
    array.flags.writeable = False
    return array


@dataclass(frozen=True)
class Pose:
    """An OpenXR pose in room space.

    orientation: (4,) float64 unit quaternion in OpenXR's (x, y, z, w) order, taking the
    posed thing's local axes into the room (normalised here; a copy). position: (3,)
    float64 metres in the room (a copy). Both arrays are read-only: a pose is a value.
    ValueError for a zero or non-finite quaternion (OpenXR reports one for a pose it
    does not track: check its validity flags before making a Pose).
    """

    orientation: np.ndarray
    position: np.ndarray

    def __post_init__(self) -> None:
        quaternion = np.array(self.orientation, dtype=np.float64)
        norm = float(np.linalg.norm(quaternion)) if quaternion.shape == (4,) else 0.0
        if not (math.isfinite(norm) and norm > 1e-12):
            raise ValueError(f"a pose's orientation must be a nonzero finite (x, y, z, w) quaternion, "
                             f"got {self.orientation!r}")
        object.__setattr__(self, "orientation", finite_vector(quaternion / norm, 4, "a pose's orientation"))
        object.__setattr__(self, "position", finite_vector(self.position, 3, "a pose's position"))

    @property
    def matrix(self) -> np.ndarray:
        """(3, 3) float64 room-from-local rotation: its columns are the local x, y, z axes
        in the room (for a view: right, up, back)."""
        return quaternion_to_matrix(xyzw_to_wxyz(self.orientation)[None])[0]

    @property
    def forward(self) -> np.ndarray:
        """(3,) float64 unit vector in the room along which the pose looks (its local -z)."""
        return -self.matrix[:, 2]


def pose_from_matrix(matrix: np.ndarray, position) -> Pose:
    """The Pose whose :attr:`Pose.matrix` is the (3, 3) rotation ``matrix``, at ``position``."""
    return Pose(wxyz_to_xyzw(matrix_to_quaternion(np.asarray(matrix, np.float64))), position)


@dataclass(frozen=True)
class Fov:
    """An OpenXR field of view: four angles in radians (module docstring). ValueError
    unless each is finite and inside (-pi/2, pi/2), left < right and down < up."""

    left: float
    right: float
    up: float
    down: float

    def __post_init__(self) -> None:
        angles = {name: getattr(self, name) for name in ("left", "right", "up", "down")}
        for name, angle in angles.items():
            number = finite_float(angle, f"a field of view's {name} angle")
            if not -math.pi / 2 < number < math.pi / 2:
                raise ValueError(f"a field of view's {name} angle must be within (-pi/2, pi/2) radians, got {angle!r}")
            object.__setattr__(self, name, number)
        if not (self.left < self.right and self.down < self.up):
            raise ValueError(f"a field of view needs left < right and down < up, got {self}")


@dataclass(frozen=True)
class Room:
    """Where the room lies in the world: ``world = origin + units_per_metre * rotation @ room``.

    rotation: (3, 3) float64 world-from-room rotation (its column 1 is the world direction
    of room up); origin: (3,) float64 world position of the room's origin;
    units_per_metre: scene units per room metre, > 0 (larger: the scene looks smaller).
    Arrays are copied and read-only. ValueError for a rotation that is not a proper one
    (to :data:`ROTATION_TOLERANCE`), a non-finite origin or a scale that is not a
    positive finite number.
    """

    rotation: np.ndarray
    origin: np.ndarray
    units_per_metre: float

    def __post_init__(self) -> None:
        rotation = np.array(self.rotation, dtype=np.float64)
        if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)) \
                or not is_rotation(rotation, ROTATION_TOLERANCE):
            raise ValueError("a room's rotation must be a (3, 3) proper rotation matrix")
        rotation.flags.writeable = False
        object.__setattr__(self, "rotation", rotation)
        object.__setattr__(self, "origin", finite_vector(self.origin, 3, "a room's origin"))
        scale = finite_float(self.units_per_metre, "a room's units per metre")
        if not scale > 0:
            raise ValueError(f"a room's units per metre must be positive, got {self.units_per_metre!r}")
        object.__setattr__(self, "units_per_metre", scale)

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """(3,) or (N, 3) room points (metres) -> the same shape of world points (units)."""
        points = np.asarray(points, np.float64)
        return self.origin + self.units_per_metre * (points @ self.rotation.T)

    def to_room(self, points: np.ndarray) -> np.ndarray:
        """(3,) or (N, 3) world points -> room points: the inverse of :meth:`to_world`."""
        points = np.asarray(points, np.float64)
        return ((points - self.origin) @ self.rotation) / self.units_per_metre


def intrinsics(fov: Fov, width: int, height: int) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) in pixels of an image ``width`` x ``height`` that spans ``fov``.

    In the project's pixel convention the ray through image x-coordinate u (pixel
    centres at u + 0.5) has x / z = (u - cx) / fx, so the image's left edge (u = 0) lies
    at tan(left) and its right edge (u = W) at tan(right) when fx = W / (tan r - tan l)
    and cx = -tan(l) fx. Camera y points down, so the top edge (v = 0) is at
    y / z = -tan(up): fy = H / (tan u - tan d), cy = tan(u) fy. A symmetric field of view
    gives cx = W / 2, cy = H / 2.
    """
    if not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n > 0 for n in (width, height)):
        raise ValueError(f"an eye image's width and height must be positive integers, got {width!r}, {height!r}")
    left, right, up, down = (math.tan(angle) for angle in (fov.left, fov.right, fov.up, fov.down))
    fx = width / (right - left)
    fy = height / (up - down)
    return fx, fy, -left * fx, up * fy


def eye_camera(pose: Pose, fov: Fov, width: int, height: int, room: Room) -> Camera:
    """The project Camera of an eye (``pose``: its OpenXR view pose in the room) showing
    ``fov`` on a ``width`` x ``height`` image.

    Centre: ``room.to_world(pose.position)``. Axes: the view's GL axes (columns of
    ``pose.matrix``: right, up, back) flipped into OpenCV's (right, down, forward), then
    turned into the world by ``room.rotation``; ``units_per_metre`` only moves the centre.
    """
    fx, fy, cx, cy = intrinsics(fov, width, height)
    camera_to_world = room.rotation @ pose.matrix @ GL_TO_OPENCV
    centre = room.to_world(pose.position)
    R = np.ascontiguousarray(camera_to_world.T)
    return Camera(int(width), int(height), fx, fy, cx, cy, R, -R @ centre)


def halfway(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion half-way between unit quaternions ``a`` and ``b`` (either
    order of components): b's sign is aligned to a's so the short way is taken, and the
    normalised sum is exactly slerp at one half."""
    b = b if float(np.dot(a, b)) >= 0 else -b
    total = a + b
    return total / np.linalg.norm(total)  # |a + b| >= sqrt(2) once aligned


def midpoint(left: Pose, right: Pose) -> Pose:
    """The pose between two (the eyes' views -> the head): positions averaged,
    orientation half-way (:func:`halfway`)."""
    return Pose(halfway(left.orientation, right.orientation), 0.5 * (left.position + right.position))


def midpoint_camera(left: Camera, right: Camera) -> Camera:
    """The camera that the one depth sort shared by both eyes is made from.

    Centre: the eyes' midpoint (the depth keys' origin). Rotation: half-way between the
    eyes' (equal rotations are kept bit for bit). Size and intrinsics: the left eye's,
    but with cx the mean of the two. The sort reads fx and fy only for its cull
    dilation (the pixel filter's width per unit distance), for which the left eye's
    speak for both: headsets mirror one field of view between the eyes, so their fx
    and fy agree. Culling itself goes by each eye's own camera (the sort request's
    cull cameras), so the midpoint's frustum culls nothing; cx is averaged because
    the eyes' principal points are mirrored (each eye sees more on its own side), and
    their mean gives the frustum that a level-of-detail choice made for this camera
    sees: a roughly centred one spanning what both eyes look at, not one eye's skew.
    """
    if np.array_equal(left.R, right.R):
        R = np.array(left.R, np.float64)
    else:
        q = halfway(matrix_to_quaternion(np.asarray(left.R, np.float64)),
                    matrix_to_quaternion(np.asarray(right.R, np.float64)))
        R = quaternion_to_matrix(q[None])[0]
    centre = 0.5 * (left.center + right.center)
    return Camera(left.width, left.height, left.fx, left.fy, 0.5 * (left.cx + right.cx), left.cy, R, -R @ centre)


def heading(forward: np.ndarray, image_up: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(3,) unit vector normal to the unit ``up``: where something looking along
    ``forward`` faces, its pitch taken away.

    ``forward`` projected on the plane normal to ``up``, normalised. Looking straight
    along ``up`` there is no such projection; then the image's own up (``image_up``,
    normal to ``forward``) gives it: looking straight down, the top of the image is
    where one faces (tilt a level view down by 90 degrees and its up turns into the old
    forward), looking straight up, the bottom is. This is the limit of the projection as
    a roll-free view tilts to the pole, so the fallback does not jump. Should both
    fail (vectors that are not a camera's), any direction normal to ``up``."""
    along = float(np.dot(forward, up))
    flat = forward - along * up
    if np.linalg.norm(flat) > LEVEL_EPSILON:
        return flat / np.linalg.norm(flat)
    flat = -math.copysign(1.0, along) * (image_up - float(np.dot(image_up, up)) * up)
    if np.linalg.norm(flat) > LEVEL_EPSILON:
        return flat / np.linalg.norm(flat)
    other = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    flat = other - float(np.dot(other, up)) * up
    return flat / np.linalg.norm(flat)


def level_frame(facing: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(3, 3) rotation whose columns are ``facing``, ``up`` and their cross product: the
    frame of a level heading (both unit, normal to each other)."""
    return np.stack([facing, up, np.cross(facing, up)], axis=1)


def room_at_view(view: Camera, head: Pose, up: np.ndarray, units_per_metre: float) -> Room:
    """The room in which the headset starts where the desktop camera ``view`` was.

    ``head``: the head's pose in the room (the eyes' midpoint, :func:`midpoint`);
    ``up``: (3,) the scene's up direction in world coordinates (normalised here; e.g.
    (0, -1, 0) for OpenCV / COLMAP scenes). The room's rotation takes room +y to ``up``
    and the head's heading (its -z projected on the room's floor plane) to the desktop
    camera's heading (its forward, row 2 of R, projected on the plane normal to ``up``);
    the origin is placed so that the head's position lands on the camera's centre. Only
    yaw is matched: the desktop camera's pitch and roll are dropped (the floor stays
    level), and the head keeps its own.

    Degenerate headings (the camera looking straight along ``up``, the head straight
    up or down) fall back to the image's up axis (:func:`heading`): the camera's -y row,
    the head's local +y; the rotation is always a proper one.
    """
    up = np.asarray(up, np.float64)
    norm = float(np.linalg.norm(up)) if up.shape == (3,) else 0.0
    if not (math.isfinite(norm) and norm > 1e-12):
        raise ValueError(f"the scene's up must be a nonzero finite 3-vector, got {up!r}")
    up = up / norm
    R = np.asarray(view.R, np.float64)
    world_heading = heading(R[2], -R[1], up)
    head_axes = head.matrix
    room_heading = heading(-head_axes[:, 2], head_axes[:, 1], ROOM_UP)
    rotation = level_frame(world_heading, up) @ level_frame(room_heading, ROOM_UP).T
    origin = view.center - units_per_metre * rotation @ head.position
    return Room(rotation, origin, units_per_metre)
