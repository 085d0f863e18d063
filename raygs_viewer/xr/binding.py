"""The graphics binding of the window's own OpenGL context: what a session is made on.

The context is the one the window draws with (GLFW made it; moderngl wraps it), so the
swapchain images are textures of that context and the eyes are drawn into them directly.
Which binding depends on how GLFW made the context:

- GLX (X11): ``XrGraphicsBindingOpenGLXlibKHR`` with the display, drawable and context
  current, and the context's FBConfig and its visual. Monado refuses a NULL FBConfig
  (pyopenxr's own helper leaves it NULL): it is found from the context's
  ``GLX_FBCONFIG_ID`` (``glXQueryContext``, ``glXChooseFBConfig``).
- EGL (Wayland, GLFW's null platform, no display server): ``XR_MNDX_egl_enable``'s
  binding, with the display, the context, its config (from ``EGL_CONFIG_ID``) and
  ``eglGetProcAddress``.
- WGL (Windows): ``XrGraphicsBindingOpenGLWin32KHR`` with the current HDC and HGLRC.

:func:`context_binding` reads which one is current; :func:`make_binding` fills it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys
from types import ModuleType

from raygs_viewer.errors import UserError

GLX_VISUAL_ID = 0x800B
GLX_FBCONFIG_ID = 0x8013
EGL_CONFIG_ID = 0x3028
EGL_NONE = 0x3038


def _library(name: str) -> ctypes.CDLL | None:
    try:
        return ctypes.CDLL(name)
    except OSError:
        return None


def _current(library: ctypes.CDLL | None, function: str) -> int:
    """The pointer ``function()`` of ``library`` returns (0: none, or no such library)."""
    if library is None or not hasattr(library, function):
        return 0
    call = getattr(library, function)
    call.restype = ctypes.c_void_p
    return call() or 0


def context_binding() -> str:
    """"win32", "glx" or "egl": the API of the OpenGL context current on this thread."""
    if sys.platform == "win32":
        return "win32"
    if _current(_library("libGL.so.1"), "glXGetCurrentContext"):
        return "glx"
    if _current(_library("libEGL.so.1"), "eglGetCurrentContext"):
        return "egl"
    raise UserError("no OpenGL context is current to bind to the headset (GLX or EGL)")


def make_binding(xr: ModuleType, kind: str):
    """The binding structure of the current context, of ``kind`` (:func:`context_binding`).
    Keep it alive while the session is being made: the session reads it then."""
    if kind == "glx":
        return _glx_binding(xr)
    if kind == "egl":
        return _egl_binding(xr)
    return _win32_binding(xr)


def _glx_binding(xr: ModuleType):
    from OpenGL import GLX  # pyopenxr's own dependency: its binding's field types

    gl = _library("libGL.so.1")
    display, context = _current(gl, "glXGetCurrentDisplay"), _current(gl, "glXGetCurrentContext")
    drawable = _current(gl, "glXGetCurrentDrawable")
    config_id = ctypes.c_int()
    gl.glXQueryContext(ctypes.c_void_p(display), ctypes.c_void_p(context), GLX_FBCONFIG_ID, ctypes.byref(config_id))
    gl.glXChooseFBConfig.restype = ctypes.POINTER(ctypes.c_void_p)
    count = ctypes.c_int()
    attributes = (ctypes.c_int * 3)(GLX_FBCONFIG_ID, config_id.value, 0)
    screen = _default_screen(display)
    configs = gl.glXChooseFBConfig(ctypes.c_void_p(display), screen, attributes, ctypes.byref(count))
    if not configs or count.value < 1:
        raise UserError("the window's GLX context has no FBConfig to give the headset's runtime")
    config = configs[0]
    visual = ctypes.c_int()
    gl.glXGetFBConfigAttrib(ctypes.c_void_p(display), ctypes.c_void_p(config), GLX_VISUAL_ID, ctypes.byref(visual))
    _free(configs)
    return xr.GraphicsBindingOpenGLXlibKHR(
        x_display=ctypes.cast(display, ctypes.POINTER(GLX.Display)), visualid=visual.value,
        glx_fbconfig=ctypes.cast(config, GLX.GLXFBConfig), glx_drawable=drawable,
        glx_context=ctypes.cast(context, GLX.GLXContext))


def _default_screen(display: int) -> int:
    x11 = _library(ctypes.util.find_library("X11") or "libX11.so.6")
    if x11 is None:
        return 0
    x11.XDefaultScreen.argtypes = [ctypes.c_void_p]
    return int(x11.XDefaultScreen(ctypes.c_void_p(display)))


def _free(pointer) -> None:
    x11 = _library(ctypes.util.find_library("X11") or "libX11.so.6")
    if x11 is not None:
        x11.XFree.argtypes = [ctypes.c_void_p]
        x11.XFree(ctypes.cast(pointer, ctypes.c_void_p))


def _egl_binding(xr: ModuleType):
    from xr.platform.linux import (  # the binding's field types
        EGLConfig,
        EGLContext,
        EGLDisplay,
    )

    egl = _library("libEGL.so.1")
    display, context = _current(egl, "eglGetCurrentDisplay"), _current(egl, "eglGetCurrentContext")
    config_id = ctypes.c_int()
    egl.eglQueryContext(ctypes.c_void_p(display), ctypes.c_void_p(context), EGL_CONFIG_ID, ctypes.byref(config_id))
    config, count = ctypes.c_void_p(), ctypes.c_int()
    attributes = (ctypes.c_int * 3)(EGL_CONFIG_ID, config_id.value, EGL_NONE)
    if not egl.eglChooseConfig(ctypes.c_void_p(display), attributes, ctypes.byref(config), 1, ctypes.byref(count)) \
            or count.value < 1:
        raise UserError("the window's EGL context has no config to give the headset's runtime")
    return xr.GraphicsBindingEGLMNDX(
        get_proc_address=ctypes.cast(egl.eglGetProcAddress, xr.PFN_xrEglGetProcAddressMNDX),
        display=ctypes.cast(display, EGLDisplay), config=ctypes.cast(config.value, EGLConfig),
        context=ctypes.cast(context, EGLContext))


def _win32_binding(xr: ModuleType):
    opengl = ctypes.WinDLL("opengl32")  # type: ignore[attr-defined]  Windows only
    opengl.wglGetCurrentDC.restype = ctypes.c_void_p
    opengl.wglGetCurrentContext.restype = ctypes.c_void_p
    return xr.GraphicsBindingOpenGLWin32KHR(h_dc=opengl.wglGetCurrentDC(), h_glrc=opengl.wglGetCurrentContext())


def gl_function(name: str, restype, argtypes: list):
    """The current context's GL entry point ``name`` as a ctypes function (for the one
    thing moderngl cannot do here: attach a depth texture made elsewhere)."""
    kind = context_binding()
    if kind == "glx":
        loader = _library("libGL.so.1").glXGetProcAddressARB
    elif kind == "egl":
        loader = _library("libEGL.so.1").eglGetProcAddress
    else:
        loader = ctypes.WinDLL("opengl32").wglGetProcAddress  # type: ignore[attr-defined]  Windows only
    loader.restype, loader.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
    address = loader(name.encode())
    if not address:
        raise UserError(f"this OpenGL has no {name}")
    return ctypes.CFUNCTYPE(restype, *argtypes)(address)
