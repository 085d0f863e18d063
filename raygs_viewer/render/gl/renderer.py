"""The RayGS renderer on OpenGL 4.3: storage buffers, the preprocessing pass, instanced quads.

Per frame: the CPU sort gives the visible gaussians back to front; the compute
pass turns every gaussian into a per-view :file:`splat.glsl` record (colour,
opacity, c^2, quad axes); the vertex stage draws one quad per sorted index and
the fragment stage evaluates Eq. 16, blending premultiplied colour back to front
into a float32 target with depth clamp on (no near-plane clipping).

The scene's storage buffers, and how they are cut into ranges a GPU can bind, are
:mod:`raygs_viewer.render.gl.storage`. The accuracy options of :class:`RenderSettings`
and the scene select shader variants by ``#define``
(:mod:`raygs_viewer.render.gl.variants`: EWA splatting, the two MIP filters, the parity
switches, the SH degree), so a frame pays only for what is on; at SH degree 0 the
colours are computed once, at load. ``general=True`` forces the one variant that switches every
feature by uniforms instead, to measure what specialising saves. Supersampling and
the transmittance cut-off render into a sample target first; a resolve pass filters
it down into the caller's target.

The renderer draws the :class:`~raygs_viewer.sort.request.Order` it is handed (it owns
no sorter); an order of a level-of-detail choice carries the rows it covers, and only
those are preprocessed. Each render returns what it did (:class:`RenderResult`).

Work that the view has not changed is skipped: :meth:`GLRenderer.preprocess` for the
view, settings, colour origin and rows it last wrote the records for, and the order's
upload for the order array it last uploaded (orders are never modified once made).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_key
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.channels import ChannelImage
from raygs_viewer.render.gl.geometry import GeometryOutputs
from raygs_viewer.render.gl.results import OrderStats, RenderResult
from raygs_viewer.render.gl.per_pixel import PerPixelOrder
from raygs_viewer.render.gl.shaders import set_uniform
from raygs_viewer.render.gl.storage import (
    EXACT_MIP_SPLAT_BYTES,
    GEOMETRY_BYTES,
    SPLAT_BYTES,
    SceneBuffers,
    StorageLayout,
)
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.gl.variants import ShaderVariants
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.request import Order

GL_DEPTH_CLAMP = 0x864F
GL_EXT_FRAMEBUFFER_FETCH = "GL_EXT_shader_framebuffer_fetch"
WORKGROUP = 128  # local_size_x of preprocess.comp


@dataclass
class WorkCounters:
    """What the renderer did and skipped since it was made (for tests and the panel)."""

    preprocessed: int = 0       # preprocessing passes run
    preprocess_skipped: int = 0  # ... skipped: the records were already this view's
    uploads: int = 0            # order uploads
    upload_skipped: int = 0     # ... skipped: that order was already on the GPU


def as_order(order: Order | np.ndarray) -> Order:
    """``order`` as an :class:`Order`: an index array given by hand (a test's, the
    reference's ``global_order``) is an order over the whole scene."""
    return order if isinstance(order, Order) else Order(order)


class GLRenderer:
    """Renders one scene; keeps its storage buffers until :meth:`release`.

    ``block_limit`` overrides the GPU's per-block storage limit (tests use a tiny one
    to exercise the splitting). ``pool_fragments`` and ``order_path`` ("auto", "lists",
    "fetch") configure the per-pixel order (render/gl/per_pixel.py).
    ``general``: draw with the all-features variant (see the module docstring).
    ``storage`` holds the buffers (render/gl/storage.py),
    ``variants`` the compiled programs (render/gl/variants.py).
    """

    def __init__(self, ctx: moderngl.Context, scene: Scene, *, block_limit: int | None = None,
                 memory_limit: int | None = None, general: bool = False,
                 pool_fragments: int | None = None, order_path: str = "auto"):
        self.ctx = ctx
        self.general = bool(general)
        self.counters = WorkCounters()
        self.scene = scene
        self.storage = SceneBuffers(ctx, scene, block_limit=block_limit, memory_limit=memory_limit)
        self.layout = self.storage.layout
        self.gpu_bytes = self.storage.gpu_bytes
        self.variants = ShaderVariants(ctx, scene.sh_degree, self.general)
        self._last_layout = self.layout
        self._preprocessed_key: tuple | None = None  # what the records in storage.splats were made for
        #: Off only to demonstrate the near-plane seam that depth clamp prevents.
        self.depth_clamp = True
        self.per_pixel = PerPixelOrder(ctx, scene.count, self.storage.block_limit, pool_fragments, order_path)
        self._target: FloatTarget | None = None          # render()'s image, the latest size
        self._samples: FloatTarget | None = None         # supersampling and front to back
        self.geometry = GeometryOutputs(ctx)

    def layout_for(self, settings: RenderSettings, geometry: bool = False) -> StorageLayout:
        """The storage layout of ``settings``' records (exact MIP's are larger, and
        ``geometry``'s hold the normal too)."""
        splat_bytes = EXACT_MIP_SPLAT_BYTES if settings.mode == "raygs-exact-mip" else SPLAT_BYTES
        return self.storage.layout_for(splat_bytes + (GEOMETRY_BYTES if geometry else 0))

    def supports(self, settings: RenderSettings, geometry: bool = False) -> str | None:
        """None when this GPU can render ``settings`` (with the geometry outputs), else
        why not (one line)."""
        if settings.per_pixel or geometry:  # composites in its own passes, the cut-off included
            return self.per_pixel.problem(settings, self.layout_for(settings, geometry).splat_blocks, geometry)
        if settings.transmittance_cutoff and GL_EXT_FRAMEBUFFER_FETCH not in self.ctx.extensions:
            return (f"the transmittance cut-off needs {GL_EXT_FRAMEBUFFER_FETCH}, "
                    f"which this GPU's OpenGL driver does not offer")
        return None

    # -- per-frame passes ---------------------------------------------------------
    def preprocess(self, camera: Camera, settings: RenderSettings, frame: Camera | None = None,
                   color_origin: np.ndarray | None = None, geometry: bool = False,
                   spans: np.ndarray | None = None) -> None:
        """Writes the per-view splat record of every gaussian for ``camera`` (the camera
        actually rasterized: already supersampled). ``frame``: the whole image's camera
        when ``camera`` renders one tile of it (GS clamps rays to the whole image).
        ``color_origin``: the world point SH colour is seen from (default: the camera's
        centre; stereo shares the eyes' midpoint). ``geometry``: records with the normal.
        ``spans``: (S, 2) ascending [start, stop) rows to write (the order's level-of-detail
        choice, ``Order.spans``); None: every row."""
        origin = camera.center if color_origin is None else np.asarray(color_origin, np.float64)
        spans = None if spans is None else np.asarray(spans, np.int64).reshape(-1, 2)
        key = (camera_key(camera), settings, None if frame is None else camera_key(frame), origin.tobytes(),
               geometry, None if spans is None else spans.tobytes())
        if key == self._preprocessed_key:
            self.counters.preprocess_skipped += 1
            return
        self._preprocessed_key = None  # until this pass has written every record
        layout = self.layout_for(settings, geometry)
        self.storage.hold_records(layout, settings.mode)
        self._last_layout = layout
        program = self.variants.preprocess(settings, geometry)
        self.variants.set_features(program, settings)
        set_view_uniforms(program, camera, settings, frame, origin)
        for chunk in self.storage.preprocess_chunks(layout, self.variants.colors_at_load(settings)):
            program["u_out_offset"].value = chunk.offset
            for first, count in chunk_runs(chunk.start, chunk.count, spans):
                set_uniform(program, "u_first", first)  # gone where a negative control breaks the shader
                program["u_count"].value = count
                program.run(group_x=-(-count // WORKGROUP))
        self.ctx.memory_barrier()
        self.counters.preprocessed += 1
        self._preprocessed_key = key

    def read_splats(self) -> np.ndarray:
        """(N, F) float32 copy of the per-view records of the last :meth:`preprocess`
        (the ``Splat`` struct, row by row; F = 16, or 28 in exact MIP mode), for tests
        and diagnostics."""
        return self.storage.read_records(self._last_layout)

    def draw(self, camera: Camera, settings: RenderSettings, order: Order, *, floor: bool = False,
             path: str | None = None, uniforms: dict | None = None, geometry: bool = False) -> None:
        """Draws the quads of ``order`` (back to front) into the bound framebuffer, as
        the last :meth:`preprocess` (same camera and settings) prepared them.
        ``floor``: the same quads with a constant, never discarded fragment instead
        (glsl/quads.*): the least this rasterizer can spend on them (bench perf).
        ``path``, ``uniforms``: a per-pixel order pass (render/gl/per_pixel.py) and its
        uniforms; blending off, the quads drawn front to back. ``geometry``: the lists
        pass of the geometry outputs (render/gl/geometry.py)."""
        if order.count == 0:
            return
        layout = self.layout_for(settings, geometry)
        problem = self.supports(settings, geometry and path is not None)  # the blended geometry needs nothing more
        if problem:
            raise UserError(problem)
        program, vao = self.variants.draw(settings, layout, floor, path, geometry)
        for name, value in (uniforms or {}).items():
            set_uniform(program, name, value)
        self.upload_order(order)
        self.storage.bind_for_draw(layout, order.count)
        set_uniform(program, "u_projection", camera.gl_projection().astype(np.float32).tobytes(order="F"))
        set_uniform(program, "u_image_size", (camera.width, camera.height))
        set_uniform(program, "u_pixel_variance", settings.pixel_variance(camera))
        set_uniform(program, "u_order_count", order.count)
        set_uniform(program, "u_p_min", settings.p_min)
        set_uniform(program, "u_intrinsics", (camera.fx, camera.fy, camera.cx, camera.cy))  # GS geometry
        self.variants.set_features(program, settings)
        ctx = self.ctx
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        if settings.transmittance_cutoff or path is not None:
            ctx.disable(moderngl.BLEND)  # the fragment stage composites (framebuffer fetch) or stores
        else:
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            ctx.blend_equation = moderngl.FUNC_ADD
        if self.depth_clamp:
            ctx.enable_direct(GL_DEPTH_CLAMP)
        else:
            ctx.disable_direct(GL_DEPTH_CLAMP)
        vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=order.count)

    def upload_order(self, order: Order) -> None:
        """Puts ``order`` in the GPU's order buffer, unless its very index array is
        already there (orders are not modified once made: a new view makes a new one).
        The one door an order takes to the GPU."""
        uploaded = self.storage.upload_order(order.indices)  # which refuses an order longer than the scene
        self.counters.uploads += uploaded
        self.counters.upload_skipped += not uploaded

    def render(self, camera: Camera, settings: RenderSettings, order: Order | np.ndarray,
               frame: Camera | None = None, color_origin: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 4) float32 image, top row first: RGB over the background, and alpha.
        ``frame``, ``color_origin``: see :meth:`preprocess`."""
        self._target = sized(self._target, self.ctx, camera.width, camera.height)
        self.render_into(self._target, camera, settings, order, frame, color_origin)
        return self._target.read()

    def render_channels(self, camera: Camera, settings: RenderSettings, order: Order | np.ndarray,
                        frame: Camera | None = None, color_origin: np.ndarray | None = None,
                        median: bool = True) -> ChannelImage:
        """Colour, alpha and the geometry outputs of ``camera``'s image (camera-space
        normals; render/gl/geometry.py). Arguments as :meth:`render`; ``median`` False
        leaves the median depth out (None): a global order then draws once, blending."""
        return self.geometry.render(self, camera, settings, as_order(order), frame, color_origin, median)

    def render_into(self, target: FloatTarget, camera: Camera, settings: RenderSettings,
                    order: Order | np.ndarray, frame: Camera | None = None,
                    color_origin: np.ndarray | None = None, view: ChannelView | None = None) -> RenderResult:
        """Clears ``target`` (camera-sized, float colour) and draws the scene into it:
        background-composited colour in RGB and the accumulated alpha in A; or, with a
        ``view`` of another channel than rgb, that channel's picture (alpha 1; the depth
        range it used is in the result).

        Plain back-to-front rendering draws straight into ``target``, cleared to
        (background, 0). Supersampling (k x k) draws into a k-times larger sample target
        with the camera scaled to match, and the transmittance cut-off composites front
        to back into a target cleared to 0; a resolve pass then averages the samples and
        adds the background."""
        k = settings.supersample
        order = as_order(order)
        if view is not None and view.channel != "rgb":
            return self.geometry.render_view(self, target, camera, settings, order, view, frame, color_origin)
        if settings.per_pixel:
            return RenderResult(self._render_per_pixel(target, camera, settings, order, frame, color_origin))
        if k == 1 and not settings.transmittance_cutoff:
            target.use()
            target.fbo.clear(*settings.background, 0.0)
            self.preprocess(camera, settings, frame, color_origin, spans=order.spans)
            self.draw(camera, settings, order)
            return RenderResult()
        sampled = camera.resized(camera.width * k, camera.height * k) if k > 1 else camera
        self._samples = samples = sized(self._samples, self.ctx, sampled.width, sampled.height)
        samples.use()
        if settings.transmittance_cutoff:
            samples.fbo.clear(0.0, 0.0, 0.0, 0.0)
        else:
            samples.fbo.clear(*settings.background, 0.0)
        self.preprocess(sampled, settings, frame or camera, color_origin, spans=order.spans)  # the bounds are scale-invariant
        self.draw(sampled, settings, order)
        self.resolve_samples(samples, target, k, settings, settings.transmittance_cutoff)
        return RenderResult()

    def _render_per_pixel(self, target: FloatTarget, camera: Camera, settings: RenderSettings,
                          order: Order, frame: Camera | None, color_origin: np.ndarray | None) -> OrderStats:
        """render_into for the per-pixel order: its passes write the finished image (over
        the background) into ``target``, or into the sample target that supersampling
        then averages down. Returns what the passes did."""
        k = settings.supersample
        problem = self.supports(settings)
        if problem:
            raise UserError(problem)
        sampled = camera.resized(camera.width * k, camera.height * k) if k > 1 else camera
        image = target
        if k > 1 or target.dtype != "f4":
            self._samples = image = sized(self._samples, self.ctx, sampled.width, sampled.height)
        self.preprocess(sampled, settings, frame or camera, color_origin, spans=order.spans)
        stats = self.per_pixel.render(self, image, sampled, settings, order)
        if image is not target:
            self.resolve_samples(image, target, k, settings, False)
        return stats

    def resolve_samples(self, samples: FloatTarget, target: FloatTarget, k: int,
                        settings: RenderSettings, front_to_back: bool, geometry: bool = False) -> None:
        """Averages ``samples``' k x k blocks into ``target`` (resolve.frag); after
        front-to-back compositing, adds the background. ``geometry``: both have the
        geometry attachments, averaged too."""
        program, vao = self.variants.resolve(front_to_back, geometry)
        target.use()
        self.ctx.disable(moderngl.BLEND)
        samples.texture.use(0)
        program["u_samples"].value = 0
        if geometry:
            for unit, name in ((1, "u_depth"), (2, "u_normal")):
                samples.textures[unit].use(unit)
                program[name].value = unit
        program["u_factor"].value = k
        set_uniform(program, "u_background", settings.background)
        vao.render(moderngl.TRIANGLES, vertices=3)

    def release(self) -> None:
        release_all(self._target, self._samples)
        self._target = self._samples = None
        self.geometry.release()
        self.per_pixel.release()
        self.variants.release()
        self.storage.release()


def set_view_uniforms(program, camera: Camera, settings: RenderSettings, frame: Camera | None,
                      origin: np.ndarray) -> None:
    """The preprocessing pass's uniforms of the view (see ``GLRenderer.preprocess``)."""
    program["u_world_to_camera"].write(camera.R.astype(np.float32).tobytes(order="F"))
    program["u_translation"].value = tuple(np.asarray(camera.t, np.float64).astype(np.float32))
    set_uniform(program, "u_color_origin", tuple(origin.astype(np.float32)))  # gone at SH degree 0
    program["u_log_p_min"].value = math.log(settings.p_min)
    set_uniform(program, "u_pixel_variance", settings.pixel_variance(camera))
    set_uniform(program, "u_intrinsics", (camera.fx, camera.fy, camera.cx, camera.cy))
    set_uniform(program, "u_ray_bounds", gs_ray_bounds(frame or camera))


def chunk_runs(start: int, count: int, spans: np.ndarray | None) -> list[tuple[int, int]]:
    """(first, count) runs, relative to the chunk, of the chunk's rows ``start ..
    start + count`` that ``spans`` cover (all of them for None)."""
    if spans is None:
        return [(0, count)]
    lo = np.maximum(spans[:, 0], start)
    hi = np.minimum(spans[:, 1], start + count)
    keep = hi > lo
    return [(int(a) - start, int(b - a)) for a, b in zip(lo[keep], hi[keep])]


def gs_ray_bounds(camera: Camera) -> tuple[float, float, float, float]:
    """INRIA's clamp box for the ray x/z, y/z of GS's Jacobian: the image's borders
    widened by 15 % of its size on each side (lower x, lower y, upper x, upper y)."""
    margin_x, margin_y = 0.15 * camera.width / camera.fx, 0.15 * camera.height / camera.fy
    return (-camera.cx / camera.fx - margin_x, -camera.cy / camera.fy - margin_y,
            (camera.width - camera.cx) / camera.fx + margin_x, (camera.height - camera.cy) / camera.fy + margin_y)
