"""The one offscreen target type: an RGBA texture in a framebuffer, made after a size
check, read back top row first, released once.

Every pass that draws offscreen goes through it: the renderer's image and sample
targets, the stereo eyes and their composed image, the window's scene targets and its
capture, and the benchmarks' timed renders.
"""

from __future__ import annotations

import moderngl
import numpy as np

from raygs_viewer.errors import UserError

#: What a driver that reports no GL_MAX_TEXTURE_SIZE is assumed to draw.
DEFAULT_TEXTURE_LIMIT = 16384


def texture_limit(ctx: moderngl.Context) -> int:
    return int(ctx.info.get("GL_MAX_TEXTURE_SIZE", DEFAULT_TEXTURE_LIMIT))


def check_size(ctx: moderngl.Context, width: int, height: int, label: str = "image", advice: str = "") -> None:
    """UserError when this GPU cannot render a ``width`` x ``height`` target (see FloatTarget)."""
    limit = texture_limit(ctx)
    if not (1 <= width <= limit and 1 <= height <= limit):
        raise UserError(f"{label} size {width}x{height} is outside what this GPU renders (1..{limit}){advice}")


class FloatTarget:
    """A ``width`` x ``height`` colour target: float32 RGBA by default (``dtype="f4"``),
    float16 (``"f2"``, a blend precision) or normalised 8-bit (``"f1"``: a blend
    precision, and what is shown as it is).

    ``attachments`` > 1 adds textures of the same kind as further colour attachments
    (the geometry outputs: render/gl/renderer.py), or of the kinds ``dtypes`` names,
    one per attachment; ``texture`` is the first.
    ``label`` and ``advice`` word the UserError for a size the GPU cannot render,
    e.g. "stereo image" and "; use a smaller scale"."""

    def __init__(self, ctx: moderngl.Context, width: int, height: int, *, dtype: str = "f4",
                 label: str = "image", advice: str = "", attachments: int = 1, dtypes: tuple[str, ...] = ()):
        check_size(ctx, width, height, label, advice)
        self.ctx = ctx
        self.dtypes = tuple(dtypes) or (dtype,) * attachments
        self.dtype = self.dtypes[0]
        self.textures = [ctx.texture((width, height), 4, dtype=kind) for kind in self.dtypes]
        self.texture = self.textures[0]
        self.fbo = ctx.framebuffer(color_attachments=self.textures)
        self._single: list[moderngl.Framebuffer] = []  # one per attachment, for clear_each
        self._owned = True  # the textures are this target's (see wrapping)

    @classmethod
    def wrapping(cls, ctx: moderngl.Context, texture: moderngl.Texture, dtype: str = "f1") -> "FloatTarget":
        """A target that draws into a texture made elsewhere (a headset's swapchain image,
        ``ctx.external_texture``), of kind ``dtype``; :meth:`release` frees the
        framebuffer and leaves the texture to its owner."""
        target = cls.__new__(cls)
        target.ctx, target.dtypes, target.dtype = ctx, (dtype,), dtype
        target.textures, target.texture = [texture], texture
        target.fbo = ctx.framebuffer(color_attachments=[texture])
        target._single, target._owned = [], False
        return target

    @property
    def attachments(self) -> int:
        return len(self.textures)

    @property
    def size(self) -> tuple[int, int]:
        return self.fbo.size

    def use(self) -> None:
        self.fbo.use()

    def clear_each(self, *colors: tuple[float, float, float, float]) -> None:
        """Clears attachment i to ``colors[i]`` (a framebuffer clear sets them all alike)."""
        if not self._single:
            self._single = [self.ctx.framebuffer(color_attachments=[texture]) for texture in self.textures]
        for fbo, color in zip(self._single, colors, strict=True):
            fbo.clear(*color)

    def read(self, components: int = 4, attachment: int = 0, as_bytes: bool = False) -> np.ndarray:
        """(H, W, components) float32 of one attachment, top row first, whatever its kind
        (a window's scene target takes the blend precision's, and is read as the float32
        image a headless render gives); ``as_bytes``: an "f1" attachment's uint8 as stored."""
        width, height = self.size
        if as_bytes and self.dtypes[attachment] == "f1":
            pixels = np.frombuffer(self.fbo.read(components=components, attachment=attachment), np.uint8)
        else:
            pixels = np.frombuffer(self.fbo.read(components=components, dtype="f4", attachment=attachment),
                                   np.float32)
        return pixels.reshape(height, width, components)[::-1].copy()

    def release(self) -> None:
        if self.fbo is not None:
            for fbo in self._single:
                fbo.release()
            self._single = []
            self.fbo.release()
            for texture in self.textures if self._owned else ():
                texture.release()
            self.fbo = self.texture = None
            self.textures = []


def sized(target: FloatTarget | None, ctx: moderngl.Context, width: int, height: int, **options) -> FloatTarget:
    """``target`` when it already has this size (and ``options``' attachments and
    dtypes), else a new one (``target`` released first: one size held at a time)."""
    dtypes = tuple(options.get("dtypes", ())) or (options.get("dtype", "f4"),) * options.get("attachments", 1)
    if target is not None and target.size == (width, height) and target.dtypes == dtypes:
        return target
    if target is not None:
        target.release()
    return FloatTarget(ctx, width, height, **options)


def release_all(*targets: FloatTarget | None) -> None:
    for target in targets:
        if target is not None:
            target.release()
