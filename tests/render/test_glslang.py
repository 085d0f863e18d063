"""Every shader variant the package can build compiles as desktop GLSL 4.30 core under
Khronos' reference front end, glslangValidator (issue 39, part 3): so a variant no test
renders, or that only a stricter driver than llvmpipe would refuse, fails here, naming
the variant and the file and line.

The variants are :func:`raygs_viewer.render.gl.variants.all_programs` (every program
the renderer and its passes can build, derived by running the planning), and the
sources to compile :func:`~raygs_viewer.render.gl.variants.compile_units`. Each is the
exact text ``Programs`` gives the driver (``shaders.shader_source``: the same includes,
the same ``#line`` mapping), written with its stage's suffix.

Why plain ``glslangValidator file.<stage>``: without ``-G``/``-V`` glslang checks GLSL
as an OpenGL driver compiles it, with the version, profile and built-ins that the
``#version 430 core`` line names (no later built-in, no ES or compatibility rule, no
implicit conversion 4.30 lacks). ``-G`` (SPIR-V for OpenGL) would add GL_ARB_gl_spirv's
rules, which a GLSL program never meets (every uniform with an explicit location).
glslang reports each error as ``string:line``, which ``shaders.name_locations`` turns
back into ``file.glsl:line``. The stages are compiled one by one; linking them is the
driver's, in the render tests.

glslang has no GL_EXT_shader_framebuffer_fetch (KhronosGroup/glslang#2835, #3146): for
it alone, the directive that enables the extension becomes a definition and each
fragment output it makes ``inout`` an ``out`` (GLSL lets a shader read its outputs),
bound to that definition, so that an ``inout`` whose extension the preprocessor did not
enable is still an error. The extension's own rules are the driver's.
"""

from __future__ import annotations

import itertools
import random
import re
import shutil
import subprocess
import time
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from testkit import patched_glsl, random_scene

from raygs_viewer.errors import UserError
from raygs_viewer.render.channels import OUTPUTS
from raygs_viewer.render.gl import variants
from raygs_viewer.render.gl.kbuffer import FRAMEBUFFER_FETCH
from raygs_viewer.render.gl.plan import RenderPlan
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.shaders import name_locations, shader_source
from raygs_viewer.render.gl.storage import MAX_SPLAT_BLOCKS
from raygs_viewer.render.gl.variants import Program, Unit
from raygs_viewer.render.setting_info import settings_table
from raygs_viewer.render.settings import MAX_SUPERSAMPLE, SH_DEGREES, RenderSettings

REPO_GLSL = Path(__file__).resolve().parents[2] / "glsl"
GLSLANG = shutil.which("glslangValidator")
needs_glslang = pytest.mark.skipif(GLSLANG is None, reason="glslangValidator is not installed (Debian's "
                                                           "glslang-tools, which .ci/run installs)")
#: Compiles run in this many glslangValidator processes at once, each given many files.
PROCESSES = 2
#: Plans GLRenderer.plan makes on llvmpipe, with a 4 KiB block limit (several splat blocks).
RENDERER_CASES = [(RenderSettings(), "color"), (RenderSettings(mode="gs", alpha_clamp=True), "geometry"),
                  (RenderSettings(transmittance_cutoff=True, sh_degree=1), "color"),
                  (RenderSettings(mode="raygs-exact-mip", order="per-pixel", order_k=3), "color"),
                  (RenderSettings(order="per-pixel", transmittance_cutoff=True), "median"),
                  (RenderSettings(mip=True, mip_modulation=False), "median")]

_FETCH_DIRECTIVE = re.compile(rf"^\s*#\s*extension\s+{FRAMEBUFFER_FETCH}\s*:\s*(?:require|enable)\s*$", re.MULTILINE)
_GLOBAL_INOUT = re.compile(r"^(\s*(?:layout\s*\([^)]*\)\s*)?)inout(\s+\w+\s+\w+(?:\s*\[[^\]]*\])?\s*;)", re.MULTILINE)
FETCH_ENABLED = "framebuffer_fetch_enabled"
_SUMMARY = re.compile(r"^ERROR: (\d+ compilation errors|.*compilation terminated)")


def for_glslang(source: str) -> str:
    """``source`` with framebuffer fetch lowered as the module's docstring says; every
    line keeps its place, so the ``#line`` mapping holds."""
    source = _FETCH_DIRECTIVE.sub(f"#define {FETCH_ENABLED} true", source)
    number = itertools.count()
    return _GLOBAL_INOUT.sub(lambda m: f"{m.group(1)}out{m.group(2)} "
                                       f"const bool fetch_output_{next(number)} = {FETCH_ENABLED};", source)


def _run(files: Sequence[str], folder: Path) -> tuple[int, str]:
    done = subprocess.run([GLSLANG, *files], cwd=folder, capture_output=True, text=True, timeout=120)
    return done.returncode, done.stdout + done.stderr


