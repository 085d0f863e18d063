"""``doctor``'s correctness rows: the built-in demo and every hard case of
:mod:`raygs_viewer.bench.hard_cases`, rendered small with GL in each setting this GL can
draw and compared with the float64 reference at the tolerances the tests use
(:mod:`raygs_viewer.render.tolerance`).

Not the cross product: each axis is varied from one base (RayGS, float32 blend, depth
order, instanced quads with records at scene index, the CPU sort), as the tests vary
them (:data:`VARIANTS`):

- mode: RayGS + MIP, exact MIP, GS (``hard_cases.MODES``);
- precision: float16, 8-bit (against the float32 reference, both clipped to 0..1);
- order: distance, per-pixel exact (fragment lists), per-pixel K=4 through the fragment
  lists and through the k-buffer (framebuffer fetch);
- draw layout: every other ``DrawLayout`` (vertices x records);
- sort: the GPU sort's order drawn.

A setting this GL cannot draw (``GLRenderer.supports``, ``GpuSorter.problem``) is a row
"not supported here: <why>", never a failure. ``quick`` varies every axis for the demo
and only the mode for the hard cases.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, replace
from typing import Callable, Iterator

import numpy as np

from raygs_viewer.bench.hard_cases import HARD_CASES, MODES, HardCase, as_gl_decided
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.gl.plan import DEFAULT_DRAW_LAYOUT, DRAW_VERTICES, RECORDS, DrawLayout
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import PRECISION_LABELS, PRECISIONS, RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.render.tolerance import AMBIGUOUS_P999, BLENDS, MATCH, PER_RAY, Agreement, Tolerance, agreement
from raygs_viewer.scene.demo import demo_camera, demo_scene
from raygs_viewer.sort.depth import DepthSorter

DEMO = "demo"
#: The demo's size here: the float64 reference takes about 0.3 s a setting at it.
DEMO_SIZE = (64, 48)
#: How much of an error's message a failed row keeps (a compile log follows the defines).
ERROR_CHARACTERS = 1000
#: The bounded per-pixel order's window in the order rows.
WINDOW = 4
BASE = "base"
#: The axes the quick run varies for the hard cases (the demo: all of them).
QUICK_HARD_AXES = (BASE, "mode")
#: Cases a narrow blend's bound does not cover, and why: it holds for the layers the test
#: scenes blend a pixel, and its rounding adds up with every layer.
UNBOUNDED_BLENDS = {"coincident": "no bound: 2,000 layers a pixel, where a narrow blend's rounding adds up past "
                                  "the bound stated for the test scenes"}


@dataclass(frozen=True)
class Variant:
    """One setting a case is drawn in: the ``axis`` it varies from the base and its
    ``name`` there, the render settings, the draw layout, the per-pixel path the
    renderer is made with, and the sort ("cpu" or "gpu")."""

    axis: str
    name: str
    settings: RenderSettings = RenderSettings()
    layout: DrawLayout = DEFAULT_DRAW_LAYOUT
    order_path: str = "auto"
    sort: str = "cpu"

    @property
    def label(self) -> str:
        return self.name if self.axis == BASE else f"{self.axis} {self.name}"

    @property
    def reference_settings(self) -> RenderSettings:
        """What the reference renders: the same settings blended in float64."""
        return replace(self.settings, precision="float32")


def _variants() -> tuple[Variant, ...]:
    per_pixel = RenderSettings(order="per-pixel")
    windowed = replace(per_pixel, order_k=WINDOW)
    variants = [Variant(BASE, "RayGS, float32 blend, depth order, instanced quads, CPU sort")]
    variants += [Variant("mode", name, settings) for name, settings in MODES.items() if name != "RayGS"]
    variants += [Variant("precision", PRECISION_LABELS[p], RenderSettings(precision=p)) for p in PRECISIONS[1:]]
    variants += [Variant("order", "distance", RenderSettings(order="distance")),
                 Variant("order", "per-pixel exact (fragment lists)", per_pixel, order_path="lists"),
                 Variant("order", f"per-pixel K={WINDOW} (fragment lists)", windowed, order_path="lists"),
                 Variant("order", f"per-pixel K={WINDOW} (k-buffer, framebuffer fetch)", windowed, order_path="fetch")]
    layouts = [DrawLayout(vertices, records) for records in RECORDS for vertices in DRAW_VERTICES]
    variants += [Variant("draw layout", layout.name, layout=layout) for layout in layouts
                 if layout != DEFAULT_DRAW_LAYOUT]
    variants.append(Variant("sort", "GPU", sort="gpu"))
    return tuple(variants)


#: Every setting of a case, the base first.
VARIANTS = _variants()


def tolerance(case: HardCase, variant: Variant) -> Tolerance:
    """The tolerance the tests hold ``variant`` of ``case`` to: a narrow blend's bound,
    the per-pixel order's allowance for near-ties of t*, else the case's own bound."""
    if variant.settings.precision != "float32":
        return BLENDS[variant.settings.precision]
    base = PER_RAY if variant.settings.per_pixel else replace(MATCH, max_error=case.bound)
    return replace(base, p999=AMBIGUOUS_P999) if case.ambiguous else base


@dataclass(frozen=True, kw_only=True)
class CorrectnessRow:
    """What doctor's summary asks of every correctness row, a check's or a sort's:
    ``problem``, why this GL cannot run it (no failure); ``faults``, how it failed (none:
    it passed); ``label``, its name. Keyword-only, so that each row's own fields keep
    their places."""

    problem: str | None = None
    faults: tuple[str, ...] = ()

    @property
    def supported(self) -> bool:
        return self.problem is None

    @property
    def judged(self) -> bool:
        """Held to its test: whenever this GL can run it, unless a row says otherwise."""
        return self.supported

    @property
    def failed(self) -> bool:
        return bool(self.faults)

    @property
    def label(self) -> str:
        raise NotImplementedError


@dataclass(frozen=True)
class CheckRow(CorrectnessRow):
    """One correctness row: ``problem`` says why this GL cannot draw it, ``unbounded``
    why no tolerance holds for it (either way it is no failure); else ``agreement`` and,
    in ``faults``, what of the tolerance it failed (none: it passed)."""

    case: str
    variant: Variant
    tolerance: Tolerance | None = None
    agreement: Agreement | None = None
    unbounded: str | None = None

    @property
    def judged(self) -> bool:
        """Held to a tolerance: supported here, and one holds for it."""
        return self.supported and self.unbounded is None

    @property
    def label(self) -> str:
        return f"{self.case}, {self.variant.label}"


def demo_case() -> HardCase:
    """The built-in demo as a case: its default view at :data:`DEMO_SIZE`, the usual bound."""
    return HardCase(DEMO, demo_scene(), demo_camera(*DEMO_SIZE), "", "", MATCH.max_error)


def check_cases(names: tuple[str, ...] | None = None) -> list[tuple[str, Callable[[], HardCase]]]:
    """(name, factory) of the demo and every hard case (``names``: only those, in this order)."""
    every = {DEMO: demo_case, **HARD_CASES}
    if names is None:
        return list(every.items())
    unknown = [name for name in names if name not in every]
    if unknown:
        raise UserError(f"unknown case '{unknown[0]}': use one of {', '.join(every)}")
    return [(name, every[name]) for name in names]


class _CaseRender:
    """What one case's rows share: a renderer per per-pixel path, the CPU sorter, the
    references made so far (by the settings and GL's decisions where they matter)."""

    def __init__(self, ctx, case: HardCase):
        self.ctx, self.case = ctx, case
        self.renderers: dict[str, GLRenderer] = {}
        self.sorter = DepthSorter(case.scene)
        self.references: dict[tuple, np.ndarray] = {}

    def renderer(self, order_path: str) -> GLRenderer:
        if order_path not in self.renderers:
            self.renderers[order_path] = GLRenderer(self.ctx, self.case.scene, order_path=order_path)
        return self.renderers[order_path]

    def row(self, name: str, variant: Variant) -> CheckRow:
        case, camera, settings = self.case, self.case.camera, variant.settings
        renderer = self.renderer(variant.order_path)
        problem = renderer.supports(settings)
        if problem is None and variant.sort == "gpu":
            problem = GpuSorter.problem(self.ctx)
        if problem is not None:
            return CheckRow(name, variant, problem=problem)
        with self._sorter(variant.sort) as sorter:
            image = renderer.render(camera, settings, exact_order(sorter, camera, settings),
                                    draw_layout=variant.layout)
        limit = tolerance(case, variant)
        measured = agreement(image, self.reference(renderer, variant), limit.clipped)
        if settings.precision != "float32" and name in UNBOUNDED_BLENDS:
            return CheckRow(name, variant, None, measured, unbounded=UNBOUNDED_BLENDS[name])
        return CheckRow(name, variant, limit, measured, faults=tuple(measured.failures(limit)))

    @contextlib.contextmanager
    def _sorter(self, sort: str) -> Iterator:
        if sort == "cpu":
            yield self.sorter
            return
        with GpuSorter(self.ctx, self.case.scene) as gpu:
            yield gpu

    def reference(self, renderer: GLRenderer, variant: Variant) -> np.ndarray:
        """The float64 image of the variant's settings; of the scene as GL decided it
        where the case is ambiguous (``hard_cases.as_gl_decided``)."""
        settings = variant.reference_settings
        drawn = self._decided(renderer, settings)
        key = (settings, None if drawn is None else drawn.tobytes())
        if key not in self.references:
            scene = self.case.scene if drawn is None else as_gl_decided(self.case, drawn)
            self.references[key] = render_reference(scene, self.case.camera, settings)
        return self.references[key]

    def _decided(self, renderer: GLRenderer, settings: RenderSettings) -> np.ndarray | None:
        """(N,) bool, which gaussians GL drew, where the case is ambiguous (else None):
        from records at scene index (a record's c^2, its fourth float, is 0 when skipped)."""
        if not self.case.ambiguous:
            return None
        if settings.mode == "gs":
            return np.ones(self.case.scene.count, bool)
        renderer.preprocess(self.case.camera, renderer.plan(settings))
        return renderer.read_splats()[:, 3] != 0

    def close(self) -> None:
        self.sorter.close()
        for renderer in self.renderers.values():
            renderer.release()


def error_words(exc: Exception) -> str:
    """An error as a failed row says it: its type and its message on one line, cut."""
    return f"{type(exc).__name__}: {one_line(exc, ERROR_CHARACTERS)}"


def guarded_row(render: _CaseRender, name: str, variant: Variant) -> CheckRow:
    """``render.row``, where a UserError (a scene this GL's memory cannot hold) is a row
    this GL does not support, and any other error (a shader this driver does not
    compile, a GL error) a failed row: what doctor is run to find, not a reason to stop."""
    try:
        return render.row(name, variant)
    except UserError as exc:
        return CheckRow(name, variant, problem=one_line(exc))
    except Exception as exc:  # noqa: BLE001 - every other failure becomes the row's one line
        return CheckRow(name, variant, faults=(error_words(exc),))


def check_renders(ctx, cases: list[tuple[str, Callable[[], HardCase]]], axes_of: Callable[[str], tuple[str, ...]],
                  say: Callable[[str], None]) -> list[CheckRow]:
    """Every case's rows, of the axes ``axes_of(case name)`` varies; a line per case."""
    rows = []
    for name, factory in cases:
        case = factory()
        render = _CaseRender(ctx, case)
        try:
            done = [guarded_row(render, name, variant) for variant in VARIANTS if variant.axis in axes_of(name)]
        finally:
            render.close()
        rows += done
        failed = sum(row.failed for row in done)
        say(f"correct: {name}: {len(done)} rows" + (f", {failed} FAILED" if failed else ", all passed"))
    return rows
