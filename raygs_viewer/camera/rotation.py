"""Rotations in float64 numpy: quaternions (w, x, y, z) and matrices, the level
(roll-free) rotation a camera looks along, and yaw and pitch that stop short of the
poles.

This is the project's one home of quaternion maths. A smooth flight's slerp is
scipy's (:mod:`scipy.spatial.transform`); what stays here is what scipy computes with
other roundings or other signs, and whose every bit reaches a rendered image: the
camera paths of render-path and the float64 reference renderer. Each function says
where scipy differs."""

from __future__ import annotations

import math

import numpy as np

#: Level rotations keep forward at least this far from the up axis (yaw and pitch stay defined).
POLE_MARGIN = math.radians(1.0)


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """(N, 4) unit quaternions (w, x, y, z) -> (N, 3, 3) rotation matrices, in q's dtype.

    Not scipy's ``Rotation.as_matrix``: that one normalises q again and sums
    w² + x² - y² - z² on the diagonal, so its matrices differ in the last bits (and are
    float64 only); the reference renderer's gaussians and the camera paths' rotations
    would move."""
    w, x, y, z = (q[:, i] for i in range(4))
    m = np.empty(q.shape[:1] + (3, 3), dtype=q.dtype)
    m[:, 0, 0] = 1 - 2 * (y * y + z * z)
    m[:, 0, 1] = 2 * (x * y - w * z)
    m[:, 0, 2] = 2 * (x * z + w * y)
    m[:, 1, 0] = 2 * (x * y + w * z)
    m[:, 1, 1] = 1 - 2 * (x * x + z * z)
    m[:, 1, 2] = 2 * (y * z - w * x)
    m[:, 2, 0] = 2 * (x * z - w * y)
    m[:, 2, 1] = 2 * (y * z + w * x)
    m[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return m


def is_rotation(matrix: np.ndarray, tolerance: float) -> bool:
    """Whether the (3, 3) float64 ``matrix`` is a proper rotation to ``tolerance`` (the
    largest entry of M Mᵀ - I): a scaled, sheared or mirrored matrix is not."""
    # Entries of a rotation lie in [-1, 1]: bounded first, the product cannot overflow.
    return bool(matrix.shape == (3, 3) and np.abs(matrix).max() <= 2
                and np.abs(matrix @ matrix.T - np.eye(3)).max() <= tolerance and np.linalg.det(matrix) > 0)


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` (right-handed) about the unit vector ``axis``."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return c * np.eye(3) + s * k + (1.0 - c) * np.outer(axis, axis)


def orthonormalize(R: np.ndarray) -> np.ndarray:
    """Nearest proper rotation that keeps the forward row's direction exactly.

    Keeping forward (rather than an SVD projection) matters in orbit mode: the target
    lies on that axis, so it stays on the image centre however long the session.
    """
    f = R[2] / np.linalg.norm(R[2])
    r = R[0] - np.dot(R[0], f) * f
    r /= np.linalg.norm(r)
    return np.stack([r, np.cross(f, r), f])  # rows right, down, forward with right x down = forward


def level_rotation(forward: np.ndarray, up: np.ndarray, right_hint: np.ndarray | None = None) -> np.ndarray:
    """World-to-camera rotation looking along ``forward`` with no roll about ``up``.

    Forward is tilted to at most 89 degrees from the horizon (the pole margin), so the
    result is always something yaw/pitch can carry on from.
    """
    f = forward / np.linalg.norm(forward)
    elevation = math.asin(max(-1.0, min(1.0, float(np.dot(f, up)))))
    elevation = max(-(math.pi / 2 - POLE_MARGIN), min(math.pi / 2 - POLE_MARGIN, elevation))
    horizontal = f - np.dot(f, up) * up
    if np.linalg.norm(horizontal) < 1e-9:
        # Straight along the up axis: the only hint of a heading left is the old right
        # axis (horizontal here, being perpendicular to forward).
        hint = np.array([1.0, 0.0, 0.0]) if right_hint is None else right_hint
        hint = hint - np.dot(hint, up) * up
        if np.linalg.norm(hint) < 1e-9:
            hint = np.cross(up, [0.0, 0.0, 1.0]) if abs(up[2]) < 0.9 else np.cross(up, [1.0, 0.0, 0.0])
        horizontal = np.cross(up, hint / np.linalg.norm(hint))  # = forward of a level camera with that right
    horizontal /= np.linalg.norm(horizontal)
    f = math.cos(elevation) * horizontal + math.sin(elevation) * up
    right = np.cross(f, up)  # camera +y (down) is -up for a level camera
    right /= np.linalg.norm(right)
    return orthonormalize(np.stack([right, np.cross(f, right), f]))


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method, which
    picks the largest diagonal term so no branch divides by a tiny number).

    Not scipy's ``Rotation.from_matrix``: its variant of the same method differs in the
    last bit for most rotations, and a camera path's pacing and squad start from these
    quaternions."""
    m = R
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q, dtype=np.float64)
    return q / np.linalg.norm(q)


def yaw_pitch(R: np.ndarray, up: np.ndarray, yaw: float, pitch: float) -> np.ndarray:
    """World-to-camera ``R`` (3, 3) turned by ``yaw`` radians about the unit world ``up``
    (> 0: the view turns right) and then ``pitch`` radians about the camera x axis
    (> 0: the view tilts up), forward kept at least :data:`POLE_MARGIN` from up and its
    opposite. Both keep the camera x axis's angle to up, so a camera's roll neither
    grows nor vanishes."""
    yaw %= 2 * math.pi  # a huge turn: keep sin/cos accurate
    # Yaw right = forward towards right = a negative turn about up (right x forward = up).
    R = R @ axis_rotation(up, -yaw).T
    R = orthonormalize(R)

    # Pitch about camera x: forward moves in the plane spanned by forward and camera
    # up (g). There f.u = A sin(psi) with psi = psi0 + phi, so the pole limit is a
    # clamp on psi; with roll, A < 1 and the pole is farther than psi = 89 degrees.
    f, g = R[2], -R[1]
    phi = pitch
    p, q = float(np.dot(f, up)), float(np.dot(g, up))
    if math.hypot(p, q) > 1e-12:
        psi0 = math.atan2(p, q)
        limit = math.pi / 2 - POLE_MARGIN
        if abs(psi0) <= math.pi / 2:
            lo, hi = -limit, limit
        else:
            # Upside down relative to up: the allowed band is the one through 180 deg.
            psi0 %= 2 * math.pi
            lo, hi = math.pi - limit, math.pi + limit
        # Already inside the margin (a camera looking straight down): allow moving out,
        # never further in.
        psi = max(min(lo, psi0), min(max(hi, psi0), psi0 + phi))
        phi = psi - psi0
    else:
        phi %= 2 * math.pi  # rolled 90 degrees: pitch cannot reach the pole
    c, s = math.cos(phi), math.sin(phi)
    f_new, g_new = c * f + s * g, c * g - s * f
    return orthonormalize(np.stack([R[0], -g_new, f_new]))


# --------------------------------------------------------------------------- quaternion algebra
# Vectorised over (..., 4) quaternions for the camera paths' squad. Not scipy's Rotation:
# it composes with another order of operations (other last bits) and its log, as_rotvec,
# always takes the short way round, while squad's inner slerps must follow the signs the
# path aligned.


def row_norms(v: np.ndarray) -> np.ndarray:
    """(...,) Euclidean lengths of the last axis of ``v`` (..., k)."""
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products of (..., 4) quaternions (w, x, y, z): matrix(a b) = matrix(a) matrix(b)."""
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bw - ax * bx - ay * by - az * bz
    out[..., 1] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 2] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 3] = aw * bz + ax * by - ay * bx + az * bw
    return out


def qconj(q: np.ndarray) -> np.ndarray:
    """Conjugates of (..., 4) quaternions: the inverse rotations of unit ones."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def qlog(q: np.ndarray) -> np.ndarray:
    """(..., 3) logs of unit quaternions (half the rotation vector), along q's own sign."""
    v = q[..., 1:]
    norm = row_norms(v)
    half = np.arctan2(norm, q[..., 0])
    # half / sin(half) -> 1 as the angle vanishes; norm = sin(half).
    factor = np.where(norm > 1e-12, half / np.where(norm > 1e-12, norm, 1.0), 1.0 / np.maximum(q[..., 0], 1e-300))
    return v * factor[..., None]


def qlog_short(q: np.ndarray) -> np.ndarray:
    """Like :func:`qlog` but the short way round (q and -q are one rotation)."""
    return qlog(np.where(q[..., :1] < 0, -q, q))


def qexp(v: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions exp(v) of (..., 3) pure quaternions."""
    half = row_norms(v)
    sinc = np.where(half > 1e-8, np.sin(half) / np.where(half > 1e-8, half, 1.0), 1.0 - half * half / 6.0)
    return np.concatenate([np.cos(half)[..., None], v * sinc[..., None]], axis=-1)


def slerp_along(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Slerp of (M, 4) quaternions at fractions ``s`` (M,) WITHOUT choosing a sign: the
    caller aligns a and b (squad's inner slerps must follow the aligned control points)."""
    step = qlog(qmul(qconj(a), b))
    return qmul(a, qexp(step * s[:, None]))


def align_signs(q: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions, each negated where needed so that consecutive ones are in the
    same hemisphere (dot >= 0): slerp then never takes the long way round."""
    q = np.array(q, dtype=np.float64)
    for i in range(1, len(q)):
        if np.dot(q[i - 1], q[i]) < 0:
            q[i] = -q[i]
    return q
