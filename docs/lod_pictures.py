"""The pictures of docs/lod.md: a streamed SOG at its finest level and at budgets of 100, 50,
25 and 10 % of it, side by side, labelled; then the same views with each level tinted.

Usage (from the repository root):

    .venv/bin/python docs/lod_pictures.py /tmp/lod-real/lod-meta.json docs/images

writes OUT/lod-budgets.png and OUT/lod-levels.png (replacing them). The first renders
each panel with the command line, exactly as a user would:

    raygs-viewer render LOD.json --lod 0 --width 480 --height 360 --out level0.png
    raygs-viewer render LOD.json --lod-budget N --width 480 --height 360 --out budgetN.png

(N: the fraction of the finest level's gaussians, plus the environment's), and labels it
with what the command printed it drew. The second renders the same choices through the
package's API (``lod_choice.choose`` and an exact order of the choice's rows, as ``render`` does) after
replacing every gaussian's colour by its level's tint (80 %) and its own grey (20 %).
"""
import re
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from raygs_viewer.camera.pinhole import frame_points
from raygs_viewer.render.gl.context import create_headless_context
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.lod_file import load_lod, lod_summary
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import choose

WIDTH, HEIGHT = 480, 360
FRACTIONS = (1.0, 0.5, 0.25, 0.1)
#: Level 0 (finest) to 3 in the colours of the window's "colour by level"
#: (viewer/lod_window.py's LEVEL_COLOURS), further levels grey; the environment keeps its own.
TINTS = ((0.9, 0.15, 0.1), (0.15, 0.8, 0.2), (0.15, 0.35, 0.95), (0.95, 0.85, 0.1))
OTHER_TINT = (0.6, 0.6, 0.6)
SH_C0 = 0.28209479177387814  # colour = 0.5 + SH_C0 * DC
LABEL_HEIGHT, GAP = 56, 6


def cases(path: str) -> list[tuple[str, int | None]]:
    """(title, budget) of each panel: the finest level (None), then each budget."""
    summary = lod_summary(path)
    finest, environment = summary["counts"][0], summary["environment"] or 0
    return [("level 0 (finest)", None)] + [
        (f"budget {f * 100:g} %: {round(f * finest) + environment:,}", round(f * finest) + environment)
        for f in FRACTIONS]


def render_with_cli(path: str, budget: int | None, out: Path) -> str:
    """Renders one panel with ``raygs-viewer render``; returns what it says it drew."""
    choice = ["--lod", "0"] if budget is None else ["--lod-budget", str(budget)]
    command = [sys.executable, "-m", "raygs_viewer", "render", path, *choice, "--width", str(WIDTH),
               "--height", str(HEIGHT), "--out", str(out), "--overwrite"]
    printed = subprocess.run(command, check=True, capture_output=True, text=True).stdout.strip()
    print(printed)
    count = int(re.search(r", (\d+)(?: of \d+)? gaussians", printed).group(1))
    parts = re.findall(r"(\d+) at level (\d+)", printed)
    leaves = ", ".join(f"{n} at level {level}" for n, level in parts) if parts else "all at level 0"
    over = " (the coarsest level alone is over)" if "exceed" in printed else ""
    return f"{count:,} gaussians drawn; leaves: {leaves}{over}"


def font(size: int):
    return ImageFont.load_default(size=size)


