"""Drawing the scene for the window: the mono frame (both sides in the A/B split view)
or the stereo frame, each time the view, the settings or the order changed, under the
GPU timers the panel and the summary read.

Each side draws the order of its settings' sort key (``RenderSettings.sort_key``:
depth or distance; per-pixel order is fed in the depth order). One sort serves every
side shown: the window asks the background sorter for one cull (the more
conservative of the two sides') and an order per distinct key (:func:`sort_keys`).
In the split view both sides render the whole viewport, each with its key's order;
the present pass shows each on its side of the divider. In the stereo preview both
eyes are drawn offscreen with one order sorted from their midpoint, then the lens
preview and the layout compose one image.

After each per-pixel-order render the renderer's ``order_stats`` (what the per-pixel
pass did: fragments, pool, parts) is kept in the frame statistics, per side.

A streamed SOG's level-of-detail choice is made on the sort thread with the order
(``request_sort``'s ``lod``); every side and eye draws the one result, so the renderer
is restricted to that result's rows (``SceneDrawer.draw``'s ``spans``) before drawing.

A channel view (the panel's view mode: depth, median depth, normal or alpha) is drawn
on every side and eye; an automatic depth range is the left side's (or left eye's),
fixed for the other, so that one colour is one depth across the divider.
"""

from __future__ import annotations

from typing import Mapping

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_key
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.mono_frame import MonoFrame
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.gl.stereo_frame import StereoFrame, fixed_range, view_argument
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.lod_choice import LodRequest
from raygs_viewer.viewer.state import PanelState
from raygs_viewer.viewer.stats import FrameStats, sort_key


def sort_cull(camera: Camera, left: RenderSettings, right: RenderSettings | None = None
              ) -> tuple[float, float | None]:
    """(p_min, dilation) of the one sort that serves every side shown: the more
    conservative cull of the two (the smaller p_min; no frustum culling if either side
    needs none, else the larger dilation)."""
    sides = [left] if right is None else [left, right]
    dilations = [side.cull_dilation(camera) for side in sides]
    dilation = None if any(d is None for d in dilations) else max(dilations)
    return min(side.p_min for side in sides), dilation


def sort_keys(left: RenderSettings, right: RenderSettings | None = None) -> tuple[str, ...]:
    """The sort keys of every side shown, the left's first, each once."""
    return tuple(dict.fromkeys(side.sort_key for side in (left, right) if side is not None))


def request_sort(sorter, stats: FrameStats, camera: Camera, settings: RenderSettings, right: RenderSettings | None,
                 cull_cameras, frame_index: int, wait: bool = False, lod: LodRequest | None = None
                 ) -> tuple[object, tuple]:
    """Asks ``sorter`` (a BackgroundSorter) for this frame's view: one cull for every side
    shown, an order per key, of the levels ``lod`` chooses for the view (a streamed SOG);
    ``wait``: until that sort is done (a scripted run's last frame). Returns (its newest
    finished result, the key of the orders this view wants: stats.order_to_draw takes both)."""
    p_min, dilation = sort_cull(camera, settings, right)  # the eyes share the midpoint's fx, fy
    keys = sort_keys(settings, right)
    serial = sorter.request(camera, p_min, dilation, cull_cameras, keys, lod)
    stats.asked(serial, frame_index)
    if wait:
        sorter.wait(serial, timeout=120)
    result = sorter.latest()
    if sorter.started > sorter.finished:
        stats.frames_with_sort_running += 1
    return result, sort_key(camera, p_min, dilation, cull_cameras, keys, None if lod is None else lod.key)


def order_for(orders: Mapping[str, np.ndarray], key: str) -> np.ndarray:
    """The order sorted by ``key``; while the sort for a newly chosen key is under way,
    another key's order of the same gaussians (the image is drawn, only its blending
    order is the old one, and the statistics show the order as not up to date); empty
    before the first sort."""
    if key in orders:
        return orders[key]
    return next(iter(orders.values()), np.zeros(0, np.uint32))


