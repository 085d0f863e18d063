"""The geometry outputs on the GL path (docs/geometry.md): expected depth, median depth
and normal beside colour, in the same pass and the same order.

Two ways, one target layout (colour; (sum T alpha z, median z or 0, found, -); (sum
T alpha n, -)):

- blended: a global order without the cut-off and without the median draws the quads
  once, as for colour, into two more attachments blended exactly as colour is
  (glsl/fragment_output.glsl, ``GEOMETRY``): the sums cost a few more outputs a fragment;
- lists: the median needs each pixel's fragments in blend order (the first at which the
  accumulated alpha reaches 0.5), which blending cannot express, and the per-pixel
  order and the cut-off composite in their own passes anyway. They go through the
  fragment lists (render/gl/fragment_lists.py, any OpenGL 4.3 driver): the per-pixel
  order sorts each list by t* as it does for colour, a global order by rank (the very
  order blending composites in), and one resolve pass writes colour and geometry.

Records gain the gaussian's shortest axis (``GEOMETRY``), so a frame that asks for no
geometry runs the variants without it and pays nothing. Supersampling averages every
attachment in its resolve pass; :func:`raygs_viewer.render.channels.finish` divides the
sums out on the host.
"""

from __future__ import annotations

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ChannelView, channel_picture
from raygs_viewer.render.channels import ChannelImage, finish
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.settings import RenderSettings

#: Colour, depth (sum T alpha z, median z or 0, found) and normal (sum T alpha n).
GEOMETRY_ATTACHMENTS = 3


def takes_lists(settings: RenderSettings, median: bool) -> bool:
    """Whether the geometry outputs of ``settings`` go through the fragment lists (else
    they blend beside colour in its one draw)."""
    return median or settings.per_pixel or settings.transmittance_cutoff


class GeometryOutputs:
    """One renderer's geometry targets (made on first use, one size held) and the depth
    range of the last view picture it made (``view_range``; None unless a depth view)."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.view_range: tuple[float, float] | None = None
        self._image: FloatTarget | None = None
        self._samples: FloatTarget | None = None

    def render(self, renderer, camera: Camera, settings: RenderSettings, order: np.ndarray,
               frame: Camera | None = None, color_origin: np.ndarray | None = None,
               median: bool = True) -> ChannelImage:
        """Every channel of ``camera``'s image (camera-space normals) as ``renderer``
        (a GLRenderer) draws ``order`` with ``settings``; ``frame``, ``color_origin``:
        see GLRenderer.preprocess. ``median`` False leaves the median out (None), which
        lets a global order blend the rest in its one draw."""
        image = self.draw(renderer, camera, settings, order, frame, color_origin, median)
        color, depth, normal = (image.read(attachment=i) for i in range(GEOMETRY_ATTACHMENTS))
        sums = np.concatenate([depth[..., :1], normal[..., :3]], axis=-1)
        return finish(color, sums, depth[..., 1:3] if median else None)

    def draw(self, renderer, camera: Camera, settings: RenderSettings, order: np.ndarray,
             frame: Camera | None = None, color_origin: np.ndarray | None = None,
             median: bool = True) -> FloatTarget:
        """The GPU work of :meth:`render`: the camera-sized target holding colour, depth
        and normal (its three attachments), not yet read back."""
        lists = takes_lists(settings, median)
        problem = renderer.supports(settings, geometry=lists)
        if problem:
            raise UserError(problem)
        k = settings.supersample
        sampled = camera.resized(camera.width * k, camera.height * k) if k > 1 else camera
        self._image = image = sized(self._image, self.ctx, camera.width, camera.height,
                                    attachments=GEOMETRY_ATTACHMENTS)
        # The blend starts every attachment at 0 (colour without its background, which the
        # resolve pass adds behind what remains transparent); the lists' resolve writes
        # finished colour, and needs a resolve pass only to average samples.
        resolved = k > 1 or not lists
        drawn = image
        if resolved:
            self._samples = drawn = sized(self._samples, self.ctx, sampled.width, sampled.height,
                                          attachments=GEOMETRY_ATTACHMENTS)
        renderer.preprocess(sampled, settings, frame or camera, color_origin, geometry=True)
        renderer.order_stats = None
        if lists:
            stats = renderer.per_pixel.render(renderer, drawn, sampled, settings, order, geometry=True)
            renderer.order_stats = stats if settings.per_pixel else None
        else:
            drawn.use()
            drawn.fbo.clear(0.0, 0.0, 0.0, 0.0)
            renderer.draw(sampled, settings, order, geometry=True)
        if resolved:
            renderer.resolve_samples(drawn, image, k, settings, front_to_back=not lists, geometry=True)
        return image

    def render_view(self, renderer, target: FloatTarget, camera: Camera, settings: RenderSettings,
                    order: np.ndarray, view: ChannelView, frame: Camera | None = None,
                    color_origin: np.ndarray | None = None) -> None:
        """Puts the picture of ``view``'s channel (render/channel_pictures.py; alpha 1)
        into ``target`` (camera-sized) and records the depth range it used."""
        image = self.render(renderer, camera, settings, order, frame, color_origin,
                            median=view.channel == "median_depth")
        picture, self.view_range = channel_picture(image.in_space(view.normal_space, camera), view)
        rgba = np.concatenate([picture, np.ones(picture.shape[:2] + (1,), np.float32)], axis=-1)[::-1]
        if target.dtype == "f4":
            target.texture.write(np.ascontiguousarray(rgba, np.float32).tobytes())
        else:
            target.texture.write(np.ascontiguousarray(np.rint(rgba * 255.0), np.uint8).tobytes())

    def release(self) -> None:
        release_all(self._image, self._samples)
        self._image = self._samples = None
