"""The window's screenshots: its last view re-rendered offscreen at the chosen scale with
an exact sort (no panel), saved as PNG with a JSON sidecar each, so every image
reproduces headlessly (``raygs-viewer render --sidecar``).

In the split view each side is saved whole with its own settings and sidecar
(``<name>-left.png``, ``<name>-right.png``). In the stereo preview: the side-by-side
pair of eyes at the headset's size times the scale, and on request each eye
(``<name>-pair.png``, ``<name>-left.png``, ``<name>-right.png``).

In a view mode (a depth, median depth, normal or alpha picture) the screenshot is that
picture, in the depth range the window showed (an automatic range is fixed to the one
in use, so the file shows what the window did), and the sidecar's "channel_view" records
it (capture/sidecar.py), so ``render --sidecar`` draws the same picture again.

A streamed SOG's screenshot draws the level-of-detail choice for its own camera, as
``render --sidecar`` does with the settings the sidecar records (budget, distance, level):
every side and eye sorts that one choice's rows.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import moderngl
import numpy as np

from raygs_viewer.camera.navigation import Navigator
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.capture.screenshot import (
    render_tiled,
    render_tiled_channels,
    save_screenshot,
    save_screenshots,
    scaled_camera,
)
from raygs_viewer.capture.sidecar import ImageView, build_sidecar
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ChannelView, channel_picture
from raygs_viewer.render.gl.stereo_frame import render_stereo_view, stereo_order
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest
from raygs_viewer.sort.request import Order
from raygs_viewer.viewer.state import Message, ScreenshotOptions, SplitView, done, failed

#: (png, sidecar) paths of one saved image.
Saved = tuple[Path, Path]


@dataclass(frozen=True)
class ShownView(ImageView):
    """What the window showed in its last frame: the camera (viewport-sized; in stereo
    the midpoint between the eyes at the headset's size), the render settings (the
    left side's in the split view), the stereo view when the preview was on, the
    picture shown instead of the colour (its depth range the one in use); and the split
    view when it was shown, with the picture its right side showed."""

    split: SplitView | None = None
    right_view: ChannelView | None = None


def sidecar_extra(navigator: Navigator, loaded: LoadedScene, training_index: int | None, gl: str) -> dict:
    """The window's details every sidecar records besides the view: navigation, the
    training camera flown to, the GL renderer."""
    return {"navigation": navigator.mode, "up_axis": navigator.up, "training_camera": training_index,
            "training_camera_name": loaded.camera_names[training_index] if training_index is not None else None,
            "gl": gl}


@dataclass(frozen=True)
class Offscreen:
    """What renders a screenshot: the window's renderer, an exact sorter of its scene, and
    a streamed SOG's level choice for the screenshot's camera (None: the whole scene), and
    the rows deleted in the window (None: none)."""

    renderer: object
    sorter: DepthSorter
    levels: LodChoice | None = None
    deleted: DeletedRows | None = None

    def order(self, camera: Camera, settings: RenderSettings) -> Order:
        return exact_order(self.sorter, camera, settings, levels=self.levels, deleted=self.deleted)


@dataclass(frozen=True)
class Shot:
    """A screenshot to take: the view ``shown``, the scene as ``loaded``, a streamed SOG's
    level-of-detail request (made for the screenshot's camera: both sides, both eyes take
    the one camera's choice; None: the whole scene), whether the stereo eyes are saved
    besides the pair, what every sidecar records besides the view (:func:`sidecar_extra`,
    and the edit document where the scene was edited), and the rows deleted (None: none)."""

    shown: ShownView
    loaded: LoadedScene
    lod: LodRequest | None = None
    save_eyes: bool = False
    extra: dict = field(default_factory=dict)
    deleted: DeletedRows | None = None
    edits: dict | None = None


def take_screenshots(renderer, sorter: DepthSorter, shot: Shot, options: ScreenshotOptions,
                     path: str | Path | None = None) -> list[Saved]:
    """Renders ``shot`` at ``options.scale`` with exact sorts by ``sorter`` and saves it
    into ``options.folder`` (or at ``path``, tagged names beside it for several images);
    never overwrites anything. Returns every (png, json) pair written, the left side's or
    the pair's first."""
    camera = scaled_camera(shot.shown.camera, options.scale)
    offscreen = Offscreen(renderer, sorter, None if shot.lod is None else shot.lod.choose(camera), shot.deleted)
    return _take(offscreen, shot, options, path, camera)


def _take(offscreen: Offscreen, shot: Shot, options: ScreenshotOptions, path: str | Path | None,
          camera: Camera) -> list[Saved]:
    loaded, shown, extra, scale = shot.loaded, shot.shown, shot.extra, options.scale
    scene_path = loaded.source.recorded_path
    sha256 = loaded.content_sha256

    def sidecar(settings: RenderSettings, details: dict, stereo: StereoView | None = None,
                view: ChannelView | None = shown.channel_view) -> dict:
        return build_sidecar(scene_path=scene_path, scene_sha256=sha256, scene=loaded.scene, camera=camera,
                             settings=settings, scale=scale, window_camera=shown.camera, extra=details, stereo=stereo,
                             channel_view=view, levels=levels_read(loaded, settings), edits=shot.edits)

    if shown.stereo is not None:
        shots = [(image, sidecar(shown.settings, {**extra, "stereo_window_layout": shown.stereo.layout}, view), tag)
                 for image, view, tag in _stereo_images(offscreen, camera, shown.settings, shown.stereo,
                                                        save_eyes=shot.save_eyes, view=shown.channel_view)]
    elif shown.split is None:
        shots = [(render_shown(offscreen, camera, shown.settings, shown.channel_view), sidecar(shown.settings, extra),
                  "left")]
    else:
        split = shown.split
        shots = [(render_shown(offscreen, camera, settings, view), sidecar(settings, {**extra, "split_view": {
                     "side": side, "preset": split.preset if side == "right" else None, "divider": split.fraction}},
                     view=view), side)
                 for side, settings, view in (("left", shown.settings, shown.channel_view),
                                              ("right", split.right(shown.settings), shown.right_view))]
    if len(shots) == 1:
        image, data, _ = shots[0]
        if path is not None:
            return [save_screenshot(image, data, path=Path(path))]
        return [save_screenshot(image, data, folder=Path(options.folder))]
    if path is not None:
        return save_screenshots(shots, path=Path(path))
    return save_screenshots(shots, folder=Path(options.folder))


def levels_read(loaded: LoadedScene, settings: RenderSettings) -> tuple[int, ...] | None:
    """A streamed SOG's levels read, when its levels are chosen per view: the choice
    depends on them (while finer ones are still being read, or on a GPU that holds fewer)."""
    if loaded.lod is None or settings.lod is not None:
        return None
    return tuple(np.flatnonzero(loaded.lod.loaded).tolist())


def render_shown(offscreen: Offscreen, camera: Camera, settings: RenderSettings, view: ChannelView | None
                 ) -> np.ndarray:
    """(H, W, 4) float32, top row first: the colour (tiled), or the picture ``view``
    shows (alpha 1)."""
    renderer, sorter, order = offscreen.renderer, offscreen.sorter, offscreen.order(camera, settings)
    if view is None:
        return render_tiled(renderer, sorter, order, camera, settings)
    channels = render_tiled_channels(renderer, sorter, order, camera, settings, median=view.channel == "median_depth")
    channels = channels.in_space(view.normal_space, camera)
    picture, _ = channel_picture(channels, view)
    return np.concatenate([picture, np.ones(picture.shape[:2] + (1,), np.float32)], axis=-1)


def _stereo_images(offscreen: Offscreen, camera: Camera, settings: RenderSettings, stereo: StereoView, *,
                   save_eyes: bool, view: ChannelView | None) -> list[tuple[np.ndarray, StereoView, str]]:
    """The side-by-side pair whatever the window's layout (the sidecar notes that
    layout), and each eye when asked, each with the view that reproduces it."""
    pair = replace(stereo, layout="sbs")
    order = stereo_order(offscreen.sorter, camera, settings, stereo.rig, levels=offscreen.levels,
                         deleted=offscreen.deleted)
    image, left, right = render_stereo_view(offscreen.renderer, order, camera, settings, pair, channel_view=view)
    shots = [(image, pair, "pair")]
    if save_eyes:
        shots += [(left, replace(stereo, layout="left"), "left"), (right, replace(stereo, layout="right"), "right")]
    return shots


class Captures:
    """What the window saves of itself: screenshots (``options``: the folder and the
    scale, which the panel edits; ``requested``: one at the end of the next frame;
    ``saved``: every (png, json) pair of the last, the left side's or the stereo pair's
    first) and its own image (``keep_next``: keep the next frame's, in ``window``:
    (H, W, 3) uint8, the panel included)."""

    def __init__(self, options: ScreenshotOptions):
        self.options = options
        self.requested = False
        self.saved: list[Saved] = []
        self.keep_next = False
        self.window: np.ndarray | None = None

    @property
    def last(self) -> Saved | None:
        """The (png, json) pair of the last screenshot (the left side's, or the stereo pair's)."""
        return self.saved[0] if self.saved else None

    def request(self) -> None:
        """A screenshot at the end of the next frame."""
        self.requested = True

    def take(self, renderer, sorter: DepthSorter, shot: Shot, path: str | Path | None = None) -> Saved:
        """Saves ``shot`` (:func:`take_screenshots`); returns :attr:`last`."""
        self.saved = take_screenshots(renderer, sorter, shot, self.options, path)
        return self.last

    def due(self) -> bool:
        """Whether a screenshot was requested since the last call (the request is then taken)."""
        requested, self.requested = self.requested, False
        return requested

    def window_due(self) -> bool:
        """Whether the frame shown now is to be kept (the request is then taken): set
        :attr:`window` to its image."""
        keep, self.keep_next = self.keep_next, False
        return keep


def screenshot_said(take: Callable[[], list[Saved]]) -> Message:
    """What the panel says of a screenshot ``take`` saves: the files written, or why
    nothing was."""
    try:
        return done(saved_message(take()))
    except (UserError, MemoryError, moderngl.Error) as exc:
        return failed(exc, "screenshot not saved")


def saved_message(saved: list[Saved]) -> str:
    """The panel's line about what a capture wrote."""
    if len(saved) == 1:
        return f"saved {saved[0][0]}"
    return "saved " + " and ".join(str(png) for png, _ in saved) + " (each with its .json sidecar)"
