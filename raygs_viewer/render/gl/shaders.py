"""GLSL programs: the sources of ``glsl/`` with ``#include`` expanded and variants by
``#define`` (:func:`shader_source`), built in one place (:class:`Programs`), whose
compile errors name the file and line they come from; and :func:`set_uniform`, for
the uniforms a variant may compile away.

The ``glsl/`` folder ships inside the installed package as ``raygs_viewer.glsl``;
in a source checkout it is read where it stands.

Where an error points: GLSL's ``#line L S`` takes a source-string number S, not a
name, so each file has a number (:func:`file_number`) and the expanded source carries a
``#line`` wherever the file being read changes: entering an include, returning from
it, and after each ``#else``, ``#elif`` and ``#endif`` (an include in a branch the
preprocessor skips takes its directives with it). L carries the file as well, as
``number * LINE_STRIDE + line``: Mesa (llvmpipe, 22.3) reports its semantic errors in
source string 0 whatever ``#line`` said, so S alone would lose the file.
:func:`name_locations` turns the locations back into ``file.glsl:line``.
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources
from pathlib import Path

import moderngl

#: Where glsl/ stands in a source checkout: beside the package (raygs_viewer/render/gl/ is three down).
CHECKOUT_GLSL = Path(__file__).resolve().parents[3] / "glsl"
SUFFIXES = (".vert", ".frag", ".comp", ".glsl")
#: Line numbers of file n run from n * LINE_STRIDE + 1; no file may be this long.
LINE_STRIDE = 10_000
#: What a location in the ``#version`` and ``#define`` lines before the file is named.
HEADER = "<defines>"
#: The vertex stage of every full-screen pass (:meth:`Programs.fullscreen`).
FULLSCREEN_VERTEX = "fullscreen.vert"

#: A compiled draw or full-screen program with the (attribute-less) vertex array that runs it.
ProgramAndArray = tuple[moderngl.Program, moderngl.VertexArray]

_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')
_BRANCH = re.compile(r"^\s*#\s*(?:else|elif|endif)\b")
# Mesa writes "S:L(column)", NVIDIA "S(L)"; not inside a longer number or name.
_LOCATION = re.compile(r"(?<![\w.:(])(\d+)(?::(\d+)|\((\d+)\))")


def _glsl_dir():
    try:
        return resources.files("raygs_viewer.glsl")
    except ModuleNotFoundError:  # source checkout: glsl/ sits beside the package
        return CHECKOUT_GLSL


@lru_cache(maxsize=None)
def _read(name: str) -> str:
    return (_glsl_dir() / name).read_text(encoding="utf-8")


@lru_cache(maxsize=None)
def glsl_files() -> tuple[str, ...]:
    """The shader files of glsl/, sorted by name: file n (from 1) is ``glsl_files()[n - 1]``."""
    return tuple(sorted(entry.name for entry in _glsl_dir().iterdir() if entry.name.endswith(SUFFIXES)))


def file_number(name: str) -> int:
    """``name``'s source-string number, from 1 (0 is the header: ``#version``, the defines)."""
    try:
        return glsl_files().index(name) + 1
    except ValueError:
        raise ValueError(f"no glsl file {name!r} among {', '.join(glsl_files())}") from None


def _line(name: str, line: int) -> str:
    """The directive after which the source reads as ``name`` from ``line`` on."""
    number = file_number(name)
    return f"#line {number * LINE_STRIDE + line} {number}"


def _expand(name: str, seen: tuple[str, ...] = ()) -> str:
    if name in seen:
        raise ValueError(f"glsl include cycle: {' -> '.join(seen + (name,))}")
    lines = _read(name).split("\n")
    if len(lines) >= LINE_STRIDE:
        raise ValueError(f"{name} has {len(lines)} lines; error locations allow {LINE_STRIDE - 1}")
    out = []
    for number, text in enumerate(lines, start=1):
        include = _INCLUDE.match(text)
        if include:
            child = include.group(1)
            out += [_line(child, 1), _expand(child, seen + (name,)), _line(name, number + 1)]
        elif _BRANCH.match(text):
            out += [text, _line(name, number + 1)]
        else:
            out.append(text)
    return "\n".join(out)


