"""The GLFW window, its OpenGL 4.3+ core context as a moderngl context, and imgui on top.

imgui_bundle is imported before glfw on purpose: it points pyGLFW at its own
libglfw 3.5, which has the null platform (a window with no display server: tests,
scripted captures) that pyGLFW's bundled 3.4 cannot open.
"""

from __future__ import annotations

import ctypes
import os
import sys

from imgui_bundle import imgui  # before glfw, see above

# isort: split
import glfw
import moderngl

from raygs_viewer.errors import UserError

PLATFORMS = ("auto", "x11", "wayland", "null")
# Newest first: llvmpipe and every current driver give 4.5; 4.3 is the floor
# (compute shaders and shader-storage buffers).
CONTEXT_VERSIONS = ((4, 5), (4, 3))


def choose_platform(requested: str = "auto") -> str:
    """"null" when nothing could show a window (no DISPLAY and no WAYLAND_DISPLAY on
    Linux), else the requested one; "auto" lets GLFW pick among the real ones."""
    if requested not in PLATFORMS:
        raise UserError(f"unknown window platform '{requested}' (use {', '.join(PLATFORMS)})")
    if requested == "auto" and sys.platform.startswith("linux") and not (
            os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "null"
    return requested


class _GlfwLoader:
    """glcontext's loader interface over GLFW, so moderngl uses the window's context
    whatever API GLFW created it with (GLX, EGL, WGL, NSGL)."""

    def __init__(self, window):
        self.window = window

    def load_opengl_function(self, name: str) -> int:
        return glfw.get_proc_address(name) or 0

    def __enter__(self):
        glfw.make_context_current(self.window)
        return self

    def __exit__(self, *args) -> None:
        pass

    def release(self) -> None:
        pass


class Window:
    """One window with a moderngl context and an imgui context, both current.

    ``size`` is in screen coordinates; the framebuffer may be larger (HiDPI).
    """

    def __init__(self, title: str, width: int, height: int, platform: str = "auto", vsync: bool = True):
        self.platform = choose_platform(platform)
        glfw.set_error_callback(_record_glfw_error)
        # Init hints outlive glfw.terminate(): set it every time.
        glfw.init_hint(glfw.PLATFORM, {"auto": glfw.ANY_PLATFORM, "x11": glfw.PLATFORM_X11,
                                       "wayland": glfw.PLATFORM_WAYLAND, "null": glfw.PLATFORM_NULL}[self.platform])
        if not glfw.init():
            raise UserError(f"cannot start GLFW on the '{self.platform}' platform: {_glfw_error()}")
        try:
            self.handle = self._create(title, width, height)
        except BaseException:
            glfw.terminate()
            raise
        glfw.make_context_current(self.handle)
        self._dropped: list[str] = []
        glfw.set_drop_callback(self.handle, lambda _window, paths: setattr(self, "_dropped", list(paths)))
        self.vsync = vsync
        # moderngl's own detection knows only GLX on Linux: the loader gives it the
        # window's context whatever API GLFW created it with.
        self.ctx = moderngl.create_context(context=_GlfwLoader(self.handle))
        if self.ctx.version_code < 430:
            self.close()
            raise UserError(f"OpenGL 4.3 is needed; this driver gives {self.ctx.version_code // 100}."
                            f"{self.ctx.version_code % 100 // 10}")
        imgui.create_context()
        io = imgui.get_io()
        io.set_ini_filename("")  # no imgui.ini written into the user's folder
        imgui.backends.glfw_init_for_opengl(ctypes.cast(self.handle, ctypes.c_void_p).value, True)
        imgui.backends.opengl3_init("#version 430")
        self.content_scale = 1.0
        self._apply_content_scale()

    def _create(self, title: str, width: int, height: int):
        # Without a display server only EGL can make a context; elsewhere the native
        # API is tried first and EGL is the fallback.
        apis = [glfw.EGL_CONTEXT_API] if self.platform == "null" else [glfw.NATIVE_CONTEXT_API, glfw.EGL_CONTEXT_API]
        for api in apis:
            for major, minor in CONTEXT_VERSIONS:
                glfw.default_window_hints()
                glfw.window_hint(glfw.CONTEXT_CREATION_API, api)
                glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, major)
                glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, minor)
                glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
                glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
                glfw.window_hint(glfw.SCALE_TO_MONITOR, True)
                handle = glfw.create_window(width, height, title, None, None)
                if handle:
                    return handle
        raise UserError(f"cannot open an OpenGL 4.3 window: {_glfw_error()}")

    def _apply_content_scale(self) -> None:
        scale = max(glfw.get_window_content_scale(self.handle))
        if scale > 0 and scale != self.content_scale:
            style = imgui.get_style()
            style.scale_all_sizes(scale / self.content_scale)
            style.font_scale_dpi = scale
            self.content_scale = scale

    @property
    def vsync(self) -> bool:
        return self._vsync

    @vsync.setter
    def vsync(self, on: bool) -> None:
        self._vsync = bool(on)
        glfw.swap_interval(1 if on else 0)

    def framebuffer_size(self) -> tuple[int, int]:
        return glfw.get_framebuffer_size(self.handle)

    def begin_frame(self) -> None:
        """Makes the context current (other contexts may exist in this thread) and
        starts imgui's frame; imgui.new_frame() is left to the caller so scripted
        input can be queued after the backend has read the real devices."""
        glfw.make_context_current(self.handle)
        self._apply_content_scale()
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()

    def end_frame(self) -> None:
        self.draw_imgui()
        glfw.swap_buffers(self.handle)

    @staticmethod
    def draw_imgui() -> None:
        """Draws imgui's rendered frame (imgui.render()) into the bound framebuffer."""
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())

    @staticmethod
    def poll_events() -> None:
        glfw.poll_events()

    @staticmethod
    def wait_events(timeout: float) -> None:
        """Sleeps until an event arrives or ``timeout`` seconds pass."""
        glfw.wait_events_timeout(timeout)

    def make_current(self) -> None:
        glfw.make_context_current(self.handle)

    def set_title(self, title: str) -> None:
        glfw.set_window_title(self.handle, title)

    @property
    def should_close(self) -> bool:
        return bool(glfw.window_should_close(self.handle))

    def request_close(self) -> None:
        glfw.set_window_should_close(self.handle, True)

    def keep_open(self) -> None:
        """Takes back a close asked for (the window has something to say first)."""
        glfw.set_window_should_close(self.handle, False)

    def dropped(self) -> list[str]:
        """The files of the last drop on the window since the last call (none: [])."""
        dropped, self._dropped = self._dropped, []
        return dropped

    def close(self) -> None:
        if getattr(self, "handle", None) is None:
            return
        glfw.make_context_current(self.handle)
        if imgui.get_current_context() is not None:
            imgui.backends.opengl3_shutdown()
            imgui.backends.glfw_shutdown()
            imgui.destroy_context()
        if getattr(self, "ctx", None) is not None:
            self.ctx.release()
            self.ctx = None
        glfw.destroy_window(self.handle)
        self.handle = None
        glfw.terminate()


_glfw_errors: list[str] = []


def _record_glfw_error(code: int, description) -> None:
    # Kept for the one-line message instead of pyGLFW's default warning on stderr: a
    # failed first attempt (native API) that the EGL fallback recovers is not news.
    if isinstance(description, bytes):
        description = description.decode("utf-8", "replace")
    _glfw_errors[:] = _glfw_errors[-7:] + [f"{description} (GLFW error {code:#x})"]


def _glfw_error() -> str:
    return _glfw_errors[-1] if _glfw_errors else "unknown GLFW error"
