"""The camera path drawn over the view: a polyline along the flight and a small frustum
(a pyramid of lines) at each keyframe, the selected one highlighted.

Lines are projected with the frame's camera into the viewport and drawn on imgui's
background draw list: over the scene, under the panel, and never in a screenshot
(screenshots re-render the view offscreen). A line that crosses the camera's near
plane is cut there, and every line is cut to the viewport, so nothing behind the
camera is drawn wrapped through infinity.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.path import CameraPath
from raygs_viewer.camera.pinhole import Camera

#: (x0, y0, x1, y1) in screen coordinates (imgui's).
Rect = tuple[float, float, float, float]

PATH_COLOUR = (90, 200, 255, 230)
FRUSTUM_COLOUR = (255, 255, 255, 190)
SELECTED_COLOUR = (255, 205, 0, 255)


@dataclass(frozen=True)
class DrawnPath:
    """What :func:`draw_path_overlay` drew, for tests: ``polyline_segments`` and
    ``frustum_segments`` count the lines drawn (after clipping), ``keyframe_points`` the
    screen position of each keyframe's camera centre that lies in front of the camera
    and inside the viewport (keyframe index -> (x, y))."""

    polyline_segments: int = 0
    frustum_segments: int = 0
    keyframe_points: dict[int, tuple[float, float]] = field(default_factory=dict)

    @property
    def segments(self) -> int:
        return self.polyline_segments + self.frustum_segments


def viewport_rect(viewport: tuple[int, int, int, int], scale: tuple[float, float]) -> Rect:
    """The viewport (framebuffer pixels, from the top-left) in screen coordinates."""
    vx, vy, vw, vh = viewport
    sx, sy = scale
    return vx / sx, vy / sy, (vx + vw) / sx, (vy + vh) / sy


def project_points(camera: Camera, points: np.ndarray, rect: Rect) -> np.ndarray:
    """(N, 2) screen positions of (N, 3) world points as ``camera`` sees them, its
    image filling ``rect``; no clipping (points behind the camera land anywhere)."""
    return _project(camera, np.asarray(points, np.float64).reshape(-1, 3) @ camera.R.T + camera.t, rect)


def screen_segments(camera: Camera, starts: np.ndarray, ends: np.ndarray, rect: Rect, near: float) -> np.ndarray:
    """(M, 2, 2) screen segments of the world segments ``starts`` -> ``ends`` ((N, 3)
    each): cut at the plane ``near`` in front of the camera, projected, and cut to
    ``rect``; those with nothing left are dropped."""
    return visible_segments(camera, starts, ends, rect, near)[0]


def visible_segments(camera: Camera, starts: np.ndarray, ends: np.ndarray, rect: Rect, near: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`screen_segments` and the index of the world segment each one comes from."""
    starts, ends = np.asarray(starts, np.float64).reshape(-1, 3), np.asarray(ends, np.float64).reshape(-1, 3)
    a, b = starts @ camera.R.T + camera.t, ends @ camera.R.T + camera.t
    index = np.flatnonzero((a[:, 2] >= near) | (b[:, 2] >= near))
    a, b = a[index], b[index]
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = a + ((near - a[:, 2]) / (b[:, 2] - a[:, 2]))[:, None] * (b - a)
    # The end behind the near plane moves along the segment onto it.
    a = np.where((a[:, 2] < near)[:, None], crossing, a)
    b = np.where((b[:, 2] < near)[:, None], crossing, b)
    segments, inside = _clip_to_rect(_project(camera, a, rect), _project(camera, b, rect), rect)
    return segments, index[inside]


def _project(camera: Camera, p: np.ndarray, rect: Rect) -> np.ndarray:
    """(N, 2) screen positions of (N, 3) camera-space points."""
    x0, y0, x1, y1 = rect
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        u = camera.fx * p[:, 0] / p[:, 2] + camera.cx
        v = camera.fy * p[:, 1] / p[:, 2] + camera.cy
    return np.stack([x0 + u * (x1 - x0) / camera.width, y0 + v * (y1 - y0) / camera.height], axis=1)


