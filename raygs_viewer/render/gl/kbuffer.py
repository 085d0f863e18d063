"""The bounded per-pixel order as a k-buffer through framebuffer fetch (maths page,
section 11): one draw, where ``GL_EXT_shader_framebuffer_fetch`` exists (llvmpipe; not
NVIDIA's desktop drivers).

Colour attachment 0 holds each pixel's composite state, attachments 1..K its window
of fragments (t*, alpha, scene index as a float: exact below 2^24). The quads are drawn
front to back in the global order; each fragment enters the window, and once it is full
the first by (t*, index) of the K + 1 is composited (glsl/kbuffer.glsl).
glsl/kbuffer_resolve.comp then composites the window in order, adds the background and
sums the fragment statistics.
"""

from __future__ import annotations

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.gl.plan import Passes, RenderPlan
from raygs_viewer.render.gl.results import OrderStats
from raygs_viewer.render.gl.shaders import set_uniform
from raygs_viewer.render.gl.targets import FloatTarget, check_size
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import Order

FRAMEBUFFER_FETCH = "GL_EXT_shader_framebuffer_fetch"
#: Scene indices travel as float32: exact below this.
MAX_EXACT_INDEX = 1 << 24
STATS_BINDING = 14  # glsl/kbuffer_resolve.comp
WORKGROUP_2D = 8


def max_window(ctx: moderngl.Context) -> int:
    """The largest K this GPU's colour attachments hold (one for the state, one per entry)."""
    return min(int(ctx.info.get("GL_MAX_DRAW_BUFFERS", 8)), int(ctx.info.get("GL_MAX_COLOR_ATTACHMENTS", 8))) - 1


def why_not(ctx: moderngl.Context, settings: RenderSettings, scene_count: int) -> str | None:
    """None when the k-buffer can render ``settings``, else why not (one line)."""
    if settings.order_k == 0:
        return "the exact per-pixel order (K = 0) needs fragment lists; the k-buffer holds a bounded window"
    if FRAMEBUFFER_FETCH not in ctx.extensions:
        return f"the k-buffer needs {FRAMEBUFFER_FETCH}, which this GPU's OpenGL driver does not offer"
    if settings.order_k > max_window(ctx):
        return f"the k-buffer holds at most K = {max_window(ctx)} on this GPU, got K = {settings.order_k}"
    if scene_count > MAX_EXACT_INDEX:
        return f"the k-buffer stores scene indices as floats, exact up to {MAX_EXACT_INDEX:,} gaussians"
    return None


class KBuffer:
    """The k-buffer's attachments (made for a size and K, kept) and its passes."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._textures: list[moderngl.Texture] = []
        self._fbo: moderngl.Framebuffer | None = None
        self._key: tuple[int, int, int] | None = None
        self._stats = ctx.buffer(reserve=16)

    def _hold(self, width: int, height: int, k: int) -> moderngl.Framebuffer:
        if self._key != (width, height, k):
            self._release_targets()
            check_size(self.ctx, width, height, label="k-buffer")
            self._textures = [self.ctx.texture((width, height), 4, dtype="f4") for _ in range(k + 1)]
            self._fbo = self.ctx.framebuffer(color_attachments=self._textures)
            self._key = (width, height, k)
        return self._fbo

    def render(self, passes: Passes, target: FloatTarget, camera: Camera, plan: RenderPlan,
               order: Order) -> OrderStats:
        """Like :meth:`FragmentLists.render`, for K = ``plan.window``."""
        ctx, settings = self.ctx, plan.settings
        width, height, k = camera.width, camera.height, plan.window
        fbo = self._hold(width, height, k)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        passes.draw(camera, plan, order)
        ctx.memory_barrier()
        program = passes.programs.compute("kbuffer_resolve.comp", plan.pass_defines())
        for unit, texture in enumerate(self._textures):
            texture.use(unit)
        set_uniform(program, "u_state", 0)
        set_uniform(program, "u_entries", np.arange(1, k + 1, dtype=np.int32).tobytes())
        set_uniform(program, "u_background", settings.background)
        self._stats.clear()
        self._stats.bind_to_storage_buffer(STATS_BINDING)
        target.texture.bind_to_image(0, read=False, write=True)
        program.run(-(-width // WORKGROUP_2D), -(-height // WORKGROUP_2D))
        ctx.memory_barrier()
        fragments, most, covered, _ = np.frombuffer(self._stats.read(), np.uint32)
        return OrderStats(path="fetch", width=width, height=height, fragments=int(fragments),
                          max_per_pixel=int(most), covered_pixels=int(covered), pool_fragments=0, pool_bytes=0,
                          parts=1)

    def _release_targets(self) -> None:
        if self._fbo is not None:
            self._fbo.release()
        for texture in self._textures:
            texture.release()
        self._fbo, self._textures, self._key = None, [], None

    def release(self) -> None:
        self._release_targets()
        self._stats.release()
