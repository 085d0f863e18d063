"""Each GL extension the package relies on has a fallback, forced here on llvmpipe by
hiding the extension from the renderer (issue 39, part 3). The extensions:

- GL_EXT_shader_framebuffer_fetch (render/gl/kbuffer.py, glsl/fragment_output.glsl,
  glsl/kbuffer.glsl): the per-pixel order's k-buffer falls back to the fragment lists,
  the same image bit for bit (here; a forced k-buffer is refused in one line); the
  transmittance cut-off of a global order is refused in one line naming the extension
  (here), while the per-pixel order and the geometry outputs still give it, through the
  lists (here, against the fetch path's image).
- GL_NVX_gpu_memory_info, GL_ATI_meminfo (render/gl/memory.py): without them a software
  rasterizer stands for half the system memory, and any other GPU's memory is unknown
  (here).

Every other feature is core OpenGL 4.3 (the doctor's table lists what it reports but
does not use); the shader variants of both kinds of GPU are compiled by
tests/render/test_glslang.py.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from testkit import assert_matches, random_scene, rendered, sorted_channels, sorted_render

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl import memory
from raygs_viewer.render.gl.kbuffer import FRAMEBUFFER_FETCH
from raygs_viewer.render.gl.planner import GpuDescription
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings

CAMERA = look_at([0.3, -0.2, -3.0], [0, 0, 0], width=64, height=48, fov_y_degrees=40)
CUTOFF = RenderSettings(transmittance_cutoff=True, background=(0.1, 0.2, 0.3))
WINDOW = RenderSettings(order="per-pixel", order_k=4, background=(0.1, 0.2, 0.3))


class Hiding:
    """The session's context with ``hidden`` extensions missing from ``extensions``:
    whatever plans or probes with it sees a driver without them."""

    def __init__(self, ctx, *hidden: str):
        self._ctx = ctx
        self.extensions = set(ctx.extensions) - set(hidden)

    def __getattr__(self, name):
        return getattr(self._ctx, name)


@pytest.fixture
def pair(gl_ctx):
    """(renderer on llvmpipe, renderer on the same context without framebuffer fetch) of
    one dense scene, where the cut-off fires."""
    if FRAMEBUFFER_FETCH not in gl_ctx.extensions:
        pytest.skip(f"this driver has no {FRAMEBUFFER_FETCH} to hide")
    scene = random_scene(n=400, seed=5, spread=0.4, log_scale=(-2.5, -1.5))
    renderers = GLRenderer(gl_ctx, scene), GLRenderer(Hiding(gl_ctx, FRAMEBUFFER_FETCH), scene)
    yield renderers
    for renderer in renderers:
        renderer.release()


def test_the_k_buffer_falls_back_to_the_lists_bit_for_bit(pair):
    fetched, (image, result) = rendered(pair[0], CAMERA, WINDOW), rendered(pair[1], CAMERA, WINDOW)
    assert fetched[1].order_stats.path == "fetch" and result.order_stats.path == "lists"
    np.testing.assert_array_equal(image, fetched[0])


def test_a_forced_k_buffer_without_fetch_is_refused_in_one_line(gl_ctx, pair):
    renderer = GLRenderer(Hiding(gl_ctx, FRAMEBUFFER_FETCH), pair[0].scene, order_path="fetch")
    try:
        problem = renderer.supports(WINDOW)
        assert problem and FRAMEBUFFER_FETCH in problem and "\n" not in problem
        with pytest.raises(UserError, match=FRAMEBUFFER_FETCH):
            sorted_render(renderer, CAMERA, WINDOW)
    finally:
        renderer.release()


@pytest.mark.parametrize("settings", [CUTOFF, replace(CUTOFF, supersample=2),
                                      replace(CUTOFF, alpha_clamp=True, precision="8bit")],
                         ids=["cutoff", "cutoff-2x2", "cutoff-clamp-8bit"])
def test_the_cutoff_of_a_global_order_without_fetch_composites_through_the_lists(pair, settings):
    with_fetch, without = pair
    assert without.supports(settings) is None
    assert with_fetch.plan(settings).path is None and without.plan(settings).path == "lists"
    image = sorted_render(without, CAMERA, settings)
    np.testing.assert_array_equal(image, sorted_render(with_fetch, CAMERA, settings))
    assert_matches(image, render_reference(without.scene, CAMERA, settings), max_error=0.05 if
                   settings.precision == "8bit" else 8e-3)


def test_the_cutoff_still_renders_through_the_lists_without_fetch(pair):
    """The per-pixel order composites in its own passes, and the geometry outputs of a
    global order take the fragment lists: neither needs the fragment stage to read the target."""
    with_fetch, without = pair
    per_pixel = replace(CUTOFF, order="per-pixel")
    image = sorted_render(without, CAMERA, per_pixel)
    np.testing.assert_array_equal(image, sorted_render(with_fetch, CAMERA, per_pixel))
    assert_matches(image, render_reference(without.scene, CAMERA, per_pixel))
    channels, reference = sorted_channels(without, CAMERA, CUTOFF), sorted_render(with_fetch, CAMERA, CUTOFF)
    np.testing.assert_allclose(channels.rgb, reference[..., :3], atol=2e-6)
    # The cut-off fired: without it the same scene composites differently.
    assert not np.allclose(reference, sorted_render(with_fetch, CAMERA, RenderSettings(background=CUTOFF.background)),
                           atol=1e-4)


def test_without_a_memory_extension_software_takes_half_the_system_memory(gl_ctx, monkeypatch):
    monkeypatch.delenv(memory.MEMORY_VARIABLE, raising=False)
    hidden = Hiding(gl_ctx, "GL_NVX_gpu_memory_info", "GL_ATI_meminfo")
    if "llvmpipe" not in str(gl_ctx.info.get("GL_RENDERER", "")).lower():
        pytest.skip("the session's driver is no software rasterizer")
    found, how = memory.available_memory(hidden)
    assert how == "half the system memory" and found and found > 0


def test_without_a_memory_extension_a_hardware_gpu_is_unknown(monkeypatch):
    monkeypatch.delenv(memory.MEMORY_VARIABLE, raising=False)
    nvidia = GpuDescription(frozenset(), {"GL_RENDERER": "NVIDIA GeForce RTX 4090/PCIe/SSE2"})
    assert memory.available_memory(nvidia) == (None, "unknown")
    fits, found = memory.scene_fits(nvidia)
    assert found is None and fits(10 ** 9, 3)  # unknown memory refuses nothing
