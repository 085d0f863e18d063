"""The numeric kernels of camera paths, vectorised in float64 numpy: the centripetal
Catmull-Rom curve and its arc-length tables, Shoemake's squad with tangents that are
continuous in time, and the up-keeping roll of a camera.

:mod:`raygs_viewer.camera.path` puts them together; everything here works on plain
arrays so a whole video's frames are evaluated at once. The quaternion algebra squad is
built on (log, exp, slerp) is :mod:`raygs_viewer.camera.rotation`'s.
"""

from __future__ import annotations

import math

import numpy as np

from raygs_viewer.camera.rotation import qconj, qexp, qlog_short, qmul, row_norms, slerp_along

#: Cells of each segment's arc-length table. The inverse is a cubic Hermite in the exact
#: speeds at the cell ends plus a Newton step, so 32 cells give speed errors far below
#: the ~1e-3 that linear inversion of a 256-point table would leave.
ARC_CELLS = 32
#: Segments tabulated at once (bounds the temporary memory of a 100 000-keyframe path).
_CHUNK = 2048

#: Forward within this angle of +-up has no defined roll: the plain squad orientation is
#: kept there, blended smoothly into the up-keeping one by POLE_BLEND.
POLE_KEEP = math.radians(1.0)
POLE_BLEND = math.radians(5.0)


# --------------------------------------------------------------------------- positions


