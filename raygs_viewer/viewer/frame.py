"""One frame of the window as a value: what it draws and from where.

``Viewer.frame`` makes one :class:`Frame`, once, after the input has moved the camera
and the panel has returned what it changed (so every edit shows in the frame it is
made in), and hands it to everything that works on the frame: the sort request
(``drawing.request_sort``), the drawer (``drawing.SceneDrawer.draw``, whose report the
statistics record with the drawn order's age), the overlays; the viewer keeps the last
one (``Viewer.shown``), which picks, the next frame's input and panel, and screenshots
read. Nothing in it is derived twice: the eye cameras come from
``view_control.ViewControl.camera`` and are the ones the stereo frame draws; the sort
request is made here from the rest.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import sort_request
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.lod_choice import LodRequest
from raygs_viewer.sort.request import SortRequest

#: The viewport before the first frame.
NO_VIEWPORT: Viewport = (0, 0, 1, 1)


class Framing(NamedTuple):
    """Where a frame looks from (``ViewControl.camera``): the camera (viewport-sized, or
    in stereo the midpoint between the eyes at the size previewed: the headset's, or
    smaller to fit the view area), where its image is shown, and the eye cameras (None:
    mono)."""

    camera: Camera
    viewport: Viewport
    eyes: tuple[Camera, Camera] | None


@dataclass(frozen=True, eq=False)
class Frame:
    """One frame's inputs.

    index:      the frame's number (``Viewer.frame_index``).
    camera:     the view drawn: viewport-sized, or in stereo the midpoint between the eyes
                at the per-eye size previewed (its order is sorted from there;
                :attr:`full_camera` is it at the headset's size).
    viewport:   where the image is shown in the window: inside the view area
                (``layout.view_area``), the part of the window the panel leaves.
    eyes:       the eye cameras drawn in stereo (None: mono), made once with ``camera``.
    stereo:     the stereo view (None: the preview is off).
    settings:   the render settings (the left side's in the split view).
    right:      the split view's right side (None: no split view).
    lod:        a streamed SOG's level-of-detail request (None: the whole scene).
    sort:       the sort this frame asks for: one cull for every side and eye, an order per key.
    view, right_view: the pictures shown instead of the colour (left and right side;
                both the same outside the split view); None: the colour.
    """

    index: int
    camera: Camera
    viewport: Viewport
    eyes: tuple[Camera, Camera] | None
    stereo: StereoView | None
    settings: RenderSettings
    right: RenderSettings | None
    lod: LodRequest | None
    sort: SortRequest
    view: ChannelView | None = None
    right_view: ChannelView | None = None

    @classmethod
    def make(cls, index: int, framing: Framing, *, stereo: StereoView | None, settings: RenderSettings,
             right: RenderSettings | None, lod: LodRequest | None, deleted: DeletedRows | None = None,
             views: tuple[ChannelView | None, ChannelView | None] = (None, None)) -> Frame:
        """The frame of ``framing`` with these settings and (left, right) channel views,
        and the one sort that serves it (``render.sorting.sort_request``: culled for both
        eyes in stereo, without the ``deleted`` rows)."""
        camera, viewport, eyes = framing
        return cls(index, camera, viewport, eyes, stereo, settings, right, lod,
                   sort_request(camera, settings, right, cull_cameras=eyes, levels=lod, deleted=deleted), *views)

    @property
    def full_camera(self) -> Camera:
        """The view at the size it is saved at: ``camera``, or in stereo the midpoint at
        the headset's per-eye size (the window may preview the eyes smaller;
        screenshots and videos take the headset's)."""
        return self.camera if self.stereo is None else self.stereo.headset.camera(self.camera)

    @property
    def split(self) -> bool:
        """Whether the split view is shown."""
        return self.right is not None
