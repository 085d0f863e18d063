"""The RayGS renderer on OpenGL 4.3: storage buffers, the preprocessing pass, instanced quads.

Per frame: the sort gives the visible gaussians back to front (an
:class:`~raygs_viewer.sort.request.Order`, which the renderer is handed: it owns no
sorter); the compute pass turns every gaussian into a per-view :file:`splat.glsl`
record (colour, opacity, c^2, quad axes); the vertex stage draws one quad per sorted
index and the fragment stage evaluates Eq. 16, blending premultiplied colour back to
front into a float32 target with depth clamp on (no near-plane clipping). An order of
a level-of-detail choice carries the rows it covers, and only those are preprocessed.

Each render is planned once (:meth:`GLRenderer.plan`, :mod:`raygs_viewer.render.gl.plan`):
the variant of every pass, its storage layout and whether this GPU can draw it. The
scene's storage buffers, and how they are cut into ranges a GPU can bind, are
:mod:`raygs_viewer.render.gl.storage`; at SH degree 0 the colours are computed once, at
load. Supersampling, the transmittance cut-off and the per-pixel passes on a target
they cannot write draw into a sample target first; a resolve pass filters it down into
the caller's target (:meth:`GLRenderer.draw_planned`, the one home of that). Each
render returns what it did (:class:`~raygs_viewer.render.gl.results.RenderResult`).

Work that the view has not changed is skipped: the preprocessing pass
(:mod:`raygs_viewer.render.gl.preprocess_pass`) when everything it reads is what it
last wrote the records for; and the order's upload for the order array it last
uploaded (orders are never modified once made).
"""

from __future__ import annotations

from contextlib import ExitStack

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.channels import ChannelImage, Outputs
from raygs_viewer.render.gl.geometry import GeometryOutputs
from raygs_viewer.render.gl.gpu_sort import COMMAND_INDEX
from raygs_viewer.render.gl.per_pixel import PerPixelOrder
from raygs_viewer.render.gl.plan import DEFAULT_DRAW_LAYOUT, DrawLayout, RenderPlan
from raygs_viewer.render.gl.planner import Planner
from raygs_viewer.render.gl.preprocess_pass import PreprocessPass, WorkCounters
from raygs_viewer.render.gl.results import OrderStats, RenderResult
from raygs_viewer.render.gl.shaders import Programs, set_uniform
from raygs_viewer.render.gl.storage import SceneBuffers
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.request import Order

GL_DEPTH_CLAMP = 0x864F
GL_EXT_FRAMEBUFFER_FETCH = "GL_EXT_shader_framebuffer_fetch"


def as_order(order: Order | np.ndarray) -> Order:
    """``order`` as an :class:`Order`: an index array given by hand (a test's, the
    reference's ``global_order``) is an order over the whole scene."""
    return order if isinstance(order, Order) else Order(order)