def compose(panels: list[tuple[np.ndarray, str, str]], out: Path, legend: list[tuple[str, tuple]] = ()) -> None:
    """Panels (uint8 RGB image, title, detail) in one row, each labelled below; a legend
    of coloured swatches under the row, when given."""
    height = HEIGHT + LABEL_HEIGHT + (28 if legend else 0)
    sheet = Image.new("RGB", (len(panels) * WIDTH + (len(panels) - 1) * GAP, height), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (image, title, detail) in enumerate(panels):
        x = i * (WIDTH + GAP)
        sheet.paste(Image.fromarray(image), (x, 0))
        draw.text((x + 6, HEIGHT + 6), title, fill=(0, 0, 0), font=font(18))
        draw.text((x + 6, HEIGHT + 32), detail, fill=(60, 60, 60), font=font(12))
    x = 6
    for name, colour in legend:
        y = HEIGHT + LABEL_HEIGHT + 4
        draw.rectangle((x, y, x + 18, y + 18), fill=tuple(int(255 * c) for c in colour))
        draw.text((x + 24, y), name, fill=(0, 0, 0), font=font(15))
        x += 24 + int(draw.textlength(name, font=font(15))) + 24
    sheet.save(out)
    print(f"wrote {out}")


def to_uint8(image: np.ndarray) -> np.ndarray:
    return (np.clip(image[..., :3], 0.0, 1.0) * 255 + 0.5).astype(np.uint8)


def tinted(lod):
    """``lod`` with every level's gaussians coloured by its tint (SH degree 0): 80 % tint,
    20 % the gaussian's own grey (its DC colour's mean), so shapes stay readable."""
    scene = lod.scene
    c0 = SH_C0
    grey = np.clip(0.5 + c0 * scene.sh[:, 0, :], 0.0, 1.0).mean(axis=1, keepdims=True)
    colour = np.clip(0.5 + c0 * scene.sh[:, 0, :], 0.0, 1.0)  # the environment keeps its own
    for level in range(lod.levels):
        tint = np.array(TINTS[level] if level < len(TINTS) else OTHER_TINT, np.float32)
        for start, count in lod.rows[:, level]:
            colour[start:start + count] = 0.8 * tint + 0.2 * grey[start:start + count]
    sh = ((colour - 0.5) / c0).astype(np.float32)[:, None, :]
    return replace(lod, scene=replace(scene, sh=sh, sh_degree=0))


def level_panels(path: str, budgets: list[tuple[str, int | None]]) -> list[tuple[np.ndarray, str, str]]:
    lod = load_lod(path)
    colours = tinted(lod)
    start, count = lod.environment
    positions = np.concatenate([lod.scene.positions[:start], lod.scene.positions[start + count:]])
    camera = frame_points(positions).resized(WIDTH, HEIGHT)  # render's camera for a scene without cameras
    ctx = create_headless_context("auto")
    renderer, sorter = GLRenderer(ctx, colours.scene), DepthSorter(colours.scene)
    panels = []
    try:
        for title, budget in budgets:
            choice = choose(colours, camera, level=0) if budget is None else choose(colours, camera, budget=budget)
            order = exact_order(sorter, camera, RenderSettings(), levels=choice)
            image = renderer.render(camera, RenderSettings(), order)
            per_level = ", ".join(f"{n} at level {level}" for level, n in enumerate(choice.per_level(lod.levels))
                                  if n)
            over = " (the coarsest level alone is over)" if choice.over_budget else ""
            panels.append((to_uint8(image), title, f"{choice.count:,} gaussians drawn; leaves: {per_level}{over}"))
    finally:
        sorter.close()
        renderer.release()
        ctx.release()
    return panels


def main(path: str, out_folder: str) -> None:
    out = Path(out_folder)
    budgets = cases(path)
    with tempfile.TemporaryDirectory() as folder:
        panels = []
        for i, (title, budget) in enumerate(budgets):
            png = Path(folder) / f"panel{i}.png"
            drawn = render_with_cli(path, budget, png)
            panels.append((np.asarray(Image.open(png).convert("RGB")), title, drawn))
    compose(panels, out / "lod-budgets.png")
    levels = lod_summary(path)["levels"]
    legend = [(f"level {level}" + (" (finest)" if level == 0 else ""), TINTS[level])
              for level in range(min(levels, len(TINTS)))]
    compose(level_panels(path, budgets), out / "lod-levels.png", legend)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: docs/lod_pictures.py LOD.json OUT_FOLDER")
    main(sys.argv[1], sys.argv[2])
