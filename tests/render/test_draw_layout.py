"""Draw layouts (render/gl/plan.py, DrawLayout): the instanced strip, the indexed and the
plain triangle draws, and records written in draw order, draw the same image to the bit,
in every mode and pass that draws quads; the draw-order preprocessing writes exactly the
order's records at their places, and only those; from an order a GPU sort keeps on the
GPU too, which it never reads back."""

import numpy as np
import pytest
from testkit import assert_matches, random_scene, rendered, sorted_channels, spans_choice

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.gl.gpu_sort import GpuIndices, GpuSorter
from raygs_viewer.render.gl.plan import DRAW_VERTICES, DrawLayout
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.storage import StorageLayout, place_runs, spread_runs
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import Order

CAMERA = look_at([0.3, -0.2, -3.0], [0, 0, 0], width=80, height=60)
#: The camera inside the cloud: a part of it culled behind, the rest at every depth.
INSIDE = look_at([0.1, 0.05, -0.4], [0.2, 0.0, 1.0], width=64, height=48, fov_y_degrees=90)
LAYOUTS = [DrawLayout(vertices, records) for vertices in DRAW_VERTICES for records in ("scene", "draw")]
TODAY = DrawLayout()
#: 4 KiB storage blocks: 300 gaussians in 19 preprocessing chunks and 5 splat blocks, so the
#: draw-order pass takes ranked places, group by group.
SMALL_BLOCKS = 4096

SETTINGS = {
    "raygs": RenderSettings(),
    "mip": RenderSettings(mip=True),
    "exact mip": RenderSettings(mode="raygs-exact-mip"),
    "gs": RenderSettings(mode="gs"),
    "cut-off": RenderSettings(transmittance_cutoff=True, alpha_clamp=True),
    "2x2": RenderSettings(supersample=2),
    "per-pixel": RenderSettings(order="per-pixel"),
    "per-pixel K=4": RenderSettings(order="per-pixel", order_k=4),
    "sh 0": RenderSettings(sh_degree=0),
}


def _image(gl_ctx, scene, camera, settings, layout, **options):
    renderer = GLRenderer(gl_ctx, scene, draw_layout=layout, **options)
    try:
        return rendered(renderer, camera, settings)[0]
    finally:
        renderer.release()


def distinct_layouts(renderer, settings, outputs="color") -> list[DrawLayout]:
    """The layouts whose plans differ for ``settings`` (a per-pixel path keeps its records
    at scene index, so there the two record placements are one plan)."""
    seen, layouts = set(), []
    for layout in LAYOUTS:
        drawn = renderer.plan(settings, outputs, draw_layout=layout).draw
        if drawn not in seen:
            seen.add(drawn)
            layouts.append(layout)
    return layouts


@pytest.mark.parametrize("name", sorted(SETTINGS))
def test_every_layout_draws_the_same_image_to_the_bit(gl_ctx, name):
    """One renderer, its default layout switched between renders."""
    scene = random_scene(n=300, seed=5)
    settings = SETTINGS[name]
    renderer = GLRenderer(gl_ctx, scene)
    try:
        if renderer.supports(settings):
            pytest.skip("this GL cannot draw these settings")
        for camera in (CAMERA, INSIDE):
            with DepthSorter(scene) as sorter:
                order = exact_order(sorter, camera, settings)
            renderer.draw_layout = TODAY
            today = rendered(renderer, camera, settings, order)[0]
            assert today[..., 3].max() > 0.5
            for layout in distinct_layouts(renderer, settings):
                renderer.draw_layout = layout
                np.testing.assert_array_equal(rendered(renderer, camera, settings, order)[0], today,
                                              err_msg=layout.name)
            if name in ("raygs", "gs"):
                assert_matches(today, render_reference(scene, camera, settings))
    finally:
        renderer.release()


@pytest.mark.parametrize("layout", LAYOUTS, ids=lambda layout: layout.name)
def test_layouts_hold_across_split_storage_blocks(gl_ctx, layout):
    scene = random_scene(n=300, seed=6)
    today = _image(gl_ctx, scene, INSIDE, RenderSettings(), TODAY)
    np.testing.assert_array_equal(_image(gl_ctx, scene, INSIDE, RenderSettings(), layout, block_limit=SMALL_BLOCKS),
                                  today)


@pytest.mark.parametrize("median", [False, True])
def test_layouts_draw_the_same_geometry_outputs(gl_ctx, median):
    scene = random_scene(n=250, seed=7)
    renderer = GLRenderer(gl_ctx, scene)
    try:
        today = sorted_channels(renderer, CAMERA, median=median)
        for layout in distinct_layouts(renderer, RenderSettings(), "median" if median else "geometry"):
            renderer.draw_layout = layout
            channels = sorted_channels(renderer, CAMERA, median=median)
            for field in ("rgb", "alpha", "depth", "normal", "median_depth"):
                if getattr(today, field, None) is not None:
                    np.testing.assert_array_equal(getattr(channels, field), getattr(today, field), err_msg=field)
    finally:
        renderer.release()