class GLRenderer:
    """Renders one scene; keeps its storage buffers until :meth:`release`.

    ``block_limit`` overrides the GPU's per-block storage limit (tests use a tiny one
    to exercise the splitting). ``pool_fragments`` and ``order_path`` ("auto", "lists",
    "fetch") configure the per-pixel order (render/gl/per_pixel.py).
    ``general``: draw with the all-features variant (:mod:`raygs_viewer.render.gl.plan`).
    ``draw_layout``: how the quads and records are laid out (render/gl/plan.py,
    :class:`DrawLayout`; every layout draws the same image) where a render asks for no
    layout of its own (a benchmark measures each through :meth:`plan`'s ``draw_layout``).
    ``storage`` holds the buffers (render/gl/storage.py), ``programs`` the compiled ones;
    ``planner`` plans every render (:meth:`plan`). What it makes on the GPU is released
    once, by :meth:`release`; a part that fails while the renderer is being made releases
    the parts made before it.
    """

    def __init__(self, ctx: moderngl.Context, scene: Scene, *, block_limit: int | None = None,
                 memory_limit: int | None = None, general: bool = False,
                 pool_fragments: int | None = None, order_path: str = "auto",
                 draw_layout: DrawLayout = DEFAULT_DRAW_LAYOUT):
        self.ctx = ctx
        self.general = bool(general)
        self.draw_layout = draw_layout
        self.counters = WorkCounters()
        self.scene = scene
        #: Off only to demonstrate the near-plane seam that depth clamp prevents.
        self.depth_clamp = True
        self._target: FloatTarget | None = None  # render()'s image, the latest size
        self._samples: dict[tuple[str, ...], FloatTarget] = {}  # sample targets, by their attachments' kinds
        self._indexed: dict[int, moderngl.VertexArray] = {}  # the indexed draw's arrays, by program
        with ExitStack() as made:
            self.storage = SceneBuffers(ctx, scene, block_limit=block_limit, memory_limit=memory_limit)
            made.callback(self.storage.release)
            self.programs = Programs(ctx)
            made.callback(self.programs.release)
            self.per_pixel = PerPixelOrder(ctx, self.storage.block_limit, pool_fragments, order_path)
            made.callback(self.per_pixel.release)
            self.geometry = GeometryOutputs(ctx)
            made.callback(self.geometry.release)
            made.callback(self._release_targets)  # made as sizes come, released first
            self._owned = made.pop_all()
        self.layout = self.storage.layout
        self.gpu_bytes = self.storage.gpu_bytes
        self.preprocessing = PreprocessPass(ctx, self.storage, self.programs, self.upload_order, self.counters)
        self.planner = Planner(ctx, self.storage.layout_for, scene.count, scene.sh_degree, general=self.general,
                               order_path=self.per_pixel.order_path)

    def plan(self, settings: RenderSettings, outputs: Outputs = "color", *,
             draw_layout: DrawLayout | None = None) -> RenderPlan:
        """The plan of a render of ``settings`` that draws ``outputs`` on this GPU and scene
        (:meth:`Planner.plan`), in ``draw_layout`` (None: the renderer's ``draw_layout``)."""
        return self.planner.plan(settings, outputs, draw_layout or self.draw_layout)

    def supports(self, settings: RenderSettings) -> str | None:
        """None when this GPU can render ``settings``' colour, else why not (one line)."""
        return self.plan(settings).problem

    # -- per-frame passes ---------------------------------------------------------
    def preprocess(self, camera: Camera, plan: RenderPlan, order: Order | None = None, *,
                   frame: Camera | None = None, color_origin: np.ndarray | None = None) -> None:
        """The per-view records of ``camera`` in ``plan``'s variant (:meth:`PreprocessPass.run`)."""
        self.preprocessing.run(camera, plan, order, frame=frame, color_origin=color_origin)

    def forget_records(self) -> None:
        """The next :meth:`preprocess` runs whatever it last wrote (a benchmark times it)."""
        self.preprocessing.forget()

    def read_splats(self) -> np.ndarray:
        """(N, F) float32 copy of the last :meth:`preprocess`'s records (:meth:`PreprocessPass.read`)."""
        return self.preprocessing.read()

    def draw(self, camera: Camera, plan: RenderPlan, order: Order, *, floor: bool = False,
             uniforms: dict | None = None) -> None:
        """Draws the quads of ``order`` (back to front) into the bound framebuffer, as
        the last :meth:`preprocess` (same camera and plan) prepared them. ``floor``: the
        same quads with a constant, never discarded fragment instead (glsl/quads.*): the
        least this rasterizer can spend on them (bench perf). ``uniforms``: a per-pixel
        pass's own (render/gl/per_pixel.py); with a per-pixel path or the cut-off,
        blending is off and the fragment stage composites or stores."""
        if order.count == 0:
            return
        if plan.problem:
            raise UserError(plan.problem)
        vertex, fragment, defines = plan.draw_stages(floor)
        program, vao = self.programs.draw(vertex, fragment, defines)
        for name, value in {**(uniforms or {}), **plan.feature_uniforms()}.items():
            set_uniform(program, name, value)
        self.upload_order(order)
        self.storage.bind_for_draw(plan.layout, order.count)
        settings = plan.settings
        set_uniform(program, "u_projection", camera.gl_projection().astype(np.float32).tobytes(order="F"))
        set_uniform(program, "u_image_size", (camera.width, camera.height))
        set_uniform(program, "u_pixel_variance", settings.pixel_variance(camera))
        set_uniform(program, "u_order_count", order.count)
        set_uniform(program, "u_p_min", settings.p_min)
        set_uniform(program, "u_intrinsics", (camera.fx, camera.fy, camera.cx, camera.cy))  # GS geometry
        ctx = self.ctx
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        if plan.front_to_back or plan.path is not None:
            ctx.disable(moderngl.BLEND)
        else:
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            ctx.blend_equation = moderngl.FUNC_ADD
        if self.depth_clamp:
            ctx.enable_direct(GL_DEPTH_CLAMP)
        else:
            ctx.disable_direct(GL_DEPTH_CLAMP)
        vertices = plan.draw.vertices
        commands = order.indices.commands if order.on_device else None
        if commands is not None:  # a GPU sort's order: the count its own pass wrote (glsl/sort_commands.comp)
            mode = moderngl.TRIANGLE_STRIP if vertices == "instanced" else moderngl.TRIANGLES
            array = self._indexed_array(program) if vertices == "indexed" else vao
            array.render_indirect(commands, mode, count=1, first=COMMAND_INDEX[vertices])
        elif vertices == "instanced":
            vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=order.count)
        elif vertices == "indexed":
            self._indexed_array(program).render(moderngl.TRIANGLES, vertices=6 * order.count)
        else:
            vao.render(moderngl.TRIANGLES, vertices=6 * order.count)

    def _indexed_array(self, program: moderngl.Program) -> moderngl.VertexArray:
        """``program``'s vertex array with the quads' index buffer (storage.quad_indices)."""
        key = program.glo
        if key not in self._indexed:
            self._indexed[key] = self.ctx.vertex_array(program, [], index_buffer=self.storage.quad_indices(),
                                                       index_element_size=4)
        return self._indexed[key]

    def upload_order(self, order: Order) -> None:
        """Puts ``order`` in the GPU's order buffer, unless its very indices are already
        there (orders are not modified once made: a new view makes a new one). The one
        door an order takes to the GPU: an order a GPU sort made is copied there on the
        GPU, never through the CPU."""
        uploaded = self.storage.upload_order(order.indices, order.count)  # which refuses one longer than the scene
        self.counters.uploads += uploaded
        self.counters.upload_skipped += not uploaded

    def draw_planned(self, target: FloatTarget, camera: Camera, plan: RenderPlan, order: Order, *,
                     frame: Camera | None = None, color_origin: np.ndarray | None = None) -> OrderStats | None:
        """Draws ``order`` by ``plan`` into ``target`` (camera-sized, with the plan's
        attachments): the preprocessing pass, then the blended draw or the per-pixel
        passes, into a k x k sample target first where supersampling, front-to-back
        compositing or a target the per-pixel passes cannot write call for one, then
        resolved down; also where the blend precision is not the target's (float16 and
        8-bit blend into a sample target of their own). Returns what the per-pixel
        order's passes did (None otherwise)."""
        if plan.problem:
            raise UserError(plan.problem)
        settings, k = plan.settings, plan.settings.supersample
        sampled = camera.resized(camera.width * k, camera.height * k) if k > 1 else camera
        drawn = target
        dtypes = plan.target_dtypes(target.attachments)  # the blend precision's, or float32 for the per-pixel passes
        if k > 1 or plan.front_to_back or target.dtypes != dtypes:
            drawn = self._sample_target(sampled, dtypes)
        self.preprocess(sampled, plan, order, frame=frame or camera,  # the bounds are scale-invariant
                        color_origin=color_origin)
        stats = None
        if plan.path is not None:  # its passes write every pixel, over the background
            stats = self.per_pixel.render(self, drawn, sampled, plan, order)
        else:
            if plan.geometry:  # colour from (background, 0), as the colour draw does; the sums from 0
                drawn.clear_each((*settings.background, 0.0), (0.0,) * 4, (0.0,) * 4)
                drawn.use()
            else:
                drawn.use()
                drawn.fbo.clear(*((0.0,) * 3 if plan.front_to_back else settings.background), 0.0)
            self.draw(sampled, plan, order)
        if drawn is not target:
            self.resolve_samples(drawn, target, plan)
        return stats if settings.per_pixel else None

    def resolve_samples(self, samples: FloatTarget, target: FloatTarget, plan: RenderPlan) -> None:
        """Averages ``samples``' k x k blocks into ``target`` (resolve.frag), every
        attachment the plan has; after front-to-back compositing, adds the background."""
        program, vao = self.programs.fullscreen("resolve.frag", plan.resolve_defines(target.dtypes[0] == "f1"))
        target.use()
        self.ctx.disable(moderngl.BLEND)
        for unit, name in enumerate(("u_samples", "u_depth", "u_normal")[:samples.attachments]):
            samples.textures[unit].use(unit)
            set_uniform(program, name, unit)
        program["u_factor"].value = plan.settings.supersample
        set_uniform(program, "u_background", plan.settings.background)
        vao.render(moderngl.TRIANGLES, vertices=3)

    # -- whole renders ------------------------------------------------------------------
    @property
    def selection_key(self) -> bytes | None:
        """The digest of the selection drawn tinted (None: none): a frame holding another is stale."""
        return self.storage.selection_key

    def set_selection(self, mask: np.ndarray | None, key: bytes | None = None) -> None:
        """Draws the gaussians of ``mask`` ((N,) bool; None: none) tinted from the next
        render on (``SceneBuffers.set_selection``; ``key``: the mask's digest)."""
        self.storage.set_selection(mask, key)

    def render(self, camera: Camera, settings: RenderSettings, order: Order | np.ndarray, *,
               frame: Camera | None = None, color_origin: np.ndarray | None = None,
               draw_layout: DrawLayout | None = None) -> np.ndarray:
        """(H, W, 4) float32 image, top row first: RGB over the background, and alpha.
        ``frame``, ``color_origin``: see :meth:`preprocess`; ``draw_layout``: see :meth:`plan`."""
        self._target = sized(self._target, self.ctx, camera.width, camera.height)
        self.draw_planned(self._target, camera, self.plan(settings, draw_layout=draw_layout), as_order(order),
                          frame=frame, color_origin=color_origin)
        return self._target.read()

    def render_channels(self, camera: Camera, settings: RenderSettings, order: Order | np.ndarray, *,
                        frame: Camera | None = None, color_origin: np.ndarray | None = None,
                        median: bool = True) -> ChannelImage:
        """Colour, alpha and the geometry outputs of ``camera``'s image (camera-space
        normals; render/gl/geometry.py). Arguments as :meth:`render`; ``median`` False
        leaves the median depth out (None): a global order then draws once, blending."""
        image = self.geometry.image(camera)
        plan = self.plan(settings, "median" if median else "geometry")
        self.draw_planned(image, camera, plan, as_order(order), frame=frame, color_origin=color_origin)
        return self.geometry.read(image, median)

    def render_into(self, target: FloatTarget, camera: Camera, settings: RenderSettings,
                    order: Order | np.ndarray, *, frame: Camera | None = None,
                    color_origin: np.ndarray | None = None, view: ChannelView | None = None) -> RenderResult:
        """Clears ``target`` (camera-sized, float colour) and draws the scene into it:
        background-composited colour in RGB and the accumulated alpha in A; or, with a
        ``view`` of another channel than rgb, that channel's picture (alpha 1; the depth
        range it used is in the result)."""
        order = as_order(order)
        if view is None or view.channel == "rgb":
            return RenderResult(self.draw_planned(target, camera, self.plan(settings), order, frame=frame,
                                                  color_origin=color_origin))
        image = self.geometry.image(camera)
        plan = self.plan(settings, "median" if view.channel == "median_depth" else "geometry")
        stats = self.draw_planned(image, camera, plan, order, frame=frame, color_origin=color_origin)
        return RenderResult(stats, self.geometry.picture(self.programs, target, image, camera, view))

    def _sample_target(self, camera: Camera, dtypes: tuple[str, ...]) -> FloatTarget:
        self._samples[dtypes] = sized(self._samples.get(dtypes), self.ctx, camera.width, camera.height,
                                      dtypes=dtypes)
        return self._samples[dtypes]

    def _release_targets(self) -> None:
        """The targets and vertex arrays made as renders came (each size and program)."""
        release_all(self._target, *self._samples.values())
        self._target, self._samples = None, {}
        for array in self._indexed.values():
            array.release()
        self._indexed = {}

    def release(self) -> None:
        """Releases everything the renderer made on the GPU, last made first. Idempotent."""
        self._owned.close()
