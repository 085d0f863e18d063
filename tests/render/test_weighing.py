"""What "select what the view shows" selects by, weighed on the GPU (``render.gl.weighing``)
against the float64 reference (``render.contributions.max_weights``): in every mode and
order, by each GPU path that runs it (framebuffer fetch: the global orders; the fragment
lists: all), on a scene built to be hard (an occluded pair, a gaussian hidden behind an
opaque one, a stack the cut-off stops in, a deleted opaque gaussian in front of a visible
one, over random clutter with a fragment on the p_min boundary), the rows selected and
the weights agree; the click picks the reference's top row; slicing changes nothing;
the fallbacks (no framebuffer fetch, too few storage blocks, "cpu") and the empty cases
hold; and a weight without its transmittance, or an order still holding a deleted row,
is caught."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from testkit import COMPOSITING_SETUPS, make_scene, patched_glsl, point_on_pixel_ray, random_scene

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.errors import UserError
from raygs_viewer.render.contributions import cropped, max_weights
from raygs_viewer.render.gl import weighing
from raygs_viewer.render.gl.kbuffer import FRAMEBUFFER_FETCH
from raygs_viewer.render.gl.per_pixel import LIST_BLOCKS
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.weighing import (
    GpuWeighing,
    start_weighing,
    weigh_now,
    weighing_problem,
)
from raygs_viewer.render.reference import global_order
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order, part_orders
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import Order

# Odd size, fx != fy, an off-centre principal point: a slip of a band's viewport shows.
CAMERA = replace(look_at([0.3, -0.2, -3.0], [0.0, 0.05, 0.0], width=46, height=39), fx=50.0, fy=47.0, cx=22.7, cy=19.1)
SETTINGS = COMPOSITING_SETUPS
# Framebuffer fetch weighs the global orders only; the lists weigh every order.
CASES = [(name, path) for name, settings in SETTINGS.items() for path in ("fetch", "lists")
         if path == "lists" or not settings.per_pixel]

# The hard parts, each on one pixel's ray, in front of the clutter (which lies 2.2-3.8 deep).
PAIR_PIXEL, FRONT, BEHIND = (7, 6), 0, 1                 # both show: 0.7, then what it lets through
HIDING_PIXEL, SHIELD, HIDDEN = (38, 6), 2, 3             # a wide 0.99 in front of a small one
STACK_PIXEL, STACK = (24, 31), [4, 5, 6, 7, 8]           # 0.95 each: T 5e-2, 2.5e-3, 1.25e-4, then < 1e-4
DELETED_PIXEL, DELETED, UNVEILED = (7, 30), 9, 10        # a deleted wide 0.98 in front of a 0.8
PARTS = [(PAIR_PIXEL, 1.8, 0.08, 0.7), (PAIR_PIXEL, 2.4, 0.1, 0.9),
         (HIDING_PIXEL, 1.6, 0.25, 0.99), (HIDING_PIXEL, 2.2, 0.02, 0.9),
         *[(STACK_PIXEL, depth, 0.12, 0.95) for depth in (1.5, 1.7, 1.9, 2.1)], (STACK_PIXEL, 2.3, 0.12, 0.6),
         (DELETED_PIXEL, 1.6, 0.25, 0.98), (DELETED_PIXEL, 2.1, 0.08, 0.8)]
CLUTTER = 300
DELETED_MASK = np.zeros(len(PARTS) + CLUTTER, bool)
DELETED_MASK[DELETED] = True
DELETED_ROWS = DeletedRows.of(DELETED_MASK)

# Most of the image, with a hole: the box is nearly the whole image, the mask is not.
INSIDE = np.ones((CAMERA.height, CAMERA.width), bool)
INSIDE[14:22, 18:28] = False
THRESHOLDS = (0.05, 0.3)
# float32 against float64: most weights agree to ~5e-7, but a fragment whose alpha lies on
# the p_min boundary is kept by one and discarded by the other, scaling the weights behind
# it by 1 - 1/255 (measured 3.94e-3 relative in this scene's per-ray orders).
RELATIVE, ABSOLUTE, P99 = 5e-3, 1e-6, 1e-5


def combined(*scenes: Scene) -> Scene:
    fields = ("positions", "rotations", "scales", "opacities", "sh")
    return Scene(*(np.concatenate([getattr(s, f) for s in scenes]) for f in fields), scenes[0].sh_degree)


def hard_scene() -> Scene:
    positions = [point_on_pixel_ray(CAMERA, u, v, depth) for (u, v), depth, _, _ in PARTS]
    parts = make_scene(positions, [[scale] * 3 for _, _, scale, _ in PARTS],
                       opacities=[opacity for *_, opacity in PARTS], degree=2)
    clutter = random_scene(n=CLUTTER, seed=4, degree=2, spread=0.8, log_scale=(-2.6, -1.4))
    return combined(parts, clutter)


@pytest.fixture(scope="module")
def scene():
    return hard_scene()


@pytest.fixture(scope="module")
def renderer(gl_session_ctx, scene):
    gl_session_ctx.__enter__()
    made = GLRenderer(gl_session_ctx, scene)
    yield made
    made.release()


@pytest.fixture(scope="module")
def sorter(scene):
    with DepthSorter(scene) as made:
        yield made


@pytest.fixture(scope="module")
def references(scene):
    """name -> the float64 weights over INSIDE (the order without the deleted row), each once."""
    found = {}

    def weights(name):
        if name not in found:
            found[name] = reference(scene, SETTINGS[name], INSIDE)
        return found[name]
    return weights


def reference(scene, settings, inside, deleted=DELETED_MASK):
    order = global_order(scene, CAMERA, settings)
    return max_weights(scene, CAMERA, settings, order[~deleted[order]], inside)


def sort_for(sorter, settings, deleted=DELETED_ROWS):
    """The view's order culled for a band, as the window sorts it."""
    return lambda band: exact_order(sorter, CAMERA, settings, cull_cameras=[band], deleted=deleted)


