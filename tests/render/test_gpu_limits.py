"""GPU limits (issue 6, part 4): scenes cut over several storage blocks render exactly as
one block does, and a scene too large for the GPU fails with one clear line before
anything is drawn, leaving nothing allocated."""

from __future__ import annotations

import numpy as np
import pytest
from testkit import assert_matches, random_scene, sorted_render

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.storage import StorageLayout, gpu_bytes
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings

CAMERA = look_at([0.3, -0.4, -3.0], [0.0, 0.0, 0.0], width=80, height=60)


@pytest.mark.parametrize("settings", [RenderSettings(), RenderSettings(mip=True), RenderSettings(mode="raygs-exact-mip"),
                                      RenderSettings(mode="gs"), RenderSettings(supersample=2, sh_degree=1)],
                         ids=["raygs", "mip", "exact-mip", "gs", "2x2-sh1"])
def test_an_artificially_small_block_limit_changes_no_bit(gl_ctx, settings):
    """8 KiB per storage block: 300 gaussians become several splat blocks (128 records of
    64 bytes, or 64 of exact MIP's 112) and many compute chunks, in every mode."""
    scene = random_scene(n=300, seed=11)
    images = {}
    for limit in (None, 8192):
        renderer = GLRenderer(gl_ctx, scene, block_limit=limit)
        try:
            layout = renderer.plan(settings).layout
            images[limit] = sorted_render(renderer, CAMERA, settings)
        finally:
            renderer.release()
        if limit:
            assert layout.splat_blocks > 1 and layout.chunk < 300
    np.testing.assert_array_equal(images[8192], images[None])
    assert_matches(images[8192], render_reference(scene, CAMERA, settings))


def test_a_scene_needing_more_blocks_than_bindings_is_refused_in_one_line(gl_ctx):
    scene = random_scene(n=600, seed=1)
    with pytest.raises(UserError) as info:
        GLRenderer(gl_ctx, scene, block_limit=4096)  # 600 / 64 = 10 splat blocks > 8
    message = str(info.value)
    assert "\n" not in message and "600 gaussians" in message and "storage blocks" in message


class RecordingContext:
    """The session context, recording the buffers made through it; ``out_of_memory``
    makes the GL error after the uploads read GL_OUT_OF_MEMORY, as a driver reports it."""

    def __init__(self, ctx, out_of_memory=False):
        self._ctx, self.out_of_memory, self.buffers, self._errors = ctx, out_of_memory, [], 0

    def __getattr__(self, name):
        return getattr(self._ctx, name)

    def buffer(self, *args, **kwargs):
        buffer = self._ctx.buffer(*args, **kwargs)
        self.buffers.append(buffer)
        return buffer

    @property
    def error(self):
        self._errors += 1
        real = self._ctx.error
        return "GL_OUT_OF_MEMORY" if self.out_of_memory and self._errors == 2 else real


def test_a_memory_limit_refuses_the_scene_before_any_upload(gl_ctx):
    scene = random_scene(n=1000, seed=2, degree=3)
    needed = gpu_bytes(1000, 3)
    assert needed == 1000 * (48 + 16 * 12 + 16 + 112 + 4)  # gaussians, SH, colours at load, records, order
    ctx = RecordingContext(gl_ctx)
    with pytest.raises(UserError) as info:
        GLRenderer(ctx, scene, memory_limit=needed - 1)
    message = str(info.value)
    assert "\n" not in message and "1,000 gaussians" in message and "0.4 MiB" in message
    assert ctx.buffers == []  # refused before anything was allocated
    GLRenderer(ctx, scene, memory_limit=needed).release()  # exactly enough is enough
    assert len(ctx.buffers) == 4


def test_out_of_gpu_memory_is_one_line_and_releases_what_was_made(gl_ctx):
    scene = random_scene(n=200, seed=3)
    ctx = RecordingContext(gl_ctx, out_of_memory=True)
    with pytest.raises(UserError) as info:
        GLRenderer(ctx, scene)
    message = str(info.value)
    assert "\n" not in message and "does not fit in this GPU's memory" in message and "GL_OUT_OF_MEMORY" in message
    # All four were made, then released (moderngl swaps a released object's handle
    # for an InvalidObject).
    assert len(ctx.buffers) == 4
    assert all(type(buffer.mglo).__name__ == "InvalidObject" for buffer in ctx.buffers)


def test_the_cli_reports_a_scene_too_large_in_one_line(capsys, tmp_path, monkeypatch):
    from raygs_viewer.cli.main import main
    from raygs_viewer.render.gl import renderer as renderer_module

    original = renderer_module.GLRenderer.__init__

    def small_gpu(self, ctx, scene, **kwargs):
        original(self, ctx, scene, memory_limit=1 << 10, **kwargs)

    monkeypatch.setattr(renderer_module.GLRenderer, "__init__", small_gpu)
    out = tmp_path / "x.png"
    assert main(["render", "--width", "32", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "GPU buffers" in err
    assert not out.exists()


def test_storage_layout_never_exceeds_the_limit():
    for count in (1, 63, 64, 65, 1000, 123_457):
        for limit in (4096, 1 << 16, 1 << 27):
            for splat_bytes in (64, 112):
                try:
                    layout = StorageLayout.plan(count, 16 * 12, limit, splat_bytes=splat_bytes)
                except UserError:
                    continue
                assert layout.splats_per_block * splat_bytes <= limit
                assert layout.chunk * max(48, 16 * 12, splat_bytes) <= limit
                assert layout.splat_blocks * layout.splats_per_block >= count


def test_colours_at_load_stay_aligned_under_a_small_block_limit(gl_ctx):
    # SH 3 records (192 bytes) make 32-gaussian chunks at 8 KiB: the colours at load
    # must still start every chunk at an aligned offset, and draw what the SH does.
    from raygs_viewer.render.gl.storage import COLOR_BYTES, RANGE_ALIGNMENT
    scene = random_scene(n=300, seed=4, degree=3)
    camera = look_at([0.0, 0.0, -4.0], [0.0, 0.0, 0.0], width=64, height=48)
    small = GLRenderer(gl_ctx, scene, block_limit=8192)
    assert small.layout.chunk * COLOR_BYTES % RANGE_ALIGNMENT == 0 and small.layout.chunk < scene.count
    whole = GLRenderer(gl_ctx, scene.with_sh_degree(0))
    settings = RenderSettings(sh_degree=0)
    assert np.array_equal(sorted_render(small, camera, settings), sorted_render(whole, camera, settings))
    small.release()
    whole.release()
