"""``raygs-viewer doctor`` (raygs_viewer.bench.doctor*): the settings each case is drawn in
and the tolerances they are held to (the tests' own), the GL tables, and the negative
controls: a renderer path and the GPU sort broken on purpose fail their rows, and the
command exits 1 with one line naming them; a setting this GL cannot draw leaves its
option out of the speed rows, and the narrow blends of a case past their bound are
reported, not failed."""

from __future__ import annotations

import io
from dataclasses import fields

import pytest
from testkit import patched_glsl

from raygs_viewer.bench import doctor_sort
from raygs_viewer.bench.doctor import AXES, DoctorOptions, doctor_options, format_report, run_doctor, summary_line
from raygs_viewer.bench.doctor_checks import BASE, UNBOUNDED_BLENDS, VARIANTS, check_cases, demo_case, tolerance
from raygs_viewer.bench.doctor_gl import driver_of, gl_rows, limit_rows
from raygs_viewer.bench.doctor_speed import SpeedSizes
from raygs_viewer.bench.hard_cases import HARD_CASES
from raygs_viewer.cli.doctor import command_doctor
from raygs_viewer.cli.main import build_parser
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.plan import DRAW_VERTICES, RECORDS, DrawLayout
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import PRECISIONS
from raygs_viewer.render.tolerance import AMBIGUOUS_P999, BLENDS, MATCH, PER_RAY

#: A small run of the demo alone: the base and every draw layout, nothing else.
LAYOUTS_ONLY = {"cases": ("demo",), "demo_axes": (BASE, "draw layout"), "sort_count": 0, "speed": None,
                "auto": False}
#: Speed rows far smaller than --quick's: one frame of a 2k scene at 64x36, no sorts timed.
TINY_SPEED = SpeedSizes(2_000, (64, 36), 16, 1, 1, (), 1)


def test_each_variant_changes_one_axis_of_the_base():
    base = VARIANTS[0]
    assert base.axis == BASE and AXES == (BASE, "mode", "precision", "order", "draw layout", "sort")
    for variant in VARIANTS[1:]:
        changed = {name for name in ("layout", "sort") if getattr(variant, name) != getattr(base, name)}
        changed |= {f.name for f in fields(variant.settings)
                    if getattr(variant.settings, f.name) != getattr(base.settings, f.name)}
        assert changed, variant
        assert changed <= {"mode": {"mode", "mip"}, "precision": {"precision"}, "order": {"order", "order_k"},
                           "draw layout": {"layout"}, "sort": {"sort"}}[variant.axis], variant
    assert {v.layout for v in VARIANTS} == {DrawLayout(v, r) for v in DRAW_VERTICES for r in RECORDS}
    assert {v.settings.precision for v in VARIANTS} == set(PRECISIONS)
    assert {v.order_path for v in VARIANTS if v.settings.per_pixel} == {"lists", "fetch"}


def test_rows_are_held_to_the_tests_tolerances():
    demo, ambiguous = demo_case(), HARD_CASES["c2-above-kappa-1e-9"]()
    by_axis = {variant.label: variant for variant in VARIANTS}
    assert tolerance(demo, VARIANTS[0]) == MATCH
    assert tolerance(demo, by_axis["precision 8-bit"]) == BLENDS["8bit"] and BLENDS["8bit"].clipped
    assert tolerance(demo, by_axis["order per-pixel exact (fragment lists)"]) == PER_RAY
    assert tolerance(HARD_CASES["grazing"](), VARIANTS[0]).max_error == HARD_CASES["grazing"]().bound
    assert tolerance(ambiguous, VARIANTS[0]).p999 == AMBIGUOUS_P999
    assert [name for name, _ in check_cases()] == ["demo", *HARD_CASES]
    with pytest.raises(UserError, match="unknown case 'nope'"):
        check_cases(("demo", "nope"))


def test_the_gl_tables_name_the_gl_and_each_fallback(gl_ctx):
    rows = dict(gl_rows(gl_ctx))
    assert rows["renderer"] == gl_ctx.info["GL_RENDERER"]
    assert rows["context"] in ("headless EGL", "headless OSMesa")
    assert driver_of("4.5 (Core Profile) Mesa 22.3.6") == "Mesa 22.3.6"
    assert driver_of("4.6.0 NVIDIA 580.159.04") == "NVIDIA 580.159.04"
    limits = {limit.what: limit for limit in limit_rows(gl_ctx)}
    assert "GL_EXT_shader_framebuffer_fetch" in limits and "GPU memory for buffers" in limits
    assert all(limit.fallback for limit in limits.values())


def test_quick_and_full_options():
    quick, full = doctor_options(True), doctor_options(False)
    assert quick.sort_count == doctor_sort.QUICK_SORT_COUNT and full.sort_count == doctor_sort.SORT_COUNT
    assert quick.demo_axes == full.demo_axes == full.hard_axes == AXES and quick.hard_axes == (BASE, "mode")
    assert quick.speed.count < full.speed.count == 1_000_000 and full.speed.mono == (1920, 1080)
    assert doctor_options(True, speed=None).speed is None and isinstance(quick, DoctorOptions)