def test_records_in_draw_order_are_the_order_s_records_at_their_places(gl_ctx):
    """The draw-order pass over a culled order writes record i of the order's gaussian
    order[i], bit for bit the record the scene-order pass writes at that gaussian's index,
    and nothing past the order's end: culled gaussians cost no work."""
    scene = random_scene(n=300, seed=8)
    settings = RenderSettings()
    with DepthSorter(scene) as sorter:
        order = exact_order(sorter, INSIDE, settings)
    assert 0 < order.count < scene.count  # the camera inside culls some
    for block_limit in (None, SMALL_BLOCKS):
        renderer = GLRenderer(gl_ctx, scene, block_limit=block_limit)
        try:
            renderer.preprocess(INSIDE, renderer.plan(settings))
            by_scene = renderer.read_splats()
            renderer.storage.splats.write(np.full(by_scene.size, np.nan, np.float32))  # a mark on every record
            renderer.draw_layout = DrawLayout("instanced", "draw")
            renderer.preprocess(INSIDE, renderer.plan(settings), order)
            by_place = renderer.read_splats()
            np.testing.assert_array_equal(by_place[:order.count], by_scene[order.indices])
            assert np.isnan(by_place[order.count:]).all()
        finally:
            renderer.release()


def count_gpu_reads(monkeypatch) -> list:
    """The read-backs of GPU sort orders from now on (``Order.host_indices`` of one reads it)."""
    reads = []
    original = GpuIndices.read
    monkeypatch.setattr(GpuIndices, "read", lambda indices: (reads.append(indices), original(indices))[1])
    return reads


@pytest.mark.parametrize("block_limit", [None, SMALL_BLOCKS], ids=["one block", "19 chunks, 5 blocks"])
def test_a_gpu_order_draws_every_layout_to_the_bit_and_is_never_read_back(gl_ctx, monkeypatch, block_limit):
    """An order the GPU sort keeps on the GPU, drawn with records in draw order, over one
    chunk and block or over many: the image of records at scene index, to the bit, and
    the CPU order's; the pass reads nothing back to group the places."""
    scene = random_scene(n=300, seed=12)
    settings = RenderSettings()
    reads = count_gpu_reads(monkeypatch)
    with DepthSorter(scene) as cpu, GpuSorter(gl_ctx, scene) as gpu:
        for camera in (CAMERA, INSIDE):
            order = exact_order(gpu, camera, settings)
            assert order.on_device and 0 < order.count
            today = _image(gl_ctx, scene, camera, settings, TODAY, block_limit=block_limit)
            for layout in LAYOUTS:
                renderer = GLRenderer(gl_ctx, scene, draw_layout=layout, block_limit=block_limit)
                try:
                    np.testing.assert_array_equal(rendered(renderer, camera, settings, order)[0], today,
                                                  err_msg=layout.name)
                    assert renderer.counters.preprocessed == 1
                    if layout.records == "draw":
                        np.testing.assert_array_equal(rendered(renderer, camera, settings,
                                                               exact_order(cpu, camera, settings))[0], today)
                finally:
                    renderer.release()
    assert reads == []


def test_draw_order_records_of_a_gpu_order_are_its_records_at_their_places(gl_ctx, monkeypatch):
    """Over 19 chunks and 5 blocks, each place's record is written by the dispatch of its
    gaussian's chunk alone: record i is the scene-order record of gaussian order[i], and
    nothing past the order's end is written."""
    scene = random_scene(n=300, seed=8)
    settings = RenderSettings()
    with GpuSorter(gl_ctx, scene) as gpu:
        order = exact_order(gpu, INSIDE, settings)
        indices = order.host_indices()
        assert 0 < order.count < scene.count
        renderer = GLRenderer(gl_ctx, scene, block_limit=SMALL_BLOCKS)
        try:
            renderer.preprocess(INSIDE, renderer.plan(settings))
            by_scene = renderer.read_splats()
            renderer.storage.splats.write(np.full(by_scene.size, np.nan, np.float32))
            renderer.draw_layout = DrawLayout("instanced", "draw")
            reads = count_gpu_reads(monkeypatch)
            renderer.preprocess(INSIDE, renderer.plan(settings), order)
            assert reads == []
            by_place = renderer.read_splats()
            np.testing.assert_array_equal(by_place[:order.count], by_scene[indices])
            assert np.isnan(by_place[order.count:]).all()
        finally:
            renderer.release()


