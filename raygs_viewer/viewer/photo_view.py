"""The window's Photo view: at a training camera, its photo beside the render.

Standing exactly at a training camera (flown to with N / P or the Training section,
the flight finished, nothing moved since), the window can show the render, the photo,
|render − photo| as a heat map, or the photo left of a divider and the render right of
it; the panel shows the PSNR of render against photo. Any navigation away shows the
render again and says so; the chosen mode comes back at the next training camera.

What is compared is what the window shows: the render at the viewport's size (the
training camera's intrinsics scaled to it, clipped to 0..1) and the photo at that
size (``photos.dataset.load_photo`` at the camera's own size, resampled where the
viewport differs; the PSNR then says at which size it was measured). With
``at_camera_size`` the comparison is ``evaluate``'s instead, so the two give one PSNR
for a view: the training camera rendered at its own size and intrinsics by
``photos.evaluate.render_view`` (an exact sort, the dataset's background) against the
photo as loaded, and that picture shown scaled into the viewport. The photos come
from ``open_dataset`` on the model folder holding the scene's cameras.json (its
cfg_args name the source images) or ``--images``. Each photo is loaded once, on
arrival, and cached per view and size.

The picture shown instead of the render is a target of its own, which the mono
frame's present pass shows in place of the drawn image (``MonoFrame.stereo_image``:
"shown instead of the left target"); the drawn render stays untouched underneath, so
nothing is drawn again when the mode changes. Not in the stereo preview, the A/B
split view or a channel view (depth, normals...): there the Photo view says why and
the render is shown.
"""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path
from dataclasses import dataclass
from typing import Callable, Literal

import moderngl
import numpy as np

from raygs_viewer.camera.lens import Lens
from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.photos.compare import (
    DEFAULT_HEAT_MAX,
    difference_picture,
    resize_picture,
    split_picture,
)
from raygs_viewer.photos.dataset import IMAGES_HINT, Dataset, PhotoView, load_photo, open_dataset, with_images_hint
from raygs_viewer.photos.metrics import psnr
from raygs_viewer.render.gl.mono_frame import MonoFrame
from raygs_viewer.render.gl.targets import FloatTarget, sized
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.state import Message, note

#: What the Photo view shows: the render, the photo, |render - photo| as a heat map, or the
#: photo left of a divider and the render right of it.
PhotoMode = Literal["render", "photo", "difference", "split"]
#: The Photo view's modes, as the panel names them.
MODES: dict[PhotoMode, str] = {"render": "render", "photo": "photo", "difference": "|difference|", "split": "split"}
#: Photos kept in memory (each at one size): a few views' worth while stepping back and forth.
CACHE_SIZE = 8


def standing_at(cameras: list[Camera], index: int | None, lens: Lens, pose: Pose) -> int | None:
    """``index`` when the view stands exactly at training camera ``index``: its lens and
    its pose (a finished flight lands on the pose exactly); else None."""
    if index is None or lens.source is not cameras[index]:
        return None
    target = Pose.from_camera(cameras[index])
    if np.array_equal(pose.position, target.position) and np.array_equal(pose.R, target.R):
        return index
    return None


class ScenePhotos:
    """The training photos of the scene shown: its dataset (``open_dataset`` on the model
    folder holding the scene's cameras.json, whose cfg_args name the source images, or
    ``images``: ``--images``), opened on first use once per scene, or a line saying why
    there is none. The Photo view and the frustums' thumbnails share it."""

    def __init__(self, images: str | None = None):
        self.images = images
        self._dataset: Dataset | str | None = None  # str: why there is none

    def of(self, loaded: LoadedScene) -> Dataset | str:
        """The photos of ``loaded``'s training cameras, or why there are none."""
        if self._dataset is None:
            if self.images is None and loaded.cameras_path is None:
                self._dataset = f"no photos: the scene's cameras come from no model folder ({IMAGES_HINT})"
            else:
                model = Path(loaded.cameras_path).parent if loaded.cameras_path else Path(loaded.path).parent
                try:
                    self._dataset = open_dataset(model, self.images)
                except UserError as exc:
                    self._dataset = with_images_hint(f"no photos: {one_line(exc)}")
        return self._dataset

    def forget(self) -> None:
        """Another scene: another dataset."""
        self._dataset = None


