"""Every GLSL program this package can build, as (stage files, defines), found by
running the code that builds them rather than kept as a list: so a new setting, a new
define of the plan or a new fallback is among them the day it is written.

Where they come from:

- the renders: each :class:`~raygs_viewer.render.gl.plan.RenderPlan` the renderer can
  make, planned by the renderer's own :class:`~raygs_viewer.render.gl.planner.Planner`
  on described GPUs (:data:`GPUS`: with framebuffer fetch and without, each under every
  ``order_path``), and the programs its passes build from it (:func:`plan_programs`:
  the plan's ``preprocess_defines``, ``draw_stages``, ``pass_defines``, ``resolve_defines``);
- the fixed passes (:func:`fixed_programs`): present, lens, stereo composition, the
  channel pictures, the GPU sort's and the radix sort's compute passes.

Which plans: the product of every input is far too large to visit (settings, what is
asked, GPU, general build, draw layout, storage blocks, SH degrees), and most of it
changes nothing: a field the planning never reads cannot change a define. So the
settings, what is asked, the GPU and the general build are explored by reading
(:func:`explore`): planning runs with every unfixed input at its default, notes the
inputs it reads, and branches only on those, each over every value it can take
(:func:`field_values`, from the settings table). Precision and supersampling, for one,
are never read by the defines and are never branched on. Each distinct kind of plan
found (:func:`signature`) is then planned again under every draw layout with every
count of storage blocks (1 to ``MAX_SPLAT_BLOCKS``), and under every stored SH degree.
tests/render/test_glslang.py checks that random whole inputs, every axis at once, make
no source of a kind this missed.

What to compile (:func:`compile_units`): identical sources once; and of the stage
sources that take the same ``#if`` branches (they agree on every define a conditional
evaluates, :func:`branches`) and differ only in the value of a literal of the same
kind, one per such class, plus as many as it takes for every value of every define to
be compiled at least once.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import KW_ONLY, dataclass
from functools import lru_cache
from typing import ClassVar

from raygs_viewer.errors import UserError
from raygs_viewer.render.channels import OUTPUTS, Outputs
from raygs_viewer.render.gl.geometry import PICTURE_DEFINES
from raygs_viewer.render.gl.gpu_sort import DEFINES as SORT_DEFINES
from raygs_viewer.render.gl.kbuffer import FRAMEBUFFER_FETCH
from raygs_viewer.render.gl.per_pixel import ORDER_PATHS
from raygs_viewer.render.gl.plan import DRAW_VERTICES, RECORDS, DrawLayout, RenderPlan
from raygs_viewer.render.gl.planner import GpuDescription, Planner
from raygs_viewer.render.gl.radix_sort import RadixLayout
from raygs_viewer.render.gl.shaders import FULLSCREEN_VERTEX, glsl_files, shader_source
from raygs_viewer.render.gl.storage import MAX_SPLAT_BLOCKS, SPLAT_BYTES, StorageLayout
from raygs_viewer.render.setting_info import SettingField, defaults, settings_table
from raygs_viewer.render.settings import MAX_ORDER_K, SH_DEGREES, RenderSettings
from raygs_viewer.scene.model import sh_coefficient_count

Defines = tuple[tuple[str, object], ...]

#: Limits wide enough that only an extension decides: every window K fits the
#: attachments, and the per-pixel passes bind every splat block they may need.
WIDE_LIMITS = {"GL_MAX_DRAW_BUFFERS": MAX_ORDER_K + 1, "GL_MAX_COLOR_ATTACHMENTS": MAX_ORDER_K + 1,
               "GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS": 16, "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": 16,
               "GL_MAX_COMBINED_SHADER_STORAGE_BLOCKS": 48}
#: The GPUs planned for, each under every order path: the extension the planning asks
#: about (kbuffer.FRAMEBUFFER_FETCH) present (llvmpipe) and missing (NVIDIA's desktop drivers).
GPUS = tuple((GpuDescription(extensions, WIDE_LIMITS), order_path)
             for extensions in (frozenset({FRAMEBUFFER_FETCH}), frozenset()) for order_path in ORDER_PATHS)
DRAW_LAYOUTS = tuple(DrawLayout(vertices, records) for vertices in DRAW_VERTICES for records in RECORDS)
#: Real GPUs cap one storage block at 128 MiB (docs/architecture.md, "Storage limits").
BLOCK_LIMIT = 1 << 27
#: The passes a per-pixel path runs after the draw, each with the plan's pass_defines
#: (render/gl/fragment_lists.py, render/gl/kbuffer.py).
PATH_PASSES = {None: (), "lists": ("lists_scan.comp", "lists_prepare.comp", "lists_resolve.comp"),
               "fetch": ("kbuffer_resolve.comp",)}
#: The channels whose picture first gathers depth samples for an automatic range
#: (GeometryOutputs.picture, SAMPLES 1).
SAMPLED_PICTURES = ("depth", "median_depth")
STAGE_SUFFIXES = (".vert", ".frag", ".comp")


def _frozen(defines: Mapping[str, object] | None) -> Defines:
    return tuple(sorted((defines or {}).items()))


@dataclass(frozen=True, order=True)
class Unit:
    """One stage's source: ``glsl/<stage>`` with ``defines``, as shaders.shader_source makes it."""

    stage: str
    defines: Defines

    def source(self) -> str:
        return shader_source(self.stage, dict(self.defines))