def _errors_by_file(output: str, files: Sequence[str]) -> dict[str, list[str]]:
    """Each file's error lines: glslangValidator names a file before its messages
    (given a single file, only when it has some)."""
    errors: dict[str, list[str]] = {}
    current = files[0] if len(files) == 1 else None
    known = set(files)
    for line in output.splitlines():
        if line.strip() in known:
            current = line.strip()
        elif line.startswith("ERROR:") and not _SUMMARY.match(line):
            errors.setdefault(current or "?", []).append(line)
    return errors


def glslang_failures(sources: Mapping[Unit, str], programs: Mapping[Unit, Sequence[Program]],
                     folder: Path) -> list[str]:
    """One message per source glslangValidator refuses: the stage, the program and
    defines it was made for (and how many more it stands for), and each error at its
    ``file.glsl:line``."""
    names = {}
    for number, (unit, source) in enumerate(sources.items()):
        name = f"v{number:05d}{Path(unit.stage).suffix}"
        (folder / name).write_text(for_glslang(source))
        names[name] = unit
    ordered = list(names)
    parts = [part for part in (ordered[i::PROCESSES] for i in range(PROCESSES)) if part]
    with ThreadPoolExecutor(PROCESSES) as pool:
        runs = list(pool.map(lambda part: (part, *_run(part, folder)), parts))
    failures = []
    for part, code, output in runs:
        errors = _errors_by_file(output, part)
        if code != 0 and not errors:
            failures.append(f"glslangValidator exited {code} naming no file:\n{output[-2000:]}")
        for name, lines in errors.items():
            unit = names.get(name)
            made_for = programs.get(unit, ())
            what = f"{unit.stage} of {made_for[0].describe()}" if made_for else f"{name} ({unit})"
            more = f" (and {len(made_for) - 1} more programs)" if len(made_for) > 1 else ""
            failures.append(f"{what}{more}:\n    " + "\n    ".join(name_locations(line) for line in lines))
    return failures


def sources(units: Iterable[Unit]) -> dict[Unit, str]:
    """Each unit's ``shader_source``. Only the define lines after ``#version`` differ
    between the sources of one stage, so each stage is expanded once, and the first
    source of each is checked against ``shader_source`` itself."""
    bare: dict[str, list[str]] = {}
    made = {}
    for unit in units:
        first = unit.stage not in bare
        if first:
            bare[unit.stage] = shader_source(unit.stage).split("\n", 1)
        version, rest = bare[unit.stage]
        made[unit] = "\n".join([version, *(f"#define {key} {value}" for key, value in unit.defines), rest])
        assert not first or made[unit] == unit.source(), f"shader_source no longer writes {unit.stage} so"
    return made


def check(units: Mapping[Unit, Sequence[Program]], folder: Path) -> list[str]:
    return glslang_failures(sources(units), units, folder)


def line_of(name: str, text: str) -> int:
    """The line of ``glsl/<name>`` that is ``text`` (stripped), from 1."""
    lines = [line.strip() for line in (REPO_GLSL / name).read_text().split("\n")]
    return lines.index(text) + 1


@needs_glslang
def test_every_variant_compiles_as_desktop_glsl_430_core(tmp_path):
    started = time.perf_counter()
    programs = variants.all_programs()
    units = variants.compile_units(programs)
    failures = check(units, tmp_path)
    seconds = time.perf_counter() - started
    assert not failures, (f"{len(failures)} of the {len(units)} sources of {len(programs)} programs fail "
                          f"glslangValidator ({seconds:.1f} s):\n" + "\n".join(failures))


def test_every_stage_file_is_in_some_variant():
    built = {stage for program in variants.all_programs() for stage in program.stages}
    assert set(variants.stage_files()) <= built, "a glsl/ stage no variant builds: add its pass to variants.py"


def test_every_define_value_of_every_stage_is_compiled():
    programs = variants.all_programs()
    made = {(unit.stage, key, value) for program in programs for unit in program.units() for key, value in unit.defines}
    compiled = {(unit.stage, key, value) for unit in variants.compile_units(programs) for key, value in unit.defines}
    assert made == compiled


def test_random_plannings_make_no_source_the_search_missed():
    """The search branches only on what planning reads and stops where a value changes
    only literals; whole random inputs (every axis at once) must find nothing new."""
    classes = {variants.compile_class(unit) for unit in variants.compile_units(variants.all_programs())}
    rng = random.Random(39)
    rows = settings_table(RenderSettings)
    tried = 0
    while tried < 300:
        try:
            settings = RenderSettings(**{row.name: rng.choice(variants.field_values(row)) for row in rows})
        except UserError:  # per-pixel GS
            continue
        tried += 1
        inputs = variants.Inputs(settings, outputs=rng.choice(OUTPUTS), gpu=rng.choice(variants.GPUS),
                                 general=rng.random() < 0.5, draw=rng.choice(variants.DRAW_LAYOUTS),
                                 blocks=rng.randint(1, MAX_SPLAT_BLOCKS), sh_degree=rng.choice(SH_DEGREES))
        for program in variants.plan_programs(inputs.plan()):
            missed = [unit.stage for unit in program.units() if variants.compile_class(unit) not in classes]
            assert not missed, f"{inputs}: {program.describe()} ({missed}) is in no compiled class"


