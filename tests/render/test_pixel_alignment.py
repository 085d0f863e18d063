"""One GL render per pixel that checks the projection of section 1 lands a tiny
gaussian on exactly its pixel (moved from the camera tests: its subject is the renderer)."""

import numpy as np
from testkit import make_scene, point_on_pixel_ray, sorted_render

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.render.gl.renderer import GLRenderer


def test_gl_render_puts_a_tiny_gaussian_on_its_pixel(gl_ctx):
    rng = np.random.default_rng(30)
    pose = look_at([0.7, -0.4, -2.0], [0.1, 0.2, 0.5])
    camera = Camera(57, 43, 60.0, 47.0, 25.3, 24.6, pose.R, pose.t)  # odd, fx != fy, off-centre
    w, h = camera.width, camera.height
    pixels = [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1), (int(camera.cx), int(camera.cy))]
    pixels += [(int(rng.integers(w)), int(rng.integers(h))) for _ in range(5)]
    for u, v in pixels:
        depth = float(rng.uniform(1.5, 3.0))
        scene = make_scene(point_on_pixel_ray(camera, u, v, depth), 0.002, opacities=1.0, colors=(1.0, 1.0, 1.0))
        renderer = GLRenderer(gl_ctx, scene)
        try:
            image = sorted_render(renderer, camera)
        finally:
            renderer.release()
        assert image.shape == (h, w, 4)
        brightness = image[..., :3].sum(axis=-1)
        row, col = np.unravel_index(np.argmax(brightness), brightness.shape)
        assert (row, col) == (v, u), f"pixel ({u}, {v}) rendered at ({col}, {row})"
        assert image[v, u, 3] > 0.5
        # Nothing else lights up: the gaussian is 0.1 px wide.
        others = image[..., 3].copy()
        others[v, u] = 0
        assert others.max() < 1e-3