@dataclass(frozen=True, order=True)
class Program:
    """A program as ``Programs`` builds it: its stage files and the defines they all get."""

    stages: tuple[str, ...]
    defines: Defines

    @classmethod
    def of(cls, stages: Iterable[str], defines: Mapping[str, object] | None = None) -> "Program":
        return cls(tuple(stages), _frozen(defines))

    def units(self) -> tuple[Unit, ...]:
        return tuple(Unit(stage, self.defines) for stage in self.stages)

    def describe(self) -> str:
        """As ``Programs`` names a variant in its compile errors."""
        variant = ", ".join(f"{key}={value}" for key, value in self.defines)
        return f"{' + '.join(self.stages)} ({variant or 'no defines'})"


def plan_programs(plan: RenderPlan) -> list[Program]:
    """The programs the passes build for ``plan`` (none where it has a problem: the
    renderer refuses it before building anything)."""
    if plan.problem:
        return []
    vertex, fragment, defines = plan.draw_stages()
    programs = [Program.of(("preprocess.comp",), plan.preprocess_defines(selection))
                for selection in (False, True)]
    programs += [Program.of((vertex, fragment), defines),
                *(Program.of((FULLSCREEN_VERTEX, "resolve.frag"), plan.resolve_defines(unorm8))
                  for unorm8 in (False, True))]
    if not plan.mode_gs:  # bench perf's floor pass
        vertex, fragment, defines = plan.draw_stages(floor=True)
        programs.append(Program.of((vertex, fragment), defines))
    programs += [Program.of((name,), plan.pass_defines()) for name in PATH_PASSES[plan.path]]
    return programs


def fixed_programs() -> list[Program]:
    """The passes whose defines are constants of their modules."""
    programs = [Program.of((FULLSCREEN_VERTEX, name))
                for name in ("present.frag", "lens.frag", "stereo_compose.frag", "xr_depth.frag")]
    programs += [Program.of((FULLSCREEN_VERTEX, "channel_picture.frag"), {"CHANNEL": channel, "SAMPLES": samples})
                 for name, channel in PICTURE_DEFINES.items()
                 for samples in ((0, 1) if name in SAMPLED_PICTURES else (0,))]
    programs += [Program.of((name,), SORT_DEFINES)
                 for name in ("sort_cull.comp", "sort_scan.comp", "sort_compact.comp", "sort_commands.comp")]
    radix = ("radix_setup.comp", "radix_count.comp", "radix_scan_blocks.comp", "radix_scan_top.comp",
             "radix_scatter.comp")
    programs += [Program.of((name,), RadixLayout(digit_bits=bits).defines()) for bits in (4, 8) for name in radix]
    return programs


# -- planning by reading ---------------------------------------------------------------

