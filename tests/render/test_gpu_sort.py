"""The GPU sort (raygs_viewer/render/gl/gpu_sort.py) gives DepthSorter's orders bit for
bit: on scenes with exact key ties and near-ties, gaussians whose support spheres touch
each of the cull's five planes to within a few float32 ulps, every key, method, p_min,
dilation, stereo cull cameras and level spans; the images drawn from its orders, which
stay on the GPU, equal those drawn from the CPU's; and negative controls show the tests
catch an approximate square root and a tie broken by the sign of zero."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import moderngl
import numpy as np
import pytest
from moderngl import InvalidObject
from testkit import make_scene, patched_glsl, random_scene, spans_choice

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.camera.stereo import StereoRig, eye_cameras
from raygs_viewer.render.gl.gpu_sort import FLOAT, QUANTISED, SCENE, GpuIndices, GpuSorter, key_plan
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.shaders import Programs
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import sort_request
from raygs_viewer.sort.cull import RADIUS_WIDENING, Cull, cull_slack, side_planes
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.keys import camera_space, stable_order
from raygs_viewer.sort.request import DeviceIndices, SortRequest

KEYS = ("depth", "distance")
METHODS = ("auto", "radix", "float")
#: None: only what is behind the camera is culled; 0: the frustum; 0.03: a MIP filter's dilation.
DILATIONS = (None, 0.0, 0.03)


@pytest.fixture(scope="module")
def programs(gl_session_ctx):
    """Programs shared by every sorter of the module: each compiles once."""
    gl_session_ctx.__enter__()
    built = Programs(gl_session_ctx)
    yield built
    gl_session_ctx.__enter__()
    built.release()


def camera_at(eye=(0.3, -0.2, -2.5), target=(0.0, 0.0, 0.0), width=64, height=48, fov=60.0):
    return look_at(eye, target, width=width, height=height, fov_y_degrees=fov)


def assert_same_orders(gpu: GpuSorter, cpu: DepthSorter, request: SortRequest) -> dict[str, np.ndarray]:
    """Both sorters' orders for ``request`` are equal, key by key; returns them."""
    got, expected = gpu.sort(request), cpu.sort(request)
    assert tuple(got.orders) == tuple(expected.orders) == request.keys
    for key in request.keys:
        order = got.orders[key]
        assert order.on_device and isinstance(order.indices, GpuIndices) and order.key == key
        assert order.request is request and order.choice is got.choice
        indices = order.host_indices()
        assert indices.dtype == np.uint32
        np.testing.assert_array_equal(indices, expected.orders[key].indices, err_msg=f"{key} {request.method}")
    return {key: got.orders[key].host_indices() for key in request.keys}


def check_everything(ctx, programs, scene, camera, p_mins=(1 / 255,), **request) -> None:
    """Every method and dilation, both keys at once, for each p_min, on one sorter each."""
    with GpuSorter(ctx, scene, programs=programs) as gpu, DepthSorter(scene) as cpu:
        for p_min in p_mins:
            for method in METHODS:
                for dilation in DILATIONS:
                    assert_same_orders(gpu, cpu, SortRequest(camera, p_min, dilation, keys=KEYS, method=method,
                                                             **request))