def runnable(renderer, settings, path):
    problem = weighing_problem(renderer, settings, path)
    if problem:
        pytest.skip(problem)


def one_pixel(u, v):
    inside = np.zeros((CAMERA.height, CAMERA.width), bool)
    inside[v, u] = True
    return inside


def weigh_pixel(renderer, sorter, settings, pixel, path):
    """The weights at one pixel by ``path``, through lists of a pool for one pixel's
    fragments (allocating the default's 64 MiB costs more than the weighing on llvmpipe)."""
    options = {"pool_fragments": 1 << 12} if path == "lists" else {}
    weighed = GpuWeighing(renderer, CAMERA, settings, sort_for(sorter, settings), one_pixel(*pixel), path=path,
                          **options)
    try:
        while not weighed.step():
            pass
        return weighed.weights
    finally:
        weighed.release()


def assert_weights_match(got, expected):
    """The rows selected at each threshold are the reference's, but for rows within the
    weights' tolerance of it; each weight is the reference's within that tolerance."""
    got = got.astype(np.float64)
    for threshold in THRESHOLDS:
        band = np.abs(expected - threshold) <= RELATIVE * threshold + ABSOLUTE
        picked, wanted = np.flatnonzero((got >= threshold) & ~band), np.flatnonzero((expected >= threshold) & ~band)
        assert np.array_equal(picked, wanted), (f"at {threshold}: selected {np.setdiff1d(picked, wanted)} "
                                                f"beyond the reference's, missed {np.setdiff1d(wanted, picked)}")
    diff = np.abs(got - expected)
    assert np.percentile(diff, 99) < P99, f"99th percentile of |diff| {np.percentile(diff, 99):.3g}"
    worst = int(np.argmax(diff - RELATIVE * expected))
    assert diff[worst] <= RELATIVE * expected[worst] + ABSOLUTE, \
        f"row {worst}: {got[worst]:.7g} against {expected[worst]:.7g}"


# ------------------------------------------------------------------ against the reference


@pytest.mark.parametrize("name, path", CASES)
def test_the_gpu_selects_the_references_rows_in_every_mode(gl_ctx, renderer, sorter, references, name, path):
    settings = SETTINGS[name]
    runnable(renderer, settings, path)
    expected = references(name)
    # The scene is as hard as it means to be: each part weighs as built.
    assert expected[FRONT] >= 0.3 > expected[BEHIND] >= 0.05
    assert expected[SHIELD] > 0.9 and expected[HIDDEN] < 0.05
    assert expected[DELETED] == 0 and expected[UNVEILED] > 0.5
    weighed = start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE, weigh_on=path)
    try:
        while not weighed.step():
            pass
        got = weighed.weights
    finally:
        weighed.release()
    assert weighed.where == {"fetch": "GPU, framebuffer fetch", "lists": "GPU, fragment lists"}[path]
    assert got.dtype == np.float32 and got.shape == (renderer.scene.count,)
    assert got[DELETED] == 0
    assert_weights_match(got, expected)


