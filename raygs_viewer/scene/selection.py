"""What a selection tool picks out of a scene, as an (N,) bool mask: a box or a sphere in
the scene, a range of one attribute (SuperSplat's "Splat Data" histograms), or a shape
drawn on a view: a rectangle, a polygon (a lasso is a polygon of many points) or a
brush stroke, holding the gaussians whose centre the view projects inside ("through":
hidden ones included); or the rows a selection through the view found (:class:`Rows`:
the gaussians the view shows under a shape, or the one a click's pixel shows most).

Every shape is a frozen value with ``to_json`` and :func:`shape_from_json`, so an edit
document records it and replays it to the same mask. Screen shapes carry their camera
(pose and intrinsics, float64 as given) and are in that camera's continuous pixel
coordinates: pixel (u, v) covers [u, u + 1) x [v, v + 1), its centre at (u + 0.5, v + 0.5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Literal, Union

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.filters import CropBox, CropSphere, KeepValues
from raygs_viewer.scene.model import Scene

#: 4/3 pi: an ellipsoid's volume from its three semi-axes (one standard deviation each).
_BALL = 4.0 / 3.0 * math.pi
#: The base colour of SH coefficient 0 (maths page, section 2).
SH_C0 = 0.28209479177387814

#: The attributes a range selects by, as their histograms name them.
ATTRIBUTES = ("opacity", "largest scale", "volume", "distance", "red", "green", "blue")


def attribute_values(scene: Scene, attribute: str) -> np.ndarray:
    """(N,) float64 values of ``attribute`` (:data:`ATTRIBUTES`): opacity as rendered;
    the largest axis and the volume (4/3 pi s0 s1 s2) of the scene's scales; the
    distance of each centre from the scene's centre (the median of the centres, which
    floaters far out do not move); the base colour's red, green and blue, 0.5 + C0 f_dc."""
    if attribute == "opacity":
        return scene.opacities.astype(np.float64)
    scales = scene.scales.astype(np.float64)
    if attribute == "largest scale":
        return scales.max(axis=1) if scene.count else np.zeros(0)
    if attribute == "volume":
        return _BALL * np.prod(scales, axis=1)
    if attribute == "distance":
        positions = scene.positions.astype(np.float64)
        centre = np.median(positions, axis=0) if scene.count else np.zeros(3)
        return np.linalg.norm(positions - centre, axis=1)
    if attribute in ("red", "green", "blue"):
        return 0.5 + SH_C0 * scene.sh[:, 0, ("red", "green", "blue").index(attribute)].astype(np.float64)
    raise ValueError(f"unknown attribute {attribute!r}: one of {', '.join(ATTRIBUTES)}")


@dataclass(frozen=True)
class Box:
    """Centres inside the axis-aligned box (edges included): ``filters.CropBox``'s rule."""

    low: tuple[float, float, float]
    high: tuple[float, float, float]

    def mask(self, scene: Scene) -> np.ndarray:
        return CropBox(self.low, self.high).keeps(KeepValues.of_scene(scene))

    def to_json(self) -> dict:
        return {"kind": "box", "low": list(map(float, self.low)), "high": list(map(float, self.high))}


@dataclass(frozen=True)
class Sphere:
    """Centres within ``radius`` of ``centre``: ``filters.CropSphere``'s rule."""

    centre: tuple[float, float, float]
    radius: float

    def mask(self, scene: Scene) -> np.ndarray:
        return CropSphere(self.centre, self.radius).keeps(KeepValues.of_scene(scene))

    def to_json(self) -> dict:
        return {"kind": "sphere", "centre": list(map(float, self.centre)), "radius": float(self.radius)}


@dataclass(frozen=True)
class Range:
    """Gaussians whose ``attribute`` lies in ``low``..``high`` (both included)."""

    attribute: str
    low: float
    high: float

    def mask(self, scene: Scene) -> np.ndarray:
        values = attribute_values(scene, self.attribute)
        return (values >= self.low) & (values <= self.high)

    def to_json(self) -> dict:
        return {"kind": "range", "attribute": self.attribute, "low": float(self.low), "high": float(self.high)}