# -- scenes ---------------------------------------------------------------------------------------
def with_duplicates(scene, seed: int):
    """``scene`` with a third of its centres copied from others (exact ties in both keys)
    and a run of one repeated centre."""
    rng = np.random.default_rng(seed)
    positions = scene.positions.copy()
    n = scene.count
    copies = rng.choice(n, n // 3, replace=False)
    positions[copies] = positions[rng.integers(0, n, copies.size)]
    positions[n // 4: n // 2] = positions[0]
    return replace(scene, positions=positions)


def grid_scene(side: int = 12):
    """Centres on a grid, shuffled: whole planes of exact depth ties for an axis-aligned
    camera, and rings of distance ties."""
    axis = np.linspace(-1.0, 1.0, side)
    positions = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    positions = positions[np.random.default_rng(3).permutation(len(positions))]
    return make_scene(positions, 0.02, opacities=0.7)


def shell_scene(centre, count: int = 4000, seed: int = 4):
    """Centres on a sphere about ``centre``, their distances a few float32 ulps apart:
    near-ties that any rounding of |p - C| other than the CPU's reorders."""
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radii = 1.5 * (1 + 3e-7 * rng.standard_normal(count))
    return make_scene(np.asarray(centre) + directions * radii[:, None], 0.01,
                      opacities=rng.uniform(0.02, 1.0, count).astype(np.float32))


def straddling_scene(camera, count: int = 12000, seed: int = 0, p_min: float = 1 / 255, dilation: float = 0.0,
                     jitter: float = 1e-6):
    """Gaussians whose support spheres, as the cull widens them for ``camera``, touch
    one of its five planes (behind the camera, left, right, top, bottom: ``plane`` of
    each, 0 to 4) to within a few float32 ulps, the plane's coordinate shaken by
    ``jitter``: about half are kept, and any rounding unlike the CPU's flips some."""
    rng = np.random.default_rng(seed)
    planes = side_planes(camera)
    scales = np.exp(rng.uniform(-4.0, -1.5, count))
    opacities = rng.uniform(0.05, 1.0, count)
    root_kappa = np.sqrt(np.maximum(2.0 * (np.log(opacities) - math.log(p_min)), 0.0))
    plane = rng.integers(0, 5, count)
    mu = np.zeros((count, 3))
    mu[:, 2] = rng.uniform(0.3, 3.0, count)
    mu[:, 0] = (rng.uniform(0, camera.width, count) - camera.cx) / camera.fx * mu[:, 2]
    mu[:, 1] = (rng.uniform(0, camera.height, count) - camera.cy) / camera.fy * mu[:, 2]
    mu[plane == 0, :2] = 0.0  # on the axis: inside every side plane, whatever their z
    for _ in range(12):  # the slack and the dilation depend on where the centres are: iterate
        extent = np.abs(((mu - camera.t) @ camera.R).astype(np.float32)).max()
        slack = 1e-5 * (extent + np.abs(camera.t).max()) + 1e-6
        reach = (root_kappa * scales + np.linalg.norm(mu, axis=1) * root_kappa * (dilation or 0.0)) * (1 + 1e-5) \
            + slack
        mu[plane == 0, 2] = -reach[plane == 0]
        for number, (axis, a, b) in enumerate(planes, start=1):
            on = plane == number
            mu[on, axis] = (-reach[on] - mu[on, 2] * float(b)) / float(a)
    axis = np.where(plane == 0, 2, np.array([0] + [axis for axis, _, _ in planes])[plane])
    mu[np.arange(count), axis] *= 1 + jitter * rng.uniform(-1, 1, count)
    scene = make_scene((mu - camera.t) @ camera.R, scales[:, None], opacities=opacities)
    return scene, plane


# -- orders -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["duplicates", "grid", "shell", "random"])
def test_hard_scenes_give_the_cpu_orders(gl_ctx, programs, name):
    camera = camera_at()
    if name == "duplicates":
        scene = with_duplicates(random_scene(n=3000, seed=1, degree=0, spread=1.5, log_scale=(-3.0, -1.0)), 1)
    elif name == "grid":  # axis-aligned: each grid plane one depth
        scene, camera = grid_scene(), camera_at(eye=(0.0, 0.0, -3.0), fov=70.0)
    elif name == "shell":  # from the shell's centre: every distance a near-tie
        scene = shell_scene([0.1, 0.2, -0.3])
        camera = camera_at(eye=(0.1, 0.2, -0.3), target=(0.4, 0.1, 1.0), fov=100.0)
    else:
        scene = random_scene(n=5000, seed=2, degree=0, spread=2.0, log_scale=(-4.0, -1.0))
    check_everything(gl_ctx, programs, scene, camera)


@pytest.mark.parametrize("p_min, dilation", [(1 / 255, None), (1 / 255, 0.0), (0.05, 0.0), (1 / 255, 0.05)])
def test_gaussians_straddling_every_plane_are_culled_as_on_the_cpu(gl_ctx, programs, p_min, dilation):
    camera = camera_at(eye=(0.1, 0.05, -0.2), target=(0.3, 0.1, 1.0))
    scene, plane = straddling_scene(camera, p_min=p_min, dilation=dilation, seed=int(p_min * 1000))
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu, DepthSorter(scene) as cpu:
        for method in ("float", "auto"):
            orders = assert_same_orders(gpu, cpu, SortRequest(camera, p_min, dilation, keys=KEYS, method=method))
    kept = np.isin(np.arange(scene.count), orders["depth"])
    # Each plane (the side planes only where the frustum is culled) keeps some and drops some.
    for number in range(5 if dilation is not None else 1):
        assert 0.1 < kept[plane == number].mean() < 0.9, (number, kept[plane == number].mean())


def test_the_straddling_scene_would_catch_a_fused_multiply_add():
    """On the CPU: evaluating the side planes' a x + b z with one rounding (as a GPU's
    fused multiply-add would, were ``precise`` left out) keeps other gaussians of the
    straddling scene than the cull does. llvmpipe never fuses, so this is where the
    scene's teeth show here; on a GPU that fuses, the test above would fail without it."""
    camera = camera_at(eye=(0.1, 0.05, -0.2), target=(0.3, 0.1, 1.0))
    scene, _ = straddling_scene(camera)
    cull = Cull(scene)
    support = cull.support(1 / 255)
    n = scene.count
    mu = np.empty((3, n), np.float32)
    camera_space(np.ascontiguousarray(scene.positions.T), camera, mu, np.empty(n, np.float32))
    bound = -(support.radius * RADIUS_WIDENING + cull_slack(cull.coordinate_scale, camera))
    for axis, a, b in side_planes(camera):
        rounded = mu[axis] * a + mu[2] * b
        fused = (mu[axis].astype(np.float64) * float(a) + (mu[2] * b).astype(np.float64)).astype(np.float32)
        assert ((rounded > bound) != (fused > bound)).sum() > 5


def test_degenerate_ranges_and_a_single_visible_gaussian(gl_ctx, programs):
    """All depths equal (a plane facing the camera), all distances equal (a sphere about
    it), one gaussian kept, and none: nothing to quantise; "radix" keeps scene order,
    "auto" and "float" sort the floats."""
    camera = camera_at(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, 1.0), fov=90.0)
    plane = make_scene([[x, y, 2.0] for x in np.linspace(-0.5, 0.5, 7) for y in np.linspace(-0.5, 0.5, 5)],
                       0.01, opacities=0.8)
    directions = np.random.default_rng(5).normal(size=(40, 3)) * [0.2, 0.2, 0.0] + [0.0, 0.0, 1.0]
    sphere = make_scene(2.0 * directions / np.linalg.norm(directions, axis=1, keepdims=True), 0.01, opacities=0.8)
    single = make_scene([[0.0, 0.0, 2.0], [0.0, 0.0, -5.0], [50.0, 0.0, 2.0]], 0.05, opacities=0.9)
    behind = make_scene([[0.0, 0.0, -2.0], [0.3, 0.0, -1.0]], 0.05, opacities=0.9)
    for scene, expected in ((plane, None), (sphere, None), (single, 1), (behind, 0)):
        check_everything(gl_ctx, programs, scene, camera)
        if expected is not None:
            with GpuSorter(gl_ctx, scene, programs=programs) as gpu:
                assert gpu.sort(SortRequest(camera, 1 / 255, keys=KEYS)).order.count == expected


def test_a_change_of_p_min_uploads_the_support_again(gl_ctx, programs):
    scene = random_scene(n=2000, seed=6, degree=0, spread=1.5, log_scale=(-3.0, -1.0))
    camera = camera_at()
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu, DepthSorter(scene) as cpu:
        counts = []
        for p_min in (1 / 255, 0.05, 0.05, 1 / 255, 0.3):
            orders = assert_same_orders(gpu, cpu, SortRequest(camera, p_min, 0.02, keys=KEYS))
            counts.append(orders["depth"].size)
        assert gpu.support_uploads == 4 and counts[0] > counts[1] > counts[4] > 0


def test_stereo_cull_cameras(gl_ctx, programs):
    """Both eyes' union, sorted from the midpoint (a camera that is neither eye), and an
    eye's own sort (the sort camera is one of the cull cameras)."""
    scene = random_scene(n=3000, seed=7, degree=0, spread=2.0, log_scale=(-4.0, -2.0))
    camera = camera_at(eye=(0.2, 0.1, -1.5))
    eyes = eye_cameras(camera, StereoRig(ipd=0.5, convergence=1.0))
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu, DepthSorter(scene) as cpu:
        for sort_camera in (camera, eyes[1]):
            for method in METHODS:
                for dilation in (0.0, 0.03):
                    orders = assert_same_orders(gpu, cpu, SortRequest(sort_camera, 1 / 255, dilation, eyes, KEYS,
                                                                      method=method))
        one_eye = assert_same_orders(gpu, cpu, SortRequest(camera, 1 / 255, 0.0, eyes[:1], KEYS))
    assert orders["depth"].size > one_eye["depth"].size  # the other eye sees more


def test_level_spans_restrict_the_rows(gl_ctx, programs):
    """A choice's spans (empty ones, one at each end, many short ones): only their rows
    are culled and sorted, and the distance range comes from their candidates alone."""
    scene = with_duplicates(random_scene(n=6000, seed=8, degree=0, spread=1.5, log_scale=(-3.0, -1.0)), 8)
    camera = camera_at()
    short = [[start, start + 7] for start in range(3000, 4000, 13)]
    spans = [[0, 500], [700, 700], [900, 2600], *short, [4100, 4101], [5000, 6000]]
    choice = spans_choice(spans, leaves=3)
    check_everything(gl_ctx, programs, scene, camera, levels=choice)
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu:
        result = gpu.sort(SortRequest(camera, 1 / 255, None, keys=KEYS, levels=choice))
        assert result.choice is choice and result.order.choice is choice
        rows = result.order.host_indices()
        inside = np.zeros(scene.count, bool)
        for start, stop in spans:
            inside[start:stop] = True
        assert inside[rows].all() and rows.size == inside.sum()  # dilation None: every candidate in them


def test_empty_scenes_and_empty_choices_give_empty_orders(gl_ctx, programs):
    camera = camera_at()
    scene = random_scene(n=0, seed=1, degree=0)
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu:
        np.testing.assert_array_equal(gpu.sort(SortRequest(camera, 1 / 255, keys=KEYS)).order.host_indices(),
                                      DepthSorter(scene).sort(SortRequest(camera, 1 / 255)).order.indices)
    scene = random_scene(n=100, seed=1, degree=0)
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu:
        # (DepthSorter raises on a choice without rows: min() of no pieces.)
        for spans in (np.zeros((0, 2)), [[5, 5]]):
            result = gpu.sort(SortRequest(camera, 1 / 255, keys=KEYS, levels=spans_choice(spans)))
            assert all(order.count == 0 and order.host_indices().size == 0 for order in result.orders.values())


def test_each_sort_makes_new_indices_valid_until_the_second_sort_after(gl_ctx, programs):
    scene = random_scene(n=500, seed=9, degree=0)
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu:
        requests = [SortRequest(camera_at(eye=(0.1 * k, 0.0, -2.5)), 1 / 255, keys=KEYS) for k in range(3)]
        results = [gpu.sort(request) for request in requests[:2]]
        first = results[0].order.host_indices()
        indices = [result.order.indices for result in results]
        assert isinstance(indices[0], DeviceIndices) and indices[0] is not indices[1]
        assert indices[0].buffer is not indices[1].buffer and indices[0].valid
        np.testing.assert_array_equal(indices[0].read(), first)
        gpu.sort(requests[2])  # writes the first one's buffer
        assert not indices[0].valid and indices[1].valid
        with pytest.raises(RuntimeError, match="overwritten"):
            indices[0].read()
    assert not indices[1].valid  # closed


def test_images_drawn_from_gpu_orders_equal_those_from_cpu_orders(gl_ctx, programs):
    """The renderer copies a GPU order GPU to GPU; the image is the CPU order's, to the bit."""
    scene = random_scene(n=400, seed=10, degree=1, spread=1.0)
    camera = camera_at(eye=(0.4, -0.3, -2.2))
    renderer = GLRenderer(gl_ctx, scene)
    try:
        with GpuSorter(gl_ctx, scene, programs=programs) as gpu, DepthSorter(scene) as cpu:
            for settings in (RenderSettings(), RenderSettings(order="distance"), RenderSettings(mode="gs")):
                request = sort_request(camera, settings)
                gpu_order, cpu_order = gpu.sort(request).order, cpu.sort(request).order
                uploads = renderer.counters.uploads
                from_gpu = renderer.render(camera, settings, gpu_order)
                assert renderer.counters.uploads == uploads + 1
                from_cpu = renderer.render(camera, settings, cpu_order)
                assert from_gpu[..., 3].max() > 0.5
                np.testing.assert_array_equal(from_gpu, from_cpu)
    finally:
        renderer.release()


def test_a_gpu_order_is_drawn_through_the_commands_its_sort_wrote(gl_ctx, monkeypatch):
    """The draw of a GPU order takes its count from the indirect commands the sort's last
    pass wrote on the GPU (glsl/sort_commands.comp), in every draw layout and in the
    per-pixel passes: the image is the CPU order's to the bit; commands that halve the
    count (the negative control) draw another."""
    from raygs_viewer.render.gl.plan import DRAW_VERTICES, DrawLayout
    from raygs_viewer.render.sorting import exact_order

    scene = random_scene(n=300, seed=13)
    camera = camera_at(eye=(0.3, -0.2, -2.5))
    settings_cases = (RenderSettings(), RenderSettings(order="per-pixel"))

    def images(gpu_sorter) -> list[np.ndarray]:
        out = []
        for settings in settings_cases:
            order = exact_order(gpu_sorter, camera, settings)
            assert order.on_device and order.indices.commands is not None
            for vertices in DRAW_VERTICES:
                renderer = GLRenderer(gl_ctx, scene, draw_layout=DrawLayout(vertices))
                try:
                    out.append(renderer.render(camera, settings, order))
                finally:
                    renderer.release()
        return out

    reference = GLRenderer(gl_ctx, scene)
    try:
        with DepthSorter(scene) as cpu:
            expected = [reference.render(camera, s, exact_order(cpu, camera, s))
                        for s in settings_cases for _ in DRAW_VERTICES]
    finally:
        reference.release()
    with GpuSorter(gl_ctx, scene) as gpu:
        for image, want in zip(images(gpu), expected):
            np.testing.assert_array_equal(image, want)
    with monkeypatch.context() as patch:
        patched_glsl(patch, "sort_commands.comp", "uint n = summary.visible;", "uint n = summary.visible / 2u;")
        with GpuSorter(gl_ctx, scene) as gpu:
            assert all(not np.array_equal(image, want) for image, want in zip(images(gpu), expected))


# -- negative controls ----------------------------------------------------------------------------
def test_an_approximate_square_root_breaks_the_distance_order(gl_ctx, monkeypatch):
    """The negative control: the distance as s * inversesqrt(s) (how a GPU's sqrt is
    often made, not correctly rounded) reorders near-ties of the shell; the same
    approximation as sqrt_rn's first guess is corrected to the CPU's root."""
    scene = shell_scene([0.1, 0.2, -0.3], count=20000, seed=11)
    camera = camera_at(eye=(0.1, 0.2, -0.3), target=(0.4, 0.1, 1.0), fov=100.0)
    request = SortRequest(camera, 1 / 255, None, keys=("distance",), method="float")
    expected = DepthSorter(scene).sort(request).order.indices

    def gpu_order() -> np.ndarray:
        with GpuSorter(gl_ctx, scene) as gpu:  # its own programs: built from the patched source
            return gpu.sort(request).order.host_indices()

    with monkeypatch.context() as patch:
        patched_glsl(patch, "sort_exact.glsl", "return sqrt_rn(sum);", "return sum * inversesqrt(sum);")
        assert not np.array_equal(gpu_order(), expected)
    with monkeypatch.context() as patch:
        patched_glsl(patch, "sort_exact.glsl", "float r = float(sqrt(exact_double(s)));",
                     "float r = s * inversesqrt(s);")
        np.testing.assert_array_equal(gpu_order(), expected)


def test_treating_minus_zero_apart_breaks_the_tie_order(gl_ctx, monkeypatch):
    """Depths of -0.0 and +0.0 are one key to numpy (a tie: scene order); the float key
    without the sign of zero folded orders +0 first."""
    camera = replace(camera_at(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, 1.0)), t=np.array([0.0, 0.0, -0.0]))
    positions = np.zeros((8, 3), np.float32)
    positions[::2] = -0.0  # (-0, -0, -0): every product and sum -0, depth -0.0; (0, 0, 0): +0.0
    scene = make_scene(positions, 0.05, opacities=0.9)
    request = SortRequest(camera, 1 / 255, 0.0, keys=("depth",), method="float")
    expected = DepthSorter(scene).sort(request).order.indices
    assert expected.tolist() == list(range(8))
    with GpuSorter(gl_ctx, scene) as gpu:
        np.testing.assert_array_equal(gpu.sort(request).order.host_indices(), expected)
    with monkeypatch.context() as patch:
        patched_glsl(patch, "sort_compact.comp", "if ((bits & 0x7FFFFFFFu) == 0u) bits = 0u;", "")
        with GpuSorter(gl_ctx, scene) as gpu:
            assert gpu.sort(request).order.host_indices().tolist() == [1, 3, 5, 7, 0, 2, 4, 6]


