"""An evaluation's report (docs/evaluation.md): JSON, CSV or Markdown by the file's
suffix, and a contact sheet of the worst views (photo | render | error heat map) as a
PNG beside it. Every file is written atomically and never over an existing one unless
``overwrite``.

The JSON: ``{"views": [{"name", "psnr", "ssim", "flip", "lpips"}, ...], "mean": {...},
"skipped": [{"name", "reason"}], "settings": {...}, "ssim_kind": ..., ...}``; a PSNR of
null is an infinite one (a render identical to its photo), an LPIPS of null one not
computed (``lpips_note`` says why).
"""

from __future__ import annotations

import csv
import dataclasses
import io
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from raygs_viewer.capture.image_io import check_output_path, encode_png, to_rgb8
from raygs_viewer.files import write_atomically
from raygs_viewer.jsonfile import json_text
from raygs_viewer.photos.compare import difference_picture
from raygs_viewer.photos.evaluate import METRICS, EvaluationResult, finite_or_none
from raygs_viewer.photos.metrics import SSIM_KIND
from raygs_viewer.render.setting_info import setting_parts

REPORT_SUFFIXES = (".json", ".csv", ".md")
#: How many of the worst views (by PSNR) the Markdown lists and the contact sheet shows.
WORST_COUNT = 5
#: A contact sheet tile's largest width in pixels (photos are scaled down to it).
TILE_WIDTH = 320
LABEL_HEIGHT = 16


def sheet_path(report: Path) -> Path:
    """The contact sheet beside ``report``: ``r.md`` -> ``r.worst.png``."""
    return report.with_name(report.stem + ".worst.png")


def check_report_paths(path: str | Path, overwrite: bool = False) -> tuple[Path, Path]:
    """(report, contact sheet) for ``path``, checked before any work: a report suffix,
    an existing folder, neither file there unless ``overwrite``."""
    report = check_output_path(path, overwrite, REPORT_SUFFIXES)
    return report, check_output_path(sheet_path(report), overwrite, (".png",))


def settings_line(result: EvaluationResult) -> str:
    """The render settings in the words the window's status line uses, the mode always
    (the line leaves the default out; a report must say it)."""
    parts = setting_parts(result.settings, "line", changes_only=True)
    if not any(part.startswith("mode ") for part in parts):
        parts.insert(0, f"mode {result.settings.mode}")
    return ", ".join(parts)


def report_document(result: EvaluationResult, about: dict | None = None) -> dict:
    """The JSON report's value; ``about``: what the caller adds (dataset, split, scene)."""
    return {
        "views": [{metric: finite_or_none(score.value(metric)) if metric != "name" else score.name
                   for metric in ("name", *METRICS)} for score in result.scores],
        "mean": {metric: finite_or_none(value) for metric, value in result.mean().items()},
        "skipped": [{"name": skip.name, "reason": skip.reason} for skip in result.skipped],
        "views_total": result.total,
        "interrupted": result.interrupted,
        "settings": dataclasses.asdict(result.settings),
        "ssim_kind": SSIM_KIND,
        "lpips_note": result.lpips_note,
        **(about or {}),
    }


def report_json(result: EvaluationResult, about: dict | None = None) -> str:
    return json_text(report_document(result, about))


def number(value: float | None, digits: int) -> str:
    """A metric for CSV and Markdown: ``digits`` decimals, "inf", or empty for None."""
    if value is None:
        return ""
    return f"{value:.{digits}f}" if np.isfinite(value) else "inf"


DIGITS = {"psnr": 3, "ssim": 4, "flip": 4, "lpips": 4}


