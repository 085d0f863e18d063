"""The two sort keys of a gaussian and the stable back-to-front order of key values
(sections 9, 11).

The keys are float32, as the GPU sees the centres: the camera-space depth z of the
centre ("depth"), or its distance |p - C| from the camera centre C ("distance"). An
order is descending by key, ties in scene order. "radix" quantises the keys to 16 bits
over a range [near, far] so that numpy takes its radix sort; "float" sorts the float32
keys exactly; "auto" is radix, or float when the range cannot be quantised.
"""

from __future__ import annotations

import math
from typing import Literal, Sequence

import numpy as np

from raygs_viewer.camera.pinhole import Camera

SortMethod = Literal["auto", "radix", "float"]
#: The global sort keys: camera-space depth of the centre, or its distance from the camera.
SortKey = Literal["depth", "distance"]
SORT_KEYS = ("depth", "distance")
SORT_METHODS = ("auto", "radix", "float")


def checked_keys(keys: Sequence[str]) -> tuple[str, ...]:
    """``keys`` without repeats, in their order; ValueError on an unknown one."""
    for key in keys:
        if key not in SORT_KEYS:
            raise ValueError(f"unknown sort key {key!r}; expected one of {', '.join(SORT_KEYS)}")
    return tuple(dict.fromkeys(keys))


def check_method(method: str) -> None:
    if method not in SORT_METHODS:
        raise ValueError(f"unknown sort method {method!r}")


def snapped_centre(camera: Camera, coordinate_scale: float) -> np.ndarray:
    """(3,) float32: the camera centre C of the distance key, snapped to a grid 2^-32 of
    ``coordinate_scale`` (the scene's extent). A turn in place recomputes t from R and C,
    and C = -R^T t comes back off by rounding (1e-17 where it was 0, which float32
    keeps): the snapped centre is the same, so the keys of the turn are bit for bit the
    same. Adding 0.0 turns the -0.0 that rounds from a tiny negative into 0.0: the turn
    cache compares the bytes, and those of -0.0 and 0.0 differ."""
    step = 2.0 ** (math.frexp(max(coordinate_scale, 1e-30))[1] - 32)
    return (np.round(np.asarray(camera.center, np.float64) / step) * step + 0.0).astype(np.float32)


def camera_space(columns: np.ndarray, camera: Camera, out: np.ndarray, work: np.ndarray) -> None:
    """out[:] = (3, n) float32 mu = R p + t of the (3, n) float32 ``columns`` (x, y, z
    rows). Each axis is ((R_i0 x + R_i1 y) + R_i2 z) + t_i with every product and sum
    rounded to float32 on its own: a defined sequence of IEEE operations, which the GPU
    sort repeats bit for bit (``precise`` in GLSL), and which gives the same keys on every
    machine (a BLAS product does not: its kernels differ by CPU, with or without fused
    multiply-adds, each in its own summation order). ``work``: (n,) float32 scratch."""
    rotation, translation = camera.R.astype(np.float32), camera.t.astype(np.float32)
    for axis in range(3):
        row = out[axis]
        np.multiply(columns[0], rotation[axis, 0], out=row)
        row += np.multiply(columns[1], rotation[axis, 1], out=work)
        row += np.multiply(columns[2], rotation[axis, 2], out=work)
        row += translation[axis]


def distances(positions: np.ndarray, centre: np.ndarray, work: np.ndarray, out: np.ndarray) -> None:
    """out[:] = |p - C| of (n, 3) ``positions`` in float32, summed x, y, z in that order:
    element by element, so the same for any chunking, and independent of the camera's
    rotation. ``work``: (3, n) float32 scratch."""
    np.subtract(positions.T, centre[:, None], out=work)
    np.square(work, out=work)
    np.add(work[0], work[1], out=out)
    out += work[2]
    np.sqrt(out, out=out)


def key_values(positions: np.ndarray, camera: Camera, key: str, coordinate_scale: float) -> np.ndarray:
    """(n,) float32 ``key`` of each of (n, 3) ``positions`` seen from ``camera``, in the
    forms the chunked cull computes (the distance from the snapped centre)."""
    if key == "depth":
        mu = np.empty((3, positions.shape[0]), np.float32)
        camera_space(np.ascontiguousarray(positions.T), camera, mu, np.empty(positions.shape[0], np.float32))
        return mu[2]
    if key == "distance":
        values = np.empty(positions.shape[0], np.float32)
        distances(positions, snapped_centre(camera, coordinate_scale),
                  np.empty((3, positions.shape[0]), np.float32), values)
        return values
    raise ValueError(f"unknown sort key {key!r}; expected one of {', '.join(SORT_KEYS)}")


def quantise_scale(near: float, far: float) -> np.float32:
    """The factor :func:`quantise` multiplies ``far - value`` by: computed in float64 and
    rounded once to float32 (the GPU sort takes this very value: a GPU's division is not
    correctly rounded)."""
    return np.float32(65535.0 / (far - near))


def quantise(values: np.ndarray, near: float, far: float) -> np.ndarray:
    """(M,) uint16: 0 at ``far`` up to 65535 at ``near`` (far > near, both finite)."""
    scaled = (far - values) * quantise_scale(near, far)
    return np.minimum(scaled, np.float32(65535.0)).astype(np.uint16)  # rounding may pass 65535


def quantisable(near: float, far: float) -> bool:
    """Whether keys over [near, far] have a range to quantise (two distinct finite ends)."""
    return math.isfinite(far - near) and far > near


def stable_order(values: np.ndarray, near: float, far: float, method: SortMethod) -> np.ndarray:
    """Stable argsort of ``values``, farthest first, quantised over [near, far] (see
    :func:`sort_back_to_front`)."""
    if values.size == 0:
        return np.zeros(0, np.int64)
    if method in ("auto", "radix"):
        if quantisable(near, far):
            return np.argsort(quantise(values, near, far), kind="stable")
        if method == "radix":
            return np.arange(values.size)  # all keys equal: scene order is the stable order
    elif method != "float":
        raise ValueError(f"unknown sort method {method!r}")
    return np.argsort(-values, kind="stable")


def sort_back_to_front(depth: np.ndarray, method: SortMethod = "auto") -> np.ndarray:
    """Stable argsort of (M,) keys (depths or distances), farthest first.

    "radix" quantises depth to 16 bits over its range so numpy picks its radix sort
    (about 2x faster than float argsort at 1M); depths closer than range/65535 keep
    scene order. "float" sorts the float32 depths exactly. "auto" is radix, falling
    back to float when the range cannot be quantised (fewer than two distinct finite
    depths)."""
    if depth.size == 0:
        return np.zeros(0, np.int64)
    return stable_order(depth, float(depth.min()), float(depth.max()), method)
