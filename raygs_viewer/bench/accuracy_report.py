"""``raygs-viewer bench accuracy``'s report and plot: the verdict's data-driven part
(per view class over the scenes: mean time ratio and PSNR gain, the Pareto front; with
``--photos``, each configuration over the photos' views), the markdown report (whose human verdict survives a rewrite) and the PNG plot of PSNR
against time ratio.
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from raygs_viewer.bench.accuracy import (
    BASELINE,
    CONFIGS,
    AccuracyResults,
    CaseResult,
    case_title,
    fmt_number,
)
from raygs_viewer.bench.common import fmt_error, write_plot, write_report
from raygs_viewer.bench.plot import Panel, Point, ScatterRow, scatter_png
from raygs_viewer.bench.views import (
    CLOSE_FRACTION,
    CLOSE_SUPPORT_MARGIN,
    FAR_DISTANCE_FACTOR,
    FAR_RESOLUTION_DIVISOR,
    VIEW_CLASSES,
    VIEW_TITLES,
)
from raygs_viewer.render.settings import DEFAULT_P_MIN

#: PSNR plotted where the error is exactly zero.
PSNR_CAP = 100.0
#: The verdict's comparisons count any PSNR above this as this: an RMS error of 1e-3 is a
#: quarter of an 8-bit step, and differences between invisible errors should not decide.
VERDICT_PSNR_CAP = 60.0
#: "Within this many dB of the best" in the verdict's summary.
VERDICT_TOLERANCE_DB = 0.5
#: PSNR gains closer than this count as equal for the Pareto front.
PARETO_TOLERANCE_DB = 0.1
#: A time ratio above this counts as slower than RayGS in the verdict (timings are noisy).
SLOWER = 1.1

HUMAN_VERDICT_BEGIN = "<!-- BEGIN HUMAN VERDICT (kept when the report is regenerated with --overwrite) -->"
HUMAN_VERDICT_END = "<!-- END HUMAN VERDICT -->"
HUMAN_VERDICT_PLACEHOLDER = "_Verdict to be written from the numbers below: which settings are worth their cost, " \
                            "for which views._"


# --- the verdict's data-driven part -----------------------------------------------------------

def _capped(value: float, cap: float = VERDICT_PSNR_CAP) -> float:
    return min(value, cap) if not math.isnan(value) else value


@dataclass
class ViewSummary:
    """One configuration in one view class, over all scenes."""
    config: str
    ratio: float         # geometric mean over scenes of the time ratio
    gain_db: float       # mean over scenes of PSNR - PSNR(BASELINE), PSNRs capped at VERDICT_PSNR_CAP
    worst_gain_db: float
    best_gain_db: float  # the best scene's
    raw_gain_db: float   # the same without the cap (breaks ties between capped gains)
    pareto: bool = False


def summarize(results: AccuracyResults, view: str) -> list[ViewSummary]:
    cases = [c for c in results.cases if c.view == view]
    if not cases:
        return []
    summaries = []
    for config in cases[0].rows:
        ratios = [c.rows[config].ratio for c in cases]
        gains = [_capped(c.rows[config].psnr) - _capped(c.rows[BASELINE].psnr) for c in cases]
        raw = [_capped(c.rows[config].psnr, PSNR_CAP) - _capped(c.rows[BASELINE].psnr, PSNR_CAP) for c in cases]
        good = [r for r in ratios if r > 0 and math.isfinite(r)]
        ratio = math.exp(sum(math.log(r) for r in good) / len(good)) if good else math.nan
        summaries.append(ViewSummary(config, ratio, float(np.mean(gains)), float(np.min(gains)), float(np.max(gains)),
                                     float(np.mean(raw))))
    for s in summaries:  # gains within PARETO_TOLERANCE_DB of each other count as equal
        s.pareto = not any(o is not s and ((o.ratio < s.ratio and o.gain_db >= s.gain_db - PARETO_TOLERANCE_DB)
                                           or (o.ratio <= s.ratio and o.gain_db > s.gain_db + PARETO_TOLERANCE_DB))
                           for o in summaries)
    return summaries


def verdict_lines(summaries: list[ViewSummary]) -> list[str]:
    """Facts for one view class: the best, the cheapest near it, the Pareto front, and
    what is slower than the baseline without being more accurate."""
    valid = [s for s in summaries if math.isfinite(s.gain_db) and math.isfinite(s.ratio)]
    if not valid:
        return ["no finite results"]
    best = max(valid, key=lambda s: (s.gain_db, s.raw_gain_db))
    near = [s for s in valid if s.gain_db >= best.gain_db - VERDICT_TOLERANCE_DB]
    cheapest = min(near, key=lambda s: s.ratio)

    def named(s: ViewSummary) -> str:
        return f"{s.config} ({s.gain_db:+.2f} dB, x{s.ratio:.2f} time)"

    lines = [f"most accurate: {named(best)}",
             f"cheapest within {VERDICT_TOLERANCE_DB:g} dB of it: {named(cheapest)}",
             f"Pareto front (no other configuration is faster and as accurate, within {PARETO_TOLERANCE_DB:g} dB): "
             + ", ".join(named(s) for s in sorted((s for s in valid if s.pareto), key=lambda s: s.ratio))]
    useless = [s.config for s in valid if s.config != BASELINE and s.ratio > SLOWER and s.best_gain_db <= 0.0]
    if useless:
        lines.append(f"over {SLOWER - 1:.0%} slower than RayGS and no more accurate in any scene: "
                     + ", ".join(useless))
    return lines


def case_notes(case: CaseResult) -> dict[str, str]:
    """Per row of one case: "best" (highest PSNR), "cheapest near best" (within
    VERDICT_TOLERANCE_DB of it, fastest), "baseline"."""
    rows = [r for r in case.rows.values() if not math.isnan(r.psnr)]
    notes = {BASELINE: "baseline"}
    if rows:
        best = max(rows, key=lambda r: (_capped(r.psnr), _capped(r.psnr, PSNR_CAP)))
        near = [r for r in rows if _capped(r.psnr) >= _capped(best.psnr) - VERDICT_TOLERANCE_DB]
        cheapest = min(near, key=lambda r: r.ratio if math.isfinite(r.ratio) else math.inf)
        for row, note in ((cheapest, "cheapest near best"), (best, "best")):
            notes[row.config] = ", ".join(n for n in (notes.get(row.config), note) if n)
    return notes


@dataclass
class PhotoSummary:
    """One configuration over the ``--photos`` views: time ratio (geometric mean), and
    means of PSNR against the float64 truth, PSNR and SSIM against the photos, and the
    photo PSNR's gain over BASELINE."""
    config: str
    ratio: float
    psnr: float
    photo_psnr: float
    photo_ssim: float
    photo_gain_db: float


