"""Headless OpenGL contexts: EGL, OSMesa, the auto fallback and its errors.

OSMesa contexts are made in a worker thread: OSMesa and EGL share Mesa's
per-thread dispatch, so a thread of its own keeps the EGL context of the main
thread (used by every other test) untouched.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from raygs_viewer.errors import UserError
from raygs_viewer.render.gl import context as context_mod
from raygs_viewer.render.gl.context import (
    ENV_VAR,
    context_backend,
    context_description,
    create_headless_context,
)
from raygs_viewer.render.gl.osmesa import find_osmesa_library

needs_osmesa = pytest.mark.skipif(
    find_osmesa_library() is None,
    reason="libOSMesa.so.8 not found: apt-get install libosmesa6 to test the OSMesa fallback",
)

COMPUTE = """
#version 430
layout(local_size_x = 64) in;
layout(std430, binding = 0) buffer Data { uint values[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    values[i] = i * i + 7u;
}
"""

VERTEX = """
#version 430
in vec2 in_pos;
in vec3 in_color;
out vec3 color;
void main() {
    color = in_color;
    gl_Position = vec4(in_pos, 0.0, 1.0);
}
"""

FRAGMENT = """
#version 430
in vec3 color;
out vec4 frag;
void main() {
    frag = vec4(color, 0.75);
}
"""

N = 256


def run_compute(ctx) -> np.ndarray:
    buf = ctx.buffer(reserve=N * 4)
    shader = ctx.compute_shader(COMPUTE)
    try:
        buf.bind_to_storage_buffer(0)
        shader.run(group_x=N // 64)
        return np.frombuffer(buf.read(), dtype=np.uint32).copy()
    finally:
        shader.release()
        buf.release()


def render_image(ctx, size=(64, 48)) -> np.ndarray:
    """Clear plus one colour-interpolated triangle, as RGBA8."""
    fbo = ctx.simple_framebuffer(size, components=4)
    prog = ctx.program(vertex_shader=VERTEX, fragment_shader=FRAGMENT)
    vertices = np.array(
        [-0.9, -0.8, 1, 0, 0,
         0.85, -0.6, 0, 1, 0,
         -0.1, 0.9, 0, 0, 1],
        dtype="f4",
    )
    vbo = ctx.buffer(vertices.tobytes())
    vao = ctx.vertex_array(prog, [(vbo, "2f 3f", "in_pos", "in_color")])
    try:
        fbo.use()
        fbo.clear(0.1, 0.2, 0.3, 1.0)
        vao.render()
        data = fbo.read(components=4)
        return np.frombuffer(data, dtype=np.uint8).reshape(size[1], size[0], 4).copy()
    finally:
        vao.release()
        vbo.release()
        prog.release()
        fbo.release()


def in_thread(fn):
    """Run fn() in a fresh thread; return its result or raise its exception."""
    out = {}

    def target():
        try:
            out["value"] = fn()
        except BaseException as exc:  # handed to the calling thread
            out["error"] = exc

    thread = threading.Thread(target=target)
    thread.start()
    thread.join()
    if "error" in out:
        raise out["error"]
    return out["value"]


@pytest.fixture(scope="module")
def egl_ctx():
    ctx = create_headless_context("egl")
    yield ctx
    ctx.release()


def test_egl_context_has_gl43_and_compute(egl_ctx):
    assert egl_ctx.version_code >= 430
    assert context_backend(egl_ctx) == "egl"
    description = context_description(egl_ctx)
    assert "egl" in description and egl_ctx.info["GL_RENDERER"] in description
    values = run_compute(egl_ctx)
    i = np.arange(N, dtype=np.uint32)
    np.testing.assert_array_equal(values, i * i + 7)


def test_auto_mode_from_env(monkeypatch):
    monkeypatch.delenv(ENV_VAR, raising=False)
    ctx = create_headless_context()
    try:
        assert ctx.version_code >= 430
        assert context_backend(ctx) == "egl"  # EGL works on this platform, so auto picks it
    finally:
        ctx.release()


@pytest.mark.parametrize("value", ["vulkan", "EGL2"])
def test_bad_env_value_is_user_error(monkeypatch, value):
    monkeypatch.setenv(ENV_VAR, value)
    with pytest.raises(UserError) as info:
        create_headless_context()
    message = str(info.value)
    assert ENV_VAR in message and value in message and "\n" not in message


def test_bad_backend_argument_is_user_error():
    with pytest.raises(UserError):
        create_headless_context("metal")


def test_nothing_works_names_what_was_tried_and_what_to_install(monkeypatch):
    def broken(name):
        def create():
            raise RuntimeError(f"{name} is broken\non two lines")
        return create

    creators = {"egl": broken("egl"), "osmesa": broken("osmesa")}
    monkeypatch.setenv(ENV_VAR, "auto")
    with pytest.raises(UserError) as info:
        create_headless_context(creators=creators)
    message = str(info.value)
    assert "\n" not in message
    assert "egl: egl is broken on two lines" in message
    assert "osmesa: osmesa is broken" in message
    assert "libegl1" in message and "libosmesa6" in message

    with pytest.raises(UserError) as info:
        create_headless_context("egl", creators=creators)
    assert "libegl1" in str(info.value) and "libosmesa6" not in str(info.value)


@needs_osmesa
def test_auto_falls_back_to_osmesa_when_egl_fails(monkeypatch):
    def no_egl():
        raise RuntimeError("eglInitialize failed")

    monkeypatch.setenv(ENV_VAR, "auto")

    def work():
        ctx = create_headless_context(creators={**context_mod.CREATORS, "egl": no_egl})
        try:
            return context_backend(ctx), ctx.version_code, context_description(ctx)
        finally:
            ctx.release()

    backend, version, description = in_thread(work)
    assert backend == "osmesa"
    assert version >= 430
    assert description.endswith("via osmesa")


@needs_osmesa
def test_osmesa_renders_bit_identical_to_egl(egl_ctx):
    egl_image = render_image(egl_ctx)
    egl_values = run_compute(egl_ctx)

    def work():
        ctx = create_headless_context("osmesa")
        try:
            assert ctx.version_code >= 430
            return render_image(ctx), run_compute(ctx)
        finally:
            ctx.release()

    osmesa_image, osmesa_values = in_thread(work)
    # The image is not trivial: background, and all three vertex colours.
    assert len(np.unique(egl_image.reshape(-1, 4), axis=0)) > 100
    np.testing.assert_array_equal(osmesa_image, egl_image)
    np.testing.assert_array_equal(osmesa_values, egl_values)

    # The EGL context of this thread still works after the OSMesa one is gone.
    np.testing.assert_array_equal(render_image(egl_ctx), egl_image)
