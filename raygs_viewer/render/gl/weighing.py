"""Each gaussian's largest weight T alpha over a set of pixels, weighed on the GPU in
slices: what "select what the view shows" selects by, the twin of the float64
``render.contributions.max_weights`` (which the tests hold this to, and which weighs
where this cannot run).

Each fragment at the pixels asked about raises ``weights[scene row]`` to its weight with
``atomicMax`` on the float's bits (which order as the floats do for weights >= 0). Two
paths, both drawing into targets whose viewport puts the camera's whole image around
the pixels' box (the records stay the view's):

- "fetch": the global order (with or without the cut-off) drawn front to back, each
  fragment reading T through ``GL_EXT_shader_framebuffer_fetch`` (glsl/fragment_output.glsl,
  ``WEIGHTS``): one draw.
- "lists": every order, through the fragment lists (render/gl/fragment_lists.py), whose
  resolve (glsl/lists_resolve.comp, ``WEIGHTS``) composites each pixel's list as the
  window does (the global order by rank; each ray's own, exact or through the window of
  K). The fallback where fetch is missing (NVIDIA's desktop drivers).

The gaussians drawn are the order's: rows it leaves out (deleted ones) weigh 0 and hide
nothing. A slice is a band of the box's rows, drawn with the view's order keeping only
what reaches the band (``Sort``), as many rows as the last slice's time says fit
``slice_seconds``; so a selection runs beside the frames, a slice each, and can be
dropped between slices. Where neither path runs, :class:`CpuWeighing` weighs in float64.
A pixel's ray is its centre's (supersampling's sub-samples are not weighed), as the
reference's.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Callable, Iterator, Literal, Protocol

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.contributions import bounds, cropped, weigh_bands
from raygs_viewer.render.gl.fragment_lists import FragmentLists
from raygs_viewer.render.gl.kbuffer import FRAMEBUFFER_FETCH
from raygs_viewer.render.gl.per_pixel import LIST_BLOCKS, storage_block_problem
from raygs_viewer.render.gl.plan import DrawLayout, RenderPlan
from raygs_viewer.render.gl.shaders import set_uniform
from raygs_viewer.render.gl.storage import gpu_limit
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import Order

#: Where a weighing runs: "auto" the fastest this GPU and order allow, or forced: "fetch"
#: (the global order front to back through framebuffer fetch), "lists" (the fragment
#: lists: every order, any OpenGL 4.3), "cpu" (float64, render.contributions).
WeighOn = Literal["auto", "fetch", "lists", "cpu"]
WEIGH_ON: tuple[WeighOn, ...] = ("auto", "fetch", "lists", "cpu")
#: The view's order keeping what the cull for a camera (a band of the view's image)
#: keeps, in the view's own sequence (``render.sorting.part_orders``: a sort of the band
#: alone would order near ties of the radix keys otherwise than the view).
Sort = Callable[[Camera], Order]
#: The weights' storage binding (glsl/lists_resolve.comp, glsl/fragment_output.glsl).
WEIGHTS_BINDING = 16
#: The mask's texture unit.
INSIDE_UNIT = 0
#: The time a slice aims at when none is given (seconds).
DEFAULT_SLICE_SECONDS = 0.05
#: Rows the first slice of a front-to-back weighing draws (later ones as its time says).
FIRST_ROWS = 8


class Weighing(Protocol):
    """A weighing under way: :meth:`step` runs one slice (True once finished),
    :attr:`progress` the share done so far (0..1), :attr:`weights` the result
    ((N,) float32, once finished), :meth:`release` frees what it holds (a dropped one
    too). ``where``: the path, as the panel and the benchmark name it."""

    where: str

    def step(self) -> bool: ...

    @property
    def progress(self) -> float: ...

    @property
    def weights(self) -> np.ndarray: ...

    def release(self) -> None: ...


def weighing_plan(renderer, settings: RenderSettings, path: str) -> RenderPlan:
    """The plan of weighing ``settings``' view by ``path`` ("fetch" or "lists"), at one
    sample a pixel, whatever path the view itself takes (blending, the k-buffer)."""
    plan = renderer.plan(replace(settings, supersample=1))
    # Records at their scene rows: each band draws an order of its own from the same records.
    return replace(plan, path="lists" if path == "lists" else None, weights=True, problem=None,
                   draw=DrawLayout(plan.draw.vertices, "scene"))


def weighing_problem(renderer, settings: RenderSettings, path: str) -> str | None:
    """Why ``renderer``'s GPU cannot weigh ``settings``' view by ``path`` (one line), or
    None. "fetch": the global order and ``GL_EXT_shader_framebuffer_fetch``, one storage
    block in the fragment stage; "lists": the fragment lists' blocks and one more in the
    compute stage."""
    layout = renderer.plan(settings).layout
    ctx = renderer.ctx
    if path == "fetch":
        if settings.per_pixel:
            return "the per-ray order is weighed through the fragment lists"
        if FRAMEBUFFER_FETCH not in ctx.extensions:
            return f"weighing front to back needs {FRAMEBUFFER_FETCH}, which this GPU's OpenGL driver does not offer"
        needs = {"GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS": 1}
    else:
        problem = storage_block_problem(ctx, "lists", layout.splat_blocks)
        if problem:
            return problem
        needs = {"GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": layout.splat_blocks + LIST_BLOCKS + 1}
    for limit, needed in needs.items():
        offered = gpu_limit(ctx, limit, 8)
        if needed > offered:
            return f"weighing needs {needed} storage blocks where this GPU offers {offered} ({limit})"
    return None


def start_weighing(renderer, camera: Camera, settings: RenderSettings, sort: Sort, inside: np.ndarray, *,
                   weigh_on: WeighOn = "auto", slice_seconds: float = DEFAULT_SLICE_SECONDS) -> Weighing:
    """The weighing of the pixels of ``camera`` where ``inside`` ((H, W) bool, top row
    first) holds, drawn with ``settings`` in the orders ``sort`` gives (the view's, culled
    to a part of ``camera``'s image) by ``renderer``: front to back through framebuffer fetch where it can run (the global
    order), else through the fragment lists, else on the CPU in float64; ``weigh_on``
    forces one. UserError: a forced path that cannot run here, or a weighing too large
    for the CPU's."""
    if weigh_on not in WEIGH_ON:
        raise UserError(f"weigh on must be one of {', '.join(WEIGH_ON)}, got {weigh_on!r}")
    reasons = []
    for path in ("fetch", "lists") if weigh_on == "auto" else () if weigh_on == "cpu" else (weigh_on,):
        problem = weighing_problem(renderer, settings, path)
        if problem is None or weigh_on != "auto":  # a forced path that cannot run says why
            return GpuWeighing(renderer, camera, settings, sort, inside, path=path, slice_seconds=slice_seconds)
        reasons.append(problem)
    return CpuWeighing(renderer.scene, camera, settings, sort, inside, slice_seconds=slice_seconds,
                       reason=reasons[-1] if reasons else "forced")


