"""Times "what the view shows" selection (render.contributions.max_weights) at 1280x720.

Usage: .venv/bin/python docs/visible_selection_timing.py SCENE...
For each scene: a click, a brush stroke and a rectangle, in the global and the per-ray order.
"""
import sys
import time

import numpy as np

from raygs_viewer.camera.pinhole import frame_points
from raygs_viewer.render.contributions import bounds, cropped, max_weights
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.selection import ScreenShape
from raygs_viewer.sort.depth import DepthSorter

for name in sys.argv[1:]:
    scene = load_scene(name)
    camera = frame_points(scene.positions, 1280, 720)
    shapes = [("click", ScreenShape("rectangle", camera, ((640, 360), (641, 361)))),
              ("brush r=20 px, 300 px", ScreenShape("brush", camera, ((490, 360), (790, 360)), 20.0)),
              ("rectangle 200x200", ScreenShape("rectangle", camera, ((540, 260), (740, 460))))]
    with DepthSorter(scene) as sorter:
        for settings in (RenderSettings(), RenderSettings(order="per-pixel")):
            for label, shape in shapes:
                start = time.perf_counter()
                inside = shape.pixel_mask()
                order = exact_order(sorter, cropped(camera, *bounds(inside)), settings)
                sorted_at = time.perf_counter()
                weights = max_weights(scene, camera, settings, np.asarray(order.indices), inside)
                done = time.perf_counter()
                print(f"{name.split('/')[-1]} ({scene.count:,}), {settings.order}: {label}: sort {sorted_at - start:.3f} s,"
                      f" weigh {done - sorted_at:.3f} s, {order.count:,} ordered, {(weights >= 0.05).sum():,} at >= 0.05")
