"""How much memory the GPU has for a scene's buffers, where it can be known.

OpenGL has no core query for it. NVIDIA's drivers offer ``GL_NVX_gpu_memory_info``
and AMD's ``GL_ATI_meminfo`` (both in KiB); Mesa's software rasterizers keep their
buffers in system memory, so half of it stands for theirs. Elsewhere the amount is
unknown and nothing is refused on its account. ``RAYGS_GPU_MEMORY`` (MiB) replaces
whatever was found: a user's cap, and how the tests force a small GPU.

The queries go through ``glGetIntegerv`` of the process's OpenGL library (moderngl
exposes no raw query); with the context current, its dispatch reaches the context's
driver. A failed lookup reads as unknown.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

import moderngl

from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.storage import gpu_bytes

MEMORY_VARIABLE = "RAYGS_GPU_MEMORY"
#: What of the memory found a scene's buffers may take: render targets, the per-pixel
#: order's pool and the window need the rest.
SCENE_SHARE = 0.8
_NVX = ("GL_NVX_gpu_memory_info", 0x9049, 1)   # GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX
_ATI = ("GL_ATI_meminfo", 0x87FC, 4)            # TEXTURE_FREE_MEMORY_ATI: total free first
_SOFTWARE = ("llvmpipe", "softpipe", "swrast")


def memory_override() -> int | None:
    """``RAYGS_GPU_MEMORY`` in bytes, None when unset; UserError when it is not a size."""
    text = os.environ.get(MEMORY_VARIABLE)
    if text is None or not text.strip():
        return None
    try:
        mib = float(text)
    except ValueError:
        mib = -1.0
    if not mib > 0 or mib != mib or mib == float("inf"):
        raise UserError(f"{MEMORY_VARIABLE}={text!r}: expected the GPU's memory in MiB, a positive number")
    return int(mib * (1 << 20))


def available_memory(ctx: moderngl.Context) -> tuple[int | None, str]:
    """(bytes free for buffers, or None when unknown; how that was found, in words)."""
    forced = memory_override()
    if forced is not None:
        return forced, f"{MEMORY_VARIABLE}"
    extensions = ctx.extensions
    for name, enum, values in (_NVX, _ATI):
        if name in extensions:
            kib = _get_integers(ctx, enum, values)
            if kib is not None:
                return kib * 1024, name
    renderer = str(ctx.info.get("GL_RENDERER", "")).lower()
    if any(word in renderer for word in _SOFTWARE):
        try:
            return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2, "half the system memory"
        except (ValueError, OSError):
            pass
    return None, "unknown"


def scene_fits(ctx: moderngl.Context):
    """``fits(count, sh_degree)`` for ``scene.lod_file.load_lod``: whether a scene's
    buffers (``storage.gpu_bytes``) take at most :data:`SCENE_SHARE` of the memory
    found (always, where it is unknown); and that memory, in bytes or None."""
    memory, _ = available_memory(ctx)
    if memory is None:
        return (lambda count, degree: True), None
    return (lambda count, degree: gpu_bytes(count, degree) <= SCENE_SHARE * memory), memory


def _get_integers(ctx: moderngl.Context, enum: int, count: int) -> int | None:
    """The first of ``count`` integers of ``glGetIntegerv(enum)``, None where the call
    cannot be made or leaves an error."""
    function = _gl_get_integerv()
    if function is None:
        return None
    out = (ctypes.c_int * count)(*([-1] * count))
    ctx.error  # noqa: B018 - clears an earlier error so the check below sees this call's
    function(ctypes.c_uint(enum), out)
    if ctx.error != "GL_NO_ERROR" or out[0] <= 0:
        return None
    return int(out[0])


def _gl_get_integerv():
    for name in ("OpenGL", "GL"):
        path = ctypes.util.find_library(name)
        if path is None:
            continue
        try:
            library = ctypes.CDLL(path)
            function = library.glGetIntegerv
        except (OSError, AttributeError):
            continue
        function.restype = None
        function.argtypes = (ctypes.c_uint, ctypes.POINTER(ctypes.c_int))
        return function
    return None
