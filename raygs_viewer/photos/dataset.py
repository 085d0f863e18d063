"""A capture's photos and the cameras they were taken with, read as users have them
(docs/evaluation.md): an INRIA model folder (cameras.json, cfg_args), a COLMAP folder
(sparse/0, binary or text; PINHOLE and SIMPLE_PINHOLE), a nerfstudio transforms.json.

THE INTERFACE (skeleton: the dataset helper fills it in; others build on these names).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import Camera

#: --split: the paper's protocol, every TEST_EVERY-th view (index % 8 == 0 in name order) is a test view.
SPLITS = ("test", "train", "all")
TEST_EVERY = 8
LAYOUTS = ("inria", "colmap", "nerfstudio")


@dataclass(frozen=True)
class PhotoView:
    """One photo: ``name`` (the image's name as the dataset gives it), ``camera`` (OpenCV
    axes, at the size the render is compared at), ``image_path`` (the photo file, None
    when it was not found: loading it is then a one-line UserError), ``index`` (its
    place in name order, which the split uses)."""

    name: str
    camera: Camera
    image_path: Path | None
    index: int


@dataclass(frozen=True)
class Dataset:
    """``layout`` (one of LAYOUTS), ``root`` (the folder or file opened), ``views`` (in
    name order), ``background`` (the model's: white where its cfg_args says so, else
    black), ``scene_path`` (the trained model's point cloud when the layout names one:
    an INRIA folder's point_cloud/iteration_<highest>/point_cloud.ply; else None)."""

    layout: str
    root: Path
    views: tuple[PhotoView, ...]
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scene_path: Path | None = None


def open_dataset(path: str | Path, images: str | Path | None = None) -> Dataset:
    """The dataset at ``path`` (an INRIA model folder, a COLMAP folder, a transforms.json
    or its folder); ``images``: the photos' folder where the layout does not say.
    UserError (one line) for anything unreadable or unsupported."""
    raise NotImplementedError


def select_split(views: tuple[PhotoView, ...], split: str) -> tuple[PhotoView, ...]:
    """The views of ``split`` (one of SPLITS): "test" every TEST_EVERY-th by index, "train" the others."""
    raise NotImplementedError


def load_photo(view: PhotoView, background: tuple[float, float, float]) -> np.ndarray:
    """(H, W, 3) float32 in 0..1, at ``view.camera``'s size (resized as the INRIA loader
    does where the file is larger), alpha (RGBA photos) composited over ``background``.
    UserError (one line naming the file) for a missing or unreadable photo, or one whose
    aspect ratio does not match the camera."""
    raise NotImplementedError
