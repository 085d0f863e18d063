"""GLSL sources: one file per stage in ``glsl/``, ``#include`` expanded, variants by
``#define``; and :func:`set_uniform`, which every pass uses to feed them.

The ``glsl/`` folder ships inside the installed package as ``raygs_viewer.glsl``;
in a source checkout it is read where it stands.
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources
from pathlib import Path

import moderngl

#: Where glsl/ stands in a source checkout: beside the package (raygs_viewer/render/gl/ is three down).
CHECKOUT_GLSL = Path(__file__).resolve().parents[3] / "glsl"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


def _glsl_dir():
    try:
        return resources.files("raygs_viewer.glsl")
    except ModuleNotFoundError:  # source checkout: glsl/ sits beside the package
        return CHECKOUT_GLSL


@lru_cache(maxsize=None)
def _read(name: str) -> str:
    return (_glsl_dir() / name).read_text(encoding="utf-8")


def _expand(name: str, seen: tuple[str, ...] = ()) -> str:
    if name in seen:
        raise ValueError(f"glsl include cycle: {' -> '.join(seen + (name,))}")
    return _INCLUDE.sub(lambda m: _expand(m.group(1), seen + (name,)), _read(name))


def shader_source(name: str, defines: dict[str, object] | None = None) -> str:
    """The complete source of ``glsl/<name>`` for GLSL 4.30 with ``defines`` prepended."""
    header = ["#version 430 core"] + [f"#define {key} {value}" for key, value in sorted((defines or {}).items())]
    return "\n".join(header) + "\n#line 1\n" + _expand(name)


def set_uniform(program: moderngl.Program | moderngl.ComputeShader, name: str, value) -> None:
    """Sets a uniform the variant uses; variants that compiled it away are skipped.
    ``bytes`` are written as they are (matrices, arrays), anything else by value."""
    if name in program:
        if isinstance(value, bytes):
            program[name].write(value)
        else:
            program[name].value = value
