"""The RayGS renderer on OpenGL 4.3: storage buffers, the preprocessing pass, instanced quads.

Per frame: the CPU sort gives the visible gaussians back to front; the compute
pass turns every gaussian into a per-view :file:`splat.glsl` record (colour,
opacity, c^2, quad axes); the vertex stage draws one quad per sorted index and
the fragment stage evaluates Eq. 16, blending premultiplied colour back to front
into a float32 target with depth clamp on (no near-plane clipping).

The accuracy options of :class:`RenderSettings` and the scene select shader
variants by ``#define`` (EWA splatting, the two MIP filters, the parity switches,
the SH degree), so a frame pays only for what is on; at SH degree 0 the colours are
computed once, at load. ``general=True`` forces the one variant that switches every
feature by uniforms instead, to measure what specialising saves. Supersampling and
the transmittance cut-off render into a sample target first; a resolve pass filters
it down into the caller's target.

Work that the view has not changed is skipped: :meth:`GLRenderer.preprocess` for the
view, settings and colour origin it last wrote the records for, and the order's
upload for the order array it last uploaded (orders are never modified once made).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_key
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.shaders import shader_source
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.settings import (
    ALPHA_CLAMP,
    GS_DILATION,
    GS_NEAR,
    TRANSMITTANCE_CUTOFF,
    RenderSettings,
)
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sh import C0 as SH_C0
from raygs_viewer.sort.depth import DepthSorter

GL_DEPTH_CLAMP = 0x864F
# The largest GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT drivers report (moderngl's
# ctx.info omits it); every range offset we bind is a multiple of it.
RANGE_ALIGNMENT = 256

GAUSSIAN_BYTES = 48  # struct Gaussian in preprocess.comp
SPLAT_BYTES = 64     # struct Splat in splat.glsl
COLOR_BYTES = 16     # RGB computed at load, for SH degree 0, padded so chunk ranges stay aligned
EXACT_MIP_SPLAT_BYTES = 112  # ... with EXACT_MIP's three extra vec4
GL_EXT_FRAMEBUFFER_FETCH = "GL_EXT_shader_framebuffer_fetch"
MAX_SPLAT_BLOCKS = 8  # bindings raygs.vert declares
WORKGROUP = 128
# GL guarantees 65535 workgroups per dispatch; drivers that report a 2 GiB block
# limit would otherwise ask for more in one chunk.
MAX_CHUNK = 1 << 22


def _power_of_two_at_most(value: int) -> int:
    return 1 << (max(int(value), 1).bit_length() - 1)


@dataclass(frozen=True)
class StorageLayout:
    """How N gaussians are cut so that no bound storage range exceeds ``block_limit`` bytes.

    Splat records live in ``splat_blocks`` bindings of ``splats_per_block``; the
    preprocessing pass runs in chunks of ``chunk`` gaussians (a power of two that
    divides ``splats_per_block``, so a chunk never straddles two splat blocks).
    """

    count: int
    block_limit: int
    splats_per_block: int
    chunk: int
    splat_bytes: int = SPLAT_BYTES

    @classmethod
    def plan(cls, count: int, harmonics_bytes: int, block_limit: int, alignment: int = RANGE_ALIGNMENT,
             splat_bytes: int = SPLAT_BYTES) -> "StorageLayout":
        record_bytes = (GAUSSIAN_BYTES, harmonics_bytes, COLOR_BYTES, splat_bytes)
        splats_per_block = _power_of_two_at_most(block_limit // splat_bytes)
        chunk = min(_power_of_two_at_most(block_limit // max(record_bytes)), splats_per_block, MAX_CHUNK)
        # Every bound offset is a multiple of chunk * record size: keep those aligned.
        if chunk * max(record_bytes) > block_limit or any(chunk * b % alignment for b in record_bytes):
            raise UserError(f"a storage block limit of {block_limit} bytes is too small for "
                            f"{max(record_bytes)}-byte gaussian records")
        return cls(count, block_limit, splats_per_block, chunk, splat_bytes)

    @property
    def splat_blocks(self) -> int:
        return max(1, -(-self.count // self.splats_per_block))


@dataclass
class WorkCounters:
    """What the renderer did and skipped since it was made (for tests and the panel)."""

    preprocessed: int = 0       # preprocessing passes run
    preprocess_skipped: int = 0  # ... skipped: the records were already this view's
    uploads: int = 0            # order uploads
    upload_skipped: int = 0     # ... skipped: that order was already on the GPU


class GLRenderer:
    """Renders one scene; keeps its storage buffers until :meth:`release`.

    ``block_limit`` overrides the GPU's per-block storage limit (tests use a tiny one
    to exercise the splitting). ``general``: draw with the all-features variant (see
    the module docstring).
    """

    def __init__(self, ctx: moderngl.Context, scene: Scene, *, block_limit: int | None = None,
                 memory_limit: int | None = None, general: bool = False):
        self.ctx = ctx
        self.general = bool(general)
        self.counters = WorkCounters()
        self.scene = scene
        self.sorter = DepthSorter(scene)
        count = scene.count
        coeffs = sh_coefficient_count(scene.sh_degree)
        gpu_limit = _limit(ctx, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27)
        self._block_limit = min(block_limit or gpu_limit, gpu_limit)
        self._layouts: dict[int, StorageLayout] = {}
        self.layout = self._layout(SPLAT_BYTES)
        self.gpu_bytes = gpu_bytes(count, scene.sh_degree)
        if memory_limit is not None and self.gpu_bytes > memory_limit:
            raise UserError(f"scene of {count:,} gaussians needs {_mib(self.gpu_bytes)} of GPU buffers, more than "
                            f"the {_mib(memory_limit)} allowed")

        try:
            packed = np.zeros((count, 12), np.float32)
            packed[:, 0:3] = scene.positions
            packed[:, 3] = scene.opacities
            packed[:, 4:7] = scene.scales
            packed[:, 8:12] = scene.rotations
        except MemoryError:
            raise UserError(f"scene of {count:,} gaussians: not enough memory to pack it for the GPU") from None
        buffers = []
        try:
            ctx.error  # noqa: B018 - clears an earlier error, so the check below sees only these
            for make in (lambda: _buffer(ctx, packed), lambda: _buffer(ctx, scene.sh.reshape(count, coeffs * 3)),
                         lambda: ctx.buffer(reserve=max(count, 1) * SPLAT_BYTES),
                         lambda: ctx.buffer(reserve=max(count, 1) * 4)):
                buffers.append(make())
            if ctx.error == "GL_OUT_OF_MEMORY":  # drivers report it here, not by failing the call
                raise moderngl.Error("GL_OUT_OF_MEMORY")
        except (moderngl.Error, MemoryError) as exc:
            for buffer in buffers:
                buffer.release()
            raise UserError(f"scene of {count:,} gaussians does not fit in this GPU's memory "
                            f"({_mib(self.gpu_bytes)} of buffers: {' '.join(str(exc).split()) or 'out of memory'})"
                            ) from None
        self._gaussians, self._harmonics, self._splats, self._order = buffers
        self._colors: moderngl.Buffer | None = None  # made on first use of SH degree 0
        self._last_layout = self.layout
        self._preprocessed_key: tuple | None = None  # what the records in _splats were made for
        self._uploaded_order: np.ndarray | None = None  # the array whose indices _order holds

        # Shader variants, compiled on first use: keyed by their #defines.
        self._preprocess_programs: dict[tuple, moderngl.ComputeShader] = {}
        self._draw_programs: dict[tuple, tuple[moderngl.Program, moderngl.VertexArray]] = {}
        self._resolve_programs: dict[bool, tuple[moderngl.Program, moderngl.VertexArray]] = {}
        #: Off only to demonstrate the near-plane seam that depth clamp prevents.
        self.depth_clamp = True
        self._target: FloatTarget | None = None          # render()'s image, the latest size
        self._samples: FloatTarget | None = None         # supersampling and front to back

    def _layout(self, splat_bytes: int) -> StorageLayout:
        if splat_bytes not in self._layouts:
            count = self.scene.count
            harmonics_bytes = sh_coefficient_count(self.scene.sh_degree) * 12
            layout = StorageLayout.plan(count, harmonics_bytes, self._block_limit, splat_bytes=splat_bytes)
            vertex_blocks = _limit(self.ctx, "GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS", 16) - 1  # one holds the order
            if layout.splat_blocks > min(MAX_SPLAT_BLOCKS, vertex_blocks):
                raise UserError(f"scene of {count} gaussians needs {layout.splat_blocks} storage blocks "
                                f"of {layout.block_limit} bytes; this GPU and renderer allow "
                                f"{min(MAX_SPLAT_BLOCKS, vertex_blocks)}")
            self._layouts[splat_bytes] = layout
        return self._layouts[splat_bytes]

    @staticmethod
    def _splat_bytes(settings: RenderSettings) -> int:
        return EXACT_MIP_SPLAT_BYTES if settings.mode == "raygs-exact-mip" else SPLAT_BYTES

    def supports(self, settings: RenderSettings) -> str | None:
        """None when this GPU can render ``settings``, else why not (one line)."""
        if settings.transmittance_cutoff and GL_EXT_FRAMEBUFFER_FETCH not in self.ctx.extensions:
            return (f"the transmittance cut-off needs {GL_EXT_FRAMEBUFFER_FETCH}, "
                    f"which this GPU's OpenGL driver does not offer")
        return None

    # -- per-frame passes ---------------------------------------------------------
    def sort(self, camera: Camera, settings: RenderSettings) -> np.ndarray:
        return self.sorter.order(camera, settings.p_min, dilation=settings.cull_dilation(camera))

    def preprocess(self, camera: Camera, settings: RenderSettings, frame: Camera | None = None,
                   color_origin: np.ndarray | None = None) -> None:
        """Writes the per-view splat record of every gaussian for ``camera`` (the camera
        actually rasterized: already supersampled). ``frame``: the whole image's camera
        when ``camera`` renders one tile of it (GS clamps rays to the whole image).
        ``color_origin``: the world point SH colour is seen from (default: the camera's
        centre; stereo shares the eyes' midpoint)."""
        origin = camera.center if color_origin is None else np.asarray(color_origin, np.float64)
        key = (camera_key(camera), settings, None if frame is None else camera_key(frame), origin.tobytes())
        if key == self._preprocessed_key:
            self.counters.preprocess_skipped += 1
            return
        self._preprocessed_key = None  # until this pass has written every record
        count = self.scene.count
        layout = self._layout(self._splat_bytes(settings))
        if self._splats.size < max(count, 1) * layout.splat_bytes:  # the exact MIP record, on first use
            self.ctx.error  # noqa: B018 - clears an earlier error, so the check below sees only this one
            self._splats.orphan(max(count, 1) * layout.splat_bytes)
            if self.ctx.error == "GL_OUT_OF_MEMORY":
                raise UserError(f"not enough GPU memory for the {settings.mode} records of {count:,} gaussians")
        self._last_layout = layout
        program = self._preprocess_program(settings)
        colors_at_load = self._colors_at_load(settings)
        if self.general:
            _set_general_uniforms(program, settings, self.scene.sh_degree)
        program["u_world_to_camera"].write(camera.R.astype(np.float32).tobytes(order="F"))
        program["u_translation"].value = tuple(np.asarray(camera.t, np.float64).astype(np.float32))
        _set_uniform(program, "u_color_origin", tuple(origin.astype(np.float32)))  # gone at SH degree 0
        program["u_log_p_min"].value = math.log(settings.p_min)
        _set_uniform(program, "u_pixel_variance", settings.pixel_variance(camera))
        _set_uniform(program, "u_intrinsics", (camera.fx, camera.fy, camera.cx, camera.cy))
        _set_uniform(program, "u_ray_bounds", gs_ray_bounds(frame or camera))
        if colors_at_load:
            colors, harmonics_bytes = self._color_buffer(), COLOR_BYTES
        else:
            colors, harmonics_bytes = self._harmonics, sh_coefficient_count(self.scene.sh_degree) * 12
        splat_bytes = layout.splat_bytes
        for start in range(0, count, layout.chunk):
            n = min(layout.chunk, count - start)
            self._gaussians.bind_to_storage_buffer(0, offset=start * GAUSSIAN_BYTES, size=n * GAUSSIAN_BYTES)
            colors.bind_to_storage_buffer(1, offset=start * harmonics_bytes, size=n * harmonics_bytes)
            block_start = start - start % layout.splats_per_block
            block_count = min(layout.splats_per_block, count - block_start)
            self._splats.bind_to_storage_buffer(2, offset=block_start * splat_bytes, size=block_count * splat_bytes)
            program["u_count"].value = n
            program["u_out_offset"].value = start - block_start
            program.run(group_x=-(-n // WORKGROUP))
        self.ctx.memory_barrier()
        self.counters.preprocessed += 1
        self._preprocessed_key = key

    def _colors_at_load(self, settings: RenderSettings) -> bool:
        """Whether this variant reads colours computed at load instead of evaluating SH."""
        return not self.general and settings.effective_sh_degree(self.scene.sh_degree) == 0

    def _color_buffer(self) -> moderngl.Buffer:
        """(N, 4) float32: RGB of SH degree 0 (view-independent) and a zero pad;
        computed once, on first use."""
        if self._colors is None:
            colors = np.zeros((self.scene.count, 4))
            colors[:, :3] = np.maximum(SH_C0 * self.scene.sh[:, 0, :].astype(np.float64) + 0.5, 0.0)
            self._colors = _buffer(self.ctx, colors)
        return self._colors

    def _preprocess_program(self, settings: RenderSettings) -> moderngl.ComputeShader:
        defines = {"SH_STORED_DEGREE": self.scene.sh_degree,
                   "MODE_GS": int(settings.mode == "gs"),
                   "GS_DILATION": _glsl_float(GS_DILATION),
                   "GS_NEAR": _glsl_float(GS_NEAR),
                   "EXACT_MIP": int(settings.mode == "raygs-exact-mip"),
                   **self._feature_defines(settings)}
        if not self.general:
            defines["COLOR_AT_LOAD"] = _glsl_bool(self._colors_at_load(settings))
        key = tuple(sorted(defines.items()))
        if key not in self._preprocess_programs:
            self._preprocess_programs[key] = self.ctx.compute_shader(shader_source("preprocess.comp", defines))
        return self._preprocess_programs[key]

    def _feature_defines(self, settings: RenderSettings) -> dict[str, object]:
        """The feature switches of features.glsl: literals for this scene and these
        settings, or GENERAL (uniforms, set by :func:`_set_general_uniforms`)."""
        if self.general:
            return {"GENERAL": 1}
        return {"GENERAL": 0,
                "SH_DEGREE": settings.effective_sh_degree(self.scene.sh_degree),
                "MIP": _glsl_bool(settings.mode == "raygs" and settings.mip),
                "MIP_MODULATION": _glsl_bool(settings.mip_modulation),
                "GS_COMPENSATION": _glsl_bool(settings.mode == "gs" and settings.gs_compensation),
                "ALPHA_CLAMP": _glsl_bool(settings.alpha_clamp)}

    def read_splats(self) -> np.ndarray:
        """(N, F) float32 copy of the per-view records of the last :meth:`preprocess`
        (the ``Splat`` struct, row by row; F = 16, or 28 in exact MIP mode), for tests
        and diagnostics."""
        count, floats = self.scene.count, self._last_layout.splat_bytes // 4
        return np.frombuffer(self._splats.read(size=count * floats * 4), np.float32).reshape(count, floats)

    def draw(self, camera: Camera, settings: RenderSettings, order: np.ndarray, *, floor: bool = False) -> None:
        """Draws the quads of ``order`` (back to front) into the bound framebuffer, as
        the last :meth:`preprocess` (same camera and settings) prepared them.
        ``floor``: the same quads with a constant, never discarded fragment instead
        (glsl/quads.*): the least this rasterizer can spend on them (bench perf)."""
        if order.size == 0:
            return
        if order.size > self.scene.count:
            raise ValueError("order longer than the scene")
        layout, count = self._layout(self._splat_bytes(settings)), self.scene.count
        program, vao = self._draw_program(settings, layout, floor)
        self.upload_order(order)
        self._order.bind_to_storage_buffer(0, size=order.size * 4)
        for block in range(layout.splat_blocks):
            start = block * layout.splats_per_block
            n = max(1, min(layout.splats_per_block, count - start))
            self._splats.bind_to_storage_buffer(1 + block, offset=start * layout.splat_bytes,
                                                size=n * layout.splat_bytes)
        _set_uniform(program, "u_projection", camera.gl_projection().astype(np.float32).tobytes(order="F"))
        _set_uniform(program, "u_image_size", (camera.width, camera.height))
        _set_uniform(program, "u_pixel_variance", settings.pixel_variance(camera))
        _set_uniform(program, "u_order_count", int(order.size))
        _set_uniform(program, "u_p_min", settings.p_min)
        if self.general:
            _set_general_uniforms(program, settings, self.scene.sh_degree)
        ctx = self.ctx
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        if settings.transmittance_cutoff:
            ctx.disable(moderngl.BLEND)  # the fragment stage composites through framebuffer fetch
        else:
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
            ctx.blend_equation = moderngl.FUNC_ADD
        if self.depth_clamp:
            ctx.enable_direct(GL_DEPTH_CLAMP)
        else:
            ctx.disable_direct(GL_DEPTH_CLAMP)
        vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=int(order.size))

    def upload_order(self, order: np.ndarray) -> None:
        """Puts ``order`` (M,) in the GPU's order buffer, unless this very array is
        already there (orders are not modified once made: a new view makes a new one)."""
        if order is self._uploaded_order:
            self.counters.upload_skipped += 1
            return
        if order.size > self.scene.count:
            raise ValueError("order longer than the scene")
        self._order.write(np.ascontiguousarray(order, dtype=np.uint32))
        self._uploaded_order = order
        self.counters.uploads += 1

    def _draw_program(self, settings: RenderSettings, layout: StorageLayout, floor: bool = False):
        problem = self.supports(settings)
        if problem:
            raise UserError(problem)
        gs = settings.mode == "gs"
        if floor and gs:
            raise ValueError("the floor pass draws RayGS quads; EWA's records are not quads in space")
        defines = {"SPLAT_BLOCKS": layout.splat_blocks, "SPLATS_PER_BLOCK": layout.splats_per_block,
                   "EXACT_MIP": int(settings.mode == "raygs-exact-mip"),
                   "ALPHA_MAX": _glsl_float(ALPHA_CLAMP),
                   "FRONT_TO_BACK": int(settings.transmittance_cutoff),
                   "MIN_TRANSMITTANCE": _glsl_float(TRANSMITTANCE_CUTOFF),
                   **self._feature_defines(settings)}
        key = (gs, floor, *sorted(defines.items()))
        if key not in self._draw_programs:
            stage = "quads" if floor else "gs" if gs else "raygs"
            program = self.ctx.program(vertex_shader=shader_source(f"{stage}.vert", defines),
                                       fragment_shader=shader_source(f"{stage}.frag", defines))
            self._draw_programs[key] = program, self.ctx.vertex_array(program, [])
        return self._draw_programs[key]

    def render(self, camera: Camera, settings: RenderSettings = RenderSettings(),
               order: np.ndarray | None = None, frame: Camera | None = None,
               color_origin: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 4) float32 image, top row first: RGB over the background, and alpha.
        ``frame``, ``color_origin``: see :meth:`preprocess`."""
        if order is None:
            order = self.sort(camera, settings)
        self._target = sized(self._target, self.ctx, camera.width, camera.height)
        self.render_into(self._target, camera, settings, order, frame, color_origin)
        return self._target.read()

    def render_into(self, target: FloatTarget, camera: Camera, settings: RenderSettings,
                    order: np.ndarray, frame: Camera | None = None, color_origin: np.ndarray | None = None) -> None:
        """Clears ``target`` (camera-sized, float colour) and draws the scene into it:
        background-composited colour in RGB and the accumulated alpha in A.

        Plain back-to-front rendering draws straight into ``target``, cleared to
        (background, 0). Supersampling (k x k) draws into a k-times larger sample target
        with the camera scaled to match, and the transmittance cut-off composites front
        to back into a target cleared to 0; a resolve pass then averages the samples and
        adds the background."""
        k = settings.supersample
        if k == 1 and not settings.transmittance_cutoff:
            target.use()
            target.fbo.clear(*settings.background, 0.0)
            self.preprocess(camera, settings, frame, color_origin)
            self.draw(camera, settings, order)
            return
        sampled = camera.resized(camera.width * k, camera.height * k) if k > 1 else camera
        self._samples = samples = sized(self._samples, self.ctx, sampled.width, sampled.height)
        samples.use()
        if settings.transmittance_cutoff:
            samples.fbo.clear(0.0, 0.0, 0.0, 0.0)
        else:
            samples.fbo.clear(*settings.background, 0.0)
        self.preprocess(sampled, settings, frame or camera, color_origin)  # the bounds are scale-invariant
        self.draw(sampled, settings, order)
        self._resolve(samples, target, k, settings)

    def _resolve(self, samples: FloatTarget, target: FloatTarget, k: int,
                 settings: RenderSettings) -> None:
        front_to_back = settings.transmittance_cutoff
        if front_to_back not in self._resolve_programs:
            program = self.ctx.program(vertex_shader=shader_source("present.vert"),
                                       fragment_shader=shader_source("resolve.frag",
                                                                     {"FRONT_TO_BACK": int(front_to_back)}))
            self._resolve_programs[front_to_back] = program, self.ctx.vertex_array(program, [])
        program, vao = self._resolve_programs[front_to_back]
        target.use()
        self.ctx.disable(moderngl.BLEND)
        samples.texture.use(0)
        program["u_samples"].value = 0
        program["u_factor"].value = k
        _set_uniform(program, "u_background", settings.background)
        vao.render(moderngl.TRIANGLES, vertices=3)

    def release(self) -> None:
        release_all(self._target, self._samples)
        self._target = self._samples = None
        for program in self._preprocess_programs.values():
            program.release()
        self._preprocess_programs.clear()
        for programs in (self._draw_programs, self._resolve_programs):
            for program, vao in programs.values():
                vao.release()
                program.release()
            programs.clear()
        for obj in (self._gaussians, self._harmonics, self._splats, self._order, self._colors):
            if obj is not None:
                obj.release()
        self._colors = None


def gs_ray_bounds(camera: Camera) -> tuple[float, float, float, float]:
    """INRIA's clamp box for the ray x/z, y/z of GS's Jacobian: the image's borders
    widened by 15 % of its size on each side (lower x, lower y, upper x, upper y)."""
    margin_x, margin_y = 0.15 * camera.width / camera.fx, 0.15 * camera.height / camera.fy
    return (-camera.cx / camera.fx - margin_x, -camera.cy / camera.fy - margin_y,
            (camera.width - camera.cx) / camera.fx + margin_x, (camera.height - camera.cy) / camera.fy + margin_y)


def _set_general_uniforms(program, settings: RenderSettings, stored_degree: int) -> None:
    """The general variant's feature uniforms (features.glsl), from ``settings``."""
    _set_uniform(program, "u_sh_degree", settings.effective_sh_degree(stored_degree))
    _set_uniform(program, "u_mip", settings.mode == "raygs" and settings.mip)
    _set_uniform(program, "u_mip_modulation", settings.mip_modulation)
    _set_uniform(program, "u_gs_compensation", settings.mode == "gs" and settings.gs_compensation)
    _set_uniform(program, "u_alpha_clamp", settings.alpha_clamp)


def _set_uniform(program: moderngl.Program, name: str, value) -> None:
    """Sets a uniform the variant uses; variants that compiled it away are skipped."""
    if name in program:
        if isinstance(value, bytes):
            program[name].write(value)
        else:
            program[name].value = value


def _glsl_bool(value: bool) -> str:
    return "true" if value else "false"


def _glsl_float(value: float) -> str:
    return repr(float(value))


def gpu_bytes(count: int, sh_degree: int) -> int:
    """The storage buffers a scene takes on the GPU: gaussians, SH, colours computed
    at load (SH degree 0), one splat record each (the exact MIP record, the largest)
    and the order."""
    return count * (GAUSSIAN_BYTES + sh_coefficient_count(sh_degree) * 12 + COLOR_BYTES + EXACT_MIP_SPLAT_BYTES + 4)


def _mib(size: int) -> str:
    return f"{size / (1 << 20):,.1f} MiB"


def _buffer(ctx: moderngl.Context, array: np.ndarray) -> moderngl.Buffer:
    data = np.ascontiguousarray(array, dtype=np.float32)
    return ctx.buffer(data.tobytes() if data.size else bytes(16))


def _limit(ctx: moderngl.Context, name: str, default: int) -> int:
    value = ctx.info.get(name)
    return int(value) if isinstance(value, int) and value > 0 else default
