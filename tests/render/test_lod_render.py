"""A streamed scene drawn through a level-of-detail choice: an order of the choice (sorted
over its spans, and carrying them, so the renderer preprocesses only those rows) against
the float64 reference of those gaussians alone; and the choice made per view."""

from __future__ import annotations

import numpy as np
import pytest
from lod_kit import random_gaussians, write_streamed_sog
from testkit import assert_differs, assert_matches, patched_glsl, sorted_render

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.gl.preprocess_pass import chunk_runs
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.lod_view import open_scene
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.lod_file import load_lod, span_rows
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import choose
from raygs_viewer.sort.request import Order

CAMERA = look_at([0.0, -0.3, -2.0], [1.5, 0.0, 3.0], width=48, height=36)


@pytest.fixture(scope="module")
def streamed(tmp_path_factory):
    """Six leaves in two rows, three levels (the coarser ones larger and fainter), SH
    degree 1, an environment."""
    leaves = []
    for k in range(6):
        centre = (1.2 * (k % 3), 0.8 * (k // 3) - 0.4, 2.0 + 1.5 * (k % 3))
        leaves.append([random_gaussians(40 >> level, centre=centre, spread=0.3, scale=0.04 * 1.6 ** level,
                                        seed=11 * k + level, sh_degree=1) for level in range(3)])
    environment = random_gaussians(12, spread=30.0, scale=1.5, seed=5, sh_degree=1)
    path = write_streamed_sog(tmp_path_factory.mktemp("lod") / "scene", leaves, environment=environment, file_bin=50)
    return path, load_lod(path)


@pytest.mark.parametrize("budget", [None, 120])
def test_the_render_of_a_choice_s_order_is_the_render_of_the_chosen_gaussians_alone(gl_ctx, streamed, budget):
    _, lod = streamed
    settings = RenderSettings(p_min=0.01, background=(0.1, 0.2, 0.3))
    choice = choose(lod, CAMERA, budget=budget, distance=3.5)
    assert len(set(choice.levels.tolist())) > 1  # several levels in one picture
    renderer = GLRenderer(gl_ctx, lod.scene, block_limit=1 << 12)  # several preprocessing chunks
    try:
        image = sorted_render(renderer, CAMERA, settings, levels=choice)
        reference = render_reference(lod.subset(choice.spans), CAMERA, settings)
        assert_matches(image, reference)
        whole = render_reference(lod.scene, CAMERA, settings)
        assert_differs(image, whole)  # every level at once is another picture
    finally:
        renderer.release()


def test_preprocessing_only_the_spans_matters(gl_ctx, streamed, monkeypatch):
    """The negative control: a preprocess that ignores where each span starts writes the
    wrong gaussians' records."""
    _, lod = streamed
    patched_glsl(monkeypatch, "preprocess.comp", "uint i = u_first + gl_GlobalInvocationID.x;",
                 "uint i = gl_GlobalInvocationID.x;")
    settings = RenderSettings(p_min=0.01)
    choice = choose(lod, CAMERA, distance=3.5)
    assert choice.spans.shape[0] > 1  # spans that start past 0
    renderer = GLRenderer(gl_ctx, lod.scene)
    try:
        image = sorted_render(renderer, CAMERA, settings, levels=choice)
        assert_differs(image, render_reference(lod.subset(choice.spans), CAMERA, settings))
    finally:
        renderer.release()


def test_an_order_s_spans_limit_the_preprocess(gl_ctx, streamed):
    """The records of the rows outside the order's spans are not written; the same
    indices as an order over the whole scene write every row, the spans' alike."""
    _, lod = streamed
    settings = RenderSettings(p_min=0.01)
    choice = choose(lod, CAMERA, distance=3.5)
    rows = span_rows(choice.spans)
    outside = np.setdiff1d(np.arange(lod.scene.count), rows)
    assert rows.size and outside.size
    other = look_at([0.5, 0.3, -4.0], [1.0, 0.0, 3.0], width=48, height=36)
    renderer = GLRenderer(gl_ctx, lod.scene, block_limit=1 << 12)
    try:
        with DepthSorter(lod.scene) as sorter:
            renderer.render(other, settings, exact_order(sorter, other, settings))
            before = renderer.read_splats()
            order = exact_order(sorter, CAMERA, settings, levels=choice)
        assert order.choice is choice and np.isin(order.indices, rows).all()
        renderer.render(CAMERA, settings, order)
        limited = renderer.read_splats()
        np.testing.assert_array_equal(limited[outside], before[outside])  # left as the other view wrote them
        assert not np.array_equal(limited[rows], before[rows])
        preprocessed = renderer.counters.preprocessed
        renderer.render(CAMERA, settings, Order(order.indices))  # the same indices, no spans: every row
        assert renderer.counters.preprocessed == preprocessed + 1
        every = renderer.read_splats()
        np.testing.assert_array_equal(every[rows], limited[rows])
        assert not np.array_equal(every[outside], before[outside])
    finally:
        renderer.release()


def test_chunk_runs_are_the_spans_within_a_chunk():
    spans = np.array([[2, 5], [8, 20], [30, 31]])
    assert chunk_runs(0, 16, spans) == [(2, 3), (8, 8)]
    assert chunk_runs(16, 16, spans) == [(0, 4), (14, 1)]
    assert chunk_runs(32, 16, spans) == []
    assert chunk_runs(0, 16, None) == [(0, 16)]


def test_open_scene_reads_a_level_or_every_level_for_the_choice(streamed):
    path, lod = streamed
    level = open_scene(SceneSource(path), RenderSettings(lod=2))
    assert level.lod is None and level.scene.count == 12 + 6 * 10
    chosen = open_scene(SceneSource(path), RenderSettings(lod_budget=70, lod_distance=3.5))
    assert chosen.lod.budget == 70 and chosen.scene.count == lod.scene.count
    assert chosen.framed.shape[0] == lod.scene.count - 12  # framing leaves the environment out


def test_the_opened_scene_s_levels_are_chosen_per_camera(streamed):
    path, lod = streamed
    settings = RenderSettings(lod_distance=3.5)
    opened = open_scene(SceneSource(path), settings)
    far_camera = look_at([0.0, -0.3, -30.0], [1.5, 0.0, 3.0], width=48, height=36)
    with DepthSorter(opened.scene) as sorter:
        near = exact_order(sorter, CAMERA, settings, levels=opened.lod)
        far = exact_order(sorter, far_camera, settings, levels=opened.lod)
        shared = exact_order(sorter, far_camera, settings, levels=near.choice)  # a choice made serves any view
    assert np.array_equal(near.spans, choose(lod, CAMERA, distance=3.5).spans)
    assert np.array_equal(far.spans, choose(lod, far_camera, distance=3.5).spans)
    assert far.choice.count < near.choice.count
    assert shared.choice is near.choice and np.isin(shared.indices, span_rows(near.spans)).all()
    assert near.request.levels is opened.lod and near.answers(near.request)