def weigh_now(renderer, camera: Camera, settings: RenderSettings, sort: Sort, inside: np.ndarray, *,
              weigh_on: WeighOn = "auto") -> np.ndarray:
    """(N,) float32: :func:`start_weighing`'s weights, every slice run now."""
    weighing = start_weighing(renderer, camera, settings, sort, inside, weigh_on=weigh_on)
    try:
        while not weighing.step():
            pass
        return weighing.weights
    finally:
        weighing.release()


def _checked(inside: np.ndarray, camera: Camera) -> np.ndarray:
    inside = np.asarray(inside, bool)
    if inside.shape != (camera.height, camera.width):
        raise ValueError(f"inside is {inside.shape}, the camera's image is {(camera.height, camera.width)}")
    return inside


class GpuWeighing:
    """One weighing on the GPU (see the module docstring) by ``path`` ("fetch" or
    "lists"), a band of the box's rows a slice, each drawn with ``sort``'s order for
    that band alone (the view's order culled to it: the vertex stage pays for the
    gaussians reaching the band, not the scene's). ``renderer``: the scene's
    ``GLRenderer``, whose records a slice prepares again where a frame drew others."""

    def __init__(self, renderer, camera: Camera, settings: RenderSettings, sort: Sort, inside: np.ndarray, *,
                 path: str = "lists", slice_seconds: float = DEFAULT_SLICE_SECONDS,
                 pool_fragments: int | None = None):
        inside = _checked(inside, camera)
        problem = weighing_problem(renderer, settings, path)
        if problem:
            raise UserError(problem)
        self.renderer, self.camera, self.sort, self.path = renderer, camera, sort, path
        self.where = "GPU, framebuffer fetch" if path == "fetch" else "GPU, fragment lists"
        self.plan = weighing_plan(renderer, settings, path)
        self.slice_seconds = max(float(slice_seconds), 1e-3)
        self.count = renderer.scene.count
        self._weights: np.ndarray | None = None
        self._made: list = []
        self._box = bounds(inside) if inside.any() else None
        self._next = 0                          # the box's next row (from its top)
        self._rows = FIRST_ROWS                 # rows the next slice weighs
        if self._box is None:
            self._weights = np.zeros(self.count, np.float32)
            return
        ctx: moderngl.Context = renderer.ctx
        rows, cols = self._box
        width, height = cols.stop - cols.start, rows.stop - rows.start
        try:
            self._buffer = self._own(ctx.buffer(reserve=max(4, self.count * 4)))
            self._buffer.clear()
            mask = np.ascontiguousarray(inside[rows, cols][::-1]).astype(np.uint8) * 255
            self._inside = self._own(ctx.texture((width, height), 1, mask.tobytes(), dtype="f1"))
            self._inside.filter = (moderngl.NEAREST, moderngl.NEAREST)
            if path == "fetch":  # read and written front to back: float32, from 0 (nothing composited)
                self._target = self._own(self._box_target(0, height, "f4"))
                self._target.fbo.clear(0.0, 0.0, 0.0, 0.0)
            else:
                self._lists = self._own(FragmentLists(ctx, renderer.storage.block_limit, pool_fragments))
                self._resolve = renderer.programs.compute("lists_resolve.comp", self.plan.pass_defines())
        except BaseException:
            self.release()
            raise

    def _own(self, thing):
        self._made.append(thing)
        return thing

    def _box_target(self, top: int, bottom: int, dtype: str) -> FloatTarget:
        """A target of the box's rows top..bottom-1 (from its top), whose viewport puts
        the camera's whole image around them: the records are the whole camera's, and a
        pixel's place in the target is its place in those rows (GL's from the bottom)."""
        rows, cols = self._box
        target = FloatTarget(self.renderer.ctx, cols.stop - cols.start, bottom - top, dtype=dtype)
        camera = self.camera
        target.fbo.viewport = (-cols.start, -(camera.height - rows.start - bottom), camera.width, camera.height)
        return target

    @property
    def done(self) -> bool:
        return self._weights is not None

    @property
    def progress(self) -> float:
        if self.done:
            return 1.0
        rows, _ = self._box
        return self._next / (rows.stop - rows.start)

    @property
    def weights(self) -> np.ndarray:
        if self._weights is None:
            raise RuntimeError("the weighing has not finished")
        return self._weights

    def step(self) -> bool:
        """Weighs the box's next rows, as many as the last slice's time says fit one."""
        if self.done:
            return True
        rows, cols = self._box
        height = rows.stop - rows.start
        top = self._next
        bottom = min(height, top + max(1, self._rows))
        started = time.perf_counter()
        band = cropped(self.camera, slice(rows.start + top, rows.start + bottom), cols)
        order = self.sort(band)
        if order.count:
            self.renderer.preprocess(self.camera, self.plan, order)  # skipped where the records are this view's
            self._buffer.bind_to_storage_buffer(WEIGHTS_BINDING)
            self._inside.use(INSIDE_UNIT)
            if self.path == "fetch":
                self._fetch(order, top, bottom)
            else:
                self._resolve_lists(order, top, bottom)
        self.renderer.ctx.finish()  # the slice's time sizes the next
        seconds = time.perf_counter() - started
        self._next = bottom
        self._rows = max(1, int((bottom - top) * self.slice_seconds / max(seconds, 1e-6)))
        return self._finish() if self._next >= height else False

    def _fetch(self, order: Order, top: int, bottom: int) -> None:
        """The rows top..bottom-1 drawn front to back into the box's target (scissored)."""
        target = self._target
        target.use()
        target.fbo.scissor = (0, target.size[1] - bottom, target.size[0], bottom - top)
        try:
            self.renderer.draw(self.camera, self.plan, order, uniforms={"u_inside": INSIDE_UNIT})
        finally:
            target.fbo.scissor = None

    def _resolve_lists(self, order: Order, top: int, bottom: int) -> None:
        """The rows top..bottom-1 through the fragment lists: counted, then filled and
        resolved a pool's worth at a time."""
        renderer, camera, plan = self.renderer, self.camera, self.plan
        target = self._box_target(top, bottom, "f1")
        try:
            row_stats = self._lists.count(renderer, target, camera, plan, order)
            set_uniform(self._resolve, "u_inside", INSIDE_UNIT)
            # The band's rows start this far up the box's mask (GL's rows from the bottom).
            set_uniform(self._resolve, "u_inside_origin", (0, self._inside.size[1] - bottom))
            for part in self._lists.parts(row_stats):
                self._buffer.bind_to_storage_buffer(WEIGHTS_BINDING)
                self._lists.fill_and_resolve(renderer, target, camera, plan, order, part=part,
                                             resolve=self._resolve)
            self.renderer.ctx.memory_barrier()
            self._lists.check_status()
        finally:
            target.release()

    def _finish(self) -> bool:
        self.renderer.ctx.memory_barrier()
        self._weights = np.frombuffer(self._buffer.read(), np.float32)[:self.count].copy()
        self.release()
        return True

    def release(self) -> None:
        made, self._made = self._made, []
        for thing in reversed(made):
            thing.release()