def field_values(row: SettingField) -> tuple:
    """The values a settings field is explored over: a switch both ways, a choice each
    choice, a whole number each value of a range of at most 64; anything else (a float,
    a colour, a budget) its default only. None too where that is the default."""
    default = defaults(RenderSettings)[row.name]
    info = row.info
    if row.hint is bool:
        return (False, True)
    values: tuple = ()
    if info.choices:
        values = tuple(info.choices)
    elif info.limits and all(float(limit).is_integer() for limit in info.limits) and row.hint in (int, int | None):
        low, high = (int(limit) for limit in info.limits)
        values = tuple(range(low, high + 1)) if high - low < 64 else ()
    if default not in values:
        values = (default,) + values
    return values


class _Watched(RenderSettings):
    """RenderSettings that note which fields are read, so exploring branches on those only."""

    reads: ClassVar[list[str]] = []
    fields: ClassVar[frozenset[str]] = frozenset(f.name for f in dataclasses.fields(RenderSettings))

    def __getattribute__(self, name: str):
        if name in _Watched.fields:
            _Watched.reads.append(name)
        return super().__getattribute__(name)


@dataclass(frozen=True, eq=False)
class _WatchedGpu:
    """A described GPU that notes being asked about (``gpu`` among the reads)."""

    description: GpuDescription

    @property
    def extensions(self) -> frozenset[str]:
        _Watched.reads.append("gpu")
        return self.description.extensions

    @property
    def info(self) -> Mapping[str, object]:
        _Watched.reads.append("gpu")
        return self.description.info


Evaluation = Callable[[Mapping[str, object]], tuple[list[str], object]]
Kind = Callable[[object], object]


def explore(axes: Mapping[str, tuple], evaluate: Evaluation, kind: Kind) -> Iterator[object]:
    """The result of every distinct way ``evaluate`` can run, up to ``kind``: it runs
    with the inputs fixed so far (the others at their first value) and returns what it
    read, in order, and its result. The search branches on the first input read and not
    yet fixed, over each of its ``axes`` values; a branch that reads what the first
    value's read and gives a result of the same kind only changes values, and is not
    searched further (its result is still yielded). The first value's branch runs
    exactly as its parent did, so it reuses the parent's run."""
    stack: list[tuple[dict[str, object], tuple[list[str], object] | None, object]] = [({}, None, None)]
    while stack:
        fixed, run, like = stack.pop()
        reads, result = run if run is not None else evaluate(fixed)
        free = next((name for name in reads if name not in fixed and len(axes.get(name, ())) > 1), None)
        if free is None or (like is not None and like == (reads, kind(result))):
            yield result
            continue
        first, *others = axes[free]
        same = (reads, kind(result))
        stack += [({**fixed, free: value}, None, same) for value in reversed(others)]
        stack.append(({**fixed, free: first}, (reads, result), None))


def blocks_layout(blocks: int) -> Callable[[int], StorageLayout]:
    """``layout_for`` of a scene whose records of any size fill ``blocks`` storage blocks."""
    harmonics = sh_coefficient_count(SH_DEGREES[-1]) * 12

    def layout_for(splat_bytes: int) -> StorageLayout:
        per_block = StorageLayout.plan(1, harmonics, BLOCK_LIMIT, splat_bytes=splat_bytes).splats_per_block
        return StorageLayout.plan((blocks - 1) * per_block + 1, harmonics, BLOCK_LIMIT, splat_bytes=splat_bytes)
    return layout_for


@dataclass(frozen=True)
class Inputs:
    """One planning's inputs: the settings, what the render draws, the GPU, the renderer's
    options and the scene (its storage blocks and stored SH degree)."""

    settings: RenderSettings
    _: KW_ONLY
    outputs: Outputs = OUTPUTS[0]
    gpu: tuple[GpuDescription, str] = GPUS[0]
    general: bool = False
    draw: DrawLayout = DRAW_LAYOUTS[0]
    blocks: int = 1
    sh_degree: int = SH_DEGREES[-1]

    def plan(self) -> RenderPlan:
        description, order_path = self.gpu
        layout_for = blocks_layout(self.blocks)
        planner = Planner(_WatchedGpu(description), layout_for, layout_for(SPLAT_BYTES).count, self.sh_degree,
                          general=self.general, order_path=order_path)
        return planner.plan(self.settings, self.outputs, self.draw)


