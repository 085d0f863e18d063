"""The training cameras' photos as small GL textures, for their frustums in the scene
(:mod:`.training_frustums`).

The photos are the Photo view's (its dataset, opened once per scene: the model folder
holding the scene's cameras.json, or ``--images``). Each is read at most once per scene
as a thumbnail ``THUMBNAIL_WIDTH`` pixels wide (``photos.dataset.load_thumbnail``), a
few per frame, only for the cameras asked for (those drawn), so opening a scene of a
thousand cameras costs no long pause. Nothing here raises into the frame: a dataset
or photo that cannot be read becomes :attr:`Thumbnails.status`, one line for the panel.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Callable

import moderngl
import numpy as np

from raygs_viewer.errors import UserError, one_line
from raygs_viewer.photos.dataset import Dataset, load_thumbnail
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.photo_view import photo_view_named

#: A thumbnail's width in pixels: sharp enough for a frustum a few hundred pixels wide.
THUMBNAIL_WIDTH = 128
#: Photos read per frame at most (each a few milliseconds): the frame rate holds while they arrive.
PER_FRAME = 2
#: What reading a dataset or a photo may raise besides UserError (a file vanished, a
#: folder that cannot be read, a decoder's own error, a photo too large for memory).
READ_ERRORS = (UserError, OSError, ValueError, MemoryError)


class Thumbnails:
    """One per window. ``dataset_of(loaded)``: the scene's photos (a Dataset) or a line
    saying why there are none (``photo_view.ScenePhotos.of``). ``status``: "" while all is
    well, else one line: why there are no photos, or which could not be read."""

    def __init__(self, ctx: moderngl.Context, dataset_of: Callable[[LoadedScene], Dataset | str]):
        self.ctx, self.dataset_of = ctx, dataset_of
        self.status = ""
        self._textures: dict[int, moderngl.Texture] = {}
        self._failed: dict[int, str] = {}  # camera index -> why its photo was not read
        self._dataset: Dataset | str | None = None

    def texture(self, index: int) -> moderngl.Texture | None:
        """Training camera ``index``'s thumbnail; None until read, or when it has none."""
        return self._textures.get(index)

    def load(self, loaded: LoadedScene, indices: Iterable[int], budget: int = PER_FRAME) -> None:
        """Reads the thumbnails of up to ``budget`` of the training cameras ``indices``
        (in that order) not tried yet."""
        dataset = self._dataset_for(loaded)
        if isinstance(dataset, str):
            return
        for index in indices:
            if budget <= 0:
                break
            if index in self._textures or index in self._failed:
                continue
            budget -= 1
            name = loaded.camera_names[index]
            view = photo_view_named(dataset.views, name)
            try:
                if view is None:
                    raise UserError(f"no photo of {name} in {dataset.root}")
                self._textures[index] = self._upload(load_thumbnail(view, dataset.background, THUMBNAIL_WIDTH))
            except (*READ_ERRORS, moderngl.Error) as exc:
                self._failed[index] = one_line(exc)
                self.status = (f"{len(self._failed)} photo{'s' if len(self._failed) != 1 else ''} not shown: "
                               f"{next(iter(self._failed.values()))}")

    def _dataset_for(self, loaded: LoadedScene) -> Dataset | str:
        if self._dataset is None:
            try:
                self._dataset = self.dataset_of(loaded)
            except READ_ERRORS as exc:
                self._dataset = f"no photos: {one_line(exc)}"
            if isinstance(self._dataset, str):
                self.status = self._dataset
        return self._dataset

    def _upload(self, pixels: np.ndarray) -> moderngl.Texture:
        height, width = pixels.shape[:2]
        # Rows top first, as imgui's texture coordinates run (v = 0: the image's top).
        texture = self.ctx.texture((width, height), 3, np.ascontiguousarray(pixels, np.uint8).tobytes(),
                                   alignment=1)
        texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        return texture

    def forget(self) -> None:
        """Another scene: its photos are another dataset's; the textures are released."""
        for texture in self._textures.values():
            texture.release()
        self._textures.clear()
        self._failed.clear()
        self._dataset, self.status = None, ""

    release = forget