def projected(scene: Scene, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """((N, 2) float64 continuous pixel positions of the centres, (N,) bool in front of
    the camera): camera-space mu = R p + t, (fx x / z + cx, fy y / z + cy)."""
    mu = scene.positions.astype(np.float64) @ np.asarray(camera.R, np.float64).T + np.asarray(camera.t, np.float64)
    front = mu[:, 2] > 0
    z = np.where(front, mu[:, 2], 1.0)
    uv = np.stack([camera.fx * mu[:, 0] / z + camera.cx, camera.fy * mu[:, 1] / z + camera.cy], axis=1)
    return uv, front


def inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """(P,) bool: which of ``points`` ((P, 2)) lie inside ``polygon`` ((V, 2), closed
    implicitly) by the even-odd rule (a lasso that crosses itself leaves the overlap out)."""
    inside = np.zeros(points.shape[0], bool)
    x, y = points[:, 0], points[:, 1]
    for (x0, y0), (x1, y1) in zip(polygon, np.roll(polygon, -1, axis=0)):
        crosses = (y0 > y) != (y1 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        inside ^= crosses & (x < at)
    return inside


def near_stroke(points: np.ndarray, stroke: np.ndarray, radius: float) -> np.ndarray:
    """(P,) bool: which of ``points`` lie within ``radius`` of the polyline ``stroke``
    ((V, 2); one point is a dab)."""
    near = np.zeros(points.shape[0], bool)
    ends = [(stroke[0], stroke[0])] if stroke.shape[0] == 1 else zip(stroke[:-1], stroke[1:])
    for a, b in ends:
        d = b - a
        length2 = float(d @ d)
        t = np.zeros(points.shape[0]) if length2 == 0 else np.clip((points - a) @ d / length2, 0.0, 1.0)
        gap = points - (a + t[:, None] * d)
        near |= np.einsum("ij,ij->i", gap, gap) <= radius * radius
    return near


def within_corners(uv: np.ndarray, corners: np.ndarray, radius: float = 0.0) -> np.ndarray:
    """(P,) bool: which of ``uv`` ((P, 2)) lie in the axis-aligned rectangle spanned by
    ``corners`` ((2+, 2)), edges included."""
    low, high = corners.min(axis=0), corners.max(axis=0)
    return np.all((uv >= low) & (uv <= high), axis=1)


#: The shapes drawn on a view.
ScreenKind = Literal["rectangle", "polygon", "brush"]
#: Each kind's test of image positions: holds(uv (P, 2), points (V, 2), radius) -> (P,) bool.
SCREEN_KINDS: dict[ScreenKind, Callable[[np.ndarray, np.ndarray, float], np.ndarray]] = {
    "rectangle": within_corners,
    "polygon": lambda uv, corners, radius: inside_polygon(uv, corners),
    "brush": lambda uv, stroke, radius: near_stroke(uv, stroke, radius),
}
#: The fewest points of each kind: a rectangle's two corners, a polygon's three, a brush's one dab.
LEAST_POINTS: dict[ScreenKind, int] = {"rectangle": 2, "polygon": 3, "brush": 1}


@dataclass(frozen=True, eq=False)
class ScreenShape:
    """A shape drawn on ``camera``'s image: ``kind`` "rectangle" (``points``: two
    opposite corners), "polygon" (its corners, at least three) or "brush" (the stroke's
    points, at least one, and ``radius`` in pixels). Selects the centres in front of the
    camera that project inside ("through")."""

    kind: ScreenKind
    camera: Camera
    points: tuple[tuple[float, float], ...]
    radius: float = 0.0

    def __post_init__(self) -> None:
        least = LEAST_POINTS.get(self.kind)
        if least is None:
            raise ValueError(f"unknown screen shape {self.kind!r}: rectangle, polygon or brush")
        points = tuple((float(u), float(v)) for u, v in self.points)
        if len(points) < least or not all(math.isfinite(c) for p in points for c in p):
            raise ValueError(f"a {self.kind} needs at least {least} finite points")
        if self.kind == "brush" and not (math.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"a brush needs a radius > 0 pixels, got {self.radius}")
        object.__setattr__(self, "points", points)

    def mask(self, scene: Scene) -> np.ndarray:
        uv, front = projected(scene, self.camera)
        return self.holds(uv) & front

    def holds(self, uv: np.ndarray) -> np.ndarray:
        """(P,) bool: which of the image positions ``uv`` ((P, 2) continuous pixels) the shape holds."""
        return SCREEN_KINDS[self.kind](uv, np.array(self.points, np.float64), float(self.radius))

    def pixel_mask(self) -> np.ndarray:
        """(H, W) bool: the camera's pixels whose centre the shape holds (the pixels a
        "visible" selection weighs). Only the pixels of the shape's bounding box are tested."""
        c = self.camera
        mask = np.zeros((c.height, c.width), bool)
        points = np.array(self.points, np.float64)
        low, high = points.min(axis=0) - self.radius, points.max(axis=0) + self.radius
        # Centre u + 0.5 lies in [low, high] for u in ceil(low - 0.5) .. floor(high - 0.5).
        u0, v0 = (max(0, math.ceil(x - 0.5)) for x in low)
        u1, v1 = (min(size, math.floor(x - 0.5) + 1) for x, size in zip(high, (c.width, c.height)))
        if u0 >= u1 or v0 >= v1:
            return mask
        u, v = np.meshgrid(np.arange(u0, u1) + 0.5, np.arange(v0, v1) + 0.5)
        mask[v0:v1, u0:u1] = self.holds(np.stack([u.ravel(), v.ravel()], axis=1)).reshape(u.shape)
        return mask

    def to_json(self) -> dict:
        c = self.camera
        entry = {"kind": self.kind, "points": [list(p) for p in self.points],
                 "camera": {"width": int(c.width), "height": int(c.height), "fx": float(c.fx), "fy": float(c.fy),
                            "cx": float(c.cx), "cy": float(c.cy), "R": np.asarray(c.R, np.float64).tolist(),
                            "t": np.asarray(c.t, np.float64).tolist()}}
        if self.kind == "brush":
            entry["radius"] = float(self.radius)
        return entry


#: What a selection by rows was found by: the gaussians whose largest weight over the
#: shape's pixels is at least ``min_weight`` ("visible"), or the one with the largest
#: ("top": a click, through the one pixel of its shape).
FOUND_BY = ("visible", "top")


@dataclass(frozen=True, eq=False)
class Rows:
    """Gaussians by row (``rows``: distinct, ascending): what a selection through the view
    (``render.contributions``) found, recorded as rows, so an edit document replays it
    exactly without rendering. ``found_by`` (:data:`FOUND_BY`), ``through`` (the screen
    shape whose pixels were weighed) and ``min_weight`` record how, for the reader."""

    rows: tuple[int, ...]
    found_by: str
    through: ScreenShape
    min_weight: float = 0.0

    def __post_init__(self) -> None:
        rows = tuple(int(r) for r in self.rows)
        if any(r < 0 for r in rows) or any(a >= b for a, b in zip(rows, rows[1:])):
            raise ValueError("rows must be distinct, ascending and >= 0")
        if self.found_by not in FOUND_BY:
            raise ValueError(f"found_by must be one of {', '.join(FOUND_BY)}, got {self.found_by!r}")
        if not (math.isfinite(self.min_weight) and 0 <= self.min_weight <= 1):
            raise ValueError(f"min_weight must lie in 0..1, got {self.min_weight}")
        object.__setattr__(self, "rows", rows)

    def mask(self, scene: Scene) -> np.ndarray:
        if self.rows and self.rows[-1] >= scene.count:
            raise ValueError(f"row {self.rows[-1]} is past the scene's {scene.count:,} gaussians")
        mask = np.zeros(scene.count, bool)
        mask[list(self.rows)] = True
        return mask

    def to_json(self) -> dict:
        entry = {"kind": "rows", "rows": list(self.rows), "found by": self.found_by, "through": self.through.to_json()}
        if self.found_by == "visible":
            entry["min weight"] = float(self.min_weight)
        return entry


Shape = Union[Box, Sphere, Range, ScreenShape, Rows]


def shape_from_json(entry: dict) -> Shape:
    """The shape ``entry`` (as ``to_json`` wrote it) describes; ValueError, saying what is
    wrong, for anything else."""
    if not isinstance(entry, dict):
        raise ValueError("a shape must be an object")
    kind = entry.get("kind")
    try:
        if kind == "box":
            box = CropBox(entry["low"], entry["high"])
            return Box(box.low, box.high)
        if kind == "sphere":
            sphere = CropSphere(entry["centre"], entry["radius"])
            return Sphere(sphere.centre, sphere.radius)
        if kind == "range":
            if entry["attribute"] not in ATTRIBUTES:
                raise ValueError(f"unknown attribute {entry['attribute']!r}: one of {', '.join(ATTRIBUTES)}")
            low, high = float(entry["low"]), float(entry["high"])
            if not (low <= high):
                raise ValueError(f"a range needs low <= high, got {low:g}..{high:g}")
            return Range(entry["attribute"], low, high)
        if kind == "rows":
            through = shape_from_json(entry["through"])
            if not isinstance(through, ScreenShape):
                raise ValueError("'through' must be a rectangle, polygon or brush")
            rows = entry["rows"]
            if not isinstance(rows, list) or not all(isinstance(r, int) and not isinstance(r, bool) for r in rows):
                raise ValueError("'rows' must be a list of whole numbers")
            return Rows(tuple(rows), entry["found by"], through, float(entry.get("min weight", 0.0)))
        if kind in SCREEN_KINDS:
            c = entry["camera"]
            R, t = np.array(c["R"], np.float64), np.array(c["t"], np.float64)
            if R.shape != (3, 3) or t.shape != (3,) or not (np.isfinite(R).all() and np.isfinite(t).all()):
                raise ValueError("a screen shape's camera needs a finite 3x3 R and a 3-vector t")
            camera = Camera(int(c["width"]), int(c["height"]), float(c["fx"]), float(c["fy"]), float(c["cx"]),
                            float(c["cy"]), R, t)
            return ScreenShape(kind, camera, tuple(tuple(p) for p in entry["points"]), float(entry.get("radius", 0)))
    except KeyError as exc:
        raise ValueError(f"a {kind} shape needs '{exc.args[0]}'") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"a {kind} shape: {exc}") from None
    raise ValueError(f"unknown shape kind {kind!r}: box, sphere, range, rectangle, polygon, brush or rows")