def summarize_photos(results: AccuracyResults) -> list[PhotoSummary]:
    cases = [c for c in results.cases if c.photo]
    if not cases:
        return []
    summaries = []
    for config in cases[0].rows:
        rows = [c.rows[config] for c in cases]
        good = [r.ratio for r in rows if r.ratio > 0 and math.isfinite(r.ratio)]
        ratio = math.exp(sum(math.log(r) for r in good) / len(good)) if good else math.nan
        gains = [c.rows[config].photo_psnr - c.rows[BASELINE].photo_psnr for c in cases]
        summaries.append(PhotoSummary(config, ratio, float(np.mean([_capped(r.psnr, PSNR_CAP) for r in rows])),
                                      float(np.mean([r.photo_psnr for r in rows])),
                                      float(np.mean([r.photo_ssim for r in rows])), float(np.mean(gains))))
    return summaries


def photo_summary_lines(results: AccuracyResults) -> list[str]:
    """The report's table of the configurations against the photos (none without them)."""
    summaries = summarize_photos(results)
    if not summaries:
        return []
    lines = ["#### Against the photos", "",
             f"Over the {sum(1 for c in results.cases if c.photo)} test view(s) of the photos: time ratio as a "
             f"geometric mean, the rest as means (PSNR against the float64 truth capped at {PSNR_CAP:g} dB).", "",
             "| configuration | time ratio | PSNR truth (dB) | PSNR photos (dB) | SSIM photos | photo PSNR gain (dB) |",
             "|---|---:|---:|---:|---:|---:|"]
    for s in summaries:
        lines.append(f"| {s.config} | {fmt_number(s.ratio)} | {fmt_number(s.psnr)} | {fmt_number(s.photo_psnr)} | "
                     f"{fmt_number(s.photo_ssim, 4)} | {s.photo_gain_db:+.2f} |")
    return lines + [""]


