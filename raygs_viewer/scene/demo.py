"""The built-in demo scene: a few thousand gaussians that show what RayGS is for.

World axes are OpenCV's (+y down); the floor is the plane y = +1 and everything
stands on or floats above it, inside a box of about 10 units around the origin.

What is where (seen from :func:`demo_camera`, which looks along +z):

- **floor** (pancakes, opacity 1): a tiled floor of flat discs, thickness 1/100 of
  their width, y = 1, seen at ever more grazing angles towards the back;
- **iridescent sphere** (view-dependent colour): a sphere of surface discs at the
  centre whose SH degree 1..3 coefficients encode thin-film colour as a function
  of the angle between the view direction and the surface normal, so the colour
  bands follow the viewer;
- **ring** (needles, scale ratio 100..180): a tilted ring of thin golden strands
  around the sphere, in front of it on one side and behind it on the other;
- **grass** (needles): tufts of blades rising from the floor, left front, right
  front and along the back;
- **glass panes** (overlapping translucent layers): five coloured sheets, each a
  grid of flat gaussians of opacity 0.28..0.4, one behind the other right of the
  sphere, staggered so each partly covers the next on screen: the blending
  order matters;
- **petals** (pancakes, opacity 0.3..0.6): pink petals drifting in the air and
  lying flat on the floor (grazing discs);
- **fireflies** (small round, faint): warm dots floating above the floor;
- **close to the camera** (the depth clamp): a leaf, dust motes and a blade less
  than 0.5 units in front of the default camera, and a strand and a petal that
  straddle its image plane (they reach behind the camera; the petal is the pink
  haze across the top of the default view).

Generation is deterministic: a fixed ``numpy.random.default_rng`` seed, float64
arithmetic, and every array rounded to a fixed number of decimals before the cast
to float32, so last-ulp differences between platforms' ``sin``/``exp``/sums are
absorbed before they reach a stored value (``tests/test_demo.py`` pins a SHA-256
of the arrays). Quaternions are normalised after that rounding.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_to_json, look_at
from raygs_viewer.camera.rotation import matrix_to_quaternion, qmul
from raygs_viewer.jsonfile import json_text
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sh import C0, sh_basis

SEED = 20240615
SH_DEGREE = 3
FLOOR_Y = 1.0

#: The default view: from the front, a little above the objects, looking slightly down.
DEFAULT_EYE = (0.35, -1.25, -4.6)
DEFAULT_TARGET = (0.25, 0.05, 1.2)
DEFAULT_FOV_Y = 60.0

SPHERE_CENTER = (0.0, 0.05, 1.0)
SPHERE_RADIUS = 0.9


# --- small helpers ---------------------------------------------------------------------

def _normalize(v: np.ndarray) -> np.ndarray:
    return v / np.sqrt(np.sum(v * v, axis=-1, keepdims=True))


def _quat_z_to(axis: np.ndarray, twist: np.ndarray | float = 0.0) -> np.ndarray:
    """(N, 4) quaternions whose rotation takes local +z to ``axis`` (N, 3), after a
    rotation by ``twist`` radians about local z."""
    axis = _normalize(np.asarray(axis, dtype=np.float64))
    n = axis.shape[0]
    # Shortest arc from e_z: q = (1 + a_z, e_z x a) normalised; a = -e_z: 180 deg about x.
    arc = np.stack([1.0 + axis[:, 2], -axis[:, 1], axis[:, 0], np.zeros(n)], axis=-1)
    flipped = arc[:, 0] < 1e-9
    arc[flipped] = (0.0, 1.0, 0.0, 0.0)
    arc = _normalize(arc)
    half = 0.5 * np.broadcast_to(np.asarray(twist, dtype=np.float64), (n,))
    spin = np.stack([np.cos(half), np.zeros(n), np.zeros(n), np.sin(half)], axis=-1)
    return qmul(arc, spin)


def _quat_from_axes(x_axis, z_axis) -> np.ndarray:
    """(1, 4) quaternion of the rotation whose local x and z axes point along the given
    (orthogonalised) world directions."""
    z = np.asarray(z_axis, dtype=np.float64)
    z = z / np.linalg.norm(z)
    x = np.asarray(x_axis, dtype=np.float64)
    x = x - (x @ z) * z
    x = x / np.linalg.norm(x)
    m = np.stack([x, np.cross(z, x), z], axis=1)  # columns: local axes in world space
    return matrix_to_quaternion(m)[None]


def _sh_from_rgb(rgb: np.ndarray) -> np.ndarray:
    """(N, 3) target colours -> (N, 16, 3) SH with only the DC term set."""
    sh = np.zeros((rgb.shape[0], sh_coefficient_count(SH_DEGREE), 3))
    sh[:, 0, :] = (np.asarray(rgb, dtype=np.float64) - 0.5) / C0
    return sh


def _fibonacci_sphere(n: int) -> np.ndarray:
    """n nearly uniform unit vectors (golden-angle spiral), (n, 3)."""
    i = np.arange(n, dtype=np.float64) + 0.5
    y = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - y * y))
    phi = i * (math.pi * (3.0 - math.sqrt(5.0)))
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=-1)


class _Parts:
    """Accumulates groups of gaussians (float64) before the final rounding and cast."""

    def __init__(self) -> None:
        self.groups: list[tuple[np.ndarray, ...]] = []

    def add(self, positions, rotations, scales, opacities, sh) -> None:
        n = np.asarray(positions).shape[0]
        group = (
            np.asarray(positions, dtype=np.float64).reshape(n, 3),
            np.asarray(rotations, dtype=np.float64).reshape(n, 4),
            np.asarray(scales, dtype=np.float64).reshape(n, 3),
            np.broadcast_to(np.asarray(opacities, dtype=np.float64), (n,)),
            np.asarray(sh, dtype=np.float64).reshape(n, sh_coefficient_count(SH_DEGREE), 3),
        )
        self.groups.append(group)

    def scene(self) -> Scene:
        pos, rot, scl, opa, sh = (np.concatenate([g[i] for g in self.groups]) for i in range(5))
        rot = np.round(rot, 6)
        norm2 = rot[:, 0] * rot[:, 0] + rot[:, 1] * rot[:, 1] + rot[:, 2] * rot[:, 2] + rot[:, 3] * rot[:, 3]
        rot = rot / np.sqrt(norm2)[:, None]  # explicit order: the same bits everywhere
        scl = np.maximum(np.round(scl, 7), 1e-7)
        return Scene(
            positions=np.round(pos, 5).astype(np.float32),
            rotations=rot.astype(np.float32),
            scales=scl.astype(np.float32),
            opacities=np.clip(np.round(opa, 4), 0.0, 1.0).astype(np.float32),
            sh=np.round(sh, 5).astype(np.float32),
            sh_degree=SH_DEGREE,
            source="demo",
        )


# --- the groups ------------------------------------------------------------------------

def _floor(parts: _Parts, rng: np.random.Generator) -> None:
    """Tiled floor of pancakes at y = FLOOR_Y: checkerboard of two stone tones."""
    step = 0.3
    xs = np.arange(-4.5, 4.5 + 1e-9, step)
    zs = np.arange(-2.1, 6.3 + 1e-9, step)
    gx, gz = np.meshgrid(xs, zs, indexing="xy")
    gx, gz = gx.ravel(), gz.ravel()
    keep = (gx / 4.8) ** 2 + ((gz - 2.1) / 4.4) ** 2 <= 1.0  # an oval floor, not a slab
    gx, gz = gx[keep], gz[keep]
    n = gx.size
    ix = np.round((gx + 4.5) / step).astype(int)
    iz = np.round((gz + 2.1) / step).astype(int)
    checker = ((ix // 2 + iz // 2) % 2).astype(np.float64)[:, None]
    light = np.array([0.78, 0.74, 0.66])
    dark = np.array([0.22, 0.25, 0.33])
    rgb = checker * light + (1 - checker) * dark + rng.uniform(-0.04, 0.04, (n, 3))
    pos = np.stack([gx + rng.uniform(-0.01, 0.01, n), np.full(n, FLOOR_Y), gz + rng.uniform(-0.01, 0.01, n)], 1)
    normal = _normalize(np.stack([rng.normal(0, 0.02, n), -np.ones(n), rng.normal(0, 0.02, n)], 1))
    rot = _quat_z_to(normal, rng.uniform(0, math.pi, n))
    width = 0.14
    scl = np.stack([np.full(n, width), np.full(n, width * 0.93), np.full(n, width / 110)], 1)
    parts.add(pos, rot, scl, 1.0, _sh_from_rgb(rgb))


def _thin_film_rgb(facing: np.ndarray, thickness: np.ndarray) -> np.ndarray:
    """Soap-film-like colour (..., M, 3) for ``facing`` = -dir . normal (..., M), 1 when
    the surface faces the viewer, and a film thickness (..., 1): the optical path
    shrinks towards grazing angles, which shifts the colour bands."""
    path = thickness * (0.55 + 0.45 * facing)
    phases = np.array([0.0, 1.0 / 3.0, 2.0 / 3.0])
    return 0.55 + 0.4 * np.cos(2 * math.pi * (path[..., None] + phases))


def _sphere(parts: _Parts, rng: np.random.Generator) -> None:
    """Iridescent sphere: surface discs whose SH (degree 3) hold a thin-film colour."""
    n = 720
    normals = _fibonacci_sphere(n)
    center = np.asarray(SPHERE_CENTER)
    pos = center + SPHERE_RADIUS * normals
    rot = _quat_z_to(normals, rng.uniform(0, math.pi, n))
    spacing = math.sqrt(4 * math.pi / n) * SPHERE_RADIUS
    scl = np.stack([np.full(n, 0.62 * spacing), np.full(n, 0.62 * spacing), np.full(n, 0.08 * spacing)], 1)
    opacity = np.where(rng.random(n) < 0.5, 1.0, rng.uniform(0.85, 1.0, n))

    # Project f(dir) = film colour(|dir . normal|) on the SH basis by quadrature over
    # a fixed spiral of directions (the basis is orthonormal on the sphere).
    m = 400
    dirs = _fibonacci_sphere(m)
    basis = sh_basis(dirs, SH_DEGREE)                       # (m, 16)
    facing = -(normals @ dirs.T)                            # (n, m)
    thickness = (1.6 + 0.3 * normals[:, 1] + 0.15 * normals[:, 0])[:, None]  # bands across latitude
    target = _thin_film_rgb(facing, thickness)              # (n, m, 3)
    sh = np.einsum("nmc,mk->nkc", target - 0.5, basis) * (4 * math.pi / m)
    parts.add(pos, rot, scl, opacity, sh)


def _ring(parts: _Parts, rng: np.random.Generator) -> None:
    """A tilted ring of needles around the sphere (Saturn-like), golden to pale."""
    n = 560
    radius = rng.uniform(1.45, 1.95, n)
    angle = rng.uniform(0, 2 * math.pi, n)
    tilt = math.radians(18.0)
    # Ring in the x-z plane, then tilted about the x axis and rolled a little about z.
    local = np.stack([radius * np.cos(angle), rng.normal(0, 0.012, n), radius * np.sin(angle)], 1)
    tangent = np.stack([-np.sin(angle), np.zeros(n), np.cos(angle)], 1)
    ct, st = math.cos(tilt), math.sin(tilt)
    rx = np.array([[1, 0, 0], [0, ct, -st], [0, st, ct]])
    roll = math.radians(-12.0)
    cr, sr = math.cos(roll), math.sin(roll)
    rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
    m = rz @ rx
    pos = local @ m.T + np.asarray(SPHERE_CENTER)
    direction = tangent @ m.T + rng.normal(0, 0.05, (n, 3))
    rot = _quat_z_to(direction, rng.uniform(0, math.pi, n))
    long = rng.uniform(0.3, 0.55, n)
    thin = long / rng.uniform(100.0, 180.0, n)
    scl = np.stack([thin, thin * rng.uniform(0.8, 1.0, n), long], 1)
    t = rng.random(n)[:, None]
    rgb = (1 - t) * np.array([1.0, 0.78, 0.35]) + t * np.array([1.0, 0.95, 0.85])
    opacity = rng.uniform(0.55, 1.0, n)
    parts.add(pos, rot, scl, opacity, _sh_from_rgb(rgb))


def _grass(parts: _Parts, rng: np.random.Generator) -> None:
    """Tufts of grass blades (needles) growing from the floor."""
    tufts = [  # (x, z, spread, blades, height)
        (-2.6, -0.6, 0.55, 260, 0.75),
        (-1.7, 0.3, 0.35, 120, 0.55),
        (2.2, -1.0, 0.35, 130, 0.5),
        (-0.6, 4.6, 2.6, 380, 0.9),
        (3.2, 3.4, 0.6, 160, 0.8),
    ]
    for x0, z0, spread, n, height in tufts:
        r = spread * np.sqrt(rng.random(n))
        a = rng.uniform(0, 2 * math.pi, n)
        base = np.stack([x0 + r * np.cos(a), np.full(n, FLOOR_Y), z0 + r * np.sin(a)], 1)
        lean = rng.normal(0, 0.22, (n, 2)) + 0.35 * np.stack([np.cos(a), np.sin(a)], 1) * (r / spread)[:, None]
        direction = _normalize(np.stack([lean[:, 0], -np.ones(n), lean[:, 1]], 1))
        h = height * rng.uniform(0.55, 1.0, n)
        long = h / 2.5
        pos = base + direction * (h / 2.0)[:, None]
        thin = long / rng.uniform(110.0, 220.0, n)
        scl = np.stack([thin * 2.0, thin, long], 1)  # a flat-ish blade
        rot = _quat_z_to(direction, rng.uniform(0, math.pi, n))
        t = rng.random(n)[:, None]
        rgb = (1 - t) * np.array([0.12, 0.45, 0.12]) + t * np.array([0.55, 0.8, 0.2])
        opacity = rng.uniform(0.7, 1.0, n)
        parts.add(pos, rot, scl, opacity, _sh_from_rgb(rgb))


def _panes(parts: _Parts, rng: np.random.Generator) -> None:
    """Overlapping translucent coloured sheets, one behind the other.

    Each sheet is a grid of flat gaussians (opacity 0.3..0.45) close enough to merge
    into one even, see-through pane; the sheets are staggered in depth and sideways
    so that each overlaps the next on screen.
    """
    colours = np.array([
        [0.95, 0.12, 0.18],
        [1.0, 0.62, 0.08],
        [0.18, 0.85, 0.3],
        [0.12, 0.42, 1.0],
        [0.72, 0.2, 0.95],
    ])
    sigma, step = 0.062, 0.12
    gu = np.arange(-0.42, 0.42 + 1e-9, step)   # sheet width about 1.1
    gv = np.arange(-0.54, 0.54 + 1e-9, step)   # sheet height about 1.35
    uu, vv = np.meshgrid(gu, gv, indexing="xy")
    uu, vv = uu.ravel(), vv.ravel()
    m = uu.size
    yaw = math.radians(-20.0)
    normal = np.array([math.sin(yaw), 0.0, -math.cos(yaw)])  # faces the default camera, turned a little
    axis_u = np.array([math.cos(yaw), 0.0, math.sin(yaw)])
    axis_v = np.array([0.0, 1.0, 0.0])
    for k, rgb in enumerate(colours):
        center = np.array([1.6 + 0.42 * k, -0.3 - 0.08 * k, -0.5 + 0.5 * k])
        pos = center + uu[:, None] * axis_u + vv[:, None] * axis_v + rng.normal(0, 0.004, (m, 3))
        rot = _quat_z_to(np.tile(normal, (m, 1)), rng.uniform(0, math.pi, m))
        scl = np.stack([np.full(m, sigma), np.full(m, sigma), np.full(m, sigma / 100)], 1)
        opacity = rng.uniform(0.28, 0.4, m)
        parts.add(pos, rot, scl, opacity, _sh_from_rgb(np.tile(rgb, (m, 1))))


def _petals(parts: _Parts, rng: np.random.Generator) -> None:
    """Pink petals: some drifting in the air, some lying flat on the floor."""
    n_air, n_floor = 170, 130
    air = np.stack([rng.uniform(-3.5, 3.8, n_air), rng.uniform(-1.6, 0.6, n_air), rng.uniform(-1.5, 5.0, n_air)], 1)
    floor = np.stack([rng.uniform(-3.8, 3.8, n_floor), np.full(n_floor, FLOOR_Y - 0.004),
                      rng.uniform(-1.8, 5.5, n_floor)], 1)
    pos = np.concatenate([air, floor])
    n_air_normal = _normalize(rng.normal(0, 1, (n_air, 3)))
    n_floor_normal = _normalize(np.stack([rng.normal(0, 0.05, n_floor), -np.ones(n_floor),
                                          rng.normal(0, 0.05, n_floor)], 1))
    normal = np.concatenate([n_air_normal, n_floor_normal])
    n = n_air + n_floor
    rot = _quat_z_to(normal, rng.uniform(0, math.pi, n))
    size = rng.uniform(0.035, 0.06, n)
    scl = np.stack([size, size * 0.65, size / rng.uniform(100.0, 160.0, n)], 1)
    t = rng.random(n)[:, None]
    rgb = (1 - t) * np.array([1.0, 0.55, 0.72]) + t * np.array([1.0, 0.88, 0.93])
    opacity = rng.uniform(0.3, 0.6, n)
    parts.add(pos, rot, scl, opacity, _sh_from_rgb(rgb))


def _fireflies(parts: _Parts, rng: np.random.Generator) -> None:
    """Small faint glowing dots floating above the floor."""
    n = 140
    pos = np.stack([rng.uniform(-4.0, 4.0, n), rng.uniform(-2.2, 0.7, n), rng.uniform(-1.0, 6.0, n)], 1)
    size = rng.uniform(0.012, 0.035, n)
    scl = np.stack([size, size, size], 1) * rng.uniform(0.9, 1.1, (n, 3))
    rot = _quat_z_to(_normalize(rng.normal(0, 1, (n, 3))))
    rgb = np.array([1.3, 1.05, 0.45]) * rng.uniform(0.8, 1.0, (n, 1))
    opacity = rng.uniform(0.25, 0.6, n)
    parts.add(pos, rot, scl, opacity, _sh_from_rgb(rgb))


def _near_camera(parts: _Parts, rng: np.random.Generator) -> None:
    """A handful of gaussians right in front of the default camera, some straddling
    its image plane: large on screen, they need depth clamp and the ray-based form."""
    cam = demo_camera()
    eye = cam.center
    right, down, forward = cam.R[0], cam.R[1], cam.R[2]

    def at(x, y, z):
        return eye + x * right + y * down + z * forward

    # A leaf hanging into the lower-right corner, 0.45 in front (opacity 1).
    leaf_pos = at(0.17, 0.12, 0.4)
    leaf_normal = _normalize((-0.3 * right - 0.2 * down - forward)[None, :])
    parts.add(leaf_pos[None], _quat_z_to(leaf_normal, 0.6), [[0.045, 0.016, 0.0004]], 1.0,
              _sh_from_rgb(np.array([[0.2, 0.62, 0.18]])))
    # A grass strand passing beside the camera, along the view direction, from behind
    # it to well in front: centre on the camera plane, lower left.
    strand_pos = at(-0.3, 0.2, 0.0)
    strand_dir = _normalize((forward + 0.15 * right - 0.1 * down)[None, :])
    parts.add(strand_pos[None], _quat_z_to(strand_dir), [[0.004, 0.0025, 0.5]], 1.0,
              _sh_from_rgb(np.array([[0.35, 0.7, 0.2]])))
    # A petal across the camera plane, just above the line of sight: lying almost
    # flat, it reaches from 0.25 behind the camera to 0.4 in front (a wedge at the top).
    petal_pos = at(0.04, -0.085, 0.08)
    petal_normal = down + 0.2 * right - 0.1 * forward
    parts.add(petal_pos[None], _quat_from_axes(right, petal_normal), [[0.07, 0.11, 0.0009]], 0.55,
              _sh_from_rgb(np.array([[1.0, 0.55, 0.72]])))
    # A thin blade just in front, diagonally across the lower left.
    blade_pos = at(-0.2, 0.18, 0.3)
    blade_dir = _normalize((-0.5 * right - down + 0.2 * forward)[None, :])
    parts.add(blade_pos[None], _quat_z_to(blade_dir), [[0.003, 0.0015, 0.25]], 0.9,
              _sh_from_rgb(np.array([[0.25, 0.55, 0.15]])))
    # Dust motes: soft round blobs 0.2..0.45 in front (bokeh).
    n = 5
    motes = np.stack([rng.uniform(-0.2, 0.2, n), rng.uniform(-0.15, 0.15, n), rng.uniform(0.25, 0.45, n)], 1)
    pos = eye + motes[:, :1] * right + motes[:, 1:2] * down + motes[:, 2:3] * forward
    size = rng.uniform(0.006, 0.012, n)
    parts.add(pos, _quat_z_to(np.tile(forward, (n, 1))), np.stack([size, size, size], 1),
              rng.uniform(0.2, 0.4, n), _sh_from_rgb(np.tile([[1.0, 0.95, 0.8]], (n, 1))))


# --- public API ------------------------------------------------------------------------

def demo_scene() -> Scene:
    """The built-in demo scene: 3,914 gaussians, SH degree 3, deterministic (the same
    float32 bits on every call and machine). Built once a process (about 0.15 s; a
    window, a render and a sidecar's hash each ask for it); every call gets its own
    copy of the arrays, so a caller that changes one changes nobody else's scene."""
    built = _built_once()
    return dataclasses.replace(built, positions=built.positions.copy(), rotations=built.rotations.copy(),
                               scales=built.scales.copy(), opacities=built.opacities.copy(), sh=built.sh.copy(),
                               dropped=dict(built.dropped))


@functools.cache
def _built_once() -> Scene:
    return build_demo_scene()


def build_demo_scene() -> Scene:
    """The demo scene generated now, not shared with :func:`demo_scene`'s."""
    rng = np.random.default_rng(SEED)
    parts = _Parts()
    _floor(parts, rng)
    _grass(parts, rng)
    _petals(parts, rng)
    _panes(parts, rng)
    _sphere(parts, rng)
    _ring(parts, rng)
    _fireflies(parts, rng)
    _near_camera(parts, rng)
    return parts.scene()


def demo_camera(width: int = 640, height: int = 480) -> Camera:
    """The default view of the demo scene."""
    return look_at(DEFAULT_EYE, DEFAULT_TARGET, (0.0, -1.0, 0.0),
                   width=width, height=height, fov_y_degrees=DEFAULT_FOV_Y)


def demo_cameras(width: int = 640, height: int = 480) -> list[Camera]:
    """Views around the demo scene: the default one first, then a left and a right
    orbit, a high view from behind, a close-up of the sphere and a grazing view
    just above the floor."""
    def view(eye, target, fov=DEFAULT_FOV_Y):
        return look_at(eye, target, (0.0, -1.0, 0.0), width=width, height=height, fov_y_degrees=fov)

    return [
        demo_camera(width, height),
        view((-4.2, -1.6, -2.6), (0.2, 0.0, 1.2)),          # front left
        view((5.2, -1.2, 0.2), (0.5, -0.1, 1.4)),           # right side, through the panes
        view((0.8, -3.6, 7.4), (0.0, 0.2, 1.0)),            # high, from behind
        view((0.5, -0.35, -0.9), (0.0, 0.0, 1.0), 50.0),    # close-up of the sphere
        view((0.6, 0.9, -1.6), (0.2, 0.8, 3.0)),            # grazing, just above the floor
    ]


DEMO_VIEW_NAMES = ("default", "front-left", "through-the-sheets", "high-behind", "sphere-close-up", "grazing-floor")


def demo_cameras_json() -> list[dict]:
    """:func:`demo_cameras` in INRIA ``cameras.json`` layout (``assets/demo_cameras.json``)."""
    return [camera_to_json(camera, i, name) for i, (camera, name) in enumerate(zip(demo_cameras(), DEMO_VIEW_NAMES))]


if __name__ == "__main__":  # regenerate assets/demo_cameras.json from a source checkout
    target = Path(__file__).resolve().parents[2] / "assets" / "demo_cameras.json"
    target.write_text(json_text(demo_cameras_json()), encoding="utf-8")
    print(target)