_CONTEXT_AXES = {"outputs": OUTPUTS, "gpu": GPUS, "general": (False, True)}


@lru_cache(maxsize=None)
def _settings(fixed: tuple[tuple[str, object], ...]) -> RenderSettings | None:
    try:
        return _Watched(**dict(fixed))
    except UserError:  # a combination the settings refuse (per-pixel GS) is none to plan
        return None


def _evaluate(fixed: Mapping[str, object]) -> tuple[list[str], object]:
    settings = _settings(tuple(sorted((k, v) for k, v in fixed.items() if k not in _CONTEXT_AXES)))
    if settings is None:
        return [], None
    _Watched.reads = ["outputs", "general"]
    inputs = Inputs(settings, **{name: fixed[name] for name in _CONTEXT_AXES if name in fixed})
    programs = plan_programs(inputs.plan())
    return list(dict.fromkeys(_Watched.reads)), (inputs, programs)


def planned_inputs() -> Iterator[tuple[Inputs, list[Program]]]:
    """Every distinct planning of :func:`explore` over the settings, what is asked, the
    GPU and the general build, with its programs, up to plans whose programs only differ
    in literals (:func:`signature`)."""
    axes = {row.name: field_values(row) for row in settings_table(RenderSettings)} | _CONTEXT_AXES
    for result in explore(axes, _evaluate, lambda result: None if result is None else signature(result[1])):
        if result is not None:
            yield result


# -- what the package builds, and what to compile --------------------------------------------

_DIRECTIVE = re.compile(r"^\s*#\s*(if|ifdef|ifndef|elif|else|endif|define|undef)\b(.*)$")
_NAME = re.compile(r"\b[A-Za-z_]\w*\b")
_DEFINED = re.compile(r"\bdefined\s*(?:\(\s*(\w+)\s*\)|(\w+))")
_C_OPERATORS = (("||", " or "), ("&&", " and "), ("!=", " != "), ("!", " not "), ("/", "//"))


def _code(text: str) -> str:
    """A directive's text without its comment."""
    return text.split("//")[0].split("/*")[0].strip()


def _condition(expression: str, macros: Mapping[str, str]) -> bool:
    """A ``#if`` expression's value, as the GLSL preprocessor takes it (an undefined name is 0)."""
    names = tuple(dict.fromkeys(_NAME.findall(expression)))
    values = tuple(macros.get(name) for name in names)
    if any(value is not None and _NAME.search(value) for value in values):  # a macro naming macros
        return _evaluated(expression, macros)
    return _evaluated_once(expression, names, values)


@lru_cache(maxsize=None)
def _evaluated_once(expression: str, names: tuple[str, ...], values: tuple[str | None, ...]) -> bool:
    return _evaluated(expression, {name: value for name, value in zip(names, values) if value is not None})


def _evaluated(expression: str, macros: Mapping[str, str]) -> bool:
    text = _DEFINED.sub(lambda m: "1" if (m.group(1) or m.group(2)) in macros else "0", expression)
    for _ in range(16):  # macros that name macros
        expanded = _NAME.sub(lambda m: str(macros.get(m.group(0), "0")), text)
        if expanded == text:
            break
        text = expanded
    text = re.sub(r"\b(\d+)[uU]\b", r"\1", text)
    for c, python in _C_OPERATORS:
        text = text.replace(c, python) if c != "!" else re.sub(r"!(?!=)", python, text)
    return bool(eval(text, {"__builtins__": {}}))  # noqa: S307 - digits and operators only: names were replaced


@lru_cache(maxsize=None)
def _directives(stage: str) -> tuple[tuple[str, str], ...]:
    """The preprocessor directives of ``stage``'s source (its includes expanded), in order."""
    found = (_DIRECTIVE.match(line) for line in shader_source(stage).split("\n"))
    return tuple((match.group(1), _code(match.group(2))) for match in found if match)


