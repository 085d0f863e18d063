"""Where the GLSL sources are found: in the installed package, and in a source checkout
(where ``raygs_viewer`` is imported from the working tree and ``raygs_viewer.glsl``
does not exist as a package); and where a compile error points."""

import re
from pathlib import Path

import moderngl
import pytest

from raygs_viewer.render.gl import shaders
from raygs_viewer.render.gl.shaders import (
    CHECKOUT_GLSL,
    LINE_STRIDE,
    Programs,
    file_number,
    glsl_files,
    name_locations,
    shader_source,
)
from raygs_viewer.render.gl.plan import RenderPlan
from raygs_viewer.render.gl.storage import StorageLayout
from raygs_viewer.render.settings import RenderSettings

REPO_GLSL = Path(__file__).resolve().parents[2] / "glsl"
STAGE_SUFFIXES = (".vert", ".frag", ".comp")
STAGES = [path.name for path in sorted(REPO_GLSL.iterdir()) if path.suffix in STAGE_SUFFIXES]
_DIRECTIVE = re.compile(r"#line (\d+) (\d+)$")


def test_a_checkout_reads_glsl_beside_the_package():
    assert CHECKOUT_GLSL == REPO_GLSL
    assert (CHECKOUT_GLSL / "preprocess.comp").is_file()


def test_every_stage_file_loads_with_its_includes_expanded():
    for name in STAGES:
        source = shader_source(name)
        assert "#include" not in source and source.lstrip().startswith("#version"), name


def test_every_file_has_a_number_and_every_include_names_one():
    assert list(glsl_files()) == sorted(p.name for p in REPO_GLSL.iterdir() if p.suffix in (*STAGE_SUFFIXES, ".glsl"))
    assert [file_number(name) for name in glsl_files()] == list(range(1, len(glsl_files()) + 1))
    with pytest.raises(ValueError, match="no glsl file 'missing.glsl'"):
        file_number("missing.glsl")


@pytest.mark.parametrize("name", STAGES)
def test_each_line_of_an_expanded_source_is_numbered_as_its_file_numbers_it(name):
    """Counting lines as the GLSL preprocessor does, from each #line on, gives every line
    of the expanded source the file and line it was read from."""
    header, *lines = shader_source(name).split("\n")
    assert header == "#version 430 core" and _DIRECTIVE.match(lines[0])
    for text in lines:
        directive = _DIRECTIVE.match(text)
        if directive:
            line, source = int(directive.group(1)), int(directive.group(2))
            continue
        number, within = divmod(line, LINE_STRIDE)
        assert number == source
        assert shaders._read(glsl_files()[number - 1]).split("\n")[within - 1] == text
        line += 1


def test_driver_locations_are_named_by_file_and_line():
    frag, splat = file_number("fragment_output.glsl"), file_number("splat.glsl")
    # Mesa: semantic errors in source string 0, syntax errors in the #line's; NVIDIA: S(L).
    assert (name_locations(f"0:{frag * LINE_STRIDE + 54}(14): error: `x' undeclared")
            == "fragment_output.glsl:54(14): error: `x' undeclared")
    assert (name_locations(f"{splat}:{splat * LINE_STRIDE + 17}(20): error: syntax error")
            == "splat.glsl:17(20): error: syntax error")
    assert (name_locations(f"0({frag * LINE_STRIDE + 3}) : error C1008: undefined variable \"x\"")
            == "fragment_output.glsl:3 : error C1008: undefined variable \"x\"")
    assert name_locations("0:2(9): error: bad define") == "<defines>:2(9): error: bad define"
    # Neither a location of another file's number nor anything that is not a location.
    other = f"{splat}:{frag * LINE_STRIDE + 5}(1): vec4(1.0) at 4.30 in 3:12"
    assert name_locations(other) == other


def _broken(monkeypatch, name: str, old: str, new: str) -> int:
    """Replaces ``old`` (on one line) by ``new`` in glsl/``name`` as the shaders read it;
    returns the line it stands on."""
    text = shaders._read(name)
    assert text.count(old) == 1, f"{old!r} not once in {name}"
    read = shaders._read
    monkeypatch.setattr(shaders, "_read", lambda file: read(file).replace(old, new) if file == name else read(file))
    return text[:text.index(old)].count("\n") + 1