def test_draw_order_records_follow_the_order_and_skip_only_the_same_one(gl_ctx):
    """Records in draw order depend on the order: a new order of the same view is
    preprocessed again; the very same order is not."""
    scene = random_scene(n=200, seed=9)
    renderer = GLRenderer(gl_ctx, scene, draw_layout=DrawLayout("indexed", "draw"))
    try:
        plan = renderer.plan(RenderSettings())
        with DepthSorter(scene) as sorter:
            first = exact_order(sorter, CAMERA, RenderSettings())
        renderer.preprocess(CAMERA, plan, first)
        records = renderer.read_splats()[:first.count]
        renderer.preprocess(CAMERA, plan, first)
        assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (1, 1)
        reversed_ = first.with_indices(first.indices[::-1].copy())
        renderer.preprocess(CAMERA, plan, reversed_)
        assert renderer.counters.preprocessed == 2
        np.testing.assert_array_equal(renderer.read_splats()[:first.count], records[::-1])
        with pytest.raises(ValueError, match="for an order"):
            renderer.preprocess(CAMERA, plan)
    finally:
        renderer.release()


def test_draw_order_records_draw_a_level_of_detail_choice(gl_ctx):
    """An order over some rows only (a level-of-detail choice): the draw-order pass takes
    the order's gaussians, whatever rows they are in; the image is today's."""
    scene = random_scene(n=300, seed=10)
    choice = spans_choice(np.array([[0, 90], [150, 260]]))
    settings = RenderSettings()
    images = []
    for layout in (TODAY, DrawLayout("triangles", "draw")):
        renderer = GLRenderer(gl_ctx, scene, draw_layout=layout, block_limit=SMALL_BLOCKS)
        try:
            images.append(rendered(renderer, CAMERA, settings, levels=choice)[0])
        finally:
            renderer.release()
    np.testing.assert_array_equal(images[1], images[0])


def test_place_runs_group_the_places_by_chunk_and_block():
    layout = StorageLayout.plan(300, 16 * 12, SMALL_BLOCKS)  # chunks of 16 rows, blocks of 64 records
    rng = np.random.default_rng(0)
    indices = rng.permutation(300)[:200].astype(np.uint32)
    ranks, runs = place_runs(indices, layout)
    assert sorted(ranks.tolist()) == list(range(200))  # every place once
    covered = 0
    for run in runs:
        places = ranks[run.first:run.first + run.count]
        assert np.all(np.diff(places.astype(np.int64)) > 0)  # ascending: a stable partition
        assert np.all(indices[places] // layout.chunk == run.chunk_start // layout.chunk)
        assert np.all(places // layout.splats_per_block == run.block_start // layout.splats_per_block)
        covered += run.count
    assert covered == 200
    whole = StorageLayout.plan(300, 16 * 12, 1 << 27)
    assert place_runs(indices, whole)[0] is None  # one chunk, one block: the places as they are
    assert place_runs(np.zeros(0, np.uint32), whole) == (None, [])


def test_spread_runs_run_every_block_s_places_once_per_chunk():
    layout = StorageLayout.plan(300, 16 * 12, SMALL_BLOCKS)  # chunks of 16 rows, blocks of 64 records
    runs = spread_runs(200, layout)
    assert len(runs) == 4 * 19  # 200 places in 4 blocks, 300 rows in 19 chunks
    for run in runs:
        assert run.first == run.block_start and run.count == min(64, 200 - run.block_start)
    assert sorted({run.chunk_start for run in runs}) == list(range(0, 300, 16))
    whole = StorageLayout.plan(300, 16 * 12, 1 << 27)
    assert [(run.chunk_start, run.block_start, run.first, run.count) for run in spread_runs(200, whole)] == \
        [(0, 0, 0, 200)]  # one chunk, one block: what place_runs gives
    assert spread_runs(0, whole) == []


def test_an_empty_order_draws_the_background_in_every_layout(gl_ctx):
    scene = random_scene(n=50, seed=11)
    settings = RenderSettings(background=(0.2, 0.3, 0.4))
    for layout in LAYOUTS:
        renderer = GLRenderer(gl_ctx, scene, draw_layout=layout)
        try:
            image = renderer.render(CAMERA, settings, Order(np.zeros(0, np.uint32)))
            np.testing.assert_allclose(image[..., :3], np.broadcast_to([0.2, 0.3, 0.4], image[..., :3].shape),
                                       atol=1e-7)
        finally:
            renderer.release()


def test_an_unknown_layout_is_refused():
    with pytest.raises(ValueError, match="unknown draw vertices"):
        DrawLayout("points")
    with pytest.raises(ValueError, match="unknown records"):
        DrawLayout("instanced", "sorted")