# -- the host side --------------------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_key_plans_follow_stable_order(method):
    """Quantised exactly where keys.stable_order quantises; otherwise scene order for
    "radix" and the float order for the others (its fallbacks)."""
    for near, far in ((0.5, 2.0), (2.0, 2.0), (math.inf, -math.inf), (-math.inf, 1.0)):
        plan = key_plan(method, near, far)
        values = np.array([far, near, near] if math.isfinite(far - near) else [1.0, 1.0], np.float32)
        order = stable_order(values, near, far, method)
        if plan.mode == SCENE:
            np.testing.assert_array_equal(order, np.arange(values.size))
        assert plan.mode == (QUANTISED if method != "float" and near < far and math.isfinite(far - near)
                             else SCENE if method == "radix" else FLOAT)
        assert plan.key_bits == (16 if plan.mode == QUANTISED else 32)


def test_problem_names_what_this_gl_lacks(gl_ctx):
    assert GpuSorter.problem(gl_ctx) is None
    assert "4.1" in GpuSorter.problem(SimpleNamespace(version_code=410, info={}))
    assert "storage blocks" in GpuSorter.problem(
        SimpleNamespace(version_code=430, info={"GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": 4}))


def test_deleted_rows_are_left_out_as_on_the_cpu(gl_ctx, programs):
    """Deleted gaussians: the support is uploaded again (the scene is not) and the orders
    equal the CPU's, which hold none of them."""
    from raygs_viewer.sort.deleted import DeletedRows
    scene = random_scene(n=3000, seed=13, degree=0, spread=1.5, log_scale=(-3.0, -1.0))
    camera = camera_at()
    rng = np.random.default_rng(5)
    masks = [rng.random(scene.count) < 0.4, np.arange(scene.count) < 1500]
    with GpuSorter(gl_ctx, scene, programs=programs) as gpu, DepthSorter(scene) as cpu:
        for mask in masks:
            for method in METHODS:
                orders = assert_same_orders(gpu, cpu, SortRequest(camera, 1 / 255, 0.02, keys=KEYS, method=method,
                                                                  deleted=DeletedRows(mask)))
                assert orders["depth"].size > 0 and not mask[orders["depth"]].any()
        assert gpu.support_uploads == 2


