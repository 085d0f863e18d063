"""A tiny ctypes loader for Mesa's off-screen OpenGL (OSMesa, ``libosmesa6``).

glcontext (moderngl's context library) has no OSMesa backend, but moderngl
accepts any object with the glcontext interface as ``context=``:
``load_opengl_function(name) -> int`` (a function address, 0 when missing),
``release()``, ``__enter__`` and ``__exit__``. :class:`OSMesaLoader` is that
object. It creates a core-profile 4.5 context (4.3 when 4.5 is refused), makes
it current on a 1x1 RGBA buffer it keeps alive (all rendering goes into our own
framebuffers, so the default buffer is never read), and resolves GL functions
with ``OSMesaGetProcAddress``.

OSMesa and EGL share Mesa's ``libglapi`` dispatch (a per-thread "current
context"). EGL does not notice when OSMesa takes it over: a later
``eglMakeCurrent`` of the context EGL still believes current is a no-op, and
GL calls of the EGL context silently reach the OSMesa one. So a loader made in
a thread where an EGL context is current unbinds that EGL context first and
binds it again on ``release()``. While both live, wrap work in ``with ctx:``;
simplest of all is to keep an OSMesa context in a thread of its own.
"""

from __future__ import annotations

import ctypes
import ctypes.util

# From Mesa's GL/osmesa.h (not installed by libosmesa6; values checked by
# creating a 4.5 core context on Mesa 22.3).
OSMESA_RGBA = 0x1908  # GL_RGBA
OSMESA_FORMAT = 0x22
OSMESA_DEPTH_BITS = 0x30
OSMESA_STENCIL_BITS = 0x31
OSMESA_PROFILE = 0x33
OSMESA_CORE_PROFILE = 0x34
OSMESA_CONTEXT_MAJOR_VERSION = 0x36
OSMESA_CONTEXT_MINOR_VERSION = 0x37
GL_UNSIGNED_BYTE = 0x1401

SONAME = "libOSMesa.so.8"

# Core-profile versions asked for, best first (moderngl then checks >= 4.3).
VERSIONS = ((4, 5), (4, 3))


class OSMesaError(RuntimeError):
    """OSMesa is missing or would not give a context."""


def find_osmesa_library() -> str | None:
    """The name of a loadable libOSMesa, or None (libosmesa6 not installed)."""
    candidates = [SONAME]
    found = ctypes.util.find_library("OSMesa")
    if found and found not in candidates:
        candidates.append(found)
    for name in candidates:
        try:
            ctypes.CDLL(name)
        except OSError:
            continue
        return name
    return None


_lib: ctypes.CDLL | None = None


def _library() -> ctypes.CDLL:
    global _lib
    if _lib is None:
        name = find_osmesa_library()
        if name is None:
            raise OSMesaError(f"{SONAME} not found")
        lib = ctypes.CDLL(name)
        lib.OSMesaCreateContextAttribs.restype = ctypes.c_void_p
        lib.OSMesaCreateContextAttribs.argtypes = [ctypes.POINTER(ctypes.c_int), ctypes.c_void_p]
        lib.OSMesaMakeCurrent.restype = ctypes.c_ubyte
        lib.OSMesaMakeCurrent.argtypes = [
            ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_int,
        ]
        lib.OSMesaGetCurrentContext.restype = ctypes.c_void_p
        lib.OSMesaGetCurrentContext.argtypes = []
        lib.OSMesaGetProcAddress.restype = ctypes.c_void_p
        lib.OSMesaGetProcAddress.argtypes = [ctypes.c_char_p]
        lib.OSMesaDestroyContext.restype = None
        lib.OSMesaDestroyContext.argtypes = [ctypes.c_void_p]
        _lib = lib
    return _lib


_egl_lib: ctypes.CDLL | None | bool = False  # False: not looked up yet


