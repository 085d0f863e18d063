"""A streamed scene drawn through a level-of-detail choice: the GL renderer restricted to
the choice's spans (sorting and preprocessing only those rows) against the float64
reference of those gaussians alone; and the choice applied per frame."""

from __future__ import annotations

import numpy as np
import pytest
from lod_kit import random_gaussians, write_streamed_sog
from testkit import assert_differs, assert_matches, patched_glsl

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.gl.renderer import GLRenderer, chunk_runs
from raygs_viewer.render.lod_view import open_scene, restrict_to_view
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.lod_file import load_lod
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.lod_choice import choose

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
def test_the_restricted_render_is_the_render_of_the_chosen_gaussians_alone(gl_ctx, streamed, budget):
    _, lod = streamed
    settings = RenderSettings(p_min=0.01, background=(0.1, 0.2, 0.3))
    choice = choose(lod, CAMERA, budget=budget, distance=3.5)
    assert len(set(choice.levels.tolist())) > 1  # several levels in one picture
    renderer = GLRenderer(gl_ctx, lod.scene, block_limit=1 << 12)  # several preprocessing chunks
    try:
        renderer.restrict(choice.spans)
        image = renderer.render(CAMERA, settings)
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
        renderer.restrict(choice.spans)
        assert_differs(renderer.render(CAMERA, settings), render_reference(lod.subset(choice.spans), CAMERA, settings))
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


def test_restrict_to_view_chooses_per_camera(gl_ctx, streamed):
    path, lod = streamed
    opened = open_scene(SceneSource(path), RenderSettings(lod_distance=3.5))
    renderer = GLRenderer(gl_ctx, opened.scene)
    try:
        near = restrict_to_view(renderer, opened.lod, CAMERA)
        assert np.array_equal(renderer.spans, near.spans)
        far_camera = look_at([0.0, -0.3, -30.0], [1.5, 0.0, 3.0], width=48, height=36)
        far = restrict_to_view(renderer, opened.lod, far_camera)
        assert far.count < near.count and np.array_equal(renderer.spans, far.spans)
    finally:
        renderer.release()
