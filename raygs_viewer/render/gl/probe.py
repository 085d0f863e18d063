"""The short measurement behind ``--sort auto`` and ``--precision auto``: what this GL
does fastest, and right, measured on itself in a few seconds.

:class:`Probe` measures in small steps, each a sort or a few frames, so that the
window can run one step after each of its first frames and never stall for the whole
of it; :func:`measure_profile` runs every step at once (``doctor``, ``render-path``).

What it measures, on generated scenes (:func:`probe_scene`, the same every run):

- **the sorts**: at each of :data:`SORT_COUNTS` gaussians, the CPU sort
  (``DepthSorter``, every core) and the GPU sort (``GpuSorter``, drained at the end of
  each sort so its time is the GPU's), best of :data:`REPEATS` after a first, untimed
  sort each; the GPU's order is compared with the CPU's index for index;
- **the blends**: one frame of :data:`BLEND_COUNT` gaussians at
  :data:`BLEND_SIZE` drawn at each precision, the precisions taking turns so that a
  drift of the machine's speed falls on all of them alike; the time of each is a timer
  query on a GPU and the CPU's clock with the GL drained on a software renderer (where
  a query closes before the work is done); its largest difference from float32's image.
"""

from __future__ import annotations

import datetime
import time
from collections.abc import Callable, Iterator

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.gl.profile import BlendTiming, GlProfile, SortTiming, gl_identity
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import PRECISIONS, RenderSettings
from raygs_viewer.render.sorting import exact_order, sort_request
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.depth import DepthSorter

#: The scene sizes the sorts are measured at: a small scene, where the GPU sort's fixed
#: cost (its passes and one read-back) shows, and a trained scene's usual size.
SORT_COUNTS = (100_000, 1_000_000)
BLEND_COUNT = 200_000
BLEND_SIZE = (640, 360)
REPEATS = 3
#: Renderer names of Mesa's software rasterizers: their timer queries close before the
#: work is done, so they are timed on the CPU's clock.
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast")


