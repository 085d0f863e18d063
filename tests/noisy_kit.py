"""Datasets whose "photos" are GL renders of a tiny scene plus known, seeded gaussian
noise, so every metric the evaluation reports can be computed in advance from the same
arrays (the photos as written: 8-bit PNGs)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets_kit import write_dataset
from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.writing import write_scene
from testkit import random_scene

WIDTH, HEIGHT = 32, 24
NOISE = 0.03
VIEWS = 9  # two test views (indices 0 and 8)


@dataclass
class NoisyDataset:
    """``path``: what evaluate opens; ``scene``: the model's PLY; ``names`` the views'
    names as written; ``photos`` (H, W, 3) float64 as read back from the 8-bit files;
    ``renders`` the clean renders they were made from."""

    path: Path
    scene: Path
    images: Path
    names: list[str]
    photos: list[np.ndarray]
    renders: list[np.ndarray]


def tiny_scene():
    """A few hundred gaussians around the origin, bright enough that the noise is not clipped much."""
    scene = random_scene(n=150, seed=4, degree=0, spread=0.8, log_scale=(-2.5, -1.2))
    return scene


def cameras(count: int = VIEWS) -> list[Camera]:
    """Views on a circle around the origin, 3 units out."""
    angles = np.linspace(0.0, 2 * np.pi, count, endpoint=False)
    return [look_at((3 * np.sin(a), -0.5, -3 * np.cos(a)), (0.0, 0.0, 0.0), width=WIDTH, height=HEIGHT,
                    fov_y_degrees=45.0) for a in angles]


def quantised(image: np.ndarray) -> np.ndarray:
    """What an 8-bit PNG of ``image`` reads back as, in 0..1."""
    return np.rint(np.clip(image, 0.0, 1.0) * 255.0) / 255.0


def write_noisy_dataset(root: Path, layout: str, gl_render, seed: int = 0, noise: float = NOISE,
                        settings: RenderSettings = RenderSettings()) -> NoisyDataset:
    """The views of :func:`cameras` rendered (over black) with ``settings``, plus gaussian
    noise of ``noise`` (seeded), written as a dataset of ``layout`` with the scene."""
    root.mkdir(parents=True, exist_ok=True)
    scene = tiny_scene()
    scene_path = root / "scene.ply"
    write_scene(scene, scene_path)
    rng = np.random.default_rng(seed)
    views = cameras()
    renders = [np.clip(gl_render(scene, camera, settings)[..., :3].astype(np.float64), 0, 1) for camera in views]
    photos = [quantised(render + rng.normal(0.0, noise, render.shape)) for render in renders]
    path = write_dataset(root / layout, layout, views, photos, scene=scene)
    images = {"inria": root / layout / "source" / "images"}.get(layout, root / layout / "images")
    names = [f"view_{i:03d}" for i in range(len(views))]
    return NoisyDataset(path, scene_path, images, names, photos, renders)
