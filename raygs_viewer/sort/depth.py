"""Per-frame CPU work before drawing: conservative culling and the global sort (sections 9, 11).

The order is back to front by one key per gaussian: the camera-space depth z of the
centre ("depth") or its distance |mu| from the camera centre ("distance"),
descending, ties kept in scene order (both sorts are stable), so the GL renderer and
the float64 reference composite the same sequence.
"""

from __future__ import annotations

import math
import threading
from typing import Literal, Sequence

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.model import Scene

SortMethod = Literal["auto", "radix", "float"]
#: The global sort keys: camera-space depth of the centre, or its distance from the camera.
SortKey = Literal["depth", "distance"]
SORT_KEYS = ("depth", "distance")


class DepthSorter:
    """Caches what culling needs per scene, then culls and sorts for any camera and p_min.

    The N-sized intermediates of culling live in scratch arrays made on first use and
    reused by every later call, so a frame allocates only its M-sized results. A lock
    serialises callers that share one sorter (the window's sort thread and screenshots).
    """

    def __init__(self, scene: Scene):
        self.positions = scene.positions
        self.max_scale = scene.scales.max(axis=1) if scene.count else np.zeros(0, np.float32)
        with np.errstate(divide="ignore"):
            self.log_opacity = np.log(scene.opacities)  # -inf for opacity 0: always culled
        # float32 camera transforms lose ~1e-7 of the coordinates' magnitude: widen the
        # culling bounds by that much so rounding never drops a visible gaussian.
        self.coordinate_scale = float(np.abs(self.positions).max()) if scene.count else 0.0
        self._lock = threading.RLock()
        self._scratch: _Scratch | None = None
        self._support: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None

    def support_radius(self, p_min: float) -> np.ndarray:
        """(N,) float32 world-space radius of a sphere that holds every peak point with
        opacity >= p_min: the kappa-ellipsoid fits in a sphere of sqrt(kappa)*max(s);
        NaN-free, 0 where kappa <= 0 (those are culled separately)."""
        return self._support_for(p_min)[1]

    def _support_for(self, p_min: float) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """(p_min, support radius, sqrt(max(kappa, 0)), opacity > p_min), cached for the
        last p_min: they change only with it."""
        if self._support is None or self._support[0] != p_min:
            kappa = 2.0 * (self.log_opacity - np.float32(math.log(p_min)))
            root_kappa = np.sqrt(np.maximum(kappa, 0.0))
            with np.errstate(over="ignore"):  # absurd scales give inf: a sphere that culls nothing
                radius = root_kappa * self.max_scale
            self._support = (p_min, radius, root_kappa, self.log_opacity > np.float32(math.log(p_min)))
        return self._support

    def order(self, camera: Camera, p_min: float, method: SortMethod = "auto", *,
              dilation: float | None = 0.0, cull_cameras: Sequence[Camera] | None = None,
              key: SortKey = "depth") -> np.ndarray:
        """(M,) uint32 indices of the gaussians that may be visible, back to front by
        ``key``: :meth:`cull`, then :meth:`sort` (see them for the arguments)."""
        return self.orders(camera, p_min, method, dilation=dilation, cull_cameras=cull_cameras, keys=(key,))[key]

    def orders(self, camera: Camera, p_min: float, method: SortMethod = "auto", *,
               dilation: float | None = 0.0, cull_cameras: Sequence[Camera] | None = None,
               keys: Sequence[SortKey] = ("depth",)) -> dict[str, np.ndarray]:
        """{key: order} for each of ``keys``: one :meth:`cull`, then one :meth:`sort` per
        distinct key (the A/B split view may show two keys of one view). Each order is
        what :meth:`order` returns for that key."""
        for key in keys:
            if key not in SORT_KEYS:
                raise ValueError(f"unknown sort key {key!r}; expected one of {', '.join(SORT_KEYS)}")
        with self._lock:
            visible = self.cull(camera, p_min, dilation=dilation, cull_cameras=cull_cameras)
            return {key: self.sort(camera, visible, method, key=key) for key in dict.fromkeys(keys)}

    def cull(self, camera: Camera, p_min: float, *, dilation: float | None = 0.0,
             cull_cameras: Sequence[Camera] | None = None) -> np.ndarray:
        """(M,) int64 indices, ascending, of the gaussians that may be visible.

        A gaussian is dropped only when it cannot reach any pixel: opacity <= p_min
        (kappa <= 0), its support sphere entirely behind the camera plane, or entirely
        outside one side plane of the view frustum. ``dilation`` (from
        :meth:`RenderSettings.cull_dilation`) widens each support sphere by
        sqrt(kappa) * dilation * |mu|, the most a pixel filter of that standard deviation
        per unit distance adds; None keeps every gaussian in front of the camera plane
        (for footprints no sphere bounds, such as EWA's).

        ``cull_cameras``: keep what any of these cameras may see, instead of what
        ``camera`` may see (stereo: one sort from the midpoint between the eyes serves both).
        """
        count = self.positions.shape[0]
        if count == 0:
            return np.zeros(0, np.int64)
        with self._lock:
            if self._scratch is None:
                self._scratch = _Scratch(count)
            scratch = self._scratch
            cameras = tuple(cull_cameras or (camera,))
            for index, culling in enumerate(cameras):
                self._may_be_seen(culling, p_min, dilation, scratch)
                if index == 0:
                    scratch.union[:] = scratch.keep
                else:
                    scratch.union |= scratch.keep
            return np.flatnonzero(scratch.union)

    def sort(self, camera: Camera, visible: np.ndarray, method: SortMethod = "auto",
             key: SortKey = "depth") -> np.ndarray:
        """(M,) uint32: ``visible`` (indices) back to front by ``key`` seen from ``camera``:
        its camera-space depth z, or its distance from the camera centre."""
        R = camera.R.astype(np.float32)
        if key == "depth":
            values = self.positions[visible] @ R[2] + np.float32(camera.t[2])
        elif key == "distance":
            # |R p + t| rather than |p - C|: the same float32 form as the cull and the GPU.
            mu = self.positions[visible] @ R.T + camera.t.astype(np.float32)
            values = np.sqrt(np.einsum("ij,ij->i", mu, mu))
        else:
            raise ValueError(f"unknown sort key {key!r}; expected one of {', '.join(SORT_KEYS)}")
        return visible[sort_back_to_front(values, method)].astype(np.uint32)

    def _may_be_seen(self, camera: Camera, p_min: float, dilation: float | None, scratch: "_Scratch") -> None:
        """Sets ``scratch.keep`` to whether each support sphere may reach a pixel of ``camera``."""
        mu, radius, product, term, keep, test = (scratch.mu, scratch.radius, scratch.product, scratch.term,
                                                 scratch.keep, scratch.test)
        np.matmul(self.positions, camera.R.astype(np.float32).T, out=mu)
        mu += camera.t.astype(np.float32)
        slack = np.float32(1e-5 * (self.coordinate_scale + float(np.abs(camera.t).max())) + 1e-6)
        _, support, root_kappa, opaque_enough = self._support_for(p_min)
        radius[:] = support
        if dilation:
            np.einsum("ij,ij->i", mu, mu, out=term)
            np.sqrt(term, out=term)
            term *= root_kappa
            term *= np.float32(dilation)
            radius += term
        radius *= np.float32(1.0 + 1e-5)
        radius += slack
        np.negative(radius, out=radius)  # from here on: -radius, the bound every test compares with
        x, y, z = mu[:, 0], mu[:, 1], mu[:, 2]
        np.greater(z, radius, out=keep)
        keep &= opaque_enough
        if dilation is None:
            return
        # Side planes through the camera centre, at the image border (pixel centres lie
        # half a pixel inside it), with unit normals pointing into the frustum.
        for coordinate, a, b, extent in ((x, camera.fx, camera.cx, camera.width),
                                         (y, camera.fy, camera.cy, camera.height)):
            for normal in ((a, b), (-a, extent - b)):
                n = np.float32(1.0 / math.hypot(*normal))
                np.multiply(coordinate, np.float32(normal[0]) * n, out=product)
                np.multiply(z, np.float32(normal[1]) * n, out=term)
                product += term
                np.greater(product, radius, out=test)
                keep &= test