def _clip_to_rect(p: np.ndarray, q: np.ndarray, rect: Rect) -> tuple[np.ndarray, np.ndarray]:
    """Liang-Barsky: the part of each segment p -> q ((N, 2) each) inside ``rect``, and
    the (N,) mask of the segments with a part inside."""
    x0, y0, x1, y1 = rect
    d = q - p
    low, high = np.zeros(len(p)), np.ones(len(p))
    inside = np.ones(len(p), bool)
    for delta, distance in ((-d[:, 0], p[:, 0] - x0), (d[:, 0], x1 - p[:, 0]),
                            (-d[:, 1], p[:, 1] - y0), (d[:, 1], y1 - p[:, 1])):
        parallel = delta == 0
        inside &= ~(parallel & (distance < 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = distance / delta
        low = np.where(~parallel & (delta < 0), np.maximum(low, r), low)
        high = np.where(~parallel & (delta > 0), np.minimum(high, r), high)
    inside &= (low <= high) & np.all(np.isfinite(p), axis=1) & np.all(np.isfinite(q), axis=1)
    p, d, low, high = p[inside], d[inside], low[inside], high[inside]
    return np.stack([p + low[:, None] * d, p + high[:, None] * d], axis=1).reshape(-1, 2, 2), inside


#: Each corner's (x, y) signs round an image's rim: top left, top right, bottom right, bottom left.
CORNER_SIGNS = np.array([(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)])


def image_corners(R: np.ndarray, apex: np.ndarray, slopes: np.ndarray, depth: float) -> np.ndarray:
    """(K, 4, 3): the corners of K cameras' images ``depth`` in front of them. ``R``:
    (K, 3, 3) world-to-camera rotations (rows: right, down, forward in world axes);
    ``apex``: (K, 3) the camera centres; ``slopes``: (K, 4, 2) each corner's camera-space
    (x / z, y / z), round the rim (:data:`CORNER_SIGNS`' order)."""
    R, slopes = np.asarray(R, np.float64), np.asarray(slopes, np.float64)
    return np.asarray(apex, np.float64)[:, None] + depth * (
        R[:, None, 2] + slopes[..., :1] * R[:, None, 0] + slopes[..., 1:] * R[:, None, 1])


def pyramid_lines(apex: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K * 8, 3) starts and ends of K pyramids, eight lines each: the four edges from
    ``apex`` ((K, 3)) to the ``corners`` ((K, 4, 3), round the rim), then the rim."""
    apex, corners = np.asarray(apex, np.float64).reshape(-1, 3), np.asarray(corners, np.float64).reshape(-1, 4, 3)
    starts = np.concatenate([np.repeat(apex[:, None], 4, axis=1), corners], axis=1)
    ends = np.concatenate([corners, np.roll(corners, -1, axis=1)], axis=1)
    return starts.reshape(-1, 3), ends.reshape(-1, 3)


def frustum_lines(path: CameraPath, size: float, aspect: float) -> tuple[np.ndarray, np.ndarray]:
    """(K * 8, 3) starts and ends of each keyframe's pyramid (:func:`pyramid_lines`): its
    camera centre and the corners of its image (``aspect``: width / height) ``size`` in
    front of it."""
    if not path.keyframes:
        return np.zeros((0, 3)), np.zeros((0, 3))
    R = np.array([k.pose.R for k in path.keyframes])                       # (K, 3, 3)
    apex = np.array([k.pose.position for k in path.keyframes])              # (K, 3)
    half_h = np.tan(np.radians([k.fov_y_degrees for k in path.keyframes]) / 2)
    slopes = CORNER_SIGNS[None] * np.stack([half_h * aspect, half_h], axis=1)[:, None]   # (K, 4, 2)
    return pyramid_lines(apex, image_corners(R, apex, slopes, size))


def draw_path_overlay(path: CameraPath, camera: Camera, viewport: tuple[int, int, int, int], *,
                      selected: int | None, size: float, near: float) -> DrawnPath:
    """Draws ``path`` as ``camera`` sees it into ``viewport`` (framebuffer pixels):
    frustums ``size`` scene units deep, cut at ``near`` scene units in front of the
    camera. Returns what was drawn."""
    if not path.keyframes:
        return DrawnPath()
    scale = imgui.get_io().display_framebuffer_scale
    rect = viewport_rect(viewport, (scale.x or 1.0, scale.y or 1.0))
    draw = imgui.get_background_draw_list()
    line = path.polyline()
    polyline = screen_segments(camera, line[:-1], line[1:], rect, near)
    for p, q in polyline:
        draw.add_line(tuple(p), tuple(q), imgui.IM_COL32(*PATH_COLOUR), 2.0)
    starts, ends = frustum_lines(path, size, camera.width / camera.height)
    frustums, lines = visible_segments(camera, starts, ends, rect, near)
    plain, chosen = imgui.IM_COL32(*FRUSTUM_COLOUR), imgui.IM_COL32(*SELECTED_COLOUR)
    for (p, q), line in zip(frustums, lines):
        highlight = line // 8 == selected
        draw.add_line(tuple(p), tuple(q), chosen if highlight else plain, 2.0 if highlight else 1.0)
    centres = np.array([k.pose.position for k in path.keyframes])
    depth = (centres @ camera.R.T + camera.t)[:, 2]
    points = project_points(camera, centres, rect)
    x0, y0, x1, y1 = rect
    shown = {i: (float(x), float(y)) for i, (x, y) in enumerate(points)
             if depth[i] >= near and x0 <= x <= x1 and y0 <= y <= y1}
    for index, (x, y) in shown.items():
        draw.add_circle_filled((x, y), 4.0 if index == selected else 2.5,
                               imgui.IM_COL32(*(SELECTED_COLOUR if index == selected else FRUSTUM_COLOUR)))
    return DrawnPath(len(polyline), len(frustums), shown)
