"""The desktop mirror's view of a swapchain image (``xr.swapchain.plain_view``) on a GL of
this process's own, no runtime: an immutable sRGB texture (as runtimes make swapchain
images) gets an RGBA8 view that samples its stored bytes; a mutable one, which cannot
have views, is sampled itself."""

from __future__ import annotations

import ctypes

import moderngl
import numpy as np
import pytest

from raygs_viewer.render.gl.context import create_headless_context
from raygs_viewer.xr.binding import gl_function
from raygs_viewer.xr.swapchain import GL_SRGB8_ALPHA8, plain_view

STORED = 128  # the byte a screenshot holds; sRGB-decoded it would read 0.216, not 0.502


@pytest.fixture(scope="module")
def ctx():
    context = create_headless_context("egl")
    yield context
    context.release()


def fetched(ctx: moderngl.Context, texture: moderngl.Texture) -> float:
    """What texelFetch (the mirror's pass) reads of ``texture``'s first texel, red."""
    program = ctx.program(
        vertex_shader="#version 430\nvoid main() { vec2 c = vec2(float((gl_VertexID << 1) & 2), "
                      "float(gl_VertexID & 2)); gl_Position = vec4(c * 2.0 - 1.0, 0.0, 1.0); }",
        fragment_shader="#version 430\nuniform sampler2D u; out vec4 o; void main() { o = texelFetch(u, ivec2(0), 0); }")
    target = ctx.texture((1, 1), 4, dtype="f4")
    fbo = ctx.framebuffer([target])
    fbo.use()
    texture.use(0)
    program["u"].value = 0
    ctx.vertex_array(program, []).render(moderngl.TRIANGLES, vertices=3)
    return float(np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)[0])


def immutable_srgb(ctx: moderngl.Context) -> int:
    """A 2 x 2 GL_SRGB8_ALPHA8 texture made with glTexStorage2D, filled with STORED."""
    generate = gl_function("glGenTextures", None, [ctypes.c_int, ctypes.POINTER(ctypes.c_uint)])
    bind = gl_function("glBindTexture", None, [ctypes.c_uint, ctypes.c_uint])
    storage = gl_function("glTexStorage2D", None, [ctypes.c_uint, ctypes.c_int, ctypes.c_uint, ctypes.c_int,
                                                   ctypes.c_int])
    name = ctypes.c_uint()
    generate(1, ctypes.byref(name))
    bind(0x0DE1, name.value)
    storage(0x0DE1, 1, GL_SRGB8_ALPHA8, 2, 2)
    bind(0x0DE1, 0)
    texture = ctx.external_texture(name.value, (2, 2), 4, 0, "f1")
    texture.write(np.full((2, 2, 4), STORED, np.uint8).tobytes())
    return name.value


def test_an_immutable_srgb_image_is_mirrored_through_a_view_of_its_stored_bytes(ctx):
    image = immutable_srgb(ctx)
    assert fetched(ctx, ctx.external_texture(image, (2, 2), 4, 0, "f1")) == pytest.approx(0.2158, abs=1e-3)
    view = plain_view(ctx, image)
    assert view != image
    assert fetched(ctx, ctx.external_texture(view, (2, 2), 4, 0, "f1")) == pytest.approx(STORED / 255, abs=1e-6)


def test_a_mutable_image_has_no_view_and_is_sampled_itself(ctx):
    mutable = ctx.texture((2, 2), 4, np.full((2, 2, 4), STORED, np.uint8).tobytes(), internal_format=GL_SRGB8_ALPHA8)
    assert plain_view(ctx, mutable.glo) == mutable.glo
    assert ctx.error == "GL_NO_ERROR"  # the failed view left no error behind for moderngl to meet
