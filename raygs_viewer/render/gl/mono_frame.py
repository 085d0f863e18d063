"""The GL side of the window's mono frame, the twin of :mod:`raygs_viewer.render.gl.stereo_frame`:
the targets the scene is drawn into, at the blend precision (the A/B split view's right
side in a second one), the key of what they hold (a still view is not drawn again), the
present pass that shows the drawn image letterboxed in the window, and the capture of
the window.

The present pass (``present.frag`` over ``fullscreen.vert``) shows the left target, or the
stereo frame's composed image while the last draw was stereo; in the split view the
viewport's columns from the divider's on show the right target. Nothing here knows
imgui: a capture takes what draws over the image (the panel) as a callable.
"""

from __future__ import annotations

from typing import Callable, Hashable

import moderngl
import numpy as np

from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.gl.shaders import Programs
from raygs_viewer.render.gl.targets import FloatTarget, release_all, sized
from raygs_viewer.render.settings import RenderSettings

#: The letterbox bars' grey (linear 0..1), around an image of another aspect ratio.
LETTERBOX_GREY = 0.12

#: (x, y, w, h): the image's rectangle in the window's framebuffer, y from the top.
Viewport = tuple[int, int, int, int]


def frame_dtypes(renderer, settings: RenderSettings, view: ChannelView | None = None) -> tuple[str, ...]:
    """The kind of a window's scene target for ``settings``: the one ``renderer`` draws
    straight into (``RenderPlan.direct_dtypes``), so a narrow blend precision costs the
    frame no copy pass and the present pass reads what was blended; float32 under a
    channel ``view``, whose picture is drawn in float32."""
    if view is not None and view.channel != "rgb":
        return ("f4",)
    return renderer.plan(settings).direct_dtypes


class MonoFrame:
    """Targets are made on first use and again when the size changes."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.left: FloatTarget | None = None    # the scene (the split view's left side)
        self.right: FloatTarget | None = None   # the split view's right side
        #: The stereo frame's composed image, shown instead of ``left`` while the last
        #: draw was stereo (see :meth:`drawn`).
        self.stereo_image: FloatTarget | None = None
        #: Whether present shows ``right`` right of the divider: the split view was on
        #: in the last frame.
        self.split = False
        self._key: Hashable | None = None
        self._programs = Programs(ctx)
        self._program, self._vao = self._programs.fullscreen("present.frag")

    def targets(self, width: int, height: int, split: bool, dtypes: tuple[str, ...] = ("f4",),
                right_dtypes: tuple[str, ...] = ("f4",)) -> tuple[FloatTarget, FloatTarget | None]:
        """(left, right) at width x height, of the kinds ``dtypes`` and ``right_dtypes``
        (:func:`frame_dtypes`); right only in the split view. A target made anew (a new
        size or precision) holds nothing yet, so the next :meth:`holds` is False."""
        left = sized(self.left, self.ctx, width, height, dtypes=dtypes)
        right = sized(self.right, self.ctx, width, height, dtypes=right_dtypes) if split else None
        if left is not self.left or (split and right is not self.right):
            self._key = None
        self.left = left
        if split:
            self.right = right
        return left, right

    def holds(self, key: Hashable) -> bool:
        """Whether the last draw was of ``key`` (view, settings, order...): then the
        image shown is still right and nothing needs drawing."""
        return self._key is not None and self._key == key

    def drawn(self, key: Hashable, stereo_image: FloatTarget | None = None) -> None:
        """Records a finished draw of ``key``: into the targets, or the stereo frame's
        ``stereo_image``."""
        self._key = key
        self.stereo_image = stereo_image

    def forget(self) -> None:
        """The next draw must happen (the last one failed)."""
        self._key = None

    def present(self, screen: moderngl.Framebuffer, window: tuple[int, int], viewport: Viewport,
                split_column: int) -> None:
        """Clears ``screen`` (window = (width, height)) to the letterbox grey and shows
        the drawn image scaled into ``viewport``; in the split view ``right`` from
        viewport column ``split_column`` on."""
        width, height = window
        x, y, w, h = viewport
        screen.use()
        screen.viewport = (0, 0, width, height)
        self.ctx.clear(LETTERBOX_GREY, LETTERBOX_GREY, LETTERBOX_GREY, 1.0)
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        shown = self.stereo_image if self.stereo_image is not None else self.left
        if shown is None:  # nothing drawn yet (the first draw failed): the grey alone
            return
        split = self.stereo_image is None and self.split and self.right is not None and self.right.size == shown.size
        screen.viewport = (x, height - y - h, w, h)  # the viewport's y counts from the top, GL's from the bottom
        shown.texture.use(0)
        (self.right if split else shown).texture.use(1)
        self._program["u_image"].value = 0
        self._program["u_right"].value = 1
        # Viewport columns from the split column on show the right image (2: none).
        self._program["u_split"].value = split_column / w if split else 2.0
        self._program["u_footprint"].value = (shown.size[0] / w, shown.size[1] / h)
        self._vao.render(moderngl.TRIANGLES, vertices=3)
        screen.viewport = (0, 0, width, height)

    def capture(self, window: tuple[int, int], viewport: Viewport, split_column: int,
                overlay: Callable[[], None] | None = None) -> np.ndarray:
        """(H, W, 3) uint8, top row first: the window as :meth:`present` shows it, with
        what ``overlay`` draws on top (the panel), composed again into an offscreen
        target (reading the default framebuffer is not portable)."""
        capture = FloatTarget(self.ctx, *window, dtype="f1")
        try:
            self.present(capture.fbo, window, viewport, split_column)
            if overlay is not None:
                overlay()
            capture.use()  # an overlay (imgui's backend) restores the binding it found; read what it drew
            return capture.read(components=3, as_bytes=True)
        finally:
            capture.release()
            self.ctx.screen.use()

    def release(self) -> None:
        release_all(self.left, self.right)
        self.left = self.right = self.stereo_image = None
        self._key = None
        self._programs.release()
