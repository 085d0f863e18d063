"""The RayGS renderer on OpenGL 4.3: storage buffers, the preprocessing pass, instanced quads.

Per frame: the CPU sort gives the visible gaussians back to front; the compute
pass turns every gaussian into a per-view :file:`splat.glsl` record (colour,
opacity, c^2, quad axes); the vertex stage draws one quad per sorted index and
the fragment stage evaluates Eq. 16, blending premultiplied colour back to front
into a float32 target with depth clamp on (no near-plane clipping).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer.camera import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.shaders import shader_source
from raygs_viewer.scene import Scene, sh_coefficient_count
from raygs_viewer.settings import RenderSettings
from raygs_viewer.sorting import DepthSorter

GL_DEPTH_CLAMP = 0x864F
# The largest GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT drivers report (moderngl's
# ctx.info omits it); every range offset we bind is a multiple of it.
RANGE_ALIGNMENT = 256

GAUSSIAN_BYTES = 48  # struct Gaussian in preprocess.comp
SPLAT_BYTES = 64     # struct Splat in splat.glsl
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

    @classmethod
    def plan(cls, count: int, harmonics_bytes: int, block_limit: int, alignment: int = RANGE_ALIGNMENT) -> "StorageLayout":
        record_bytes = (GAUSSIAN_BYTES, harmonics_bytes, SPLAT_BYTES)
        splats_per_block = _power_of_two_at_most(block_limit // SPLAT_BYTES)
        chunk = min(_power_of_two_at_most(block_limit // max(record_bytes)), splats_per_block, MAX_CHUNK)
        # Every bound offset is a multiple of chunk * record size: keep those aligned.
        if chunk * max(record_bytes) > block_limit or any(chunk * b % alignment for b in record_bytes):
            raise UserError(f"a storage block limit of {block_limit} bytes is too small for "
                            f"{max(record_bytes)}-byte gaussian records")
        return cls(count, block_limit, splats_per_block, chunk)

    @property
    def splat_blocks(self) -> int:
        return max(1, -(-self.count // self.splats_per_block))


class GLRenderer:
    """Renders one scene; keeps its storage buffers until :meth:`release`.

    ``block_limit`` overrides the GPU's per-block storage limit (tests use a tiny one
    to exercise the splitting).
    """

    def __init__(self, ctx: moderngl.Context, scene: Scene, *, block_limit: int | None = None):
        self.ctx = ctx
        self.scene = scene
        self.sorter = DepthSorter(scene)
        count = scene.count
        coeffs = sh_coefficient_count(scene.sh_degree)
        gpu_limit = _limit(ctx, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27)
        self.layout = StorageLayout.plan(count, coeffs * 12, min(block_limit or gpu_limit, gpu_limit))
        vertex_blocks = _limit(ctx, "GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS", 16) - 1  # one holds the order
        if self.layout.splat_blocks > min(MAX_SPLAT_BLOCKS, vertex_blocks):
            raise UserError(f"scene of {count} gaussians needs {self.layout.splat_blocks} storage blocks "
                            f"of {self.layout.block_limit} bytes; this GPU and renderer allow "
                            f"{min(MAX_SPLAT_BLOCKS, vertex_blocks)}")

        packed = np.zeros((count, 12), np.float32)
        packed[:, 0:3] = scene.positions
        packed[:, 3] = scene.opacities
        packed[:, 4:7] = scene.scales
        packed[:, 8:12] = scene.rotations
        self._gaussians = _buffer(ctx, packed)
        self._harmonics = _buffer(ctx, scene.sh.reshape(count, coeffs * 3))
        self._splats = ctx.buffer(reserve=max(count, 1) * SPLAT_BYTES)
        self._order = ctx.buffer(reserve=max(count, 1) * 4)

        # One preprocessing variant per evaluated SH degree, compiled on first use.
        self._preprocess_programs: dict[int, moderngl.ComputeShader] = {}
        self._draw = ctx.program(
            vertex_shader=shader_source("raygs.vert", {"SPLAT_BLOCKS": self.layout.splat_blocks,
                                                       "SPLATS_PER_BLOCK": self.layout.splats_per_block}),
            fragment_shader=shader_source("raygs.frag"),
        )
        self._vao = ctx.vertex_array(self._draw, [])
        #: Off only to demonstrate the near-plane seam that depth clamp prevents.
        self.depth_clamp = True
        self._targets: dict[tuple[int, int], moderngl.Framebuffer] = {}

    # -- per-frame passes ---------------------------------------------------------
    def sort(self, camera: Camera, settings: RenderSettings) -> np.ndarray:
        return self.sorter.order(camera, settings.p_min, dilation=settings.cull_dilation(camera))

    def preprocess(self, camera: Camera, settings: RenderSettings) -> None:
        """Writes the per-view splat record of every gaussian."""
        layout, count = self.layout, self.scene.count
        program = self._preprocess_program(settings.effective_sh_degree(self.scene.sh_degree))
        program["u_world_to_camera"].write(camera.R.astype(np.float32).tobytes(order="F"))
        program["u_camera_center"].value = tuple(camera.center.astype(np.float32))
        program["u_log_p_min"].value = math.log(settings.p_min)
        harmonics_bytes = sh_coefficient_count(self.scene.sh_degree) * 12
        for start in range(0, count, layout.chunk):
            n = min(layout.chunk, count - start)
            self._gaussians.bind_to_storage_buffer(0, offset=start * GAUSSIAN_BYTES, size=n * GAUSSIAN_BYTES)
            self._harmonics.bind_to_storage_buffer(1, offset=start * harmonics_bytes, size=n * harmonics_bytes)
            block_start = start - start % layout.splats_per_block
            block_count = min(layout.splats_per_block, count - block_start)
            self._splats.bind_to_storage_buffer(2, offset=block_start * SPLAT_BYTES, size=block_count * SPLAT_BYTES)
            program["u_count"].value = n
            program["u_out_offset"].value = start - block_start
            program.run(group_x=-(-n // WORKGROUP))
        self.ctx.memory_barrier()

    def _preprocess_program(self, degree: int) -> moderngl.ComputeShader:
        if degree not in self._preprocess_programs:
            defines = {"SH_DEGREE": degree, "SH_STORED_DEGREE": self.scene.sh_degree}
            self._preprocess_programs[degree] = self.ctx.compute_shader(shader_source("preprocess.comp", defines))
        return self._preprocess_programs[degree]

    def read_splats(self) -> np.ndarray:
        """(N, 16) float32 copy of the per-view records of the last :meth:`preprocess`
        (the ``Splat`` struct, row by row), for tests and diagnostics."""
        count = self.scene.count
        return np.frombuffer(self._splats.read(size=count * SPLAT_BYTES), np.float32).reshape(count, 16)

    def draw(self, camera: Camera, settings: RenderSettings, order: np.ndarray) -> None:
        """Draws the quads of ``order`` (back to front) into the bound framebuffer."""
        if order.size == 0:
            return
        if order.size > self.scene.count:
            raise ValueError("order longer than the scene")
        self._order.write(np.ascontiguousarray(order, dtype=np.uint32))
        self._order.bind_to_storage_buffer(0, size=order.size * 4)
        layout, count = self.layout, self.scene.count
        for block in range(layout.splat_blocks):
            start = block * layout.splats_per_block
            n = max(1, min(layout.splats_per_block, count - start))
            self._splats.bind_to_storage_buffer(1 + block, offset=start * SPLAT_BYTES, size=n * SPLAT_BYTES)
        self._draw["u_projection"].write(camera.gl_projection().astype(np.float32).tobytes(order="F"))
        self._draw["u_p_min"].value = settings.p_min
        ctx = self.ctx
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        ctx.blend_equation = moderngl.FUNC_ADD
        if self.depth_clamp:
            ctx.enable_direct(GL_DEPTH_CLAMP)
        else:
            ctx.disable_direct(GL_DEPTH_CLAMP)
        self._vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=int(order.size))

    def render(self, camera: Camera, settings: RenderSettings = RenderSettings(),
               order: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 4) float32 image, top row first: RGB over the background, and alpha."""
        if order is None:
            order = self.sort(camera, settings)
        target = self._target(camera.width, camera.height)
        self.render_into(target, camera, settings, order)
        pixels = np.frombuffer(target.read(components=4, dtype="f4"), np.float32)
        return pixels.reshape(camera.height, camera.width, 4)[::-1].copy()

    def render_into(self, target: moderngl.Framebuffer, camera: Camera, settings: RenderSettings,
                    order: np.ndarray) -> None:
        """Clears ``target`` (camera-sized, float colour) and draws the scene into it.
        Clearing to (background, 0) and blending with (ONE, ONE_MINUS_SRC_ALPHA) leaves
        background-composited colour in RGB and the accumulated alpha in A."""
        target.use()
        target.clear(*settings.background, 0.0)
        self.preprocess(camera, settings)
        self.draw(camera, settings, order)

    def _target(self, width: int, height: int) -> moderngl.Framebuffer:
        limit = _limit(self.ctx, "GL_MAX_TEXTURE_SIZE", 16384)
        if not (1 <= width <= limit and 1 <= height <= limit):
            raise UserError(f"image size {width}x{height} is outside what this GPU renders (1..{limit})")
        if (width, height) not in self._targets:
            for fbo in self._targets.values():
                _release_framebuffer(fbo)
            self._targets = {(width, height): self.ctx.framebuffer(
                color_attachments=[self.ctx.texture((width, height), 4, dtype="f4")])}
        return self._targets[(width, height)]

    def release(self) -> None:
        for fbo in self._targets.values():
            _release_framebuffer(fbo)
        self._targets.clear()
        for program in self._preprocess_programs.values():
            program.release()
        self._preprocess_programs.clear()
        for obj in (self._vao, self._draw, self._gaussians, self._harmonics,
                    self._splats, self._order):
            obj.release()


def _release_framebuffer(fbo: moderngl.Framebuffer) -> None:
    for attachment in fbo.color_attachments:
        attachment.release()
    fbo.release()


def _buffer(ctx: moderngl.Context, array: np.ndarray) -> moderngl.Buffer:
    data = np.ascontiguousarray(array, dtype=np.float32)
    return ctx.buffer(data.tobytes() if data.size else bytes(16))


def _limit(ctx: moderngl.Context, name: str, default: int) -> int:
    value = ctx.info.get(name)
    return int(value) if isinstance(value, int) and value > 0 else default