def catmull_rom(points: np.ndarray, alpha: float, tension: float, loop: bool) -> np.ndarray:
    """(S, 4, 3) polynomial coefficients c0..c3 (p(u) = c0 + c1 u + c2 u^2 + c3 u^3,
    u in [0, 1]) of the Catmull-Rom segments through ``points`` (K, 3): K - 1 segments,
    or K for a loop (the last returns to point 0).

    Knots step by chord^alpha (0.5: centripetal, no cusps or self-intersections within
    a segment). An open end, or a neighbour that coincides with its keyframe, is
    replaced by the reflection of the other neighbour, so the tangent there is along the
    chord; a zero chord is a segment that stays put. Tangents are scaled by
    1 - tension (Kochanek-Bartels tension)."""
    points = np.asarray(points, dtype=np.float64)
    count = len(points)
    segments = count if loop else count - 1
    if segments < 1:
        return np.zeros((0, 4, 3))
    ends = np.roll(points, -1, axis=0)[:segments]
    chord = ends - points[:segments]
    length = np.linalg.norm(chord, axis=1)
    # Relative threshold: keyframes a rounding error apart are the same place.
    scale = max(float(length.max()), 1e-300)
    knot = np.where(length > 1e-12 * scale, length ** alpha, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        velocity = np.where(knot[:, None] > 0, chord / knot[:, None], 0.0)   # per knot unit

    # Node k sits between segment k - 1 (behind) and segment k (ahead).
    nodes = count
    ahead_v = np.zeros((nodes, 3))
    ahead_k = np.zeros(nodes)
    behind_v = np.zeros((nodes, 3))
    behind_k = np.zeros(nodes)
    ahead_v[:segments], ahead_k[:segments] = velocity, knot
    if loop:
        behind_v[:], behind_k[:] = np.roll(velocity, 1, axis=0), np.roll(knot, 1)
    else:
        behind_v[1:], behind_k[1:] = velocity, knot
    both = (ahead_k > 0) & (behind_k > 0)
    total = np.where(both, ahead_k + behind_k, 1.0)
    # Non-uniform Catmull-Rom tangent: both one-sided slopes minus the slope across both.
    tangent = np.where(both[:, None],
                       behind_v + ahead_v - (behind_v * behind_k[:, None] + ahead_v * ahead_k[:, None]) / total[:, None],
                       np.where((ahead_k > 0)[:, None], ahead_v, behind_v))
    tangent *= 1.0 - tension

    start = points[:segments]
    m0 = tangent[:segments] * knot[:, None]
    m1 = np.roll(tangent, -1, axis=0)[:segments] * knot[:, None]
    return np.stack([start, m0, 3.0 * chord - 2.0 * m0 - m1, -2.0 * chord + m0 + m1], axis=1)


def polynomial(coefficients: np.ndarray, segment: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(M, 3) points of segments ``segment`` (M,) at parameters ``u`` (M,)."""
    c = coefficients[segment]
    u = u[:, None]
    return c[:, 0] + u * (c[:, 1] + u * (c[:, 2] + u * c[:, 3]))


def _speeds(coefficients: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(S, U) |dp/du| of every segment at every ``u`` (U,)."""
    c = coefficients
    u = u[None, :, None]
    derivative = c[:, None, 1] + u * (2.0 * c[:, None, 2] + 3.0 * u * c[:, None, 3])
    return row_norms(derivative)


def arc_tables(coefficients: np.ndarray, cells: int = ARC_CELLS) -> tuple[np.ndarray, np.ndarray]:
    """Per segment, the arc length at the cell ends u = j / cells, (S, cells + 1) with
    column 0 zero and the last the segment's length (Simpson's rule per cell), and the
    cells' end slopes for :func:`invert_arc`, (S, cells, 2), dimensionless."""
    segments = len(coefficients)
    h = 1.0 / cells
    u = np.linspace(0.0, 1.0, 2 * cells + 1)
    lengths = np.zeros((segments, cells + 1))
    slopes = np.ones((segments, cells, 2))
    for first in range(0, segments, _CHUNK):
        part = slice(first, min(first + _CHUNK, segments))
        speed = _speeds(coefficients[part], u)
        node, middle = speed[:, 0::2], speed[:, 1::2]
        cell = h / 6.0 * (node[:, :-1] + 4.0 * middle + node[:, 1:])
        lengths[part, 1:] = np.cumsum(cell, axis=1)
        # du/dl = 1 / speed at each end, in units of the cell's mean slope h / cell; held
        # within [0, 3] (Fritsch-Carlson) so the inverse stays monotone where the curve
        # stops (tension 1 ends: speed 0).
        with np.errstate(divide="ignore", invalid="ignore"):
            start = np.where(cell > 0, cell / (h * node[:, :-1]), 1.0)
            end = np.where(cell > 0, cell / (h * node[:, 1:]), 1.0)
        slopes[part, :, 0] = np.clip(np.nan_to_num(start, nan=1.0, posinf=3.0), 0.0, 3.0)
        slopes[part, :, 1] = np.clip(np.nan_to_num(end, nan=1.0, posinf=3.0), 0.0, 3.0)
    return lengths, slopes


def invert_arc(lengths: np.ndarray, slopes: np.ndarray, segment: np.ndarray, fraction: np.ndarray,
               coefficients: np.ndarray | None = None) -> np.ndarray:
    """(M,) curve parameters u at which segments ``segment`` (M,) have covered
    ``fraction`` (M,) in [0, 1] of their length (a zero-length segment: u = fraction).
    With the segments' ``coefficients``, refined by a Newton step."""
    table = lengths[segment]
    cells = table.shape[1] - 1
    target = fraction * table[:, -1]
    j = np.minimum(np.count_nonzero(table[:, 1:-1] <= target[:, None], axis=1), cells - 1)
    rows = np.arange(len(segment))
    low, high = table[rows, j], table[rows, j + 1]
    width = high - low
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(width > 0, np.clip((target - low) / width, 0.0, 1.0), fraction * cells - j)
    t = np.clip(t, 0.0, 1.0)
    k0, k1 = slopes[segment, j, 0], slopes[segment, j, 1]
    t2, t3 = t * t, t * t * t
    within = (t3 - 2.0 * t2 + t) * k0 + (-2.0 * t3 + 3.0 * t2) + (t3 - t2) * k1
    u = (j + within) / cells
    if coefficients is not None:
        # Newton on the exact arc length from the cell start (3-point Gauss-Legendre,
        # exact to ~h^6), bracketed by the cell and bisecting where Newton would leave the
        # bracket: where the curve brakes to a stop (tension 1), u(l) ~ sqrt(l) and the
        # cubic guess alone is off by percent.
        c = coefficients[segment]
        lo, hi = j / cells, (j + 1) / cells
        tolerance = 1e-10 * table[:, -1]
        for _ in range(_NEWTON_STEPS):
            span = u - j / cells
            covered = np.zeros_like(u)
            for x, w in _GAUSS3:
                covered += w * _speed_at(c, j / cells + x * span)
            residual = low + span * covered - target
            done = np.abs(residual) <= tolerance
            if np.all(done):
                break
            lo, hi = np.where(residual < 0, u, lo), np.where(residual > 0, u, hi)
            speed = _speed_at(c, u)
            with np.errstate(divide="ignore", invalid="ignore"):
                guess = u - residual / speed
            u = np.where(done, u, np.where((guess >= lo) & (guess <= hi), guess, 0.5 * (lo + hi)))
    flat = table[:, -1] <= 0
    return np.where(flat, fraction, u)


_NEWTON_STEPS = 12
_GAUSS3 = ((0.5 - math.sqrt(0.15), 5.0 / 18.0), (0.5, 8.0 / 18.0), (0.5 + math.sqrt(0.15), 5.0 / 18.0))


def _speed_at(c: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(M,) |dp/du| of polynomials c (M, 4, 3) at u (M,)."""
    u = u[:, None]
    return row_norms(c[:, 1] + u * (2.0 * c[:, 2] + 3.0 * u * c[:, 3]))


# --------------------------------------------------------------------------- tangents in time


def time_tangents(ahead: np.ndarray, behind: np.ndarray, ahead_time: np.ndarray,
                  behind_time: np.ndarray) -> np.ndarray:
    """Rates of change at the nodes (N, ...) from the change over the segment ahead and
    the one behind (N, ...) and their durations (N,): the change over both spans divided
    by their time, or the one-sided rate where a span is missing or takes no time (an
    open end, a cut), so a curve built on them is C1 in time."""
    a = (ahead_time > 0).reshape((-1,) + (1,) * (ahead.ndim - 1))
    b = (behind_time > 0).reshape(a.shape)
    ta = ahead_time.reshape(a.shape)
    tb = behind_time.reshape(a.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.where(a & b, (ahead + behind) / (ta + tb),
                        np.where(a, ahead / ta, np.where(b, behind / tb, 0.0)))
    return np.nan_to_num(rate)


def hermite(start, end, s, *, start_rate, end_rate, duration):
    """Cubic Hermite values at segment fractions ``s`` of segments that last ``duration``,
    given the rates per unit time at their ends."""
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * start + (s3 - 2 * s2 + s) * duration * start_rate
            + (-2 * s3 + 3 * s2) * end + (s3 - s2) * duration * end_rate)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of (M, 3) arrays (np.cross costs ~10x more on the few rows pose_at has)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


# --------------------------------------------------------------------------- squad


def squad_controls(q: np.ndarray, durations: np.ndarray, tension: float, loop: bool) -> tuple[np.ndarray, np.ndarray]:
    """Shoemake's inner control quaternions of the nodes ``q`` (N, 4), aligned, N =
    segments + 1 (a loop repeats node 0 at the end): ``out`` (N, 4), the control leaving
    each node, and ``into`` (N, 4), the one arriving. With the segments' ``durations``
    (N - 1,), the angular velocity at each node is the same on both sides (C1 in time,
    uneven durations included). Tension 1: plain slerp between keyframes (corners at them)."""
    segments = len(q) - 1
    ahead = np.zeros((len(q), 3))
    behind = np.zeros((len(q), 3))
    ahead_time = np.zeros(len(q))
    behind_time = np.zeros(len(q))
    steps = qlog_short(qmul(qconj(q[:-1]), q[1:]))            # (S, 3) in each start's frame
    back = qlog_short(qmul(qconj(q[1:]), q[:-1]))             # (S, 3) in each end's frame
    ahead[:-1], ahead_time[:-1] = steps, durations
    behind[1:], behind_time[1:] = -back, durations
    if loop and segments > 0:
        ahead[-1], ahead_time[-1] = ahead[0], ahead_time[0]
        behind[0], behind_time[0] = behind[-1], behind_time[-1]
    rate = time_tangents(ahead, behind, ahead_time, behind_time)
    # d squad / ds is q (ahead + 2 log(q^-1 out)) at a segment's start and
    # q (behind - 2 log(q^-1 into)) at its end; both must be q * rate * duration. Tension
    # blends that towards each segment's own slerp (controls on the nodes).
    keep = 0.5 * (1.0 - tension)
    out = qmul(q, qexp(keep * (rate * ahead_time[:, None] - ahead) * (ahead_time > 0)[:, None]))
    into = qmul(q, qexp(-keep * (rate * behind_time[:, None] - behind) * (behind_time > 0)[:, None]))
    return out, into


def squad(q0, q1, out0, into1, s):
    """Squad between aligned (M, 4) quaternions q0 -> q1 with their controls, at s (M,)."""
    return slerp_along(slerp_along(q0, q1, s), slerp_along(out0, into1, s), 2.0 * s * (1.0 - s))


# --------------------------------------------------------------------------- roll about up


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped into [-pi, pi)."""
    return np.mod(angle + math.pi, 2.0 * math.pi) - math.pi


def level_axes(forward: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For (M, 3) unit forwards: the roll-free right and down axes (M, 3) (right
    perpendicular to up, as rotation.level_rotation builds them) and sin of forward's
    angle to the up axis (M,); right is arbitrary where that is 0."""
    right = cross(forward, up)
    sine = row_norms(right)
    fallback = cross(forward, np.where(np.abs(forward[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]]))
    right = np.where(sine[:, None] > 1e-12, right, fallback)
    right /= row_norms(right)[:, None]
    return right, cross(forward, right), sine


def roll_of(R: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll angles (M,) of rotations R (M, 3, 3) about their forward (0: camera x
    perpendicular to up; positive turns x towards the level down axis) and sin of
    forward's angle to up (M,)."""
    right, down, sine = level_axes(R[:, 2], up)
    x = R[:, 0]
    return np.arctan2(np.sum(x * down, axis=1), np.sum(x * right, axis=1)), sine


def pole_weight(sine: np.ndarray) -> np.ndarray:
    """How much of the roll correction applies (M,): 0 within POLE_KEEP of +-up, 1
    beyond POLE_BLEND, smoothstep between."""
    lo, hi = math.sin(POLE_KEEP), math.sin(POLE_BLEND)
    x = np.clip((sine - lo) / (hi - lo), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def with_roll(R: np.ndarray, roll: np.ndarray, up: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Rotations R (M, 3, 3) turned about their own forward until their roll is ``roll``
    (M,), by ``weight`` (M,) times the pole weight of the way (forward is kept exactly).
    Proper rotations out."""
    current, sine = roll_of(R, up)
    turn = weight * pole_weight(sine) * wrap(roll - current)
    f = R[:, 2] / row_norms(R[:, 2])[:, None]
    x = R[:, 0]
    c, s = np.cos(turn)[:, None], np.sin(turn)[:, None]
    x = c * x + s * cross(f, x)
    x -= np.sum(x * f, axis=1, keepdims=True) * f
    x /= row_norms(x)[:, None]
    return np.stack([x, cross(f, x), f], axis=1)
