"""A headset's swapchains: the images the runtime hands out for each eye's colour and
depth, each wrapped once for drawing into, and the colour format chosen from the
runtime's list.

The colour swapchain's format is the runtime's to offer (:func:`choose_format`): an sRGB
one first. The eyes' colours are display values (what a screenshot saves), and with
``GL_FRAMEBUFFER_SRGB`` off they are stored as they are: the runtime then reads the
image as sRGB, as a screenshot viewer would, with no second gamma. The desktop's mirror
reads each image through a plain RGBA8 view (:func:`plain_view`). A depth image is a
framebuffer made with GL itself (:class:`DepthImage`). What moderngl cannot do here goes
through the context's own entry points (``xr.binding.gl_function``).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
from collections.abc import Iterator

import moderngl
import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.xr.binding import gl_function

GL_SRGB8_ALPHA8, GL_SRGB8, GL_RGBA8 = 0x8C43, 0x8C41, 0x8058
GL_DEPTH_COMPONENT32F = 0x8CAC
GL_FRAMEBUFFER_SRGB = 0x8DB9
#: The colour formats this viewer draws into, best first: sRGB ones store the display
#: values as they are (see the module docstring).
COLOUR_FORMATS = (GL_SRGB8_ALPHA8, GL_SRGB8)
#: The GL names of the swapchain formats runtimes offer (others are named in hex).
GL_FORMAT_NAMES = {
    0x8058: "GL_RGBA8", 0x8C43: "GL_SRGB8_ALPHA8", 0x8051: "GL_RGB8", 0x8C41: "GL_SRGB8",
    0x805B: "GL_RGBA16", 0x881A: "GL_RGBA16F", 0x881B: "GL_RGB16F", 0x8814: "GL_RGBA32F",
    0x8059: "GL_RGB10_A2", 0x8C3A: "GL_R11F_G11F_B10F", 0x8D62: "GL_RGB565", 0x8229: "GL_R8",
    0x81A5: "GL_DEPTH_COMPONENT16", 0x81A6: "GL_DEPTH_COMPONENT24", 0x8CAC: "GL_DEPTH_COMPONENT32F",
    0x88F0: "GL_DEPTH24_STENCIL8", 0x8CAD: "GL_DEPTH32F_STENCIL8",
}
#: Nanoseconds the acquire of a swapchain image may wait before the frame is skipped:
#: a runtime that stalls longer than a few frames is not going to give it back.
IMAGE_WAIT_NS = 1_000_000_000


@contextlib.contextmanager
def kept_stdin() -> Iterator[None]:
    """Standard input as it was after the block: this Monado closes file descriptor 0
    when a swapchain is destroyed (../shared/openxr/README.md), which would leave the
    next file opened to take 0, and the runtime's next close to take it away. Put back
    whatever happened (a dup2 onto itself changes nothing)."""
    try:
        saved = os.dup(0)
    except OSError:
        saved = None  # no standard input to keep
    try:
        yield
    finally:
        if saved is not None:
            os.dup2(saved, 0)
            os.close(saved)


def format_name(value: int | None) -> str:
    """A GL internal format as its name (hex where unknown; "none" for None)."""
    return "none" if value is None else GL_FORMAT_NAMES.get(int(value), f"0x{int(value):04x}")


def choose_format(offered: list[int] | tuple[int, ...]) -> int:
    """The colour format of the eyes' swapchains among the runtime's ``offered`` ones,
    or a UserError naming what it offers instead."""
    for wanted in COLOUR_FORMATS:
        if wanted in offered:
            return wanted
    listed = ", ".join(format_name(value) for value in offered) or "none"
    raise UserError(f"the OpenXR runtime offers no sRGB colour swapchain (GL_SRGB8_ALPHA8 or GL_SRGB8; it offers "
                    f"{listed})")


class Swapchain:
    """One eye's colour (or depth) swapchain and its images, each wrapped once."""

    def __init__(self, xr, session, ctx: moderngl.Context, *, size: tuple[int, int], format: int, depth: bool):
        self.xr, self.size, self.format, self.depth = xr, size, format, depth
        usage = (xr.SwapchainUsageFlags.DEPTH_STENCIL_ATTACHMENT_BIT if depth
                 else xr.SwapchainUsageFlags.COLOR_ATTACHMENT_BIT) | xr.SwapchainUsageFlags.SAMPLED_BIT
        self.handle = xr.create_swapchain(session, xr.SwapchainCreateInfo(
            usage_flags=usage, format=format, sample_count=1, width=size[0], height=size[1], face_count=1,
            array_size=1, mip_count=1))
        self.names = [image.image for image in xr.enumerate_swapchain_images(self.handle, xr.SwapchainImageOpenGLKHR)]
        if depth:
            self.targets = [DepthImage(ctx, name, size) for name in self.names]
        else:
            self.targets = [FloatTarget.wrapping(ctx, ctx.external_texture(name, size, 4, 0, "f1"))
                            for name in self.names]
            #: Each image as RGBA8 (a texture view: the same memory, read without sRGB
            #: decoding), for the desktop's mirror (:func:`plain_view`).
            self.plain = [ctx.external_texture(plain_view(ctx, name), size, 4, 0, "f1") for name in self.names]
        self.held: int | None = None

    def acquire(self):
        """The image to draw this frame into (waited for), or None when the runtime did
        not give it back in time."""
        xr = self.xr
        index = xr.acquire_swapchain_image(self.handle, xr.SwapchainImageAcquireInfo())
        try:
            xr.wait_swapchain_image(self.handle, xr.SwapchainImageWaitInfo(timeout=IMAGE_WAIT_NS))
        except xr.TimeoutExpired:
            return None
        self.held = index
        return self.targets[index]

    def release(self) -> None:
        if self.held is not None:
            self.xr.release_swapchain_image(self.handle, self.xr.SwapchainImageReleaseInfo())
            self.held = None

    def sub_image(self):
        xr = self.xr
        return xr.SwapchainSubImage(swapchain=self.handle, image_rect=xr.Rect2Di(
            offset=xr.Offset2Di(0, 0), extent=xr.Extent2Di(*self.size)))

    def destroy(self) -> None:
        for target in self.targets:
            target.release()
        for view, image in zip(getattr(self, "plain", ()), self.names):
            if view.glo != image:  # a view of the image, not the image itself
                _delete_texture(view.glo)
        self.targets, self.plain = [], []
        self.xr.destroy_swapchain(self.handle)


