"""The per-pixel order through per-pixel fragment lists (maths page, section 11): any
OpenGL 4.3 driver, exact or with a bounded window.

1. Count: the quads are drawn with the ordinary RayGS draw program (PER_PIXEL 1,
   ``u_pass`` 0; the same program for both passes, ``invariant gl_Position``), and each
   kept fragment adds one to its pixel's counter (glsl/fragment_lists.glsl).
2. Scan (glsl/lists_scan.comp): per row, the prefix sums of the counts and the row's
   total, maximum and covered pixels; the totals come back to the host, which cuts the
   image into parts whose fragments fit the pool (:func:`plan_parts`: bands of whole
   rows; a row alone over the pool into spans of columns; one pixel over it is a
   UserError).
3. Per part: lists_prepare.comp sets each pixel's cursor at its list's start; the fill
   pass draws the quads again, scissored to the part, and each kept fragment takes the
   next slot of its list and stores (t*, alpha, scene index, rank); lists_resolve.comp
   sorts each list in place and composites it into the image (the global order's
   geometry outputs: sorted by rank, and the geometry written beside). A fragment finding its
   list full, or a list left short, is counted in a status word that
   :meth:`FragmentLists.render` checks: nothing is dropped silently.

The pool holds ``pool_fragments`` entries of 16 bytes, made on first use and kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.plan import Passes, RenderPlan
from raygs_viewer.render.gl.results import OrderStats
from raygs_viewer.render.gl.shaders import set_uniform
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.sort.request import Order

#: The pool's default capacity: 4M fragments, 64 MiB.
DEFAULT_POOL_FRAGMENTS = 1 << 22
FRAGMENT_BYTES = 16  # uvec4(t*, alpha, scene index, rank)
WORKGROUP_2D = 8     # local size of the per-pixel compute passes
SCAN_WORKGROUP = 64  # local size of lists_scan.comp
# Storage bindings (glsl/fragment_lists.glsl); 0..8 hold the order and the splat blocks.
COUNTS, ROW_OFFSETS, CURSORS, POOL, ROW_BASES, STATUS, ROW_STATS = range(9, 16)


@dataclass(frozen=True)
class Part:
    """A rectangle of the image (GL rows, y = 0 at the bottom; ends exclusive) and its
    fragment count."""

    x0: int
    y0: int
    x1: int
    y1: int
    fragments: int


def plan_parts(row_totals: np.ndarray, width: int, pool: int, row_counts) -> tuple[list[Part], np.ndarray]:
    """Cuts an image ``width`` pixels wide with ``row_totals[y]`` fragments per row into parts that fit ``pool``:
    bands of whole rows, and a row that alone exceeds it into spans of its columns
    (``row_counts(y)`` gives that row's per-pixel counts). Returns the parts and
    ``row_bases`` (each row's list start within its band; 0 for a row cut into spans).
    A pixel with more fragments than the pool is a UserError."""
    height = len(row_totals)
    totals = [int(v) for v in row_totals]
    parts: list[Part] = []
    row_bases = np.zeros(height, np.uint32)
    y = 0
    while y < height:
        if totals[y] > pool:
            counts = np.asarray(row_counts(y), np.int64)
            most = int(counts.max())
            if most > pool:
                x = int(counts.argmax())
                raise UserError(f"pixel ({x}, {height - 1 - y}) has {most:,} fragments, more than the per-pixel "
                                f"order's pool of {pool:,}: use a larger pool, a bounded order K or another order")
            x0, held = 0, 0
            for x, n in enumerate(counts.tolist()):
                if held + n > pool:
                    parts.append(Part(x0, y, x, y + 1, held))
                    x0, held = x, 0
                held += n
            parts.append(Part(x0, y, width, y + 1, held))
            y += 1
            continue
        top, held = y, 0
        while y < height and totals[y] <= pool and held + totals[y] <= pool:
            row_bases[y] = held
            held += totals[y]
            y += 1
        parts.append(Part(0, top, width, y, held))
    return parts, row_bases


def _write_mask(target: FloatTarget, writes: bool) -> None:
    """Every attachment of ``target`` written (True) or none: the draws only count and store."""
    mask = (writes,) * 4
    target.fbo.color_mask = mask if target.attachments == 1 else (mask,) * target.attachments


class FragmentLists:
    """The lists path's buffers (per-pixel counters, row offsets and cursors, the pool)
    and passes. ``pool_fragments``: the pool's capacity (default
    :data:`DEFAULT_POOL_FRAGMENTS`), capped by ``block_limit`` (bytes one storage
    block may hold)."""

    def __init__(self, ctx: moderngl.Context, block_limit: int, pool_fragments: int | None = None):
        if pool_fragments is not None and (isinstance(pool_fragments, bool) or not isinstance(pool_fragments, int)
                                           or pool_fragments < 1):
            raise UserError(f"the per-pixel order's pool must hold at least one fragment, got {pool_fragments!r}")
        self.ctx = ctx
        self.block_limit = block_limit
        self.pool_fragments = min(pool_fragments or DEFAULT_POOL_FRAGMENTS, block_limit // FRAGMENT_BYTES)
        self.pool: moderngl.Buffer | None = None
        self._pixels: list[moderngl.Buffer] = []  # counts, row offsets, cursors
        self._rows: list[moderngl.Buffer] = []    # row bases, row statistics
        self._status: moderngl.Buffer | None = None
        self._capacity = (0, 0)  # pixels, rows
        self._counted = (0, 0)   # the size the last count() counted

    def _hold(self, width: int, height: int) -> None:
        pixels, rows = width * height, height
        if pixels * 4 > self.block_limit:
            raise UserError(f"image of {width}x{height} pixels is too large for the per-pixel order's counters "
                            f"(one storage block holds {self.block_limit:,} bytes); render it in tiles")
        if self.pool is None:
            self.pool = self.ctx.buffer(reserve=self.pool_fragments * FRAGMENT_BYTES)
            self._status = self.ctx.buffer(reserve=16)
        if pixels > self._capacity[0]:
            for buffer in self._pixels:
                buffer.release()
            self._pixels = [self.ctx.buffer(reserve=pixels * 4) for _ in range(3)]
        if rows > self._capacity[1]:
            for buffer in self._rows:
                buffer.release()
            self._rows = [self.ctx.buffer(reserve=rows * 4), self.ctx.buffer(reserve=rows * 16)]
        self._capacity = (max(pixels, self._capacity[0]), max(rows, self._capacity[1]))

    def _bind(self, width: int, height: int) -> None:
        pixels = width * height
        counts, offsets, cursors = self._pixels
        row_bases, row_stats = self._rows
        counts.bind_to_storage_buffer(COUNTS, size=pixels * 4)
        offsets.bind_to_storage_buffer(ROW_OFFSETS, size=pixels * 4)
        cursors.bind_to_storage_buffer(CURSORS, size=pixels * 4)
        self.pool.bind_to_storage_buffer(POOL)
        row_bases.bind_to_storage_buffer(ROW_BASES, size=height * 4)
        self._status.bind_to_storage_buffer(STATUS)
        row_stats.bind_to_storage_buffer(ROW_STATS, size=height * 16)

    def render(self, passes: Passes, target: FloatTarget, camera: Camera, plan: RenderPlan,
               order: Order) -> OrderStats:
        """Draws ``order`` (back to front; prepared by the last preprocess of ``passes``)
        with the per-pixel order into ``target`` (camera-sized, float32): RGB over the
        background, A the accumulated alpha. With ``plan.geometry``, ``target`` has three
        attachments and receives the geometry sums and median in the second and third
        (glsl/lists_resolve.comp), in the settings' order: per-pixel, or the global one."""
        settings = plan.settings
        width, height = camera.width, camera.height
        resolve = passes.programs.compute("lists_resolve.comp", plan.pass_defines())
        set_uniform(resolve, "u_background", settings.background)
        for unit, texture in enumerate(target.textures):
            texture.bind_to_image(unit, read=False, write=True)
        if plan.geometry:
            set_uniform(resolve, "u_intrinsics", (camera.fx, camera.fy, camera.cx, camera.cy))
            set_uniform(resolve, "u_height", height)
        row_stats = self.count(passes, target, camera, plan, order)
        parts = self.parts(row_stats)
        for part in parts:
            self.fill_and_resolve(passes, target, camera, plan, order, part=part, resolve=resolve)
        self.ctx.memory_barrier()
        self.check_status()
        return OrderStats(path="lists", width=width, height=height, fragments=int(row_stats[:, 0].sum()),
                          max_per_pixel=int(row_stats[:, 1].max(initial=0)),
                          covered_pixels=int(row_stats[:, 2].sum()), pool_fragments=self.pool_fragments,
                          pool_bytes=self.pool_fragments * FRAGMENT_BYTES, parts=len(parts),
                          largest_part=max((p.fragments for p in parts), default=0))

    def count(self, passes: Passes, target: FloatTarget, camera: Camera, plan: RenderPlan, order: Order
              ) -> np.ndarray:
        """Steps 1 and 2: counts each pixel's kept fragments of ``order`` drawn from
        ``camera`` into ``target`` (its size is the lists'; a target smaller than the
        camera's image holds the part its viewport puts there), and scans the counts.
        Returns (H, 4) uint32 per row: fragments, most at one pixel, covered pixels, 0."""
        width, height = target.size
        self._hold(width, height)
        self._pixels[0].clear(size=width * height * 4)
        self._status.clear()
        self._bind(width, height)
        target.use()
        _write_mask(target, False)
        try:
            passes.draw(camera, plan, order, uniforms={"u_pass": 0, "u_width": width, "u_part": (0, 0, width, height)})
        finally:
            _write_mask(target, True)
        self.ctx.memory_barrier()
        scan = passes.programs.compute("lists_scan.comp", plan.pass_defines())
        set_uniform(scan, "u_width", width)
        set_uniform(scan, "u_height", height)
        scan.run(group_x=-(-height // SCAN_WORKGROUP))
        self.ctx.memory_barrier()
        self._counted = (width, height)
        return np.frombuffer(self._rows[1].read(size=height * 16), np.uint32).reshape(height, 4)

    def parts(self, row_stats: np.ndarray, most_fragments: int | None = None) -> list[Part]:
        """Step 3's parts for the last :meth:`count` (``row_stats``: what it returned):
        each holding at most ``most_fragments`` (None or more than the pool: the pool's
        capacity), and where each row's list starts within its part."""
        width, height = self._counted
        pool = min(self.pool_fragments, most_fragments or self.pool_fragments)
        counts = self._pixels[0]

        def row_counts(y: int) -> np.ndarray:
            return np.frombuffer(counts.read(size=width * 4, offset=y * width * 4), np.uint32)

        parts, row_bases = plan_parts(row_stats[:, 0], width, pool, row_counts)
        self._rows[0].write(row_bases.tobytes())
        return parts

    def fill_and_resolve(self, passes: Passes, target: FloatTarget, camera: Camera, plan: RenderPlan,
                         order: Order, *, part: Part, resolve: moderngl.ComputeShader) -> None:
        """Step 3 for one of the last :meth:`count`'s parts: sets its cursors, draws its
        fragments into their lists, and runs ``resolve`` (lists_resolve.comp of ``plan``,
        its own uniforms and images set) over it. The buffers are bound again first: other
        lists may have been drawn since the count."""
        width, height = self._counted
        self._bind(width, height)
        prepare = passes.programs.compute("lists_prepare.comp", plan.pass_defines())
        set_uniform(prepare, "u_width", width)
        set_uniform(resolve, "u_width", width)
        # -1: the global order itself (by rank), which the geometry outputs and weights take this way.
        set_uniform(resolve, "u_window", plan.settings.order_k if plan.settings.per_pixel else -1)
        rect = (part.x0, part.y0, part.x1, part.y1)
        groups = (-(-(rect[2] - rect[0]) // WORKGROUP_2D), -(-(rect[3] - rect[1]) // WORKGROUP_2D))
        set_uniform(prepare, "u_part", rect)
        prepare.run(*groups)
        self.ctx.memory_barrier()
        if part.fragments:
            target.use()
            _write_mask(target, False)
            target.fbo.scissor = (rect[0], rect[1], rect[2] - rect[0], rect[3] - rect[1])
            try:
                passes.draw(camera, plan, order, uniforms={"u_pass": 1, "u_width": width, "u_part": rect})
            finally:
                target.fbo.scissor = None
                _write_mask(target, True)
            self.ctx.memory_barrier()
        set_uniform(resolve, "u_part", rect)
        resolve.run(*groups)

    def check_status(self) -> None:
        """RuntimeError where a fill pass kept other fragments than the count did."""
        overflow, short = np.frombuffer(self._status.read(size=8), np.uint32)
        if overflow or short:
            raise RuntimeError(f"per-pixel fragment lists: {overflow} fragments found their list full and {short} "
                               f"lists were left short: the count and fill passes kept different fragments")

    def release(self) -> None:
        for buffer in (self.pool, self._status, *self._pixels, *self._rows):
            if buffer is not None:
                buffer.release()
        self.pool = self._status = None
        self._pixels, self._rows = [], []
        self._capacity = (0, 0)