def report_csv(result: EvaluationResult) -> str:
    """One row a view (``skipped`` holds a skipped view's reason), then a ``(mean)`` row."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["name", *METRICS, "skipped"])
    for score in result.scores:
        writer.writerow([score.name, *(number(score.value(m), DIGITS[m]) for m in METRICS), ""])
    for skip in result.skipped:
        writer.writerow([skip.name, *("" for _ in METRICS), skip.reason])
    means = result.mean()
    writer.writerow(["(mean)", *(number(means[m], DIGITS[m]) for m in METRICS), ""])
    return buffer.getvalue()


def report_markdown(result: EvaluationResult, about: dict | None = None, sheet: Path | None = None) -> str:
    """The means, the worst views by PSNR, the skipped views, how it was made."""
    about = about or {}
    means = result.mean()
    lines = ["# Evaluation against the photos", ""]
    lines += [f"- {key}: {value}" for key, value in about.items()]
    lines += [f"- render settings: {settings_line(result)}",
              f"- views: {len(result.scores)} scored, {len(result.skipped)} skipped, of {result.total}"
              + (" (interrupted: the rest were not evaluated)" if result.interrupted else ""),
              f"- SSIM: {SSIM_KIND}", f"- {result.lpips_note or 'LPIPS: VGG'}", "",
              "| mean | PSNR (dB) | SSIM | FLIP | LPIPS |", "|---|---:|---:|---:|---:|",
              "| all scored views | " + " | ".join(number(means[m], DIGITS[m]) or "-" for m in METRICS) + " |", ""]
    worst = result.worst(WORST_COUNT)
    if worst:
        lines += [f"## The {len(worst)} worst views by PSNR", "",
                  "| view | PSNR (dB) | SSIM | FLIP | LPIPS |", "|---|---:|---:|---:|---:|"]
        lines += [f"| {score.name} | " + " | ".join(number(score.value(m), DIGITS[m]) or "-" for m in METRICS)
                  + " |" for score in worst]
        lines.append("")
        if sheet is not None:
            lines += [f"![photo, render and |difference| of the worst views]({sheet.name})", ""]
    if result.skipped:
        lines += [f"## Skipped views ({len(result.skipped)})", ""]
        lines += [f"- {skip.name}: {skip.reason}" for skip in result.skipped]
        lines.append("")
    return "\n".join(lines)


def write_report(path: Path, result: EvaluationResult, about: dict | None = None, overwrite: bool = False,
                 sheet: Path | None = None) -> Path:
    """Writes the report in the format of ``path``'s suffix (.json, .csv or .md);
    ``sheet``: the contact sheet the Markdown links to."""
    suffix = path.suffix.lower()
    if suffix == ".json":
        text = report_json(result, about)
    elif suffix == ".csv":
        text = report_csv(result)
    else:
        text = report_markdown(result, about, sheet)
    write_atomically(path, text.encode("utf-8"), overwrite)
    return path


def contact_sheet(rows: list[tuple[str, np.ndarray, np.ndarray]]) -> np.ndarray:
    """(H, W, 3) uint8: one row per (label, photo, render), each (h, w, 3) in 0..1: the
    photo, the render and the heat map side by side, under the label, scaled down to
    TILE_WIDTH."""
    tiles = []
    for label, photo, render in rows:
        height, width = photo.shape[:2]
        scale = min(1.0, TILE_WIDTH / width)
        size = (max(1, round(width * scale)), max(1, round(height * scale)))
        row = [np.asarray(Image.fromarray(to_rgb8(image)).resize(size, Image.BILINEAR))
               for image in (photo, render, difference_picture(np.asarray(render, np.float32),
                                                                             np.asarray(photo, np.float32)))]
        strip = np.concatenate(row, axis=1)
        banner = Image.new("RGB", (strip.shape[1], LABEL_HEIGHT), (255, 255, 255))
        ImageDraw.Draw(banner).text((2, 2), label, fill=(0, 0, 0))
        tiles.append(np.concatenate([np.asarray(banner), strip], axis=0))
    width = max(tile.shape[1] for tile in tiles)
    return np.concatenate([np.pad(tile, ((0, 0), (0, width - tile.shape[1]), (0, 0)), constant_values=255)
                           for tile in tiles], axis=0)


def write_contact_sheet(path: Path, rows: list[tuple[str, np.ndarray, np.ndarray]], overwrite: bool = False) -> Path:
    write_atomically(path, encode_png(contact_sheet(rows)), overwrite)
    return path