@pytest.mark.parametrize("name, path", [(n, p) for n, p in CASES if SETTINGS[n].transmittance_cutoff])
def test_the_cut_offs_stopping_fragment_and_those_after_it_weigh_nothing(gl_ctx, renderer, sorter, scene, name, path):
    settings = SETTINGS[name]
    runnable(renderer, settings, path)
    at = one_pixel(*STACK_PIXEL)
    expected = reference(scene, settings, at)
    np.testing.assert_allclose(expected[STACK], [0.95, 0.05 * 0.95, 0.0025 * 0.95, 0, 0], rtol=1e-4, atol=0)
    got = weigh_pixel(renderer, sorter, settings, STACK_PIXEL, path)
    assert np.all(got[STACK[3:]] == 0)
    np.testing.assert_allclose(got[STACK[:3]], expected[STACK[:3]], rtol=1e-5)
    assert_weights_match(got, expected)
    # Without the cut-off the same fragment is drawn, and weighs what T leaves it.
    drawn = replace(settings, transmittance_cutoff=False)
    expected = reference(scene, drawn, at)
    assert expected[STACK[3]] > 1e-4
    got = weigh_pixel(renderer, sorter, drawn, STACK_PIXEL, path)
    assert got[STACK[3]] == pytest.approx(expected[STACK[3]], rel=1e-4)


@pytest.mark.parametrize("name, path", [("global", "fetch"), ("global", "lists"), ("ewa", "fetch"),
                                        ("per pixel", "lists"), ("per pixel k=2", "lists")])
def test_a_click_picks_the_references_top_row(gl_ctx, renderer, sorter, scene, name, path):
    settings = SETTINGS[name]
    runnable(renderer, settings, path)
    pixels = [PAIR_PIXEL, HIDING_PIXEL, STACK_PIXEL, DELETED_PIXEL]
    pixels += [(u, v) for u in (13, 23, 33) for v in (9, 19, 29)]
    picked = {}
    for u, v in pixels:
        expected = reference(scene, settings, one_pixel(u, v))
        top, second = np.sort(expected)[-2:][::-1]
        if top - second < 1e-3:  # a tie the float32 weights may break either way
            continue
        got = weigh_pixel(renderer, sorter, settings, (u, v), path)
        assert int(np.argmax(got)) == int(np.argmax(expected)), f"at {(u, v)}"
        picked[(u, v)] = int(np.argmax(got))
    assert len(picked) >= 10
    assert picked[HIDING_PIXEL] == SHIELD and picked[DELETED_PIXEL] == UNVEILED and picked[STACK_PIXEL] == STACK[0]


# ------------------------------------------------------------------ slices


class SlowClock:
    """``time`` for a weighing in which every slice takes half a second: each slice after
    the first weighs one row, whatever the machine."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self):
        self.now += 0.25
        return self.now


def sliced(renderer, sorter, settings, path, **options):
    """(weights, the progress after each step) of a weighing over INSIDE; ``options``:
    GpuWeighing's."""
    weighed = GpuWeighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE, path=path, **options)
    progress = []
    try:
        while True:
            finished = weighed.step()
            progress.append(weighed.progress)
            if finished:
                return weighed.weights, progress
    finally:
        weighed.release()


