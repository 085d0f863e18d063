"""Builds the example dataset of docs/evaluation.md: a shared real scene rendered in GS
mode (as INRIA 3DGS renders) at 16 cameras around it, plus seeded gaussian noise of
sigma 0.02, written as 8-bit PNG "photos" with a nerfstudio transforms.json.

    python docs/evaluation_example.py OUT_DIR [SCENE.ply]

then ``raygs-viewer evaluate OUT_DIR/transforms.json --scene SCENE.ply --out r.md``.
The GS-mode evaluation then measures the noise alone (about 34 dB), the others also
what RayGS changes against the renderer that made the "photos".
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from raygs_viewer.camera.navigation import scene_bounds
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.capture.image_io import encode_png, to_rgb8
from raygs_viewer.files import write_atomically
from raygs_viewer.jsonfile import json_text
from raygs_viewer.render.gl.context import create_headless_context
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.io import load_scene
from raygs_viewer.sort.depth import DepthSorter

SCENE = Path(__file__).resolve().parents[2] / "shared" / "scenes" / "ss-fruit_drops_minimal.ply"
VIEWS, WIDTH, HEIGHT, FOV_Y = 16, 320, 240, 40.0
NOISE, SEED = 0.02, 25
OPENGL_AXES = np.diag([1.0, -1.0, -1.0])  # nerfstudio's camera axes from OpenCV's


def main(out: Path, scene_path: Path) -> None:
    scene = load_scene(scene_path)
    center, radius = scene_bounds(scene.positions)
    distance = 1.3 * radius / np.tan(np.radians(FOV_Y / 2))
    rng = np.random.default_rng(SEED)
    (out / "images").mkdir(parents=True, exist_ok=False)
    frames = []
    ctx = create_headless_context()
    renderer, sorter = GLRenderer(ctx, scene), DepthSorter(scene)
    settings = RenderSettings(mode="gs")
    for i, angle in enumerate(np.linspace(0.0, 2 * np.pi, VIEWS, endpoint=False)):
        eye = center + distance * np.array([np.sin(angle), -0.4, -np.cos(angle)]) / np.hypot(1.0, 0.4)
        camera = look_at(eye, center, width=WIDTH, height=HEIGHT, fov_y_degrees=FOV_Y)
        render = renderer.render(camera, settings, exact_order(sorter, camera, settings))[..., :3]
        photo = np.clip(render + rng.normal(0.0, NOISE, render.shape), 0.0, 1.0)
        name = f"images/frame_{i:03d}.png"
        write_atomically(out / name, encode_png(to_rgb8(photo)))
        c2w = np.eye(4)
        c2w[:3, :3] = np.asarray(camera.R).T @ OPENGL_AXES
        c2w[:3, 3] = camera.center
        frames.append({"file_path": name, "transform_matrix": c2w.tolist()})
    sorter.close()
    renderer.release()
    ctx.release()
    document = {"camera_model": "OPENCV", "fl_x": camera.fx, "fl_y": camera.fy, "cx": camera.cx, "cy": camera.cy,
                "w": WIDTH, "h": HEIGHT, "frames": frames}
    write_atomically(out / "transforms.json", json_text(document).encode())


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]) if len(sys.argv) > 2 else SCENE)
