"""The Edit section's box and sphere drawn over the view, and moved with handles.

A left drag on a handle (a dot) moves it, before any selection tool or the camera sees
the button:

- the box's centre moves the box across the view, at the depth of its centre; each of its
  six face centres moves that face along its axis, never past the opposite face;
- the sphere's centre moves it across the view, at its depth; the dot on its rim (on the
  view's right) sets the radius: the distance from the centre to the point under the
  mouse, in the plane through the centre that faces the view.

A drag is worked out from where it began (the shape then, and the press), never from
the last frame's step, so quick moves are not lost and a drag back returns the shape to
where it was. The lines and dots are cut at a near plane like the path's overlay, and not
drawn in the stereo preview, whose image is not the frame camera's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from itertools import product

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.scene.selection import Box, Sphere
from raygs_viewer.viewer.path_overlay import Rect, project_points, screen_segments, viewport_rect
from raygs_viewer.viewer.path_widget import OVERLAY_NEAR

#: A handle's dot (screen units), and how near a press must be to take it.
DOT_RADIUS, GRAB_RADIUS = 5.0, 9.0
#: A face's dot is not offered when its axis is within this many degrees of the view's ray.
EDGE_ON = 20.0
#: Segments of each circle drawn for the sphere.
CIRCLE_SEGMENTS = 48
BOX_COLOUR, SPHERE_COLOUR, ACTIVE_COLOUR = (255, 170, 40, 230), (60, 200, 255, 230), (255, 255, 255, 255)
AXES = "xyz"


@dataclass(frozen=True)
class HandleDrag:
    """A drag under way: the handle's ``name``, the press (screen), the shape then, and the
    view it is moved in (``rect``: the camera's image on the screen)."""

    name: str
    press: tuple[float, float]
    shape: Box | Sphere
    camera: Camera
    rect: Rect


def box_handles(box: Box) -> dict[str, np.ndarray]:
    """World points of the box's handles: "box centre" and "box -x" .. "box +z" (face centres)."""
    low, high = np.array(box.low, np.float64), np.array(box.high, np.float64)
    handles = {"box centre": (low + high) / 2}
    for axis, side in product(range(3), "-+"):
        point = (low + high) / 2
        point[axis] = low[axis] if side == "-" else high[axis]
        handles[f"box {side}{AXES[axis]}"] = point
    return handles


def sphere_handles(sphere: Sphere, camera: Camera) -> dict[str, np.ndarray]:
    """World points of "sphere centre" and "sphere radius" (the rim, on the view's right)."""
    centre = np.array(sphere.centre, np.float64)
    return {"sphere centre": centre, "sphere radius": centre + sphere.radius * camera.R[0]}


def camera_pixels(drag: HandleDrag, x: float, y: float) -> tuple[float, float]:
    """Screen position (x, y) as continuous pixels of the drag's camera."""
    x0, y0, x1, y1 = drag.rect
    return (x - x0) / (x1 - x0) * drag.camera.width, (y - y0) / (y1 - y0) * drag.camera.height


def moved(drag: HandleDrag, x: float, y: float) -> Box | Sphere:
    """The shape the drag makes with the mouse at screen (x, y)."""
    camera, shape = drag.camera, drag.shape
    (u, v), (u0, v0) = camera_pixels(drag, x, y), camera_pixels(drag, *drag.press)
    handle = (box_handles(shape) if isinstance(shape, Box) else sphere_handles(shape, camera))[drag.name]
    q = camera.R @ handle + camera.t
    if not q[2] > 0:
        return shape  # behind the camera: it cannot be moved from this view
    if drag.name.endswith("centre"):
        offset = camera.R.T @ np.array([(u - u0) * q[2] / camera.fx, (v - v0) * q[2] / camera.fy, 0.0])
        if isinstance(shape, Sphere):
            return replace(shape, centre=tuple((np.array(shape.centre) + offset).tolist()))
        return Box(tuple((np.array(shape.low) + offset).tolist()), tuple((np.array(shape.high) + offset).tolist()))
    if drag.name == "sphere radius":
        point = np.array([(u - camera.cx) / camera.fx * q[2], (v - camera.cy) / camera.fy * q[2], q[2]])
        return replace(shape, radius=float(np.linalg.norm(camera.R.T @ (point - camera.t) - np.array(shape.centre))))
    # A face: the mouse's move along the screen direction of its axis, in world units.
    side, axis = drag.name[-2], AXES.index(drag.name[-1])
    d = camera.R[:, axis]
    gradient = np.array([camera.fx * (d[0] * q[2] - q[0] * d[2]), camera.fy * (d[1] * q[2] - q[1] * d[2])]) / q[2] ** 2
    length2 = float(gradient @ gradient)
    if not length2 > 1e-12:
        return shape  # the axis points at the camera: the face does not move across the view
    step = float(np.array([u - u0, v - v0]) @ gradient) / length2
    low, high = list(shape.low), list(shape.high)
    if side == "-":
        low[axis] = min(high[axis], low[axis] + step)
    else:
        high[axis] = max(low[axis], high[axis] + step)
    return Box(tuple(low), tuple(high))


class VolumeHandles:
    """The handles of the edit tool's box and sphere, over the view where ``show_box`` /
    ``show_sphere``; ``drawn``: each handle's screen position in the last frame, where it
    was visible; ``drag``: the drag under way (None: none)."""

    def __init__(self) -> None:
        self.show_box = self.show_sphere = False
        self.drag: HandleDrag | None = None
        self.drawn: dict[str, tuple[float, float]] = {}

    def handle_at(self, x: float, y: float) -> str | None:
        """The drawn handle nearest screen (x, y) within GRAB_RADIUS, if any."""
        near = [(math.hypot(x - hx, y - hy), name) for name, (hx, hy) in self.drawn.items()]
        near = [found for found in near if found[0] <= GRAB_RADIUS]
        return min(near)[1] if near else None

    def take_mouse(self, frame, box: Box, sphere: Sphere) -> tuple[bool, Box | Sphere | None]:
        """Moves a handle of ``box`` or ``sphere`` with the left button: (True while a drag
        is the handles', the shape it moved to this frame; None: none moved)."""
        io = imgui.get_io()
        if frame is None or frame.stereo is not None:
            self.drag = None
            return False, None
        x, y = io.mouse_pos.x, io.mouse_pos.y
        finite = math.isfinite(x) and math.isfinite(y) and abs(x) < 1e30 and abs(y) < 1e30
        if self.drag is None:
            name = self.handle_at(x, y) if finite else None
            if name is None or io.want_capture_mouse or not imgui.is_mouse_clicked(0):
                return False, None
            scale = io.display_framebuffer_scale
            shape = box if name.startswith("box") else sphere
            self.drag = HandleDrag(name, (x, y), shape, frame.camera,
                                   viewport_rect(frame.viewport, (scale.x or 1.0, scale.y or 1.0)))
            return True, None
        shape = moved(self.drag, x, y) if finite else None
        if not imgui.is_mouse_down(0):
            self.drag = None
        return True, shape

    def draw(self, frame, radius: float, box: Box, sphere: Sphere) -> None:
        """The shown volumes' lines and handles over ``frame``'s view (cut at the overlays'
        near plane for a scene of ``radius``)."""
        self.drawn = {}
        if frame is None or frame.stereo is not None or not (self.show_box or self.show_sphere):
            return
        near = OVERLAY_NEAR * radius
        scale = imgui.get_io().display_framebuffer_scale
        camera, rect = frame.camera, viewport_rect(frame.viewport, (scale.x or 1.0, scale.y or 1.0))
        draw = imgui.get_foreground_draw_list()
        if self.show_box:
            self._lines(draw, camera, box_edges(box), rect=rect, near=near, colour=BOX_COLOUR)
            handles = {name: point for name, point in box_handles(box).items()
                       if name == "box centre" or not along_the_view(camera, point, AXES.index(name[-1]))}
            self._dots(draw, camera, handles, rect=rect, near=near, colour=BOX_COLOUR)
        if self.show_sphere:
            self._lines(draw, camera, sphere_circles(sphere, camera), rect=rect, near=near, colour=SPHERE_COLOUR)
            self._dots(draw, camera, sphere_handles(sphere, camera), rect=rect, near=near, colour=SPHERE_COLOUR)

    @staticmethod
    def _lines(draw, camera, lines: tuple[np.ndarray, np.ndarray], *, rect, near, colour) -> None:
        """``lines``: (N, 3) starts and ends, drawn where they show in ``rect``."""
        for (x0, y0), (x1, y1) in screen_segments(camera, *lines, rect, near):
            draw.add_line((float(x0), float(y0)), (float(x1), float(y1)), imgui.IM_COL32(*colour), 1.5)

    def _dots(self, draw, camera, handles: dict[str, np.ndarray], *, rect, near, colour) -> None:
        names, points = list(handles), np.array(list(handles.values()))
        depths = (points @ camera.R.T + camera.t)[:, 2]
        active = None if self.drag is None else self.drag.name
        for name, depth, (x, y) in zip(names, depths, project_points(camera, points, rect)):
            if depth >= near and rect[0] <= x <= rect[2] and rect[1] <= y <= rect[3]:
                self.drawn[name] = (float(x), float(y))
                chosen = name == active
                draw.add_circle_filled((float(x), float(y)), DOT_RADIUS + 2 * chosen,
                                       imgui.IM_COL32(*(ACTIVE_COLOUR if chosen else colour)))


def along_the_view(camera: Camera, point: np.ndarray, axis: int) -> bool:
    """Whether world ``axis`` at ``point`` points within EDGE_ON of the view's ray there:
    that face's dot barely moves across the view and would sit on the centre's, so it
    is not offered (another view reaches it)."""
    ray = camera.R @ point + camera.t
    return abs(float(camera.R[:, axis] @ ray)) > math.cos(math.radians(EDGE_ON)) * float(np.linalg.norm(ray))


def box_edges(box: Box) -> tuple[np.ndarray, np.ndarray]:
    """(12, 3) starts and ends of the box's edges."""
    low, high = np.array(box.low, np.float64), np.array(box.high, np.float64)
    corners = np.array([[(low, high)[bit][axis] for axis, bit in enumerate(bits)] for bits in product((0, 1), repeat=3)])
    pairs = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    return corners[[a for a, _ in pairs]], corners[[b for _, b in pairs]]


def sphere_circles(sphere: Sphere, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Starts and ends of the segments of four great circles: about each axis, and the one
    facing the view (the outline, near enough, the rim handle lies on)."""
    angles = np.linspace(0.0, 2 * math.pi, CIRCLE_SEGMENTS + 1)
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    planes = [np.eye(3)[[1, 2]], np.eye(3)[[0, 2]], np.eye(3)[[0, 1]], camera.R[:2]]
    centre = np.array(sphere.centre, np.float64)
    points = np.stack([centre + sphere.radius * ring @ plane for plane in planes])  # (4, S + 1, 3)
    return points[:, :-1].reshape(-1, 3), points[:, 1:].reshape(-1, 3)
