"""The GL side of a stereo frame: both eyes drawn with one order into their own float
targets, the optional lens preview on each, and the layout composed into one image.

The window keeps one :class:`StereoFrame` and shows its composed target; screenshots
and ``render --stereo`` use a fresh one through
:func:`raygs_viewer.camera.stereo.render_stereo_view`, so both go through the same passes.
"""

from __future__ import annotations

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoRig, StereoView, composed_size, eye_cameras
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.stereo_passes import StereoPasses


class StereoFrame:
    """Targets are made on first use and again when a size changes."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.passes = StereoPasses(ctx)
        self.eyes: tuple[Camera, Camera] | None = None   # the eye cameras of the last draw
        self._eye_targets: list[moderngl.Framebuffer | None] = [None, None]
        self._lens_targets: list[moderngl.Framebuffer | None] = [None, None]
        self._image: moderngl.Framebuffer | None = None
        self._shown: list[moderngl.Framebuffer] = []      # what went into the layout

    @property
    def image(self) -> moderngl.Framebuffer | None:
        """The composed target of the last :meth:`finish`."""
        return self._image

    def draw_eyes(self, renderer, camera: Camera, settings, rig: StereoRig, order: np.ndarray) -> None:
        """Draws both eyes around the midpoint ``camera`` with ``order``; SH colour is
        seen from the midpoint (see :mod:`raygs_viewer.camera.stereo`)."""
        self.eyes = eye_cameras(camera, rig)
        for side, eye in enumerate(self.eyes):
            target = self._sized(self._eye_targets, side, eye.width, eye.height)
            renderer.render_into(target, eye, settings, order, color_origin=camera.center)

    def finish(self, view: StereoView) -> moderngl.Framebuffer:
        """The lens preview (if on) and the layout, into the composed target."""
        if self.eyes is None:
            raise RuntimeError("StereoFrame.finish before draw_eyes")
        shown = self._eye_targets
        if view.lens is not None:
            for side, eye in enumerate(self.eyes):
                target = self._sized(self._lens_targets, side, eye.width, eye.height)
                self.passes.lens(self._eye_targets[side].color_attachments[0], target, eye, view.lens)
            shown = self._lens_targets
        self._shown = list(shown)
        width, height = composed_size(self.eyes[0].width, self.eyes[0].height, view.layout)
        if self._image is None or self._image.size != (width, height):
            _release(self._image)
            self._image = None
            self._image = self._framebuffer(width, height)
        self.passes.compose(shown[0].color_attachments[0], shown[1].color_attachments[0], self._image, view.layout)
        return self._image

    def read_image(self) -> np.ndarray:
        return _read(self._image)

    def read_eyes(self) -> tuple[np.ndarray, np.ndarray]:
        """Each eye as it went into the layout (after the lens preview)."""
        return _read(self._shown[0]), _read(self._shown[1])

    def release(self) -> None:
        for fbo in [*self._eye_targets, *self._lens_targets, self._image]:
            _release(fbo)
        self._eye_targets, self._lens_targets, self._image, self._shown = [None, None], [None, None], None, []
        self.passes.release()

    def _sized(self, targets: list, side: int, width: int, height: int) -> moderngl.Framebuffer:
        if targets[side] is None or targets[side].size != (width, height):
            _release(targets[side])
            targets[side] = None
            targets[side] = self._framebuffer(width, height)
        return targets[side]

    def _framebuffer(self, width: int, height: int) -> moderngl.Framebuffer:
        limit = int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
        if not (1 <= width <= limit and 1 <= height <= limit):
            raise UserError(f"stereo image size {width}x{height} is outside what this GPU renders (1..{limit} "
                            f"per side); use a smaller scale")
        return self.ctx.framebuffer(color_attachments=[self.ctx.texture((width, height), 4, dtype="f4")])


def _read(fbo: moderngl.Framebuffer) -> np.ndarray:
    width, height = fbo.size
    pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)
    return pixels.reshape(height, width, 4)[::-1].copy()


def _release(fbo: moderngl.Framebuffer | None) -> None:
    if fbo is None:
        return
    for attachment in fbo.color_attachments:
        attachment.release()
    fbo.release()
