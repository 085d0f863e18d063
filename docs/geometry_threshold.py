"""Measures the geometry pictures' alpha threshold (docs/geometry.md, "Masking haze"): for
each scene, the pixels the colour view visibly shows against the pixels a depth picture
paints at each threshold, and their intersection over union.

A pixel is *visible* in the colour view when its 8-bit colour differs from the
background by at least DELTA (out of 255) in some channel on a black or on a white
background (so a dark object counts as shown though it sits on the viewer's black):
max over channels of max(c, alpha - c) >= DELTA / 255, c the premultiplied colour. A depth
picture *paints* a pixel when it has a depth and its alpha is at least the threshold.

    PYTHONPATH=. .venv/bin/python docs/geometry_threshold.py
"""
import glob
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import frame_points
from raygs_viewer.render.gl.context import create_headless_context
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.demo import demo_cameras, demo_scene
from raygs_viewer.scene.io import load_scene
from raygs_viewer.sort.depth import DepthSorter

W, H = 320, 240
THRESHOLDS = (0.0, 0.02, 0.03, 0.05, 0.075, 0.1, 0.25, 0.5)
TOO_SMALL = 1000  # visible pixels: a scene showing fewer is left out of the means (a few pixels swing its IoU)
DELTAS = (4, 8, 16)  # of 255: barely, plainly, clearly visible

cases = [(f"demo ({name})", demo_scene(), camera)
         for name, camera in zip(("default", "close-up"), (demo_cameras(W, H)[0], demo_cameras(W, H)[4]))]
for path in sorted(glob.glob(str(Path(__file__).resolve().parents[2] / "shared/scenes/*.ply"))):
    scene = load_scene(path)
    cases.append((Path(path).name, scene, frame_points(scene.positions, W, H)))

ctx = create_headless_context("auto")
settings = RenderSettings()
iou = {delta: {t: [] for t in THRESHOLDS} for delta in DELTAS}
print(f"{W}x{H}; IoU of the painted and visible pixels (painted / visible pixels), visible at DELTA = 8/255\n")
print("| scene | visible px | " + " | ".join(f"t = {t:g}" for t in THRESHOLDS) + " |")
print("|---|---:|" + "---:|" * len(THRESHOLDS))
for label, scene, camera in cases:
    renderer, sorter = GLRenderer(ctx, scene), DepthSorter(scene)
    image = renderer.render_channels(camera, settings, exact_order(sorter, camera, settings), median=False)
    sorter.close()
    renderer.release()
    alpha, premultiplied = image.alpha, image.rgb  # the background is black: rgb is premultiplied
    contrast = np.maximum(premultiplied, alpha[..., None] - premultiplied).max(axis=-1)
    cells = []
    for delta in DELTAS:
        visible = contrast >= delta / 255
        for t in THRESHOLDS:
            painted = (image.depth > 0) & (alpha >= np.float32(t))
            score = (painted & visible).sum() / max((painted | visible).sum(), 1)
            if (contrast >= 8 / 255).sum() >= TOO_SMALL:
                iou[delta][t].append(score)
            if delta == 8:
                cells.append(f"{score:.3f} ({painted.sum() / max(visible.sum(), 1):.2f})")
    print(f"| {label} | {int((contrast >= 8 / 255).sum())} | " + " | ".join(cells) + " |")
print(f"\nmean IoU over the scenes showing at least {TOO_SMALL} visible pixels, by DELTA\n")
print("| DELTA | " + " | ".join(f"t = {t:g}" for t in THRESHOLDS) + " |")
print("|---|" + "---:|" * len(THRESHOLDS))
for delta in DELTAS:
    print(f"| {delta}/255 | " + " | ".join(f"{np.mean(iou[delta][t]):.3f}" for t in THRESHOLDS) + " |")
