"""``doctor``'s sort rows: the GPU sort (``render.gl.gpu_sort.GpuSorter``) against the CPU
sort (``sort.depth.DepthSorter``) on generated scenes of ``count`` gaussians, both keys
(depth and distance) over one cull, with the quantised ("auto") and the float keys;
a row passes when both give the same indices, to the element.

The scenes (:data:`SORT_SCENES`), each seen by :func:`sort_camera` (at the origin,
looking along +z, so camera space is world space and a depth is the centre's z):

- random: centres in a box around the view, a part of them behind the camera or
  outside the frustum;
- equal depths: every centre on one of 16 depth planes, a quarter of the centres
  copies of others (ties in both keys);
- a float32 ulp apart: depths within 64 ulps of 3, and distances within 64 ulps of 2;
- negative zero: coordinates of -0.0 and +0.0 (one key to numpy, two bit patterns);
- culled: support spheres touching the plane behind the camera or a side plane to
  within a few ulps, the rest of the scene around them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from raygs_viewer.bench.common import count_label
from raygs_viewer.bench.doctor_checks import CorrectnessRow, error_words
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.settings import DEFAULT_P_MIN
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.cull import RADIUS_WIDENING, cull_slack, side_planes
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import SortRequest

SORT_COUNT = 1_000_000
QUICK_SORT_COUNT = 200_000
KEYS = ("depth", "distance")
METHODS = ("auto", "float")
SIZE = (640, 480)
#: The farthest coordinate of every scene (its coordinate scale, which sets the cull's slack).
REACH = 8.0


def sort_camera() -> Camera:
    """At the origin, looking along +z, 60 degrees vertical, with t = (0, 0, -0.0)."""
    width, height = SIZE
    focal = height / 2 / math.tan(math.radians(30.0))
    return Camera(width, height, focal, focal, width / 2, height / 2, np.eye(3), np.array([0.0, 0.0, -0.0]))


def _scene(positions: np.ndarray, rng: np.random.Generator, scales: np.ndarray | None = None,
           opacities: np.ndarray | None = None) -> Scene:
    """A scene of these centres (row 0 pinned at REACH: the coordinate scale), random
    rotations, sizes and opacities unless given, SH degree 0."""
    count = positions.shape[0]
    positions = np.asarray(positions, np.float32)
    positions[0] = (0.0, 0.0, REACH)
    if scales is None:
        scales = np.exp(rng.uniform(-6.0, -2.5, (count, 3)))
    if opacities is None:
        opacities = rng.uniform(0.02, 1.0, count)
    rotations = rng.normal(size=(count, 4))
    rotations /= np.linalg.norm(rotations, axis=1, keepdims=True)
    sh = rng.uniform(-1.0, 1.0, (count, 1, 3))
    return Scene(positions, rotations.astype(np.float32), np.asarray(scales, np.float32),
                 np.asarray(opacities, np.float32), sh.astype(np.float32), 0)


def _in_view(rng: np.random.Generator, depths: np.ndarray) -> np.ndarray:
    """Centres at ``depths`` spread over the view (a little beyond its edges)."""
    camera = sort_camera()
    x = (rng.uniform(-0.1, 1.1, depths.size) * camera.width - camera.cx) / camera.fx * depths
    y = (rng.uniform(-0.1, 1.1, depths.size) * camera.height - camera.cy) / camera.fy * depths
    return np.column_stack([x, y, depths])


def random_scene(count: int, rng: np.random.Generator) -> Scene:
    return _scene(rng.uniform((-4.0, -3.0, -2.0), (4.0, 3.0, 7.0), (count, 3)), rng)


def equal_depths(count: int, rng: np.random.Generator) -> Scene:
    positions = _in_view(rng, rng.choice(np.linspace(1.0, 6.0, 16), count))
    copies = rng.choice(count, count // 4, replace=False)
    positions[copies] = positions[rng.integers(0, count, copies.size)]
    return _scene(positions, rng)


def ulp_apart(count: int, rng: np.random.Generator) -> Scene:
    """Depths 3 + k ulps, then distances 2 + k ulps (k < 64), half the scene each."""
    half = count // 2
    depths = (np.float32(3.0).view(np.uint32) + rng.integers(0, 64, half).astype(np.uint32)).view(np.float32)
    directions = _in_view(rng, np.ones(count - half))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radii = (np.float32(2.0).view(np.uint32) + rng.integers(0, 64, count - half).astype(np.uint32)).view(np.float32)
    return _scene(np.concatenate([_in_view(rng, depths.astype(np.float64)), directions * radii[:, None]]), rng)


def negative_zero(count: int, rng: np.random.Generator) -> Scene:
    """Each coordinate -0.0, +0.0 or ordinary, a third each (depths ordinary ones in front)."""
    positions = _in_view(rng, rng.uniform(0.5, 6.0, count)).astype(np.float32)
    which = rng.integers(0, 3, (count, 3))
    positions[which == 0] = -0.0
    positions[which == 1] = 0.0
    return _scene(positions, rng)


def culled(count: int, rng: np.random.Generator) -> Scene:
    """Support spheres, as the cull widens them, touching the plane behind the camera
    or one of the four side planes (a fifth each), moved a relative 1e-6 either way."""
    camera = sort_camera()
    scales = np.exp(rng.uniform(-6.0, -2.5, (count, 3)))
    opacities = rng.uniform(0.02, 1.0, count)
    root_kappa = np.sqrt(np.maximum(2.0 * (np.log(opacities) - math.log(DEFAULT_P_MIN)), 0.0))
    reach = root_kappa * scales.max(axis=1) * float(RADIUS_WIDENING) + float(cull_slack(REACH, camera))
    positions = _in_view(rng, rng.uniform(0.3, 6.0, count))
    plane = rng.integers(0, 5, count)
    positions[plane == 0] = (0.0, 0.0, 0.0)
    positions[plane == 0, 2] = -reach[plane == 0]
    for number, (axis, a, b) in enumerate(side_planes(camera), start=1):
        on = plane == number
        positions[on, axis] = (-reach[on] - positions[on, 2] * float(b)) / float(a)
    moved = np.where(plane == 0, 2, np.array([0] + [axis for axis, _, _ in side_planes(camera)])[plane])
    positions[np.arange(count), moved] *= 1.0 + 1e-6 * rng.uniform(-1.0, 1.0, count)
    return _scene(positions, rng, scales, opacities)


#: name -> scene of ``count`` gaussians (module docstring), in the report's order.
SORT_SCENES: dict[str, Callable[[int, np.random.Generator], Scene]] = {
    "random": random_scene, "equal depths": equal_depths, "a float32 ulp apart": ulp_apart,
    "negative zero": negative_zero, "culled": culled,
}


@dataclass(frozen=True)
class SortRow(CorrectnessRow):
    """One scene sorted with one method: per key (depth, distance) the gaussians kept
    and, in ``faults``, where the GPU's indices differ from the CPU's, how; ``problem``:
    why the GPU sort cannot run here (no failure)."""

    scene: str
    count: int
    method: str
    kept: tuple[int, ...] = ()

    @property
    def label(self) -> str:
        return f"sort {self.scene} {count_label(self.count)}, {self.method} keys"


def _difference(key: str, gpu: np.ndarray, cpu: np.ndarray) -> str | None:
    if gpu.size != cpu.size:
        return f"{key}: {gpu.size:,} kept on the GPU, {cpu.size:,} on the CPU"
    wrong = np.flatnonzero(gpu != cpu)
    if wrong.size == 0:
        return None
    return f"{key}: {wrong.size:,} of {cpu.size:,} indices differ, the first at place {int(wrong[0]):,}"


def check_sorts(ctx, count: int, say: Callable[[str], None], scenes: tuple[str, ...] | None = None) -> list[SortRow]:
    """The rows of every scene of :data:`SORT_SCENES` (``scenes``: only those) and method."""
    names = tuple(SORT_SCENES) if scenes is None else scenes
    problem = GpuSorter.problem(ctx)
    if problem is None and count > GpuSorter.capacity(ctx):
        problem = f"the GPU sort holds at most {GpuSorter.capacity(ctx):,} gaussians here"
    if problem is not None:
        return [SortRow(name, count, method, problem=problem) for name in names for method in METHODS]
    rows = []
    for number, name in enumerate(names):
        done = scene_rows(ctx, name, SORT_SCENES[name](count, np.random.default_rng(number)))
        rows += done
        say(f"correct: sort {name} {count_label(count)}: "
            + ("; ".join(d for row in done for d in row.faults) or "identical"))
    return rows


def scene_rows(ctx, name: str, scene: Scene) -> list[SortRow]:
    """One row per method of ``scene`` sorted both ways. A UserError (this GL's memory)
    makes the rows not yet made unsupported here; any other error (a pass this driver
    does not compile or run) makes them fail with its one line."""
    rows: list[SortRow] = []
    try:
        with DepthSorter(scene) as cpu, GpuSorter(ctx, scene) as gpu:
            for method in METHODS:
                request = SortRequest(sort_camera(), DEFAULT_P_MIN, 0.0, keys=KEYS, method=method)
                expected, got = cpu.sort(request).orders, gpu.sort(request).orders
                found = [_difference(key, got[key].host_indices(), expected[key].indices) for key in KEYS]
                rows.append(SortRow(name, scene.count, method, tuple(expected[key].count for key in KEYS),
                                    faults=tuple(text for text in found if text)))
    except UserError as exc:
        rows += [SortRow(name, scene.count, method, problem=one_line(exc)) for method in METHODS[len(rows):]]
    except Exception as exc:  # noqa: BLE001 - every other failure becomes the rows' one line
        rows += [SortRow(name, scene.count, method, faults=(error_words(exc),)) for method in METHODS[len(rows):]]
    return rows