@lru_cache(maxsize=None)
def branches(unit: Unit) -> tuple[bool, ...]:
    """The value of each condition the preprocessor evaluates in ``unit``'s source, in
    order: two sources of one stage with the same values keep the same code, only the
    defines' values in it differ."""
    macros = {key: str(value) for key, value in unit.defines}
    taken: list[bool] = []
    stack: list[tuple[bool, bool]] = []  # per open conditional: (enclosing active, a branch taken)
    active = True
    for kind, text in _directives(unit.stage):
        if kind in ("if", "ifdef", "ifndef"):
            value = False
            if active:
                name = text.split()[0] if kind != "if" else ""
                value = _condition(text, macros) if kind == "if" else (name in macros) == (kind == "ifdef")
                taken.append(value)
            stack.append((active, value))
            active = active and value
        elif kind in ("elif", "else"):
            enclosing, done = stack[-1]
            value = enclosing and not done and (kind == "else" or _condition(text, macros))
            if enclosing and not done and kind == "elif":
                taken.append(value)
            stack[-1] = (enclosing, done or value)
            active = value
        elif kind == "endif":
            active = stack.pop()[0]
        elif active and kind == "define":
            name, _, body = text.partition(" ")
            macros[name] = body.strip()
        elif active and kind == "undef":
            macros.pop(text.split()[0], None)
    return tuple(taken)


@lru_cache(maxsize=None)
def literal_kind(value: object) -> str:
    """What kind of GLSL token a define's value is: two values of one kind only change a
    literal, never what the code means."""
    text = str(value)
    if text in ("true", "false"):
        return "bool"
    if re.fullmatch(r"-?\d+", text):
        return "int"
    if re.fullmatch(r"\d+[uU]", text):
        return "uint"
    if re.fullmatch(r"-?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?", text):
        return "float"
    return text  # a name or an expression: only itself is like itself


@lru_cache(maxsize=None)
def compile_class(unit: Unit) -> tuple:
    """Units of one class take the same branches and differ only in literals of one kind."""
    return (unit.stage, branches(unit)) + tuple((key, literal_kind(value)) for key, value in unit.defines)


def signature(programs: Iterable[Program]) -> frozenset:
    """What kind of plan made ``programs``: the classes of all their stage sources."""
    return frozenset(compile_class(unit) for program in programs for unit in program.units())


@lru_cache(maxsize=1)
def all_programs() -> tuple[Program, ...]:
    """Every program the package can build, sorted."""
    programs: set[Program] = set(fixed_programs())
    kinds: dict[frozenset, Inputs] = {}
    for inputs, planned in planned_inputs():
        programs.update(planned)
        kinds.setdefault(signature(planned), inputs)
    for inputs in kinds.values():
        replanned = [dataclasses.replace(inputs, draw=draw, blocks=blocks)
                     for draw in DRAW_LAYOUTS for blocks in range(1, MAX_SPLAT_BLOCKS + 1)]
        replanned += [dataclasses.replace(inputs, sh_degree=degree) for degree in SH_DEGREES]
        for again in replanned:
            programs.update(plan_programs(again.plan()))
    return tuple(sorted(programs))


def compile_units(programs: Iterable[Program]) -> dict[Unit, list[Program]]:
    """The stage sources to compile, each with the programs it stands for: one of each
    :func:`compile_class`, and more until every (stage, define, value) is among them."""
    by_unit: dict[Unit, list[Program]] = {}
    for program in programs:
        for unit in program.units():
            by_unit.setdefault(unit, []).append(program)
    chosen: dict[Unit, list[Program]] = {}
    classes: set[tuple] = set()
    values: set[tuple] = set()
    for unit in sorted(by_unit):
        pairs = {(unit.stage, key, value) for key, value in unit.defines}
        key = compile_class(unit)
        if key not in classes or not pairs <= values:
            classes.add(key)
            values |= pairs
            chosen[unit] = by_unit[unit]
    return chosen


def stage_files() -> tuple[str, ...]:
    """The glsl/ files that are a stage of some program (not only included)."""
    return tuple(name for name in glsl_files() if name.endswith(STAGE_SUFFIXES))