@pytest.mark.parametrize("name, path", [("cut-off", "fetch"), ("cut-off", "lists"), ("per pixel k=2", "lists")])
def test_the_split_into_slices_changes_nothing(gl_ctx, renderer, sorter, monkeypatch, name, path):
    settings = SETTINGS[name]
    runnable(renderer, settings, path)
    monkeypatch.setattr(weighing, "FIRST_ROWS", 10_000)
    whole, progress = sliced(renderer, sorter, settings, path, slice_seconds=100.0)
    assert progress == [1.0]
    if path == "lists":  # a small pool: the one band filled and resolved in many parts
        parted, progress = sliced(renderer, sorter, settings, path, slice_seconds=100.0, pool_fragments=256)
        assert progress == [1.0]
        np.testing.assert_array_equal(parted, whole)
    monkeypatch.setattr(weighing, "FIRST_ROWS", 1)
    monkeypatch.setattr(weighing, "time", SlowClock())
    rows = CAMERA.height  # INSIDE's box: every row
    many, progress = sliced(renderer, sorter, settings, path, slice_seconds=1e-3)
    np.testing.assert_array_equal(progress, np.arange(1, rows + 1) / rows)
    if path == "fetch":  # the bands are scissors of one target: the very same fragments
        np.testing.assert_array_equal(many, whole)
    else:
        # Each band is a target of its own, whose viewport's offset moves where the
        # rasterizer puts a pixel's centre by float32 rounding: weights move by < 6e-7.
        np.testing.assert_allclose(many, whole, rtol=0, atol=2e-6)


# ------------------------------------------------------------------ fallbacks and edges


class Limited:
    """The session's context as a driver without ``hidden`` extensions and with ``limits``
    (GL limits by name) in its ``info``: whatever plans or probes with it sees that driver."""

    def __init__(self, ctx, *hidden: str, **limits: int):
        self._ctx = ctx
        self.extensions = set(ctx.extensions) - set(hidden)
        self.info = {**ctx.info, **limits}

    def __getattr__(self, name):
        return getattr(self._ctx, name)


def test_without_framebuffer_fetch_auto_weighs_through_the_lists(gl_ctx, scene, sorter, references):
    settings = SETTINGS["global"]
    renderer = GLRenderer(Limited(gl_ctx, FRAMEBUFFER_FETCH), scene)
    try:
        with pytest.raises(UserError) as raised:
            start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE, weigh_on="fetch")
        assert "\n" not in str(raised.value) and FRAMEBUFFER_FETCH in str(raised.value)
        weighed = start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE)
        assert weighed.where == "GPU, fragment lists"
        weighed.release()
        assert_weights_match(weigh_now(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE),
                             references("global"))
        per_ray = SETTINGS["per pixel"]
        with pytest.raises(UserError, match="^the per-ray order is weighed through the fragment lists$"):
            start_weighing(renderer, CAMERA, per_ray, sort_for(sorter, per_ray), INSIDE, weigh_on="fetch")
    finally:
        renderer.release()


def test_auto_weighs_by_fetch_where_it_can(gl_ctx, renderer, sorter):
    settings = SETTINGS["global"]
    runnable(renderer, settings, "fetch")
    weighed = start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE)
    assert weighed.where == "GPU, framebuffer fetch"
    weighed.release()
    per_ray = SETTINGS["per pixel k=2"]
    weighed = start_weighing(renderer, CAMERA, per_ray, sort_for(sorter, per_ray), INSIDE)
    assert weighed.where == "GPU, fragment lists"
    weighed.release()


def test_a_gpu_that_cannot_weigh_weighs_on_the_cpu(gl_ctx, scene, renderer, sorter, references):
    settings = SETTINGS["per pixel"]
    # One storage block short of the weights' in the compute stage (the resolve's), as many
    # as the lists themselves need: the view renders, the weighing falls to the CPU.
    needed = renderer.plan(settings).layout.splat_blocks + LIST_BLOCKS
    renderer = GLRenderer(Limited(gl_ctx, FRAMEBUFFER_FETCH, GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS=needed), scene)
    try:
        assert renderer.supports(settings) is None
        problem = weighing_problem(renderer, settings, "lists")
        assert problem == (f"weighing needs {needed + 1} storage blocks where this GPU offers {needed} "
                           "(GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS)")
        with pytest.raises(UserError, match=f"^{problem}$".replace("(", r"\(").replace(")", r"\)")):
            start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE, weigh_on="lists")
        weighed = start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE)
        assert weighed.where == f"CPU ({problem})"
        while not weighed.step():
            pass
        np.testing.assert_array_equal(weighed.weights, references("per pixel").astype(np.float32))
    finally:
        renderer.release()


