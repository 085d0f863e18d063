"""The GL side of a stereo frame: both eyes drawn with one order into their own
targets (the window's at the blend precision, float32 elsewhere), the optional lens
preview on each, and the layout composed into one image.

The window keeps one :class:`StereoFrame` and shows its composed target; screenshots
and ``render --stereo`` use a fresh one through
:func:`render_stereo_view`, so both go through the same passes.

The post passes (:class:`StereoPasses`) draw the full-screen triangle of
``fullscreen.vert`` into float RGBA targets and read their sources with texelFetch, so
they reproduce :func:`raygs_viewer.camera.lens_model.lens_warp_reference` (to float32
rounding) and :func:`raygs_viewer.camera.stereo.compose` (bit for bit).

With a channel view (a depth, normal or alpha picture instead of the colour) both eyes
show it; an automatic depth range is the left eye's, fixed for the right eye, so the
same colour is the same depth in both (:func:`fixed_range`).
"""

from __future__ import annotations

from dataclasses import replace

import moderngl
import numpy as np

from raygs_viewer.camera.lens_model import LensModel, lens_radius
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoRig, StereoView, composed_size, eye_cameras
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.gl.mono_frame import frame_dtypes
from raygs_viewer.render.gl.results import RenderResult
from raygs_viewer.render.gl.shaders import Programs, set_uniform
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest
from raygs_viewer.sort.request import Order


def fixed_range(view: ChannelView | None, used: tuple[float, float] | None) -> ChannelView | None:
    """``view`` with an automatic depth range replaced by ``used`` (the range the first
    side or eye took), so a second one shows depths in the same colours."""
    if view is None or view.depth_range is not None or used is None:
        return view
    return replace(view, depth_range=used)


def stereo_order(sorter: DepthSorter, camera: Camera, settings: RenderSettings, rig: StereoRig, *,
                 levels: LodRequest | LodChoice | None = None, deleted: DeletedRows | None = None) -> Order:
    """The one back-to-front order both eyes draw: the settings' key seen from the
    midpoint, keeping what either eye may see (of ``levels``' rows, without ``deleted``)."""
    return exact_order(sorter, camera, settings, cull_cameras=eye_cameras(camera, rig), levels=levels, deleted=deleted)


def render_stereo(renderer, sorter: DepthSorter, camera: Camera, settings: RenderSettings, rig: StereoRig, *,
                  shared: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(left, right) float32 (H, W, 4) images of the eyes around the midpoint ``camera``.

    shared=True is what the viewer draws: one sort from the midpoint and SH colour seen
    from it. shared=False sorts each eye from its own position and evaluates colour
    from it: the per-eye images the shared ones approximate."""
    left, right = eye_cameras(camera, rig)
    if shared:
        order = stereo_order(sorter, camera, settings, rig)
        return tuple(renderer.render(eye, settings, order, color_origin=camera.center) for eye in (left, right))
    return tuple(renderer.render(eye, settings, exact_order(sorter, eye, settings)) for eye in (left, right))


def render_stereo_view(renderer, order: Order, camera: Camera, settings: RenderSettings, view: StereoView, *,
                       channel_view: ChannelView | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(image, left, right) float32 (H, W, 4) arrays, top row first: the composed
    stereo image of ``view`` around the midpoint ``camera``, and each eye as it goes
    into the layout (after the lens preview); ``order``: both eyes' (:func:`stereo_order`);
    ``channel_view``: the eyes show that picture instead of the colour. The same GL
    passes as the window's: what screenshots and ``render --stereo`` save."""
    frame = StereoFrame(renderer.ctx)
    try:
        frame.draw_eyes(renderer, camera, settings, eye_cameras(camera, view.rig), order, view=channel_view)
        frame.finish(view)
        return frame.read_image(), *frame.read_eyes()
    finally:
        frame.release()


class StereoFrame:
    """Targets are made on first use and again when a size changes. ``narrow`` (the
    window's): each eye's target takes the blend precision (``mono_frame.frame_dtypes``),
    drawn into with no copy pass; else float32, so that screenshots and ``render
    --stereo`` read the eyes as a float32 render gives them."""

    def __init__(self, ctx: moderngl.Context, narrow: bool = False):
        self.ctx = ctx
        self.narrow = narrow
        self.passes = StereoPasses(ctx)
        self.eyes: tuple[Camera, Camera] | None = None   # the eye cameras of the last draw
        self._eye_targets: list[FloatTarget | None] = [None, None]
        self._lens_targets: list[FloatTarget | None] = [None, None]
        self._image: FloatTarget | None = None
        self._shown: list[FloatTarget] = []      # what went into the layout

    @property
    def image(self) -> FloatTarget | None:
        """The composed target of the last :meth:`finish`."""
        return self._image

    def draw_eyes(self, renderer, camera: Camera, settings: RenderSettings, eyes: tuple[Camera, Camera],
                  order: Order, *, view: ChannelView | None = None) -> tuple[RenderResult, RenderResult]:
        """Draws both ``eyes`` (``camera.stereo.eye_cameras`` around the midpoint
        ``camera``) with ``order``; SH colour is seen from the midpoint (see
        :mod:`raygs_viewer.camera.stereo`). ``view``: the picture both eyes show instead of
        the colour (the right eye in the left's range, which both results carry). Returns
        each eye's result."""
        self.eyes = eyes
        results = []
        dtypes = frame_dtypes(renderer, settings, view) if self.narrow else ("f4",)
        for side, eye in enumerate(self.eyes):
            target = self._sized(self._eye_targets, side, eye.width, eye.height, dtypes=dtypes)
            used = results[0].view_range if results else None
            results.append(renderer.render_into(target, eye, settings, order, color_origin=camera.center,
                                                view=fixed_range(view, used)))
        left, right = results
        return left, replace(right, view_range=left.view_range)

    def finish(self, view: StereoView) -> FloatTarget:
        """The lens preview (if on) and the layout, into the composed target."""
        if self.eyes is None:
            raise RuntimeError("StereoFrame.finish before draw_eyes")
        shown = self._eye_targets
        if view.lens is not None:
            for side, eye in enumerate(self.eyes):
                target = self._sized(self._lens_targets, side, eye.width, eye.height)
                self.passes.lens(self._eye_targets[side].texture, target.fbo, eye, view.lens)
            shown = self._lens_targets
        self._shown = list(shown)
        width, height = composed_size(self.eyes[0].width, self.eyes[0].height, view.layout)
        self._image = sized(self._image, self.ctx, width, height, **_SIZE_ERROR)
        self.passes.compose(shown[0].texture, shown[1].texture, self._image.fbo, view.layout)
        return self._image

    def read_image(self) -> np.ndarray:
        return self._image.read()

    def read_eyes(self) -> tuple[np.ndarray, np.ndarray]:
        """Each eye as it went into the layout (after the lens preview)."""
        return self._shown[0].read(), self._shown[1].read()

    def release(self) -> None:
        release_all(*self._eye_targets, *self._lens_targets, self._image)
        self._eye_targets, self._lens_targets, self._image, self._shown = [None, None], [None, None], None, []
        self.passes.release()

    def _sized(self, targets: list, side: int, width: int, height: int, dtypes: tuple[str, ...] = ("f4",)
               ) -> FloatTarget:
        targets[side] = sized(targets[side], self.ctx, width, height, dtypes=dtypes, **_SIZE_ERROR)
        return targets[side]


_SIZE_ERROR = {"label": "stereo image", "advice": " per side; use a smaller scale"}


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