def probe_scene(count: int, seed: int = 0) -> Scene:
    """``count`` gaussians (SH degree 0) in a ball of radius 1 in front of
    :func:`probe_camera`, sized so that a frame is covered some ten times over whatever
    the count: what a trained scene's frame asks of the blend."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    positions = directions * rng.uniform(0.0, 1.0, (count, 1)) ** (1.0 / 3.0)
    size = 1.3 / np.sqrt(max(count, 1))
    scales = size * np.exp(rng.normal(0.0, 0.5, (count, 3)))
    rotations = rng.normal(size=(count, 4))
    rotations /= np.linalg.norm(rotations, axis=1, keepdims=True)
    opacities = rng.uniform(0.05, 0.95, count)
    sh = rng.uniform(-1.5, 1.5, (count, 1, 3))
    return Scene(positions.astype(np.float32), rotations.astype(np.float32), scales.astype(np.float32),
                 opacities.astype(np.float32), sh.astype(np.float32), 0, source=f"probe, {count:,} gaussians")


def probe_camera(width: int, height: int) -> Camera:
    return look_at((0.0, 0.0, -1.8), (0.0, 0.0, 0.0), width=width, height=height, fov_y_degrees=60.0)


def software_gl(renderer: str) -> bool:
    return any(name in renderer.lower() for name in SOFTWARE_RENDERERS)


class Probe:
    """Measures a GL in steps (see the module's docstring): ``next(probe.steps)``
    runs one and says what it measured; when the steps are done, ``profile`` holds the
    result. Runs on the thread that holds ``ctx``, leaving the context as it found it
    apart from what it draws into its own target."""

    def __init__(self, ctx: moderngl.Context, *, sort_counts: tuple[int, ...] = SORT_COUNTS,
                 blend_count: int = BLEND_COUNT, blend_size: tuple[int, int] = BLEND_SIZE,
                 repeats: int = REPEATS, today: Callable[[], str] | None = None):
        self.ctx = ctx
        self.renderer, self.version = gl_identity(ctx)
        self.software = software_gl(self.renderer)
        self.sort_counts, self.blend_count, self.blend_size = sort_counts, blend_count, blend_size
        self.repeats = repeats
        self.today = today or (lambda: datetime.date.today().isoformat())
        self.gpu_problem = GpuSorter.problem(ctx)
        self.sorts: list[SortTiming] = []
        self.blends: list[BlendTiming] = []
        self.profile: GlProfile | None = None
        self.steps: Iterator[str] = self._steps()

    def _steps(self) -> Iterator[str]:
        for count in self.sort_counts:
            yield from self._sort_steps(count)
        yield from self._blend_steps()
        self.profile = GlProfile(self.renderer, self.version, self.today(), tuple(self.sorts), tuple(self.blends),
                                 self.gpu_problem)

    def _sort_steps(self, count: int) -> Iterator[str]:
        scene = probe_scene(count)
        request = sort_request(probe_camera(*self.blend_size), RenderSettings())
        cpu_times, gpu_times = [], []
        yield f"a scene of {count:,}"
        with DepthSorter(scene) as cpu:
            expected = cpu.sort(request).order.host_indices()  # untimed: the first builds the caches
            yield f"CPU sort of {count:,}"
            for _ in range(self.repeats):
                cpu_times.append(_seconds(lambda: cpu.sort(request)))
                yield f"CPU sort of {count:,}"
        identical, gpu_ms = False, None
        if self.gpu_problem is None:
            try:
                gpu = GpuSorter(self.ctx, scene)
            except UserError as exc:  # e.g. a scene over this GPU's storage block
                self.gpu_problem = str(exc)
            else:
                with gpu:
                    identical = np.array_equal(gpu.sort(request).order.host_indices(), expected)
                    yield f"GPU sort of {count:,}"
                    for _ in range(self.repeats):
                        gpu_times.append(_seconds(lambda: gpu.sort(request)))
                        yield f"GPU sort of {count:,}"
                gpu_ms = min(gpu_times) * 1e3
        self.sorts.append(SortTiming(count, min(cpu_times) * 1e3, gpu_ms, identical))

    def _blend_steps(self) -> Iterator[str]:
        scene = probe_scene(self.blend_count, seed=1)
        camera = probe_camera(*self.blend_size)
        renderer = GLRenderer(self.ctx, scene)
        target = FloatTarget(self.ctx, camera.width, camera.height)
        timer = GpuTimer(self.ctx)
        try:
            with DepthSorter(scene) as sorter:
                order = exact_order(sorter, camera, RenderSettings())
            settings = {precision: RenderSettings(precision=precision) for precision in PRECISIONS}
            images = {}
            for precision, each in settings.items():  # untimed: compiles each variant, makes the records
                renderer.render_into(target, camera, each, order)
                images[precision] = target.read()[..., :3]
                yield f"{precision} blend compiled"
            times: dict[str, list[float]] = {precision: [] for precision in PRECISIONS}
            for _ in range(self.repeats):
                for precision, each in settings.items():
                    times[precision].append(self._frame_ms(timer, lambda: renderer.render_into(
                        target, camera, each, order)))
                    yield f"{precision} blend timed"
        finally:
            target.release()
            renderer.release()
        for precision in PRECISIONS:
            error = float(np.max(np.abs(images[precision] - images["float32"])))
            self.blends.append(BlendTiming(precision, min(times[precision]), error))

    def _frame_ms(self, timer: GpuTimer, work: Callable[[], object]) -> float:
        if not self.software:
            return timer.time_ms(work)
        self.ctx.finish()
        return _seconds(lambda: (work(), self.ctx.finish())) * 1e3


def _seconds(work: Callable[[], object]) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def measure_profile(ctx: moderngl.Context, progress: Callable[[str], None] | None = None,
                    **options) -> GlProfile:
    """Every step of a :class:`Probe` at once; ``progress`` hears each step's line."""
    probe = Probe(ctx, **options)
    for step in probe.steps:
        if progress is not None:
            progress(step)
    return probe.profile