@pytest.mark.parametrize("name", ["cut-off", "per pixel k=2"])
def test_weighing_on_the_cpu_gives_the_references_weights(gl_ctx, renderer, sorter, references, name):
    settings = SETTINGS[name]
    weighed = start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE, weigh_on="cpu")
    assert weighed.where == "CPU (forced)"
    while not weighed.step():
        pass
    assert weighed.progress == 1.0
    np.testing.assert_array_equal(weighed.weights, references(name).astype(np.float32))


@pytest.mark.parametrize("path", ["fetch", "lists", "cpu"])
def test_an_empty_mask_or_an_empty_order_weighs_nothing(gl_ctx, renderer, sorter, path):
    settings = SETTINGS["global"]
    if path != "cpu":
        runnable(renderer, settings, path)
    nowhere = np.zeros_like(INSIDE)
    weighed = start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), nowhere, weigh_on=path)
    assert weighed.step() and weighed.progress == 1.0
    assert weighed.weights.shape == (renderer.scene.count,) and not weighed.weights.any()
    weighed.release()
    nothing = weigh_now(renderer, CAMERA, settings, lambda band: Order(np.zeros(0, np.uint32)), INSIDE, weigh_on=path)
    assert nothing.shape == (renderer.scene.count,) and not nothing.any()


def test_a_bad_request_is_refused(gl_ctx, renderer, sorter):
    settings = SETTINGS["global"]
    with pytest.raises(UserError, match="^weigh on must be one of auto, fetch, lists, cpu, got 'gpu'$"):
        start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE, weigh_on="gpu")
    with pytest.raises(ValueError, match="inside is"):
        start_weighing(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE[1:])


# ------------------------------------------------------------------ negative controls


@pytest.mark.parametrize("path", ["fetch", "lists"])
def test_a_weight_without_its_transmittance_is_caught(gl_ctx, scene, sorter, references, monkeypatch, path):
    settings = SETTINGS["global"]
    patched_glsl(monkeypatch, "fragment_output.glsl", "floatBitsToUint(transmittance * alpha)",
                 "floatBitsToUint(alpha)")
    patched_glsl(monkeypatch, "per_pixel_composite.glsl", "float weight = transmittance * alpha;",
                 "float weight = alpha;")
    renderer = GLRenderer(gl_ctx, scene)  # programs of its own, built from the patched shaders
    try:
        runnable(renderer, settings, path)
        got = weigh_now(renderer, CAMERA, settings, sort_for(sorter, settings), INSIDE, weigh_on=path)
    finally:
        renderer.release()
    assert got[HIDDEN] >= 0.3  # the hidden gaussian is selected
    with pytest.raises(AssertionError, match="selected"):
        assert_weights_match(got, references("global"))


@pytest.mark.parametrize("name, path", [("cut-off", "fetch"), ("per pixel", "lists")])
def test_an_order_still_holding_the_deleted_row_is_caught(gl_ctx, renderer, sorter, references, name, path):
    settings = SETTINGS[name]
    runnable(renderer, settings, path)
    got = weigh_now(renderer, CAMERA, settings, sort_for(sorter, settings, deleted=None), INSIDE, weigh_on=path)
    assert got[DELETED] > 0.9 and got[UNVEILED] < 0.05
    with pytest.raises(AssertionError, match="selected"):
        assert_weights_match(got, references(name))


def test_a_parts_order_is_the_views_own_sequence_of_what_reaches_the_part(gl_ctx):
    """``part_orders``: a band's order keeps the view's sequence (a sort of the band alone
    would quantise its radix keys over another depth range) and holds every gaussian
    the band's own cull keeps."""
    scene = random_scene(n=4000, seed=9, degree=0, spread=1.0, log_scale=(-3.5, -2.0))
    settings = RenderSettings()
    sorter = DepthSorter(scene)
    view = exact_order(sorter, CAMERA, settings)
    band = cropped(CAMERA, slice(10, 14), slice(0, CAMERA.width))
    part = part_orders(sorter, CAMERA, settings, view)(band)
    culled = exact_order(sorter, CAMERA, settings, cull_cameras=[band]).indices
    assert set(part.indices.tolist()) == set(culled.tolist()) and 0 < part.count < view.count
    place = np.empty(scene.count, np.int64)
    place[view.indices] = np.arange(view.count)
    assert np.all(np.diff(place[part.indices]) > 0)  # the view's own sequence
