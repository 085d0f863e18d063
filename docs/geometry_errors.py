"""Measured error of every GL geometry output against the float64 reference (docs/geometry.md)."""
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path("tests").resolve()))
from testkit import channel_errors, random_scene  # noqa: E402

from raygs_viewer.camera.pinhole import frame_points, look_at  # noqa: E402
from raygs_viewer.render.gl.context import create_headless_context  # noqa: E402
from raygs_viewer.render.gl.renderer import GLRenderer  # noqa: E402
from raygs_viewer.render.reference import render_reference_channels  # noqa: E402
from raygs_viewer.render.settings import RenderSettings  # noqa: E402
from raygs_viewer.render.sorting import exact_order  # noqa: E402
from raygs_viewer.scene.io import load_scene  # noqa: E402
from raygs_viewer.sort.depth import DepthSorter  # noqa: E402

base = random_scene(n=250, seed=5, log_scale=(-3.5, -1.2), anisotropy=2.0)
generated = replace(base, opacities=np.random.default_rng(5).uniform(0.3, 1.0, base.count).astype(np.float32))
cases = [("generated 250", generated, look_at((0.4, -0.3, -3.2), (0, 0, 0), width=64, height=48))]
for name in ("ss-fruit_drops_minimal.ply", "schwa-centered_lastchance.splat", "gs3d-pr477-lod3_tile_0.ply"):
    scene = load_scene(Path("../shared/scenes") / name)
    cases.append((name, scene, frame_points(scene.positions, 64, 48)))
settings_list = {"depth order": RenderSettings(), "per-pixel": RenderSettings(order="per-pixel"),
                 "exact MIP": RenderSettings(mode="raygs-exact-mip"), "GS": RenderSettings(mode="gs")}
ctx = create_headless_context("auto")
print("| scene | settings | way | alpha max | depth rel. p99.9 / max | median rel. p99.9 / max | median found differs | normal p99.9 / max |")
print("|---|---|---|---:|---:|---:|---:|---:|")
for label, scene, camera in cases:
    renderer, sorter = GLRenderer(ctx, scene), DepthSorter(scene)
    for name, settings in settings_list.items():
        reference = render_reference_channels(scene, camera, settings)
        for median in (True, False):
            if not median and settings.per_pixel:
                continue
            image = renderer.render_channels(camera, settings, exact_order(sorter, camera, settings), median=median)
            e = channel_errors(image, reference)
            q = lambda a: f"{np.quantile(a, 0.999):.1e} / {a.max():.1e}"
            med = f"{q(e['median_depth'])} | {e['median_found'].mean():.2%}" if median else "– | –"
            way = "lists" if median or settings.per_pixel else "blend"
            print(f"| {label} | {name} | {way} | {e['alpha'].max():.1e} | {q(e['depth'])} | {med} | {q(e['normal'])} |")
    sorter.close()
    renderer.release()