class SceneDrawer:
    """The window's frames (``mono``, and ``stereo`` once the preview has been on) and
    the timers of their passes: ``timer`` the scene's draw (both sides in the split
    view, both eyes in stereo), ``post_timer`` the stereo lens preview and layout.
    ``view``: the picture the last frame showed (None: the colour), ``view_range``: the
    depth range it uses (None: not a depth view); ``orders``: the orders of the last
    frame, by sort key (what a pick in the view draws with)."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.mono = MonoFrame(ctx)
        self.stereo: StereoFrame | None = None
        self.timer = GpuTimer(ctx)
        self.post_timer = GpuTimer(ctx)
        self.view: ChannelView | None = None
        self.right_view: ChannelView | None = None
        self.view_range: tuple[float, float] | None = None
        self.orders: dict[str, np.ndarray] = {}

    def draw(self, renderer, camera: Camera, settings: RenderSettings, right: RenderSettings | None,
             stereo: StereoView | None, orders: Mapping[str, np.ndarray], serial: int, stats: FrameStats,
             panel: PanelState, view: ChannelView | None = None, right_view: ChannelView | None = None,
             spans: np.ndarray | None = None) -> None:
        """Draws each side with its key's order from ``orders`` ({sort key: order} of
        sort request ``serial``) unless the frame already holds this view, these settings
        and these orders, and notes the draw, its GPU times and the per-pixel order's
        statistics in ``stats``. ``view``: the picture shown instead of the colour (the
        left side's in the split view; ``right_view`` the right side's). ``spans``: the rows
        of the level-of-detail choice the orders hold (None: the whole scene); the renderer
        stays restricted to them, so that a pick draws what was drawn.
        Settings this GPU cannot render (the panel greys those out) are a standing error
        in ``panel``; the frame is then drawn again next time."""
        self.orders, self.view, self.right_view = dict(orders), view, right_view
        if spans is not None:
            renderer.restrict(spans)
        try:
            drew = self._draw(renderer, camera, settings, right, stereo, orders, serial, stats, view, right_view)
        except UserError as exc:
            panel.stand("draw", f"error: {one_line(exc)}")
            return
        if drew:
            panel.mend("draw")
            stats.drawn_serial, stats.draws = serial, stats.draws + 1
        stats.gpu_seconds, stats.post_seconds = self.timer.seconds, self.post_timer.seconds

    def _draw(self, renderer, camera: Camera, settings: RenderSettings, right: RenderSettings | None,
              stereo: StereoView | None, orders: Mapping[str, np.ndarray], serial: int, stats: FrameStats,
              view: ChannelView | None, right_view: ChannelView | None) -> bool:
        key = (camera_key(camera), settings, right, stereo, view, right_view, serial)
        if stereo is None:
            left_target, right_target = self.mono.targets(camera.width, camera.height, split=right is not None)
        elif self.stereo is None:
            self.stereo = StereoFrame(self.ctx)
        self.mono.split = right is not None
        if self.mono.holds(key):
            # The image shown is still right. The GPU is idle as far as this view goes,
            # so the last timings can be read without stalling.
            self.timer.flush()
            self.post_timer.flush()
            return False
        self.mono.forget()
        order = order_for(orders, settings.sort_key)
        if stereo is None:
            with self.timer.measure():  # the whole frame's GPU time, both sides in the split view
                renderer.render_into(left_target, camera, settings, order, **view_argument(view))
                self.view_range = None if view is None else renderer.geometry.view_range
                left_stats = _order_stats(renderer, settings)
                right_stats = None
                if right is not None:
                    # One depth range for both sides where both show depths: one colour, one depth.
                    renderer.render_into(right_target, camera, right, order_for(orders, right.sort_key),
                                         **view_argument(fixed_range(right_view, self.view_range)))
                    right_stats = _order_stats(renderer, right)
                    if self.view_range is None and right_view is not None:
                        self.view_range = renderer.geometry.view_range
            stats.order_stats = (left_stats, right_stats)
            self.mono.drawn(key)
        else:
            with self.timer.measure():  # both eyes: what the frame-budget meter compares
                self.stereo.draw_eyes(renderer, camera, settings, stereo.rig, order, view)
                self.view_range = self.stereo.view_range
            stats.order_stats = (_order_stats(renderer, settings), None)  # the last eye's (the right)
            with self.post_timer.measure():
                self.stereo.finish(stereo)
            self.mono.drawn(key, self.stereo.image)
        return True

    @property
    def shown_view(self) -> ChannelView | None:
        """``view`` with an automatic range fixed to the one in use: what reproduces the
        picture shown (screenshots)."""
        return fixed_range(self.view, self.view_range)

    @property
    def shown_right_view(self) -> ChannelView | None:
        """:attr:`shown_view` of the split view's right side."""
        return fixed_range(self.right_view, self.view_range)

    def forget(self) -> None:
        """A new scene: nothing drawn is of it."""
        self.mono.forget()
        self.orders = {}

    def release(self) -> None:
        self.mono.release()
        if self.stereo is not None:
            self.stereo.release()
            self.stereo = None


def _order_stats(renderer, settings: RenderSettings):
    """What the renderer's last per-pixel-order render did (None for a global order, or
    a renderer that reports nothing)."""
    return getattr(renderer, "order_stats", None) if settings.per_pixel else None
