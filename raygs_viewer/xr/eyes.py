"""Both eyes of a headset frame, drawn into the swapchain images.

The runtime locates each eye (a pose and an asymmetric field of view in the room); the
room (:class:`~raygs_viewer.xr.room.Room`) carries them into the scene as two
:class:`~raygs_viewer.camera.pinhole.Camera` s at the swapchain's size
(:func:`headset_eyes`). One order serves both eyes: sorted from their midpoint and culled
for both (``render.sorting.sort_request`` with ``cull_cameras``), as the stereo preview
does; SH colour is seen from the midpoint. Each eye is drawn with the renderer straight
into its swapchain image (an 8-bit sRGB one: a blend precision of 8 bits draws there
directly, a wider one through the renderer's sample target and its resolve pass, which
rounds as a screenshot rounds), so the image the headset gets is, bit for bit, the
screenshot of that eye's camera with that order.

Depth (``XR_KHR_composition_layer_depth``): the eye's median depth (the geometry pass's
``median`` outputs, the depth at which the ray's accumulated alpha reaches one half) is
written into the depth swapchain image by ``glsl/xr_depth.frag`` as
``1 - near / z`` (metres, an infinite far plane: :func:`depth_values` is its host twin),
and 1 (infinitely far) where the ray found no such depth.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.shaders import set_uniform
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import Order
from raygs_viewer.xr.room import Room, eye_camera, midpoint_camera
from raygs_viewer.xr.session import NEAR_METRES, HeadsetFrame
from raygs_viewer.xr.swapchain import DepthImage


@dataclass(frozen=True)
class HeadsetEyes:
    """A frame's eye cameras (left, right) in the scene, and the midpoint camera its one
    sort is made from (``xr.room.midpoint_camera``)."""

    cameras: tuple[Camera, Camera]
    midpoint: Camera


def headset_eyes(frame: HeadsetFrame, room: Room, sizes: tuple[tuple[int, int], ...]) -> HeadsetEyes | None:
    """The eyes of ``frame`` (None: not located) at the swapchains' ``sizes``."""
    if frame.views is None:
        return None
    left, right = (eye_camera(pose, fov, *size, room) for (pose, fov), size in zip(frame.views, sizes))
    return HeadsetEyes((left, right), midpoint_camera(left, right))


def depth_values(median_depth: np.ndarray, units_per_metre: float, near: float = NEAR_METRES) -> np.ndarray:
    """(H, W) float32 values of the depth image for a median-depth channel in scene units
    (0: none found): ``1 - near / z`` in float32 as ``glsl/xr_depth.frag`` computes it
    (the near plane in scene units over z), 1 where no depth was found."""
    z = np.asarray(median_depth, np.float32)
    near_units = np.float32(near * units_per_metre)
    with np.errstate(divide="ignore", invalid="ignore"):
        values = np.clip(np.float32(1.0) - near_units / z, np.float32(0.0), np.float32(1.0))
    return np.where(z > 0, values, np.float32(1.0)).astype(np.float32)


@dataclass(frozen=True)
class EyeImages:
    """What a capture read back of one headset frame, as submitted: each eye's (H, W, 3)
    uint8 image, top row first, and its depth image ((H, W) float32; None: no depth)."""

    colour: tuple[np.ndarray, np.ndarray]
    depth: tuple[np.ndarray | None, np.ndarray | None]


class EyeDrawer:
    """Draws a headset frame's eyes (:meth:`draw`) under a GPU timer per eye."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.timers = (GpuTimer(ctx), GpuTimer(ctx))

    def draw(self, renderer: GLRenderer, colours: list, depths: list, eyes: HeadsetEyes, *,
             settings: RenderSettings, order: Order, depth: bool, units_per_metre: float,
             capture: bool = False) -> EyeImages | None:
        """Both eyes into the acquired images (``HeadsetSession.acquire``: each eye's
        colour target and depth image); with ``depth``, the depth images too.
        ``capture``: reads each image back before it is released. Returns what was read
        (None without ``capture``). A settings problem is the renderer's UserError."""
        read_colour, read_depth = [], []
        origin = eyes.midpoint.center
        for side, eye in enumerate(eyes.cameras):
            with self.timers[side].measure():
                renderer.render_into(colours[side], eye, settings, order, color_origin=origin)
                if depth:
                    self._depth(renderer, depths[side], eye, settings=settings, order=order, origin=origin,
                                units_per_metre=units_per_metre)
            if capture:
                read_colour.append(colours[side].read(components=3, as_bytes=True).astype(np.uint8))
                read_depth.append(depths[side].read() if depth else None)
        return EyeImages(tuple(read_colour), tuple(read_depth)) if capture else None

    def _depth(self, renderer: GLRenderer, target: DepthImage, eye: Camera, *, settings: RenderSettings,
               order: Order, origin: np.ndarray, units_per_metre: float) -> None:
        image = renderer.geometry.image(eye)
        renderer.draw_planned(image, eye, renderer.plan(settings, "median"), order, color_origin=origin)
        program, vao = renderer.programs.fullscreen("xr_depth.frag", {})
        image.textures[1].use(0)
        set_uniform(program, "u_depth", 0)
        set_uniform(program, "u_near_units", NEAR_METRES * units_per_metre)
        target.fbo.use()
        target.fbo.viewport = (0, 0, eye.width, eye.height)
        ctx = self.ctx
        ctx.disable(moderngl.BLEND)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "1"  # always: every pixel's depth is written
        vao.render(moderngl.TRIANGLES, vertices=3)
        ctx.disable(moderngl.DEPTH_TEST)

    def seconds(self) -> tuple[float, float]:
        """Each eye's GPU seconds of its last draw (NaN: none read yet)."""
        return self.timers[0].seconds, self.timers[1].seconds