class CpuWeighing:
    """One weighing in float64 on the CPU (``render.contributions``), a few bands of
    pixel rows a slice: where the GPU cannot weigh (``reason`` says why)."""

    def __init__(self, scene, camera: Camera, settings: RenderSettings, sort: Sort, inside: np.ndarray, *,
                 slice_seconds: float = DEFAULT_SLICE_SECONDS, reason: str = ""):
        inside = _checked(inside, camera)
        self.reason = reason
        self.where = f"CPU ({reason})"
        self.slice_seconds = float(slice_seconds)
        order = sort(cropped(camera, *bounds(inside))) if inside.any() else Order(np.zeros(0, np.uint32))
        indices = order.indices.read() if order.on_device else order.indices  # a GPU sort's, fetched
        self._result = np.zeros(scene.count)
        self._bands: Iterator[tuple[int, int]] | None = weigh_bands(scene, camera, settings, indices, inside,
                                                                    weights=self._result)
        self._progress = 0.0

    @property
    def progress(self) -> float:
        return self._progress

    @property
    def weights(self) -> np.ndarray:
        if self._bands is not None:
            raise RuntimeError("the weighing has not finished")
        return self._result.astype(np.float32)

    def step(self) -> bool:
        """Bands until the slice's time is spent."""
        started = time.perf_counter()
        while self._bands is not None:
            try:
                done, rows = next(self._bands)
            except StopIteration:
                self._bands = None
                self._progress = 1.0
                break
            self._progress = done / rows
            if time.perf_counter() - started >= self.slice_seconds:
                break
        return self._bands is None

    def release(self) -> None:
        self._bands = None