def _egl() -> ctypes.CDLL | None:
    global _egl_lib
    if _egl_lib is False:
        try:
            egl = ctypes.CDLL("libEGL.so.1")
        except OSError:
            _egl_lib = None
        else:
            egl.eglGetCurrentContext.restype = ctypes.c_void_p
            egl.eglGetCurrentDisplay.restype = ctypes.c_void_p
            egl.eglGetCurrentSurface.restype = ctypes.c_void_p
            egl.eglGetCurrentSurface.argtypes = [ctypes.c_int]
            egl.eglMakeCurrent.restype = ctypes.c_uint
            egl.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
            _egl_lib = egl
    return _egl_lib


class _EGLBinding:
    """The EGL context current in this thread, if any, to unbind and restore."""

    def __init__(self):
        self.egl = _egl()
        self.saved = None

    def detach(self) -> None:
        if self.egl is None:
            return
        egl = self.egl
        context = egl.eglGetCurrentContext()
        if not context:
            return
        display = egl.eglGetCurrentDisplay()
        draw = egl.eglGetCurrentSurface(0x3059)  # EGL_DRAW
        read = egl.eglGetCurrentSurface(0x305A)  # EGL_READ
        if egl.eglMakeCurrent(display, None, None, None):
            self.saved = (display, draw, read, context)

    def restore(self) -> None:
        if self.egl is not None and self.saved is not None:
            self.egl.eglMakeCurrent(*self.saved)  # fails harmlessly if it is gone
        self.saved = None


# Live loaders by OSMesa context handle, so __exit__ can restore a previous one.
_live: dict[int, "OSMesaLoader"] = {}


class OSMesaLoader:
    """An OSMesa context, current in this thread, in glcontext's interface."""

    def __init__(self, depth_bits: int = 24, stencil_bits: int = 8):
        lib = _library()
        self._lib = lib
        self._handle: int | None = None
        self.version: tuple[int, int] | None = None
        for major, minor in VERSIONS:
            attribs = (ctypes.c_int * 13)(
                OSMESA_FORMAT, OSMESA_RGBA,
                OSMESA_DEPTH_BITS, depth_bits,
                OSMESA_STENCIL_BITS, stencil_bits,
                OSMESA_PROFILE, OSMESA_CORE_PROFILE,
                OSMESA_CONTEXT_MAJOR_VERSION, major,
                OSMESA_CONTEXT_MINOR_VERSION, minor,
                0,
            )
            handle = lib.OSMesaCreateContextAttribs(attribs, None)
            if handle:
                self._handle = handle
                self.version = (major, minor)
                break
        if self._handle is None:
            wanted = " or ".join(f"{a}.{b}" for a, b in VERSIONS)
            raise OSMesaError(f"OSMesaCreateContextAttribs refused a core {wanted} context")
        # The default framebuffer; never read, but must outlive the context.
        self._buffer = (ctypes.c_ubyte * 4)()
        self._previous: list[tuple[int | None, _EGLBinding]] = []
        _live[self._handle] = self
        self._egl = _EGLBinding()
        self._egl.detach()
        try:
            self._make_current()
        except BaseException:
            self.release()
            raise

    def _make_current(self) -> None:
        ok = self._lib.OSMesaMakeCurrent(self._handle, self._buffer, GL_UNSIGNED_BYTE, 1, 1)
        if not ok:
            raise OSMesaError("OSMesaMakeCurrent failed")

    def load_opengl_function(self, name: str) -> int:
        if self._handle is None:
            return 0
        return self._lib.OSMesaGetProcAddress(name.encode("ascii")) or 0

    def __enter__(self):
        egl = _EGLBinding()
        egl.detach()
        self._previous.append((self._lib.OSMesaGetCurrentContext(), egl))
        self._make_current()
        return self

    def __exit__(self, *args) -> None:
        if not self._previous:
            return
        previous, egl = self._previous.pop()
        other = _live.get(previous) if previous else None
        if other is not None and other is not self:
            other._make_current()
        egl.restore()

    def release(self) -> None:
        if self._handle is None:
            return
        _live.pop(self._handle, None)
        self._lib.OSMesaDestroyContext(self._handle)
        self._handle = None
        self._egl.restore()