class DepthImage:
    """A depth swapchain image as a framebuffer with it as the depth attachment (moderngl
    cannot attach a texture made elsewhere as depth: the framebuffer is made with GL
    itself and adopted)."""

    def __init__(self, ctx: moderngl.Context, name: int, size: tuple[int, int]):
        self.ctx, self.size = ctx, size
        self.fbo = ctx.detect_framebuffer(_depth_framebuffer(name))

    def read(self) -> np.ndarray:
        """(H, W) float32 depth, top row first (read with GL itself: moderngl does not
        know the depth attachment of a framebuffer it adopted)."""
        width, height = self.size
        pixels = np.empty((height, width), np.float32)
        self.fbo.use()
        read = gl_function("glReadPixels", None, [ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                                  ctypes.c_uint, ctypes.c_uint, ctypes.c_void_p])
        read(0, 0, width, height, _GL_DEPTH_COMPONENT, _GL_FLOAT, pixels.ctypes.data)
        return pixels[::-1].copy()

    def release(self) -> None:
        self.fbo = None  # the framebuffer object goes with the context


_GL_FRAMEBUFFER, _GL_DEPTH_ATTACHMENT, _GL_TEXTURE_2D = 0x8D40, 0x8D00, 0x0DE1
_GL_DEPTH_COMPONENT, _GL_FLOAT = 0x1902, 0x1406


def plain_view(ctx: moderngl.Context, texture: int) -> int:
    """A GL_RGBA8 view of an sRGB swapchain image: the desktop's mirror samples it as the
    display values it stores (as a screenshot holds them). Sampling the image itself
    would decode sRGB to linear, and ``GL_EXT_texture_sRGB_decode`` cannot stop that for
    texelFetch, which the mirror's pass uses. Views need immutable storage, which
    swapchain images have where the runtime makes them with ``glTexStorage*``; where it
    does not, the image itself (the mirror is then darker than the headset, nothing else)."""
    generate = gl_function("glGenTextures", None, [ctypes.c_int, ctypes.POINTER(ctypes.c_uint)])
    view = gl_function("glTextureView", None, [ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint,
                                               ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint])
    name = ctypes.c_uint()
    generate(1, ctypes.byref(name))
    _ = ctx.error  # what came before is not this call's
    view(name.value, _GL_TEXTURE_2D, texture, GL_RGBA8, 0, 1, 0, 1)
    if ctx.error != "GL_NO_ERROR":
        _delete_texture(name.value)
        return texture
    return name.value


def _delete_texture(texture: int) -> None:
    delete = gl_function("glDeleteTextures", None, [ctypes.c_int, ctypes.POINTER(ctypes.c_uint)])
    delete(1, ctypes.byref(ctypes.c_uint(texture)))


def _depth_framebuffer(texture: int) -> int:
    gen = gl_function("glGenFramebuffers", None, [ctypes.c_int, ctypes.POINTER(ctypes.c_uint)])
    bind = gl_function("glBindFramebuffer", None, [ctypes.c_uint, ctypes.c_uint])
    attach = gl_function("glFramebufferTexture2D", None,
                         [ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_uint, ctypes.c_int])
    name = ctypes.c_uint()
    gen(1, ctypes.byref(name))
    bind(_GL_FRAMEBUFFER, name.value)
    attach(_GL_FRAMEBUFFER, _GL_DEPTH_ATTACHMENT, _GL_TEXTURE_2D, texture, 0)
    bind(_GL_FRAMEBUFFER, 0)
    return name.value
