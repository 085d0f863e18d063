"""The stereo preview's post passes on the GPU: the lens warp of each eye and the layout.

Both draw the full-screen triangle of ``fullscreen.vert`` into float RGBA targets and read
their sources with texelFetch, so they reproduce :func:`raygs_viewer.camera.lens_model.
lens_warp_reference` (to float32 rounding) and :func:`raygs_viewer.camera.stereo.compose`
(bit for bit).
"""

from __future__ import annotations

import moderngl
import numpy as np

from raygs_viewer.camera.lens_model import LensModel, lens_radius
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import composed_size
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.shaders import Programs, set_uniform

_LEFT, _RIGHT = (0, 0, 0, 0), (1, 1, 1, 1)
# Per layout, for each eye-wide half of the target: which channels come from the right eye.
_FROM_RIGHT = {
    "sbs": (_LEFT, _RIGHT),
    "cross": (_RIGHT, _LEFT),
    "anaglyph": ((0, 1, 1, 1), _LEFT),
    "left": (_LEFT, _LEFT),
    "right": (_RIGHT, _LEFT),
}


class StereoPasses:
    """Post passes of the stereo preview, on float RGBA textures."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._programs = Programs(ctx)

    def _draw(self, vao: moderngl.VertexArray, target: moderngl.Framebuffer) -> None:
        target.viewport = (0, 0, *target.size)
        target.use()
        self.ctx.disable(moderngl.BLEND)
        vao.render(moderngl.TRIANGLES, vertices=3)

    def lens(self, source: moderngl.Texture, target: moderngl.Framebuffer, eye: Camera, model: LensModel) -> None:
        """Writes the lens-warped image of ``source`` (eye-sized, as render_into leaves it)
        into ``target`` (eye-sized)."""
        size = (eye.width, eye.height)
        if tuple(source.size) != size or tuple(target.size) != size:
            raise ValueError(f"lens pass: source {source.size} and target {target.size} must be the eye's {size}")
        program, vao = self._programs.fullscreen("lens.frag")
        source.use(0)
        set_uniform(program, "u_image", 0)
        set_uniform(program, "u_center", (float(eye.cx), float(eye.cy)))
        set_uniform(program, "u_radius", lens_radius(eye))
        set_uniform(program, "u_k1", model.k1)
        set_uniform(program, "u_k2", model.k2)
        set_uniform(program, "u_edge_gain", model.edge_gain)
        set_uniform(program, "u_scales", model.channel_scales)
        self._draw(vao, target)

    def compose(self, left: moderngl.Texture, right: moderngl.Texture, target: moderngl.Framebuffer,
                layout: str) -> None:
        """Writes stereo.compose(left, right, layout) into ``target`` (2W x H for sbs/cross, W x H otherwise)."""
        expected = composed_size(*left.size, layout)
        if layout not in _FROM_RIGHT:
            raise UserError(f"the stereo preview cannot compose the {layout!r} layout yet")
        if tuple(right.size) != tuple(left.size) or tuple(target.size) != expected:
            raise ValueError(f"compose {layout}: eyes {left.size} and {right.size} need a {expected} target, "
                             f"got {target.size}")
        program, vao = self._programs.fullscreen("stereo_compose.frag")
        left.use(0)
        right.use(1)
        set_uniform(program, "u_left", 0)
        set_uniform(program, "u_right", 1)
        set_uniform(program, "u_halves", expected[0] // left.size[0])  # eye-wide halves: 2 side by side
        set_uniform(program, "u_from_right", np.asarray(_FROM_RIGHT[layout], np.int32).tobytes())
        self._draw(vao, target)

    def release(self) -> None:
        self._programs.release()