def _plan(settings, path=None) -> RenderPlan:
    return RenderPlan(settings, StorageLayout.plan(1000, 48 * 4, 1 << 27), path=path, sh_degree=3)


def _settings_draw(ctx, settings, path=None):
    programs = Programs(ctx)
    try:
        programs.draw(*_plan(settings, path).draw_stages())
    finally:
        programs.release()


def _kbuffer_resolve(ctx, settings):
    programs = Programs(ctx)
    try:
        programs.compute("kbuffer_resolve.comp", _plan(settings, "fetch").pass_defines())
    finally:
        programs.release()


# (file broken, its line, replacement, the program that includes it). Semantic errors:
# Mesa reports them in source string 0, so only the line number can name the file.
BROKEN = {
    "a semantic error two includes down": (
        "per_pixel_composite.glsl", "return t_a < t_b ||", "return t_a < t_typo ||",
        lambda ctx: _kbuffer_resolve(ctx, RenderSettings(order="per-pixel", order_k=2))),
    "a syntax error two includes down": (
        "splat.glsl", "    vec4 center_c2;", "    vec4 center_c2 +;",
        lambda ctx: _settings_draw(ctx, RenderSettings())),
    "an error after the includes returned": (
        "kbuffer_resolve.comp", "texelFetch(u_state, p, 0)", "texelFetch(u_state_typo, p, 0)",
        lambda ctx: _kbuffer_resolve(ctx, RenderSettings(order="per-pixel", order_k=2))),
    "an error after includes the preprocessor skipped": (  # PER_PIXEL 0: neither list include
        "fragment_output.glsl", "if (alpha < u_p_min) discard;", "if (alpha < u_p_min_typo) discard;",
        lambda ctx: _settings_draw(ctx, RenderSettings())),
}


@pytest.mark.parametrize("case", BROKEN)
def test_a_broken_include_is_named_with_its_line(gl_ctx, monkeypatch, case):
    name, old, new, build = BROKEN[case]
    line = _broken(monkeypatch, name, old, new)
    with pytest.raises(moderngl.Error) as error:
        build(gl_ctx)
    message = str(error.value)
    first = re.search(r"^[\w.<>]+:\d+", message, re.MULTILINE)
    assert first and first.group(0) == f"{name}:{line}", message


def test_a_compile_error_names_the_program_and_its_defines(gl_ctx, monkeypatch):
    _broken(monkeypatch, "resolve.frag", "uniform int u_factor;", "uniform int u_factor")
    programs = Programs(gl_ctx)
    try:
        with pytest.raises(moderngl.Error, match=r"^fullscreen.vert \+ resolve.frag \(FRONT_TO_BACK=1\): "
                                                 r"GLSL Compiler failed"):
            programs.fullscreen("resolve.frag", {"FRONT_TO_BACK": 1})
    finally:
        programs.release()


def test_more_splat_blocks_than_declared_bindings_stop_the_compile(gl_ctx):
    defines = RenderPlan(RenderSettings(), StorageLayout.plan(1000, 48, 1 << 27)).pass_defines()
    programs = Programs(gl_ctx)
    try:
        for blocks in (1, 8):
            programs.draw("quads.vert", "quads.frag", {**defines, "SPLAT_BLOCKS": blocks})
        with pytest.raises(moderngl.Error, match=r"splat_blocks.glsl:\d+.*SPLAT_BLOCKS must be 1 to 8"):
            programs.draw("quads.vert", "quads.frag", {**defines, "SPLAT_BLOCKS": 9})
    finally:
        programs.release()


def test_programs_are_built_once_per_files_and_defines(gl_ctx):
    programs = Programs(gl_ctx)
    try:
        first = programs.fullscreen("resolve.frag", {"FRONT_TO_BACK": 0})
        assert programs.fullscreen("resolve.frag", {"FRONT_TO_BACK": 0}) is first
        assert programs.draw("fullscreen.vert", "resolve.frag", {"FRONT_TO_BACK": 0}) is first
        assert programs.fullscreen("resolve.frag", {"FRONT_TO_BACK": 1})[0] is not first[0]
        assert programs.compute("lists_scan.comp") is programs.compute("lists_scan.comp", {})
    finally:
        programs.release()