def test_the_renderers_own_plans_are_among_the_variants(gl_ctx):
    classes = {variants.compile_class(unit) for unit in variants.compile_units(variants.all_programs())}
    renderer = GLRenderer(gl_ctx, random_scene(n=50, seed=3), block_limit=4096)
    try:
        for settings, outputs in RENDERER_CASES:
            for program in variants.plan_programs(renderer.plan(settings, outputs)):
                assert all(variants.compile_class(unit) in classes for unit in program.units()), program.describe()
    finally:
        renderer.release()


def test_a_define_new_to_the_plan_is_among_the_variants(monkeypatch):
    """Planning never reads supersampling, so the search never varies it; a define made
    from it is searched over every factor at once."""
    assert {inputs.settings.supersample for inputs, _ in variants.planned_inputs()} == {1}
    pass_defines = RenderPlan.pass_defines
    monkeypatch.setattr(RenderPlan, "pass_defines",
                        lambda plan: {**pass_defines(plan), "NEW_SWITCH": plan.settings.supersample})
    seen = {dict(program.defines).get("NEW_SWITCH") for _, programs in variants.planned_inputs()
            for program in programs if "raygs.vert" in program.stages}
    assert seen == set(range(1, MAX_SUPERSAMPLE + 1))


def test_the_lowering_keeps_every_line_and_binds_outputs_to_the_directive():
    source = shader_source("raygs.frag", {**dict(variants.all_programs()[0].defines), "FRONT_TO_BACK": 1,
                                          "PER_PIXEL": 0, "GEOMETRY": 0})
    lowered = for_glslang(source)
    assert source.count("\n") == lowered.count("\n") and "inout vec4 frag_color" in source
    assert f"#define {FETCH_ENABLED} true" in lowered and f"= {FETCH_ENABLED};" in lowered
    assert "inout vec4 frag_color" not in lowered and "inout vec4 state" in lowered  # a parameter stays


def _units_of(stage: str, **wanted) -> dict[Unit, list[Program]]:
    units = variants.compile_units(variants.all_programs())
    return {unit: made for unit, made in units.items()
            if unit.stage == stage and all(dict(unit.defines).get(k) == v for k, v in wanted.items())}


@needs_glslang
def test_an_inout_output_without_its_extension_is_reported_with_variant_and_line(monkeypatch, tmp_path):
    """The negative control: the fragment stages lose their #extension directive."""
    broken = dict(list(_units_of("raygs.frag", FRONT_TO_BACK=1).items())[:2])
    fine = dict(list(_units_of("raygs.frag", FRONT_TO_BACK=0, PER_PIXEL=0).items())[:1])
    patched_glsl(monkeypatch, "fragment_output.glsl", f"#extension {FRAMEBUFFER_FETCH} : require", "")
    failures = check({**broken, **fine}, tmp_path)
    print("\n".join(failures))
    assert len(failures) == len(broken) == 2
    where = f"fragment_output.glsl:{line_of('fragment_output.glsl', 'inout vec4 frag_color;')}"
    for failure in failures:
        assert failure.startswith("raygs.frag of raygs.vert + raygs.frag (") and "FRONT_TO_BACK=1" in failure
        assert f"ERROR: {where}: '{FETCH_ENABLED}' : undeclared identifier" in failure


@needs_glslang
def test_an_implicit_conversion_430_lacks_is_reported_at_its_line(monkeypatch, tmp_path):
    units = _units_of("lists_scan.comp")
    patched_glsl(monkeypatch, "lists_scan.comp", "void main() {", "void main() { int broken = 0.5;")
    failures = check(units, tmp_path)
    print("\n".join(failures))
    assert failures and all(f"lists_scan.comp:{line_of('lists_scan.comp', 'void main() {')}: '=' :  cannot "
                            f"convert from ' const float' to ' temp int'" in failure for failure in failures)
    assert all(failure.startswith("lists_scan.comp of lists_scan.comp (") for failure in failures)


@needs_glslang
def test_a_variant_the_plan_never_makes_fails_naming_its_defines(tmp_path):
    program = next(p for p in variants.all_programs() if p.stages == ("raygs.vert", "raygs.frag"))
    broken = Program.of(program.stages, {**dict(program.defines), "SPLAT_BLOCKS": 9})
    failures = check({unit: [broken] for unit in broken.units()}, tmp_path)
    print("\n".join(failures))
    where = line_of("splat_blocks.glsl", "#error SPLAT_BLOCKS must be 1 to 8 (render/gl/storage.py, MAX_SPLAT_BLOCKS)")
    assert len(failures) == 1  # the fragment stage of a blended draw reads no record
    assert failures[0].startswith("raygs.vert of raygs.vert + raygs.frag (") and "SPLAT_BLOCKS=9" in failures[0]
    assert f"ERROR: splat_blocks.glsl:{where}: '#error' : SPLAT_BLOCKS must be 1 to 8" in failures[0]
