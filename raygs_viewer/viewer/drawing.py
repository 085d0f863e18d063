"""Drawing the scene for the window: the mono frame (both sides in the A/B split view)
or the stereo frame, each time the view, the settings or the order changed, under the
GPU timers the panel and the summary read.

In the split view both sides render the whole viewport with the same order (sorted
with the more conservative cull of the two); the present pass shows each on its side
of the divider. In the stereo preview both eyes are drawn offscreen with one order
sorted from their midpoint, then the lens preview and the layout compose one image.
"""

from __future__ import annotations

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_key
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.mono_frame import MonoFrame
from raygs_viewer.render.gl.stereo_frame import StereoFrame
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.viewer.state import PanelState
from raygs_viewer.viewer.stats import FrameStats


def sort_cull(camera: Camera, left: RenderSettings, right: RenderSettings | None = None
              ) -> tuple[float, float | None]:
    """(p_min, dilation) of the one sort that serves every side shown: the more
    conservative cull of the two (the smaller p_min; no frustum culling if either side
    needs none, else the larger dilation)."""
    sides = [left] if right is None else [left, right]
    dilations = [side.cull_dilation(camera) for side in sides]
    dilation = None if any(d is None for d in dilations) else max(dilations)
    return min(side.p_min for side in sides), dilation


class SceneDrawer:
    """The window's frames (``mono``, and ``stereo`` once the preview has been on) and
    the timers of their passes: ``timer`` the scene's draw (both sides in the split
    view, both eyes in stereo), ``post_timer`` the stereo lens preview and layout."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.mono = MonoFrame(ctx)
        self.stereo: StereoFrame | None = None
        self.timer = GpuTimer(ctx)
        self.post_timer = GpuTimer(ctx)

    def draw(self, renderer, camera: Camera, settings: RenderSettings, right: RenderSettings | None,
             stereo: StereoView | None, order: np.ndarray, serial: int, stats: FrameStats, panel: PanelState) -> None:
        """Draws ``order`` (sort request ``serial``) unless the frame already holds this
        view, these settings and this order, and notes the draw and its GPU times in
        ``stats``. Settings this GPU cannot render (the panel greys those out) are a
        standing error in ``panel``; the frame is then drawn again next time."""
        try:
            drew = self._draw(renderer, camera, settings, right, stereo, order, serial)
        except UserError as exc:
            panel.stand("draw", f"error: {one_line(exc)}")
            return
        if drew:
            panel.mend("draw")
            stats.drawn_serial, stats.draws = serial, stats.draws + 1
        stats.gpu_seconds, stats.post_seconds = self.timer.seconds, self.post_timer.seconds

    def _draw(self, renderer, camera: Camera, settings: RenderSettings, right: RenderSettings | None,
              stereo: StereoView | None, order: np.ndarray, serial: int) -> bool:
        key = (camera_key(camera), settings, right, stereo, serial)
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
        if stereo is None:
            with self.timer.measure():  # the whole frame's GPU time, both sides in the split view
                renderer.render_into(left_target, camera, settings, order)
                if right is not None:
                    renderer.render_into(right_target, camera, right, order)
            self.mono.drawn(key)
        else:
            with self.timer.measure():  # both eyes: what the frame-budget meter compares
                self.stereo.draw_eyes(renderer, camera, settings, stereo.rig, order)
            with self.post_timer.measure():
                self.stereo.finish(stereo)
            self.mono.drawn(key, self.stereo.image)
        return True

    def release(self) -> None:
        self.mono.release()
        if self.stereo is not None:
            self.stereo.release()
            self.stereo = None
