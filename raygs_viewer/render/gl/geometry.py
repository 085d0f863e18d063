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
geometry runs the variants without it and pays nothing. The renderer draws into
:meth:`GeometryOutputs.image` by the render's plan (supersampling averages every
attachment in its resolve pass); :func:`raygs_viewer.render.channels.finish` divides the
sums out on the host. The window's view pictures are drawn from the target on the GPU
(glsl/channel_picture.frag), with only an automatic range's samples read back.
"""

from __future__ import annotations

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.channel_pictures import ChannelView, color_table, range_of_samples, sample_step
from raygs_viewer.render.channels import ChannelImage, finish
from raygs_viewer.render.gl.shaders import Programs, set_uniform
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.settings import RenderSettings

#: Colour, depth (sum T alpha z, median z or 0, found) and normal (sum T alpha n).
GEOMETRY_ATTACHMENTS = 3
#: glsl/channel_picture.frag's CHANNEL for each picture it draws.
PICTURE_DEFINES = {"alpha": 1, "depth": 2, "median_depth": 3, "normal": 4}


def takes_lists(settings: RenderSettings, median: bool) -> bool:
    """Whether the geometry outputs of ``settings`` go through the fragment lists (else
    they blend beside colour in its one draw)."""
    return median or settings.per_pixel or settings.transmittance_cutoff


class GeometryOutputs:
    """One renderer's geometry targets (made on first use, one size held) and the
    pictures of their channels."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._image: FloatTarget | None = None
        self._gathered: FloatTarget | None = None   # an automatic range's depth samples
        self._palette: moderngl.Texture | None = None  # viridis, 256 x 1

    def image(self, camera: Camera) -> FloatTarget:
        """The camera-sized target of colour, depth and normal (its three attachments)."""
        self._image = sized(self._image, self.ctx, camera.width, camera.height, attachments=GEOMETRY_ATTACHMENTS)
        return self._image

    @staticmethod
    def read(image: FloatTarget, median: bool) -> ChannelImage:
        """Every channel of a drawn :meth:`image`, finished (``median`` False: without the median)."""
        color, depth, normal = (image.read(attachment=i) for i in range(GEOMETRY_ATTACHMENTS))
        sums = np.concatenate([depth[..., :1], normal[..., :3]], axis=-1)
        return finish(color, sums, depth[..., 1:3] if median else None)

    def picture(self, programs: Programs, target: FloatTarget, image: FloatTarget, camera: Camera,
                view: ChannelView) -> tuple[float, float] | None:
        """Draws the picture of ``view``'s channel of a drawn ``image`` (glsl/channel_picture.frag,
        the twin of render/channel_pictures.py; alpha 1) into ``target`` (camera-sized);
        returns the depth range it used (None: not a depth picture). Nothing is read
        back but an automatic range's samples."""
        channel = PICTURE_DEFINES[view.channel]
        view_range = None
        if view.channel in ("depth", "median_depth"):
            view_range = view.depth_range or range_of_samples(self._depth_samples(programs, image, view))
        program, vao = programs.fullscreen("channel_picture.frag", {"CHANNEL": channel, "SAMPLES": 0})
        to_space = np.asarray(camera.R, np.float32).T if view.normal_space == "world" else np.eye(3, dtype=np.float32)
        set_uniform(program, "u_to_space", to_space.tobytes(order="F"))
        set_uniform(program, "u_range", view_range or (0.0, 1.0))
        set_uniform(program, "u_alpha_threshold", view.alpha_threshold)
        self._bind_inputs(program, image)
        target.use()
        self.ctx.disable(moderngl.BLEND)
        vao.render(moderngl.TRIANGLES, vertices=3)
        return view_range

    def _depth_samples(self, programs: Programs, image: FloatTarget, view: ChannelView) -> np.ndarray:
        """The depths an automatic range is taken from (render/channel_pictures.depth_samples),
        gathered on the GPU into a small target and read back; 0 (none) where masked."""
        height, width = image.size[1], image.size[0]
        step = sample_step(height, width)
        columns, rows = -(-width // step), -(-height // step)
        self._gathered = gathered = sized(self._gathered, self.ctx, columns, rows)
        program, vao = programs.fullscreen("channel_picture.frag", {"CHANNEL": PICTURE_DEFINES[view.channel],
                                                                     "SAMPLES": 1})
        set_uniform(program, "u_step", step)
        set_uniform(program, "u_alpha_threshold", view.alpha_threshold)
        set_uniform(program, "u_samples", (columns, rows))
        self._bind_inputs(program, image)
        gathered.use()
        self.ctx.disable(moderngl.BLEND)
        vao.render(moderngl.TRIANGLES, vertices=3)
        return gathered.read()[..., 0]

    def _bind_inputs(self, program, image: FloatTarget) -> None:
        if self._palette is None:
            table = color_table()
            palette = np.concatenate([table, np.ones((len(table), 1), np.float32)], axis=1)
            self._palette = self.ctx.texture((len(table), 1), 4, palette.astype(np.float32).tobytes(), dtype="f4")
        for unit, (name, texture) in enumerate(zip(("u_color", "u_depth", "u_normal"), image.textures)):
            texture.use(unit)
            set_uniform(program, name, unit)
        self._palette.use(3)
        set_uniform(program, "u_palette", 3)

    def release(self) -> None:
        release_all(self._image, self._gathered)
        self._image = self._gathered = None
        if self._palette is not None:
            self._palette.release()
            self._palette = None
