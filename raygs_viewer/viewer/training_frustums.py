"""The training cameras drawn in the scene, as SIBR and nerfstudio do: a frustum (a
pyramid of lines) at each, coloured by the train/test split, its photo inside its
image rectangle when the photos are known (:mod:`.thumbnails`); the one under the
pointer highlighted and named, and a click on it flies there (the window routes the
click: :meth:`TrainingFrustums.camera_at`).

Drawn like the camera path (:mod:`.path_overlay`): on imgui's background draw list,
over the scene and under the panel, cut at a near plane and at the viewport, so never
in a screenshot (screenshots re-render the view offscreen). The camera the view
stands at (or nearly: closer than a frustum's depth) is left out, as it would cover
the view. Frustums are a fixed fraction of the scene's radius deep, so they show in
any scene's units.

The split is ``evaluate``'s: every TEST_EVERY-th view in name order is a test view.
The dataset evaluate opens lists the cameras.json's views sorted by those same names
(``photos.dataset``), so the names alone give its split, photos or not.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.photos.dataset import TEST_EVERY
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.part import NO_REPLY, Part, Pointing, Reply, SceneView
from raygs_viewer.viewer.path_overlay import (
    CORNER_SIGNS,
    SELECTED_COLOUR,
    image_corners,
    project_points,
    pyramid_lines,
    viewport_rect,
    visible_segments,
)
from raygs_viewer.viewer.path_widget import OVERLAY_NEAR
from raygs_viewer.viewer.thumbnails import Thumbnails

#: A frustum's depth as a fraction of the scene's radius: deeper than the camera path's
#: keyframes (0.05), as the photo inside needs some pixels to be told apart.
FRUSTUM_SIZE = 0.07
#: The pointer names a camera within this many screen units of its centre (or inside its image).
HOVER_REACH = 8.0
TRAIN_COLOUR = (110, 215, 110, 220)
TEST_COLOUR = (255, 105, 195, 235)
HOVER_COLOUR = SELECTED_COLOUR
#: The photo inside a frustum, slightly see-through so the frustum's lines stay readable over it.
IMAGE_TINT = (255, 255, 255, 225)
SPLIT_NAMES = {False: "train", True: "test"}


def in_test_split(names: list[str]) -> np.ndarray:
    """(N,) bool: which of the cameras named ``names`` are test views (every
    TEST_EVERY-th in name order, ``photos.dataset.select_split``'s rule)."""
    test = np.zeros(len(names), bool)
    for rank, index in enumerate(sorted(range(len(names)), key=names.__getitem__)):
        test[index] = rank % TEST_EVERY == 0
    return test


def image_slopes(cameras: list[Camera]) -> np.ndarray:
    """(K, 4, 2): the camera-space (x / z, y / z) of each camera's image corners (pixel
    (0, 0), (W, 0), (W, H), (0, H)), principal point and aspect as the camera has them."""
    pixels = (CORNER_SIGNS + 1) / 2                                        # (4, 2) in 0..1
    size = np.array([(c.width, c.height) for c in cameras], np.float64)    # (K, 2)
    centre = np.array([(c.cx, c.cy) for c in cameras], np.float64)
    focal = np.array([(c.fx, c.fy) for c in cameras], np.float64)
    return (pixels[None] * size[:, None] - centre[:, None]) / focal[:, None]


@dataclass(frozen=True)
class DrawnFrustums:
    """What a frame drew, in screen coordinates (imgui's), as arrays over the training
    cameras with a line drawn (``cameras``, their indices): ``depth`` each one's centre
    depth in the view, ``apex`` its centre on screen (``apex_shown``: in front of the
    view and inside it), ``quad`` (n, 4, 2) its image rectangle (``quad_shown``: wholly
    in front of the near plane); ``colours`` each one's lines' (RGBA), ``images`` those
    shown with their photo, ``segments`` the lines drawn, ``hovered`` the camera named."""

    cameras: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    depth: np.ndarray = field(default_factory=lambda: np.zeros(0))
    apex: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    apex_shown: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    quad: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 2)))
    quad_shown: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    colours: dict[int, tuple[int, int, int, int]] = field(default_factory=dict)
    images: frozenset[int] = frozenset()
    segments: int = 0
    hovered: int | None = None

    @property
    def depths(self) -> dict[int, float]:
        return dict(zip(self.cameras.tolist(), self.depth.tolist()))

    @property
    def apexes(self) -> dict[int, tuple[float, float]]:
        return {int(i): (float(x), float(y)) for i, (x, y) in zip(self.cameras[self.apex_shown],
                                                                   self.apex[self.apex_shown])}

    @property
    def quads(self) -> dict[int, np.ndarray]:
        return dict(zip(self.cameras[self.quad_shown].tolist(), self.quad[self.quad_shown]))

    def camera_at(self, x: float, y: float) -> int | None:
        """The drawn camera at screen position (x, y): its centre within HOVER_REACH, or
        (x, y) inside its image rectangle; the nearest to the view where several are."""
        near = self.apex_shown & (((self.apex - (x, y)) ** 2).sum(axis=1) <= HOVER_REACH ** 2)
        edges = np.roll(self.quad, -1, axis=1) - self.quad
        cross = edges[..., 0] * (y - self.quad[..., 1]) - edges[..., 1] * (x - self.quad[..., 0])   # (n, 4)
        # Either winding: a frustum seen from behind projects mirrored.
        inside = self.quad_shown & (np.all(cross >= 0, axis=1) | np.all(cross <= 0, axis=1))
        hits = np.flatnonzero(near | inside)
        return None if not len(hits) else int(self.cameras[hits[np.argmin(self.depth[hits])]])