@dataclass(frozen=True, eq=False)
class Drawn:
    """What the Photo view is handed after a frame's draw: the scene shown, the training
    camera the view stands at (``index``; None: away, or nothing drawn), the window's
    camera, why the Photo view cannot show now (``blocked``; "" when it can), whether
    the draw made a new render (``drew``), the window's frame (its drawn render is
    compared, and it shows the picture), and evaluate's render of a training view at its
    own size (``render_at``: a PhotoView and its Dataset -> (H, W, 3) float32 in 0..1,
    what ``at_camera_size`` compares)."""

    loaded: LoadedScene
    index: int | None
    camera: Camera
    blocked: str
    drew: bool
    mono: MonoFrame
    render_at: Callable[[PhotoView, Dataset], np.ndarray]


class PhotoCompare:
    """One per window. ``mode``: one of MODES; ``fraction``: the split's divider as a
    fraction of the width; ``heat_max``: the |difference| at the heat map's top colour;
    ``at_camera_size``: compare at the training camera's own size (``Drawn.render_at``)
    instead of the window's. After each frame's draw: ``at`` (the training camera stood
    at, None: away), ``status`` (the section's line: why nothing is compared, or what
    was), ``psnr`` (of render against photo, None when not compared), ``picture``
    ((H, W, 3) float32 shown instead of the render; None: the render is shown)."""

    def __init__(self, ctx: moderngl.Context, photos: ScenePhotos):
        self.ctx, self.photos = ctx, photos
        self.mode: PhotoMode = "render"
        self.fraction, self.heat_max = 0.5, DEFAULT_HEAT_MAX
        self.at_camera_size = False
        self.used = False  # photos are loaded only once a mode other than the render was chosen
        self.at: int | None = None
        self.status = ""
        self.psnr: float | None = None
        self.picture: np.ndarray | None = None
        self.size: tuple[int, int] | None = None  # the compared images' (width, height)
        self.camera_size: tuple[int, int] | None = None  # the training camera's own
        self.target: FloatTarget | None = None
        self.render: np.ndarray | None = None
        #: (view index, (width, height) or None: the camera's own) -> (photo, its view), or why there is none.
        self._photos: OrderedDict[tuple, tuple[np.ndarray, PhotoView] | str] = OrderedDict()
        self._key: tuple | None = None
        self._computed = 0  # pictures computed so far
        self._written = -1  # which of them ``target`` holds

    def choose(self, mode: PhotoMode) -> None:
        if mode not in MODES:
            raise ValueError(f"unknown photo mode {mode!r}")
        self.mode = mode
        self.used |= mode != "render"

    def set_camera_size(self, on: bool) -> None:
        """Compares at the training camera's own size (True) or the window's."""
        self.at_camera_size = bool(on)
        self.used |= self.at_camera_size

    def forget_scene(self) -> None:
        """A new scene: its photos are another dataset's."""
        self._key = None
        self._photos.clear()

    @property
    def showing(self) -> bool:
        """Whether the window shows something other than the render."""
        return self.picture is not None

    def check_screenshot(self) -> None:
        """UserError while a photo, difference or split is shown: a screenshot re-renders
        the view from its sidecar, which a photo or a heat map would not reproduce."""
        if self.showing:
            what = MODES[self.mode] + (" at the camera's size" if self.at_camera_size else "")
            raise UserError(f"screenshots save renders: the window shows the Photo view's {what}; choose "
                            f"'render' at the window's size in the Photo section first")

    # -- each frame ---------------------------------------------------------------------
    def frame(self, drawn: Drawn) -> Message | None:
        """Called after the frame's draw: puts the picture to show in the frame; returns
        what the panel says (None: nothing)."""
        index, camera, mono = drawn.index, drawn.camera, drawn.mono
        left, self.at = self.at is not None and index is None, index
        message = note("left the training camera: the window shows the render") if left and self.showing else None
        if index is None or drawn.blocked or not self.used:
            self.status = drawn.blocked if index is not None and self.used else ""
            self._hide(mono)
            return message
        key = (index, camera.width, camera.height, self.mode, self.fraction, self.heat_max, self.at_camera_size)
        if not drawn.drew and key == self._key:
            self._show(mono)
            return message
        compared = self._compared(drawn)
        if isinstance(compared, str):
            self.status = compared
            self._hide(mono)
            return message
        loaded = drawn.loaded
        self.render, photo = compared
        self.size = (photo.shape[1], photo.shape[0])
        self.psnr = psnr(self.render, photo)
        self.picture = self._picture(self.render, photo)
        self._key = key
        self._computed += 1
        self.status = self._measured(loaded, index)
        self._show(mono)
        return message

    def _compared(self, drawn: Drawn) -> tuple[np.ndarray, np.ndarray] | str:
        """(render, photo), both (H, W, 3) float32 in 0..1, at the window's size or the
        camera's own; or a line saying why there are none."""
        camera, loaded = drawn.camera, drawn.loaded
        photo = self._photo(loaded, drawn.index, None if self.at_camera_size else (camera.width, camera.height))
        if isinstance(photo, str):
            return photo
        photo, view = photo
        self.camera_size = (view.camera.width, view.camera.height)
        if not self.at_camera_size:
            return np.clip(drawn.mono.left.read()[..., :3], 0.0, 1.0), photo
        try:
            return drawn.render_at(view, self.photos.of(loaded)), photo
        except (UserError, MemoryError, moderngl.Error) as exc:
            return f"not rendered at the camera's size: {one_line(exc)}"

    def _picture(self, render: np.ndarray, photo: np.ndarray) -> np.ndarray | None:
        """The picture the mode shows instead of the window's render (None: the render)."""
        pictures: dict[PhotoMode, Callable[[], np.ndarray | None]] = {
            # At the camera's size the render compared is not the window's: it is shown instead.
            "render": lambda: render if self.at_camera_size else None,
            "photo": lambda: photo,
            "difference": lambda: difference_picture(render, photo, self.heat_max),
            "split": lambda: split_picture(photo, render, self.fraction),
        }
        return pictures[self.mode]()

    def _measured(self, loaded: LoadedScene, index: int) -> str:
        width, height = self.size
        text = f"{loaded.camera_names[index]}: PSNR {self.psnr:.2f} dB at {width}x{height}"
        if self.at_camera_size:
            text += " (the camera's size, as evaluate measures)"
        elif self.camera_size != self.size:
            text += f" (the window's size; the camera's is {self.camera_size[0]}x{self.camera_size[1]})"
        return text

    def _show(self, mono: MonoFrame) -> None:
        if self.picture is None:  # the render, compared: the PSNR stays
            self._detach(mono)
            return
        height, width = self.picture.shape[:2]
        if self.target is None or self.target.size != (width, height) or self._written != self._computed:
            self.target = sized(self.target, self.ctx, width, height, label="photo view")
            rgba = np.concatenate([self.picture, np.ones((height, width, 1), np.float32)], axis=2)
            self.target.texture.write(np.ascontiguousarray(rgba[::-1], np.float32).tobytes())  # GL: bottom row first
            self._written = self._computed
        mono.stereo_image = self.target

    def _hide(self, mono: MonoFrame) -> None:
        self.picture = self.psnr = None
        self._detach(mono)

    def _detach(self, mono: MonoFrame) -> None:
        if self.target is not None and mono.stereo_image is self.target:
            mono.stereo_image = None

    # -- the photos ---------------------------------------------------------------------
    def _photo(self, loaded: LoadedScene, index: int, size: tuple[int, int] | None
               ) -> tuple[np.ndarray, PhotoView] | str:
        """((H, W, 3) float32 at ``size`` (width, height; None: the camera's own), the
        dataset's view of it), or a line saying why there is none."""
        key = (index, size)
        if key not in self._photos:
            self._photos[key] = self._load(loaded, index, size)
            while len(self._photos) > CACHE_SIZE:
                self._photos.popitem(last=False)
        self._photos.move_to_end(key)
        return self._photos[key]

    def _load(self, loaded: LoadedScene, index: int, size: tuple[int, int] | None
              ) -> tuple[np.ndarray, PhotoView] | str:
        dataset = self.photos.of(loaded)
        if isinstance(dataset, str):
            return dataset
        name = loaded.camera_names[index]
        view = photo_view_named(dataset.views, name)
        if view is None:
            return f"no photo of {name} in {dataset.root}"
        try:
            photo = load_photo(view, dataset.background)
        except UserError as exc:
            return f"photo not loaded: {one_line(exc)}"
        if size is not None and photo.shape[:2] != (size[1], size[0]):
            photo = resize_picture(photo, *size)
        return photo, view


def photo_view_named(views: tuple[PhotoView, ...], name: str) -> PhotoView | None:
    """The view whose image is ``name`` (a cameras.json img_name, without extension)."""
    for view in views:
        if view.name == name or Path(view.name).stem == name:
            return view
    return None


def blocked_reason(stereo: bool, split: bool, channel: str) -> str:
    """Why the Photo view cannot show now ("" when it can)."""
    if stereo:
        return "the Photo view is off in the stereo preview"
    if split:
        return "the Photo view is off while the A/B split view is on"
    if channel != "rgb":
        return f"the Photo view compares the colour, not the {channel} view"
    return ""
