"""The selection's tint, drawn by the preprocessing pass from one bit a gaussian: a
selected gaussian's colour is halfway to the tint, every other pixel is untouched, in
every chunk of a scene split into several, and with records in draw order; the same
image as a scene whose selected gaussians carry that colour, and the float64 reference's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from testkit import assert_matches, make_scene

from raygs_viewer.camera.pinhole import frame_points
from raygs_viewer.render.gl.plan import DrawLayout
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.selection import SH_C0
from raygs_viewer.sort.depth import DepthSorter

TINT = np.array([1.0, 0.85, 0.0])


def grid(side=9):
    """Side x side gaussians in a plane, colours inside 0..1 (no clamp before the tint)."""
    rng = np.random.default_rng(3)
    u, v = np.meshgrid(np.linspace(-1, 1, side), np.linspace(-1, 1, side))
    positions = np.stack([u.ravel(), v.ravel(), np.zeros(side * side)], 1)
    colors = rng.uniform(0.2, 0.8, (side * side, 3))
    return make_scene(positions, np.full((side * side, 3), 0.06), opacities=np.full(side * side, 0.9), colors=colors)


def tinted_copy(scene, mask):
    sh = scene.sh.copy()
    colour = 0.5 + SH_C0 * sh[:, 0, :].astype(np.float64)
    sh[mask, 0, :] = ((0.5 * colour[mask] + 0.5 * TINT - 0.5) / SH_C0).astype(np.float32)
    return replace(scene, sh=sh)


@pytest.mark.parametrize("records", ["scene", "draw"])
@pytest.mark.parametrize("block_limit", [None, 4096])  # 4 KiB: the scene in several chunks
def test_the_selected_gaussians_are_tinted_and_nothing_else(gl_ctx, block_limit, records):
    scene = grid()
    mask = np.zeros(scene.count, bool)
    mask[[0, 5, 33, 40, 41, 79, 80]] = True
    camera = frame_points(scene.positions, 72, 72)
    settings = RenderSettings()
    order = exact_order(DepthSorter(scene), camera, settings)
    renderer = GLRenderer(gl_ctx, scene, block_limit=block_limit, draw_layout=DrawLayout(records=records))
    try:
        plain = renderer.render(camera, settings, order).copy()
        renderer.set_selection(mask)
        tinted = renderer.render(camera, settings, order).copy()
        renderer.set_selection(None)
        again = renderer.render(camera, settings, order).copy()
    finally:
        renderer.release()
    expected_scene = tinted_copy(scene, mask)
    expected = GLRenderer(gl_ctx, expected_scene)
    try:
        assert_matches(tinted, expected.render(camera, settings, order))
    finally:
        expected.release()
    assert_matches(tinted, render_reference(expected_scene, camera, settings))
    np.testing.assert_array_equal(again, plain)
    changed = np.abs(tinted - plain).max(axis=-1) > 1e-3
    assert changed.any() and changed.mean() < 0.3