def run_layouts(capsys, gl_ctx) -> tuple[int, str, str]:
    code = command_doctor(build_parser().parse_args(["doctor"]), gl_ctx, **LAYOUTS_ONLY)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_broken_draw_layout_fails_its_rows_and_doctor_exits_1_naming_them(capsys, gl_ctx, monkeypatch):
    """The negative control: the indexed draw's corners taken one vertex late."""
    code, out, err = run_layouts(capsys, gl_ctx)
    assert code == 0 and err == "", err
    assert out.rstrip().endswith("doctor: all 6 correctness rows passed")
    patched_glsl(monkeypatch, "splat_blocks.glsl", "int corner = gl_VertexID & 3;",
                 "int corner = (gl_VertexID + 1) & 3;")
    code, out, err = run_layouts(capsys, gl_ctx)
    assert code == 1
    assert err.count("\n") == 1 and err.startswith("doctor: 2 of 6 correctness rows failed: "), err
    assert "demo, draw layout indexed (max error " in err and "demo, draw layout indexed, draw-order records" in err
    assert "triangles" not in err and "instanced" not in err
    assert out.rstrip().endswith(err.rstrip())
    assert "| demo | draw layout indexed | " in out and "| **FAIL**: max error" in out


def test_a_broken_gpu_sort_fails_its_row(gl_ctx, monkeypatch):
    """The negative control: -0.0 and +0.0 depths as two keys (numpy's are one)."""
    patched_glsl(monkeypatch, "sort_compact.comp", "if ((bits & 0x7FFFFFFFu) == 0u) bits = 0u;", "")
    options = DoctorOptions(cases=(), sort_count=20_000, sort_scenes=("negative zero", "random"), speed=None,
                            auto=False)
    result = run_doctor(options, gl_ctx, out=io.StringIO())
    failed = [(row.scene, row.method) for row in result.failed]
    assert failed == [("negative zero", "float")], failed
    assert result.status == 1
    assert summary_line(result).startswith("doctor: 1 of 4 correctness rows failed: sort negative zero 20k, float "
                                           "keys (depth: ")


def test_a_shader_the_driver_cannot_compile_fails_its_rows_and_the_run_goes_on(gl_ctx, monkeypatch):
    patched_glsl(monkeypatch, "splat_blocks.glsl", "return uint(gl_VertexID) / 6u;", "return no_such_name;")
    result = run_doctor(DoctorOptions(**LAYOUTS_ONLY), gl_ctx, out=io.StringIO())
    assert [row.variant.name for row in result.failed] == ["triangles", "triangles, draw-order records"]
    assert all("no_such_name" in row.faults[0] and "\n" not in row.faults[0] for row in result.failed)
    assert len(result.judged) == 6 and result.status == 1


def test_every_hard_case_passes_its_quick_rows_here(gl_ctx):
    """What `doctor --quick` checks of the hard cases (the CLI's own run names two of
    them): each case's rows in the render modes, held to its tolerance, and passing."""
    options = DoctorOptions(cases=tuple(HARD_CASES), demo_axes=(), hard_axes=doctor_options(True).hard_axes,
                            sort_count=0, speed=None, auto=False)
    result = run_doctor(options, gl_ctx, out=io.StringIO())
    assert {row.case for row in result.checks} == set(HARD_CASES)
    assert len(result.judged) >= 2 * len(HARD_CASES) and result.status == 0, summary_line(result)


def test_an_option_this_gl_cannot_draw_is_left_out_of_the_speed_rows_as_unsupported(gl_ctx, monkeypatch):
    """A renderer that refuses float16 blending (as a GL without blendable float16
    targets would): its rows are "not supported here", no failure, and the options that
    blend in float16 are not timed but named as unsupported, while 8-bit is timed."""
    refusal = "no blendable float16 target on this GL (the test's)"
    supports = GLRenderer.supports
    monkeypatch.setattr(GLRenderer, "supports", lambda renderer, settings: refusal
                        if settings.precision == "float16" else supports(renderer, settings))
    options = DoctorOptions(cases=("demo",), demo_axes=(BASE, "precision"), sort_count=0, speed=TINY_SPEED,
                            auto=False)
    result = run_doctor(options, gl_ctx, out=io.StringIO())
    assert result.status == 0 and len(result.judged) == 2, summary_line(result)
    assert [row.problem for row in result.checks if not row.supported] == [refusal]
    float16 = ("float16 blend", "float16, indexed, draw-order records")
    assert result.speed.left_out == {name: f"not supported here: {refusal}" for name in float16}
    for case in result.speed.cases:
        assert not set(float16) & set(case.frame_ms), case.view
    assert "8-bit blend" in result.speed.cases[0].frame_ms
    assert f"| float16 blend |  |  | not measured: not supported here: {refusal} |" in format_report(result)


def test_the_narrow_blends_of_a_case_past_their_bound_are_reported_not_failed(gl_ctx):
    """The cases of UNBOUNDED_BLENDS (2,000 layers a pixel) exceed a narrow blend's bound
    here: their float16 and 8-bit rows say why no bound holds and are not held to one,
    while their float32 row is."""
    options = DoctorOptions(cases=tuple(UNBOUNDED_BLENDS), demo_axes=(), hard_axes=(BASE, "precision"),
                            sort_count=0, speed=None, auto=False)
    result = run_doctor(options, gl_ctx, out=io.StringIO())
    narrow = [row for row in result.checks if row.variant.axis == "precision"]
    assert len(narrow) == 2 * len(UNBOUNDED_BLENDS) and result.status == 0, summary_line(result)
    assert all(row.unbounded == UNBOUNDED_BLENDS[row.case] and not row.judged and not row.failed for row in narrow)
    assert any(row.agreement.failures(BLENDS[row.variant.settings.precision]) for row in narrow)
    assert [row.variant.axis for row in result.judged] == [BASE] * len(UNBOUNDED_BLENDS)
    report = format_report(result)
    assert all(f"| {UNBOUNDED_BLENDS[row.case]} |" in report for row in narrow)
