"""The GL context and the headset session ``bench xr`` and ``doctor``'s XR section
measure with: a context the runtime can bind (:func:`headset_context`: headless EGL where
the runtime offers ``XR_MNDX_egl_enable``, else a hidden GLFW window's GLX context under
X11), a session started and ended around the measurement with its wait clocked
(:class:`WaitClock`), and the facts doctor lists (:class:`SessionFacts`).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass

import moderngl

from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.context import (
    REQUIRE,
    create_headless_context,
)
from raygs_viewer.xr.runtime import EGL_EXTENSION, load_openxr
from raygs_viewer.xr.session import HeadsetSession

#: How long the runtime may take to make a session ready, and to end it.
START_SECONDS, STOP_SECONDS = 10.0, 5.0
class WaitClock:
    """pyopenxr's module as a session sees it (``HeadsetSession.xr``), with ``xrWaitFrame``
    timed: every other name passes through; :attr:`waited` is the seconds of the last
    ``wait_frame``. What the session does is unchanged; only its wait is clocked."""

    def __init__(self, module):
        self.module = module
        self.waited = math.nan

    def __getattr__(self, name: str):
        return getattr(self.module, name)

    def wait_frame(self, *args, **kwargs):
        began = time.perf_counter()
        try:
            return self.module.wait_frame(*args, **kwargs)
        finally:
            self.waited = time.perf_counter() - began


def runtime_offers(extension: str) -> bool | None:
    """Whether the active runtime offers ``extension`` (None: it could not be asked; the
    session's start then says why)."""
    xr = load_openxr()
    try:
        return extension in {p.extension_name.decode() for p in xr.enumerate_instance_extension_properties()}
    except xr.ResultException:
        return None


@contextlib.contextmanager
def headset_context(ctx: moderngl.Context | None = None, *, binding: str = "auto") -> Iterator[moderngl.Context]:
    """A GL context current on this thread that the runtime can bind: ``ctx`` as given
    (current already), else ``binding`` "egl" (a headless EGL context) or "glx" (a hidden
    GLFW window's), "auto": EGL unless the runtime lacks ``XR_MNDX_egl_enable`` and an X
    display is there. Released on leaving (``ctx`` given: left alone)."""
    if ctx is not None:
        yield ctx
        return
    if binding == "auto":
        binding = "glx" if os.environ.get("DISPLAY") and runtime_offers(EGL_EXTENSION) is False else "egl"
    if binding == "glx":
        with _hidden_window_context() as made:
            yield made
        return
    made = create_headless_context("egl")
    try:
        with made:
            yield made
    finally:
        made.release()


@contextlib.contextmanager
def _hidden_window_context() -> Iterator[moderngl.Context]:
    """The GLX context of a hidden 16x16 GLFW window (X11), current while inside."""
    import glfw  # a window only for a runtime that binds GLX alone (SteamVR on Linux)

    glfw.init_hint(glfw.PLATFORM, glfw.PLATFORM_X11)
    if not glfw.init():
        raise UserError("the OpenXR runtime binds only GLX contexts (it has no XR_MNDX_egl_enable) and GLFW "
                        "cannot open a window on this X display")
    try:
        glfw.default_window_hints()
        for hint, value in ((glfw.VISIBLE, False), (glfw.CONTEXT_CREATION_API, glfw.NATIVE_CONTEXT_API),
                            (glfw.CONTEXT_VERSION_MAJOR, REQUIRE // 100),
                            (glfw.CONTEXT_VERSION_MINOR, REQUIRE % 100 // 10),
                            (glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE), (glfw.OPENGL_FORWARD_COMPAT, True)):
            glfw.window_hint(hint, value)
        window = glfw.create_window(16, 16, "raygs-viewer", None, None)
        if not window:
            raise UserError(f"cannot open a hidden OpenGL {REQUIRE // 100}.{REQUIRE % 100 // 10} window for the "
                            f"headset's GLX context")
        try:
            glfw.make_context_current(window)
            made = moderngl.create_context(require=REQUIRE)
            try:
                yield made
            finally:
                made.release()
        finally:
            glfw.destroy_window(window)
    finally:
        glfw.terminate()


def start_session(ctx: moderngl.Context, *, scale: float, depth: bool) -> tuple[HeadsetSession, WaitClock]:
    """A session on ``ctx`` (current), driven until it runs, with its wait clocked; a
    UserError (one line) where it does not start."""
    session = HeadsetSession(ctx, scale=scale, depth=depth)
    clock = WaitClock(session.xr)
    session.xr = clock
    deadline = time.monotonic() + START_SECONDS
    while not session.running:
        news = session.poll()
        if session.over:
            raise UserError(next((item.text for item in news if item.error), "the headset session ended before "
                                                                             "it began"))
        if time.monotonic() > deadline:
            state = session.state
            session.destroy()
            raise UserError(f"the OpenXR runtime did not make the session ready within {START_SECONDS:g} s "
                            f"(state {state})")
        time.sleep(0.002)
    return session, clock


def end_session(session: HeadsetSession) -> None:
    """Asks the runtime to end the session and follows it there (frames ended empty until
    it stops), then frees everything, whatever state it reached."""
    session.request_exit()
    deadline = time.monotonic() + STOP_SECONDS
    while not session.over and time.monotonic() < deadline:
        session.poll()
        frame = session.wait() if session.running else None
        if frame is not None:
            session.submit(frame, drawn=False)
        elif not session.over:
            time.sleep(0.002)
    session.destroy()


@dataclass(frozen=True)
class SessionFacts:
    """What the runtime gave the session: for the report's head and doctor."""

    runtime: str
    version: str
    system: str
    recommended: tuple[tuple[int, int], ...]   # per view, (width, height)
    maximum: tuple[tuple[int, int], ...]
    sizes: tuple[tuple[int, int], ...]         # the eyes' swapchains
    formats: tuple[int, ...]                   # offered, the runtime's order
    colour_format: int
    depth_format: int | None
    extensions: tuple[str, ...]                # enabled on the instance
    binding: str                               # "egl", "glx", "win32"


def session_facts(session: HeadsetSession) -> SessionFacts:
    info = session.info
    return SessionFacts(info.runtime, info.version, info.system, tuple(view.recommended for view in info.views),
                        tuple(view.maximum for view in info.views), tuple(session.sizes), tuple(session.formats),
                        session.format, session.depth_format, info.extensions, session.binding)
