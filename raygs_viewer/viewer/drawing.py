"""Drawing the scene for the window: the mono frame (both sides in the A/B split view)
or the stereo frame, each time the view, the settings or the order changed, under the
GPU timers the panel and the summary read.

Each side draws the order of its settings' sort key (``RenderSettings.sort_key``:
depth or distance; per-pixel order is fed in the depth order). One sort serves every
side shown: the window asks the background sorter for one cull (the more
conservative of the two sides') and an order per distinct key: the frame's ``sort``
(``frame.Frame``, made with ``render.sorting.sort_request``).
In the split view both sides render the whole viewport, each with its key's order;
the present pass shows each on its side of the divider. In the stereo preview both
eyes (the frame's ``eyes``) are drawn offscreen with one order sorted from their
midpoint, then the lens preview and the layout compose one image.

Each render returns what the per-pixel pass did (fragments, pool, parts); the frame
statistics keep it, per side.

A streamed SOG's level-of-detail choice is made on the sort thread with the order
(the frame's ``lod``); every side and eye draws the one result, whose orders
carry the choice's rows.

A channel view (the panel's view mode: depth, median depth, normal or alpha) is drawn
on every side and eye; an automatic depth range is the left side's (or left eye's),
fixed for the other, so that one colour is one depth across the divider.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Mapping, Sequence

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import camera_key
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.gl.mono_frame import MonoFrame, frame_dtypes
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.results import OrderStats
from raygs_viewer.render.gl.stereo_frame import StereoFrame, fixed_range
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.sort.request import Order, SortResult
from raygs_viewer.sort.worker import BackgroundSorter, InlineSorter
from raygs_viewer.viewer.frame import Frame

#: What a frame draws before the first sort.
EMPTY_ORDER = Order(np.zeros(0, np.uint32))


@dataclass(frozen=True)
class SortAsked:
    """A frame's sort request to the frames' sorter: its ``serial``, and whether a sort
    was still running after it was asked (this one, or an older one)."""

    serial: int
    running: bool


def request_sort(sorter: BackgroundSorter | InlineSorter, frame: Frame, wait: bool = False
                 ) -> tuple[SortResult | None, SortAsked]:
    """Asks ``sorter`` for ``frame``'s sort (one cull for every side shown, an order per
    key, of the levels its ``lod`` chooses for the view: a streamed SOG); ``wait``: until
    that sort is done (a scripted run's last frame). Returns its newest finished result,
    and what was asked."""
    serial = sorter.request(frame.sort)
    if wait:
        sorter.wait(serial, timeout=120)
    result = sorter.latest()
    return result, SortAsked(serial, sorter.started > sorter.finished)


def order_for(orders: Mapping[str, Order], key: str) -> Order:
    """The order sorted by ``key``; while the sort for a newly chosen key is under way,
    another key's order of the same gaussians (the image is drawn, only its blending
    order is the old one, and the statistics show the order as not up to date); empty
    before the first sort."""
    if key in orders:
        return orders[key]
    return next(iter(orders.values()), EMPTY_ORDER)


@dataclass(frozen=True, eq=False)
class DrawReport:
    """What a frame's draw did, as :meth:`SceneDrawer.draw` returns it: the ``frame``, the
    sort it ``asked`` for, the sort ``result`` it drew (None: none yet), whether it drew
    the scene again (``drew``: else the image already held this view) and when (``at``, a
    perf_counter time); ``problem``: why these settings cannot be drawn here (None: they
    can); the GPU seconds of the scene's draw and of the stereo lens preview and layout,
    as the timers last read them, and the GPU sort's ``sort_timer`` (None: the CPU
    sorts); what the per-pixel order did on each side (left or the only one, the split
    view's right; None: a global order, or not drawn again)."""

    frame: Frame
    asked: SortAsked
    result: SortResult | None
    drew: bool
    at: float
    problem: str | None = None
    gpu_seconds: float = float("nan")
    post_seconds: float = float("nan")
    sort_timer: GpuTimer | None = None
    order_stats: tuple[OrderStats | None, OrderStats | None] | None = None

    @property
    def serial(self) -> int:
        """The sort request whose order was drawn (0: none)."""
        return 0 if self.result is None else self.result.serial


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
        self.orders: dict[str, Order] = {}

    def draw(self, renderer: GLRenderer, frame: Frame, result: SortResult | None, asked: SortAsked,
             sort_timer: GpuTimer | None = None) -> DrawReport:
        """Draws each side of ``frame`` with its key's order from ``result`` (the newest
        finished sort: {sort key: order}; None: none yet) unless the frame already holds
        this view, these settings and these orders, and reports what it did. The orders
        carry the rows of their level-of-detail choice, which a pick draws too. Settings
        this GPU cannot render (the panel greys those out) are the report's problem; the
        frame is then drawn again next time."""
        orders, serial = ({}, 0) if result is None else (result.orders, result.serial)
        self.orders, self.view, self.right_view = dict(orders), frame.view, frame.right_view
        try:
            drew, order_stats = self._draw(renderer, frame, orders, serial)
        except UserError as exc:
            return DrawReport(frame, asked, result, False, time.perf_counter(), one_line(exc),
                              sort_timer=sort_timer)
        return DrawReport(frame, asked, result, drew, time.perf_counter(), None, self.timer.seconds,
                          self.post_timer.seconds, sort_timer, order_stats)

    def _draw(self, renderer: GLRenderer, frame: Frame, orders: Mapping[str, Order], serial: int
              ) -> tuple[bool, tuple[OrderStats | None, OrderStats | None] | None]:
        camera, settings, right, stereo = frame.camera, frame.settings, frame.right, frame.stereo
        key = (camera_key(camera), settings, right, stereo, frame.view, frame.right_view, serial,
               renderer.selection_key)
        if stereo is None:
            right_dtypes = ("f4",) if right is None else frame_dtypes(renderer, right, frame.right_view)
            left_target, right_target = self.mono.targets(camera.width, camera.height, right is not None,
                                                          frame_dtypes(renderer, settings, frame.view), right_dtypes)
        elif self.stereo is None:
            self.stereo = StereoFrame(self.ctx, narrow=True)
        self.mono.split = right is not None
        if self.mono.holds(key):
            # The image shown is still right. The GPU is idle as far as this view goes,
            # so the last timings can be read without stalling.
            self.timer.flush()
            self.post_timer.flush()
            return False, None
        self.mono.forget()
        order = order_for(orders, settings.sort_key)
        if stereo is None:
            with self.timer.measure():  # the whole frame's GPU time, both sides in the split view
                left = renderer.render_into(left_target, camera, settings, order, view=frame.view)
                self.view_range = left.view_range
                right_result = None
                if right is not None:
                    # One depth range for both sides where both show depths: one colour, one depth.
                    right_result = renderer.render_into(right_target, camera, right, order_for(orders, right.sort_key),
                                                        view=fixed_range(frame.right_view, self.view_range))
                    if self.view_range is None:
                        self.view_range = right_result.view_range
            self.mono.drawn(key)
            return True, (left.order_stats, None if right_result is None else right_result.order_stats)
        with self.timer.measure():  # both eyes: what the frame-budget meter compares
            _, last_eye = self.stereo.draw_eyes(renderer, camera, settings, frame.eyes, order, view=frame.view)
            self.view_range = last_eye.view_range
        with self.post_timer.measure():
            self.stereo.finish(stereo)
        self.mono.drawn(key, self.stereo.image)
        return True, (last_eye.order_stats, None)  # the last eye's (the right)

    def gpu_times(self) -> tuple[Sequence[float], Sequence[float]]:
        """Every draw's GPU seconds so far, the last one's included: the scene's (both sides,
        both eyes) and the stereo lens preview and layout's."""
        self.timer.flush()
        self.post_timer.flush()
        return self.timer.history, self.post_timer.history

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