def _case_table(case: CaseResult) -> list[str]:
    notes = case_notes(case)
    photo_head, photo_rule = (" PSNR photo (dB) | SSIM photo |", "---:|---:|") if case.photo else ("", "")
    lines = [f"| configuration | GPU ms | ratio to RayGS | PSNR (dB) | p99 error | max error |{photo_head} note |",
             f"|---|---:|---:|---:|---:|---:|{photo_rule}---|"]
    for row in case.rows.values():
        photo = f" {fmt_number(row.photo_psnr)} | {fmt_number(row.photo_ssim, 4)} |" if case.photo else ""
        lines.append(f"| {row.config} | {fmt_number(row.gpu_ms)} | {fmt_number(row.ratio)} | "
                     f"{fmt_number(row.psnr)} | {fmt_error(row.p99)} | {fmt_error(row.max_error)} |{photo} "
                     f"{notes.get(row.config, '')} |")
    return lines


# --- the report and the plot ---------------------------------------------------------------------

def _existing_human_verdict(path: Path) -> str | None:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    start, end = text.find(HUMAN_VERDICT_BEGIN), text.find(HUMAN_VERDICT_END)
    if start < 0 or end < start:
        return None
    kept = text[start + len(HUMAN_VERDICT_BEGIN):end].strip()
    return kept if kept and kept != HUMAN_VERDICT_PLACEHOLDER else None


def _p_min_text(p_min: float) -> str:
    return "1/255" if p_min == DEFAULT_P_MIN else f"{p_min:g}"


def format_report(results: AccuracyResults, plot_link: str | None, human_verdict: str | None = None) -> str:
    """The markdown report."""
    configs = list(results.cases[0].rows) if results.cases else list(CONFIGS)
    lines = [
        "# Accuracy against time",
        "",
        "What each accuracy option of the renderer costs in GPU time and what it buys in error against "
        "ground truth, per kind of view. Generated by `raygs-viewer bench accuracy`; the tables, the plot and "
        "the data-driven verdict are rewritten on every run, the human verdict is kept.",
        "",
        f"- Command: `{results.command_line}`",
        f"- Date: {results.date}",
        f"- Machine: {results.gl_renderer}, {results.cpu_count} CPU cores",
        f"- Timing: GPU time of one frame (preprocessing pass and draw, `GLRenderer.render_into`) from an "
        f"OpenGL timer query, median of {results.repeat} frames, configurations interleaved round-robin; "
        f"the ratio is to plain RayGS in the same scene and view, in the same run.",
        "- Error: RGB over black against `reference.ground_truth` (exact RayGS, "
        f"p_min {_p_min_text(results.gt_p_min)}, every ray composited in its own order (per-pixel, by t*), "
        "integrated over each pixel's area with n x n samples), linear float, unclipped; PSNR = 10 log10(1/MSE); "
        "p99 and max of the absolute error over all RGB values.",
        f"- Views, from each scene's training-like camera at {results.width} px wide: *training-like*; "
        f"*far*: pulled back along the optical axis to {FAR_DISTANCE_FACTOR:g}x its distance from the scene's "
        f"centre (median of the centres), at 1/{FAR_RESOLUTION_DIVISOR} of the resolution; *close*: moved "
        f"forward to {CLOSE_FRACTION:.0%} of its distance to the gaussians at the image centre, backing off "
        f"while that would be inside a gaussian's support (c^2 <= {CLOSE_SUPPORT_MARGIN:g} kappa).",
        "- Configurations (`settings.ACCURACY_PRESETS` over p_min 1/255, black background): "
        + ", ".join(configs) + ".",
        "",
        "Scenes:",
        "",
    ]
    lines += [f"- **{name}**: {description}" for name, description in results.scenes]
    if results.photos:
        lines += ["", f"Photos (`--photos`), a second truth: {results.photos}. Each configuration over the "
                  "dataset's background at its test views (every 8th), scaled to the width above, against the "
                  "photo resized to it: PSNR and SSIM as the 3DGS training code reports them (11-pixel gaussian "
                  "window, sigma 1.5, zero padding, the mean over pixels and channels) of the render clipped "
                  "to 0..1; the float64 truth's columns beside them."]
    notes = list(results.notes)
    if results.gt_p_min == DEFAULT_P_MIN:
        notes.append("The ground truth has the baseline's cut-off p_min 1/255, so the rows that change p_min show "
                     "their difference from that cut-off, not from the image without one (see --gt-p-min).")
    if notes:
        lines += ["", "Notes:", ""] + [f"- {note}" for note in notes]
    lines += ["", "## Verdict", "", HUMAN_VERDICT_BEGIN, human_verdict or HUMAN_VERDICT_PLACEHOLDER,
              HUMAN_VERDICT_END, ""]
    lines += ["### From the numbers (generated)", "",
              f"Per view class, over all scenes: time ratio as a geometric mean, PSNR gain over RayGS as a mean "
              f"(and the worst scene's). A PSNR above {VERDICT_PSNR_CAP:g} dB counts as {VERDICT_PSNR_CAP:g} dB here "
              f"and in the notes of the tables below (an RMS error of 1e-3 is a quarter of an 8-bit step: "
              f"differences between invisible errors do not decide).", ""]
    if plot_link:
        lines += [f"![PSNR against GPU time ratio to RayGS, per view class]({plot_link})", ""]
    for view in VIEW_CLASSES:
        summaries = summarize(results, view)
        if not summaries:
            continue
        lines += [f"#### {VIEW_TITLES[view]}", ""]
        lines += [f"- {line}" for line in verdict_lines(summaries)]
        lines += ["", "| configuration | time ratio | PSNR gain (dB) | worst scene (dB) | Pareto |",
                  "|---|---:|---:|---:|:---:|"]
        for s in summaries:
            lines.append(f"| {s.config} | {fmt_number(s.ratio)} | {s.gain_db:+.2f} | {s.worst_gain_db:+.2f} | "
                         f"{'yes' if s.pareto else ''} |")
        lines.append("")
    lines += photo_summary_lines(results)
    lines += ["## Results per scene and view", ""]
    for case in results.cases:
        lines += [f"### {case.scene}: {case_title(case)}", "",
                  f"{case.width}x{case.height} px; ground truth {case.gt_samples}x{case.gt_samples} samples "
                  f"per pixel ({case.gt_seconds:.1f} s).", ""]
        lines += _case_table(case) + [""]
    return "\n".join(lines)