class RunningOut:
    """The session's context, out of GPU memory at its ``fail_at``-th buffer; ``made``:
    every buffer it did make."""

    def __init__(self, ctx, fail_at: int):
        self._ctx, self.fail_at, self.made = ctx, fail_at, []

    def buffer(self, *args, **kwargs):
        if len(self.made) + 1 == self.fail_at:
            raise moderngl.Error("GL_OUT_OF_MEMORY")
        self.made.append(self._ctx.buffer(*args, **kwargs))
        return self.made[-1]

    def __getattr__(self, name):
        return getattr(self._ctx, name)


@pytest.mark.parametrize("fail_at", [3, 6, 10])
def test_a_sorter_that_runs_out_of_memory_half_made_releases_what_it_had_made(gl_ctx, fail_at):
    ctx = RunningOut(gl_ctx, fail_at)
    with pytest.raises(moderngl.Error, match="OUT_OF_MEMORY"):
        GpuSorter(ctx, random_scene(n=200, seed=4, degree=0))
    assert len(ctx.made) == fail_at - 1
    assert all(isinstance(buffer.mglo, InvalidObject) for buffer in ctx.made)  # each one released


def test_a_closed_sorter_has_released_every_buffer_it_made_once(gl_ctx):
    ctx = RunningOut(gl_ctx, fail_at=0)
    scene = random_scene(n=200, seed=4, degree=0)
    sorter = GpuSorter(ctx, scene)
    sorter.sort(SortRequest(camera_at(), 1 / 255, keys=("depth", "distance"),
                            cull_cameras=eye_cameras(camera_at(), StereoRig())))
    assert len(ctx.made) > 10  # the sort's own: the cameras, the orders' buffers
    sorter.close()
    sorter.close()
    assert all(isinstance(buffer.mglo, InvalidObject) for buffer in ctx.made)
