"""Headless OpenGL 4.3 contexts: EGL first, OSMesa as the fallback.

``RAYGS_GL_BACKEND`` (``egl``, ``osmesa`` or ``auto``; unset means ``auto``)
picks the backend when the caller passes none.
"""

from __future__ import annotations

import os
import weakref
from collections.abc import Callable, Mapping

import moderngl

from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.osmesa import OSMesaLoader

REQUIRE = 430
ENV_VAR = "RAYGS_GL_BACKEND"
BACKENDS = ("egl", "osmesa", "auto")

INSTALL_EGL = "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri"
INSTALL_OSMESA = "apt-get install libosmesa6"

# Which backend made each live context (see context_description).
_backend_of: "weakref.WeakKeyDictionary[moderngl.Context, str]" = weakref.WeakKeyDictionary()




def _create_egl() -> moderngl.Context:
    return moderngl.create_context(standalone=True, backend="egl", require=REQUIRE)


def _create_osmesa() -> moderngl.Context:
    loader = OSMesaLoader()
    try:
        # moderngl 5.13 passes extra settings to its C create_context, which
        # takes a ready glcontext-like object as ``context=`` (this is what
        # moderngl.init_context(loader=...) does, but that one returns None and
        # probes the default framebuffer). The context calls loader.release().
        return moderngl.create_context(standalone=True, require=REQUIRE, context=loader)
    except BaseException:
        loader.release()
        raise


#: How each backend makes a context (tests hand in failing ones).
CREATORS: Mapping[str, Callable[[], moderngl.Context]] = {"egl": _create_egl, "osmesa": _create_osmesa}
_HINTS = {"egl": INSTALL_EGL, "osmesa": INSTALL_OSMESA}


def _resolve_backend(backend: str | None) -> str:
    if backend is None:
        raw = os.environ.get(ENV_VAR, "")
        value = raw.strip().lower() or "auto"
        if value not in BACKENDS:
            raise UserError(
                f"{ENV_VAR}={raw!r} is not one of {', '.join(BACKENDS)}"
            )
        return value
    value = backend.strip().lower()
    if value not in BACKENDS:
        raise UserError(f"unknown OpenGL backend {backend!r}: use one of {', '.join(BACKENDS)}")
    return value


def create_headless_context(backend: str | None = None, *,
                            creators: Mapping[str, Callable[[], moderngl.Context]] = CREATORS) -> moderngl.Context:
    """A standalone moderngl context with OpenGL >= 4.3 and no window.

    ``backend`` is ``"egl"``, ``"osmesa"``, ``"auto"`` or None (read
    ``RAYGS_GL_BACKEND``, default auto). Auto tries EGL, then OSMesa. Raises
    UserError naming what was tried and what to install when none works. The
    context has no default framebuffer: render into your own. Release it with
    ``ctx.release()``. ``creators`` makes the context of each backend (:data:`CREATORS`).
    """
    choice = _resolve_backend(backend)
    order = ("egl", "osmesa") if choice == "auto" else (choice,)
    failures = []
    for name in order:
        try:
            ctx = creators[name]()
        except Exception as exc:  # noqa: BLE001 - every failure becomes one line below
            failures.append(f"{name}: {one_line(exc, 160)}")
            continue
        _backend_of[ctx] = name
        return ctx
    hints = " or ".join(_HINTS[name] for name in order)
    raise UserError(
        f"no headless OpenGL {REQUIRE // 100}.{REQUIRE % 100 // 10} context "
        f"({'; '.join(failures)}); install Mesa: {hints}"
    )


def context_backend(ctx: moderngl.Context) -> str:
    """``"egl"`` or ``"osmesa"`` for contexts from create_headless_context, else ``"other"``."""
    return _backend_of.get(ctx, "other")


def context_description(ctx: moderngl.Context) -> str:
    """One line: renderer, OpenGL version and the backend that made the context."""
    info = ctx.info
    renderer = info.get("GL_RENDERER", "unknown renderer")
    version = info.get("GL_VERSION", "unknown version")
    return f"{renderer}, OpenGL {version}, via {context_backend(ctx)}"