def draw_plot(results: AccuracyResults) -> bytes:
    """A PNG: one panel per view class, PSNR against time ratio to RayGS (log x), a colour
    and marker per configuration and a fill per scene; below, the same per view class
    averaged over the scenes (PSNR gain over RayGS, as in the verdict's tables)."""
    configs = list(results.cases[0].rows) if results.cases else list(CONFIGS)
    scene_names = list(dict.fromkeys(case.scene for case in results.cases if not case.photo))
    x_label = "GPU time / RayGS time (log scale)"
    panels = []
    for view in VIEW_CLASSES:
        points = [Point(row.ratio, _capped(row.psnr, PSNR_CAP), row.config, f"scene: {case.scene}")
                  for case in results.cases if case.view == view for row in case.rows.values()]
        panels.append(Panel(VIEW_TITLES[view], points, guides_x=(1.0,)))
    per_scene = ScatterRow("Error against GPU time, per view class and scene", panels, x_label,
                           "PSNR against ground truth (dB)", configs, [f"scene: {s}" for s in scene_names])
    # The verdict's view: one marker per configuration, averaged over the scenes.
    panels = [Panel(VIEW_TITLES[view], [Point(s.ratio, s.gain_db, s.config) for s in summarize(results, view)],
                    guides_x=(1.0,)) for view in VIEW_CLASSES]
    mean = ScatterRow(f"Mean over scenes (time: geometric mean; PSNR capped at {VERDICT_PSNR_CAP:g} dB before "
                      f"averaging)", panels, x_label, "PSNR gain over RayGS (dB)", configs)
    return scatter_png([per_scene, mean])


def write_outputs(results: AccuracyResults, report: Path | None, plot: Path | None, overwrite: bool) -> str:
    """Writes the plot and the report that were asked for (None: not), each atomically
    (a temporary file moved into place); the report's text, which the command prints.
    A report replaced with ``overwrite`` keeps its human verdict."""
    human = _existing_human_verdict(report) if overwrite and report is not None else None
    link = None
    if plot is not None:
        start = os.path.dirname(os.path.abspath(report if report is not None else plot))
        link = os.path.relpath(os.path.abspath(plot), start).replace(os.sep, "/")
        write_plot(plot, draw_plot(results), overwrite)
    text = format_report(results, link, human)
    if report is not None:
        write_report(report, text, overwrite)
    if human:
        print(f"note: kept the human verdict of the existing {report}; check it against the new numbers",
              file=sys.stderr)
    return text