@dataclass(frozen=True)
class _Cameras:
    """A scene's training cameras as arrays, made once per scene."""

    cameras: list[Camera]
    R: np.ndarray        # (K, 3, 3)
    apex: np.ndarray     # (K, 3)
    slopes: np.ndarray   # (K, 4, 2)
    test: np.ndarray     # (K,) bool


class TrainingFrustums(Part):
    """One per window. ``show``: the panel's "show in the scene"; ``drawn``: the last
    frame's :class:`DrawnFrustums`; ``thumbnails``: the photos shown inside."""

    def __init__(self, thumbnails: Thumbnails):
        self.thumbnails = thumbnails
        self.show = True
        self.drawn = DrawnFrustums()
        self._cameras: _Cameras | None = None

    def camera_at(self, x: float, y: float) -> int | None:
        """The training camera whose frustum was drawn at screen position (x, y) last
        frame (what the pointer showed when it clicked); None where there is none."""
        return self.drawn.camera_at(x, y) if self.show else None

    def forget(self) -> None:
        """Another scene: its cameras and photos are others."""
        self.thumbnails.forget()
        self.drawn, self._cameras = DrawnFrustums(), None

    def close(self) -> None:
        self.thumbnails.release()

    def overlay(self, frame: Frame, scene: SceneView, pointing: Pointing) -> Reply:
        """The frustums of ``scene``'s training cameras over ``frame``'s view, a fraction
        of its radius deep; the one under the pointer named (not while the pointer is on
        the panel, nor while the measure tool takes the clicks). Not in the stereo
        preview, whose image shows two eyes rather than the frame's camera's."""
        self.draw(frame, scene.loaded, scene.radius, hover=not pointing.measuring)
        return NO_REPLY

    def draw(self, frame: Frame, loaded: LoadedScene, radius: float, hover: bool = True) -> None:
        """The frustums over ``frame``'s view, ``FRUSTUM_SIZE * radius`` deep; the one under
        the pointer named when ``hover``."""
        if not self.show or frame.stereo is not None or not loaded.cameras:
            self.drawn = DrawnFrustums()
            return
        cams = self._arrays(loaded)
        camera, depth, near = frame.camera, FRUSTUM_SIZE * radius, OVERLAY_NEAR * radius
        io = imgui.get_io()
        scale = io.display_framebuffer_scale
        rect = viewport_rect(frame.viewport, (scale.x or 1.0, scale.y or 1.0))
        # The camera the view stands at (or is about to land on) would fill the view with its lines.
        kept = np.flatnonzero(np.linalg.norm(cams.apex - camera.center, axis=1) > depth)
        corners = image_corners(cams.R[kept], cams.apex[kept], cams.slopes[kept], depth)   # (k, 4, 3)
        segments, lines = visible_segments(camera, *pyramid_lines(cams.apex[kept], corners), rect, near)
        owner = kept[lines // 8]
        drawn = self._geometry(camera, cams, kept, corners, np.unique(owner), rect=rect, near=near)
        hovered = None
        if hover and not io.want_capture_mouse and _in_rect(rect, io.mouse_pos.x, io.mouse_pos.y):
            hovered = drawn.camera_at(io.mouse_pos.x, io.mouse_pos.y)
        colours = {i: HOVER_COLOUR if i == hovered else TEST_COLOUR if cams.test[i] else TRAIN_COLOUR
                   for i in drawn.cameras.tolist()}
        images = self._paint(drawn, colours, segments, owner, rect=rect, hovered=hovered)
        self.drawn = replace(drawn, colours=colours, images=images, segments=len(segments), hovered=hovered)
        if hovered is not None:
            imgui.set_tooltip(f"{hovered}: {loaded.camera_names[hovered]} ({SPLIT_NAMES[bool(cams.test[hovered])]} "
                              f"view): click to fly there")
        nearest = np.argsort(drawn.depth[drawn.quad_shown], kind="stable")
        self.thumbnails.load(loaded, drawn.cameras[drawn.quad_shown][nearest].tolist())

    def _arrays(self, loaded: LoadedScene) -> _Cameras:
        if self._cameras is None or self._cameras.cameras is not loaded.cameras:
            cameras = loaded.cameras
            self._cameras = _Cameras(cameras, np.array([c.R for c in cameras], np.float64),
                                     np.array([c.center for c in cameras], np.float64), image_slopes(cameras),
                                     in_test_split(loaded.camera_names))
        return self._cameras

    @staticmethod
    def _geometry(camera: Camera, cams: _Cameras, kept: np.ndarray, corners: np.ndarray, shown: np.ndarray, *,
                  rect: tuple[float, float, float, float], near: float) -> DrawnFrustums:
        """Where each camera with a line drawn (``shown``, a sorted subset of the sorted
        ``kept``, whose ``corners`` these are) lies on screen."""
        apex = cams.apex[shown]
        depth = (apex @ camera.R.T + camera.t)[:, 2]
        apex_xy = project_points(camera, apex, rect)
        x0, y0, x1, y1 = rect
        apex_shown = (depth >= near) & (apex_xy[:, 0] >= x0) & (apex_xy[:, 0] <= x1) \
            & (apex_xy[:, 1] >= y0) & (apex_xy[:, 1] <= y1)
        corners = corners[np.searchsorted(kept, shown)]                                  # (n, 4, 3)
        # A rectangle cut by the near plane has no quad to fill.
        quad_shown = np.all((corners @ camera.R.T + camera.t)[..., 2] >= near, axis=1)
        quad = project_points(camera, corners.reshape(-1, 3), rect).reshape(-1, 4, 2)
        return DrawnFrustums(shown, depth, apex_xy, apex_shown, quad, quad_shown)

    def _paint(self, drawn: DrawnFrustums, colours: dict[int, tuple], segments: np.ndarray, owner: np.ndarray, *,
               rect: tuple[float, float, float, float], hovered: int | None) -> frozenset[int]:
        """Draws the photos, then the lines over them, the hovered camera's last, then
        the centres; returns the cameras drawn with their photo. Lists, not arrays, go
        to imgui: a thousand cameras are 8,000 lines a frame, each call's cost counts."""
        draw = imgui.get_background_draw_list()
        images = set()
        draw.push_clip_rect(rect[:2], rect[2:], True)  # a photo's quad is cut at the viewport as the lines are
        for i, quad in drawn.quads.items():
            texture = self.thumbnails.texture(i)
            if texture is not None:
                draw.add_image_quad(imgui.ImTextureRef(texture.glo), *quad.tolist(), col=imgui.IM_COL32(*IMAGE_TINT))
                images.add(i)
        draw.pop_clip_rect()
        packed = {i: imgui.IM_COL32(*colour) for i, colour in colours.items()}
        plain = owner != (-1 if hovered is None else hovered)
        line_colours = [packed[i] for i in owner[plain].tolist()]
        for (p, q), colour in zip(segments[plain].tolist(), line_colours):
            draw.add_line(p, q, colour, 1.2)
        for p, q in segments[~plain].tolist():
            draw.add_line(p, q, packed[hovered], 2.5)
        for i, point in zip(drawn.cameras[drawn.apex_shown].tolist(), drawn.apex[drawn.apex_shown].tolist()):
            draw.add_circle_filled(point, 4.0 if i == hovered else 2.5, packed[i])
        return frozenset(images)


def _in_rect(rect: tuple[float, float, float, float], x: float, y: float) -> bool:
    x0, y0, x1, y1 = rect
    return x0 <= x <= x1 and y0 <= y <= y1