class _Scratch:
    """The N-sized working arrays of :meth:`DepthSorter.cull`."""

    def __init__(self, count: int):
        self.mu = np.empty((count, 3), np.float32)
        self.radius, self.product, self.term = (np.empty(count, np.float32) for _ in range(3))
        self.keep, self.test, self.union = (np.empty(count, bool) for _ in range(3))


def sort_back_to_front(depth: np.ndarray, method: SortMethod = "auto") -> np.ndarray:
    """Stable argsort of (M,) keys (depths or distances), farthest first.

    "radix" quantises depth to 16 bits over its range so numpy picks its radix sort
    (about 2x faster than float argsort at 1M); depths closer than range/65535 keep
    scene order. "float" sorts the float32 depths exactly. "auto" is radix, falling
    back to float when the range cannot be quantised (fewer than two distinct finite
    depths)."""
    if depth.size == 0:
        return np.zeros(0, np.int64)
    if method in ("auto", "radix"):
        near, far = float(depth.min()), float(depth.max())
        if math.isfinite(far - near) and far > near:
            scaled = (far - depth) * np.float32(65535.0 / (far - near))
            key = np.minimum(scaled, np.float32(65535.0)).astype(np.uint16)  # rounding may pass 65535
            return np.argsort(key, kind="stable")
        if method == "radix":
            return np.arange(depth.size)  # all depths equal: scene order is the stable order
    elif method != "float":
        raise ValueError(f"unknown sort method {method!r}")
    return np.argsort(-depth, kind="stable")