def shader_source(name: str, defines: dict[str, object] | None = None) -> str:
    """The complete source of ``glsl/<name>`` for GLSL 4.30 with ``defines`` prepended."""
    header = ["#version 430 core"] + [f"#define {key} {value}" for key, value in sorted((defines or {}).items())]
    return "\n".join(header + [_line(name, 1), _expand(name)])


def name_locations(message: str) -> str:
    """A driver's compile log with each location in a :func:`shader_source`, ``S:L`` or
    ``S(L)``, written ``file.glsl:line`` (``<defines>:line`` in the header)."""
    files = glsl_files()

    def named(match: re.Match) -> str:
        source, line = int(match.group(1)), int(match.group(2) or match.group(3))
        number, within = divmod(line, LINE_STRIDE)
        if number == 0 and source == 0:
            return f"{HEADER}:{line}"
        if 1 <= number <= len(files) and source in (0, number):  # 0: Mesa's semantic errors
            return f"{files[number - 1]}:{within}"
        return match.group(0)

    return _LOCATION.sub(named, message)


def _key(defines: dict[str, object] | None) -> tuple:
    return tuple(sorted((defines or {}).items()))


class Programs:
    """The one place programs are built: from glsl/ file names and defines, each on
    first use, kept by those until :meth:`release`. A compile error is raised as
    ``moderngl.Error`` naming the files, the defines and, through
    :func:`name_locations`, each error's file and line."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._draw: dict[tuple, ProgramAndArray] = {}
        self._compute: dict[tuple, moderngl.ComputeShader] = {}

    def draw(self, vertex: str, fragment: str, defines: dict[str, object] | None = None) -> ProgramAndArray:
        """The program of ``glsl/<vertex>`` and ``glsl/<fragment>``, and its vertex array."""
        key = (vertex, fragment, _key(defines))
        if key not in self._draw:
            program = self._built((vertex, fragment), defines, lambda: self.ctx.program(
                vertex_shader=shader_source(vertex, defines), fragment_shader=shader_source(fragment, defines)))
            self._draw[key] = program, self.ctx.vertex_array(program, [])
        return self._draw[key]

    def fullscreen(self, fragment: str, defines: dict[str, object] | None = None) -> ProgramAndArray:
        """A full-screen pass: ``glsl/<fragment>`` over the triangle of fullscreen.vert
        (draw 3 vertices)."""
        return self.draw(FULLSCREEN_VERTEX, fragment, defines)

    def compute(self, name: str, defines: dict[str, object] | None = None) -> moderngl.ComputeShader:
        """The compute shader ``glsl/<name>``."""
        key = (name, _key(defines))
        if key not in self._compute:
            self._compute[key] = self._built((name,), defines,
                                             lambda: self.ctx.compute_shader(shader_source(name, defines)))
        return self._compute[key]

    @staticmethod
    def _built(names: tuple[str, ...], defines: dict[str, object] | None, build):
        try:
            return build()
        except moderngl.Error as exc:
            variant = ", ".join(f"{key}={value}" for key, value in _key(defines))
            raise moderngl.Error(f"{' + '.join(names)} ({variant or 'no defines'}): {name_locations(str(exc))}"
                                 ) from exc

    def release(self) -> None:
        for program, vao in self._draw.values():
            vao.release()
            program.release()
        for shader in self._compute.values():
            shader.release()
        self._draw.clear()
        self._compute.clear()


def set_uniform(program: moderngl.Program | moderngl.ComputeShader, name: str, value) -> None:
    """Sets a uniform the variant uses; variants that compiled it away are skipped.
    ``bytes`` are written as they are (matrices, arrays), anything else by value."""
    if name in program:
        if isinstance(value, bytes):
            program[name].write(value)
        else:
            program[name].value = value
