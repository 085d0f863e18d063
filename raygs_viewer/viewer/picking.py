"""Picking a 3D point under the mouse: the pixel's median depth, from a render of that
one pixel, unprojected along its ray.

A pixel is picked by rendering the channels (renderer.render_channels) of a 1 x 1
camera looking through it: the view's pose and focal lengths with the principal point
shifted so that its one pixel's ray is the picked pixel's, drawn with the view's order
and settings (supersampling samples the same sub-pixel positions). So a pick costs a
one-pixel render, whatever the window's size. The median depth (the z of the fragment at
which the pixel's alpha reaches 0.5) gives the point: camera-space
``z * ((u + 0.5 - cx) / fx, (v + 0.5 - cy) / fy, 1)``, then world space. A pixel whose
alpha never reaches 0.5 has no median depth, and nothing is picked.

Screen positions (imgui's) become pixels of the camera that drew them: the mono view's,
either side of the split view's (both are the same camera), or in the stereo preview the
eye whose image lies under the mouse (:func:`stereo_pixel`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.contributions import cropped
from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import Order

#: The stereo layouts whose composed image is two eyes side by side, and which eye is on the left.
_SIDE_BY_SIDE = {"sbs": (0, 1), "cross": (1, 0)}
#: The single-image layouts and the eye each shows (anaglyph: the midpoint, None).
_SINGLE = {"left": 0, "right": 1, "anaglyph": None}


@dataclass(frozen=True, eq=False)
class Picked:
    """A picked point: ``point`` (3,) float64 world space; ``depth``: its camera-space z
    (the pixel's median depth); ``distance``: from the camera centre; ``pixel``: (u, v)
    of ``camera``, the camera it was picked with."""

    point: np.ndarray
    depth: float
    distance: float
    pixel: tuple[int, int]
    camera: Camera


def pixel_camera(camera: Camera, u: int, v: int) -> Camera:
    """A 1 x 1 camera whose one pixel is pixel (u, v) of ``camera``: the same pose and
    focal lengths, the principal point moved by (u, v)."""
    return cropped(camera, slice(v, v + 1), slice(u, u + 1))


def unproject(camera: Camera, u: float, v: float, depth: float) -> np.ndarray:
    """(3,) float64 world point at camera-space z ``depth`` on the ray of pixel (u, v)."""
    local = depth * np.array([(u + 0.5 - camera.cx) / camera.fx, (v + 0.5 - camera.cy) / camera.fy, 1.0])
    return camera.R.T @ (local - camera.t)


def pick(renderer, camera: Camera, u: int, v: int, *, settings: RenderSettings, order: Order,
         color_origin: np.ndarray | None = None) -> Picked | None:
    """The point under pixel (u, v) of ``camera`` drawn with ``settings`` and ``order``;
    None where the pixel has no median depth."""
    channels = renderer.render_channels(pixel_camera(camera, u, v), settings, order, frame=camera,
                                        color_origin=color_origin)
    depth = float(channels.median_depth[0, 0])
    if not (math.isfinite(depth) and depth > 0):
        return None
    point = unproject(camera, u, v, depth)
    return Picked(point, depth, float(np.linalg.norm(point - camera.center)), (u, v), camera)


def screen_pixel(x: float, y: float, viewport: Viewport, scale: tuple[float, float], *, width: int, height: int
                 ) -> tuple[float, float] | None:
    """The position (continuous, in pixels of an image ``width`` x ``height`` shown
    letterboxed in ``viewport``) under screen position (x, y); None outside the image.
    ``scale``: framebuffer pixels per screen unit."""
    vx, vy, vw, vh = viewport
    if not (math.isfinite(x) and math.isfinite(y)) or vw <= 0 or vh <= 0:
        return None
    fx, fy = (x * scale[0] - vx) / vw, (y * scale[1] - vy) / vh
    if not (0.0 <= fx < 1.0 and 0.0 <= fy < 1.0):
        return None
    return fx * width, fy * height


def mono_pixel(x: float, y: float, viewport: Viewport, scale: tuple[float, float], camera: Camera
               ) -> tuple[int, int] | None:
    """Pixel (u, v) of ``camera`` (the view, filling ``viewport``) under screen position (x, y)."""
    position = screen_pixel(x, y, viewport, scale, width=camera.width, height=camera.height)
    return None if position is None else (int(position[0]), int(position[1]))


def stereo_image(x: float, y: float, viewport: Viewport, scale: tuple[float, float], camera: Camera, *,
                 eyes: tuple[Camera, Camera], layout: str) -> tuple[Camera, float, int] | None:
    """(camera, column, halves) of the image under screen position (x, y) of the stereo
    preview (arguments as :func:`stereo_pixel`): the eye (or the anaglyph's midpoint)
    whose image is there, the column of the composed image its own begins at, and how
    many images the composed one holds side by side (so that a composed column c is that
    camera's c - column). None off the image."""
    found = stereo_pixel(x, y, viewport, scale, camera, eyes=eyes, layout=layout)
    if found is None:
        return None
    shown, u, _ = found
    halves = 2 if layout in _SIDE_BY_SIDE else 1
    column = int(screen_pixel(x, y, viewport, scale, width=halves * camera.width, height=camera.height)[0])
    return shown, float(column - u), halves


def stereo_pixel(x: float, y: float, viewport: Viewport, scale: tuple[float, float], camera: Camera, *,
                 eyes: tuple[Camera, Camera], layout: str) -> tuple[Camera, int, int] | None:
    """(eye camera, u, v) under screen position (x, y) of the stereo preview of ``eyes``
    around the midpoint ``camera`` in ``layout``: the eye whose image is there (side by
    side), the one shown (one eye), or the midpoint (anaglyph, where both overlap). The
    lens preview's warp is not undone: a pick with it on lands near, not exactly on, the
    pixel shown."""
    halves = 2 if layout in _SIDE_BY_SIDE else 1
    position = screen_pixel(x, y, viewport, scale, width=halves * camera.width, height=camera.height)
    if position is None:
        return None
    column, row = int(position[0]), int(position[1])
    if halves == 2:
        eye = eyes[_SIDE_BY_SIDE[layout][column // camera.width]]
        return eye, column % camera.width, row
    shown = _SINGLE.get(layout)
    return (camera if shown is None else eyes[shown]), column, row
