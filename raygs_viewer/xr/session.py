"""A headset session on the window's own OpenGL context: its lifecycle, its swapchains
and its frames.

The lifecycle follows the specification's session states, driven by :meth:`HeadsetSession.poll`:
IDLE waits; READY begins the session (frames may then be waited for); SYNCHRONIZED,
VISIBLE and FOCUSED run frames; STOPPING ends it; LOSS_PENDING (or the instance lost)
destroys it, and EXITING is the way back to the desktop. Nothing here ever raises at
the window for a runtime that quits, a headset unplugged or a session lost: each comes
back as a :class:`SessionNews` the window shows, and :attr:`HeadsetSession.over` says
the session is gone.

Each frame (:meth:`HeadsetSession.wait`): ``xrWaitFrame`` paces it, ``xrBeginFrame``
starts it, and the two views are located at the predicted display time in the LOCAL
reference space (the room; ``xr.room`` maps it into the scene). The eyes are drawn into
the swapchain images :meth:`acquire` hands out (:class:`~raygs_viewer.render.gl.targets.FloatTarget`
wrapping them: no copy), and :meth:`submit` releases them and ends the frame with one
projection layer of both views, each with its depth where the runtime takes depth.

The swapchains, their images and the colour format are :mod:`raygs_viewer.xr.swapchain`'s.
"""

from __future__ import annotations

import ctypes
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import moderngl
import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.xr.binding import context_binding, make_binding
from raygs_viewer.xr.room import Fov, Pose
from raygs_viewer.xr.runtime import RuntimeInfo, XrRuntime, error_line
from raygs_viewer.xr.swapchain import (
    GL_DEPTH_COMPONENT32F,
    GL_FRAMEBUFFER_SRGB,
    Swapchain,
    choose_format,
    kept_stdin,
)

#: Where the depth layer's projection starts, in metres: depth is stored as
#: 1 - NEAR_METRES / z (an infinite far plane), see ``xr.eyes.depth_values``.
NEAR_METRES = 0.05

SessionPhase = Literal["starting", "running", "stopping", "over"]


@dataclass(frozen=True)
class HeadsetFrame:
    """One headset frame between :meth:`HeadsetSession.wait` and :meth:`HeadsetSession.submit`.

    display_time: the runtime's predicted display time (XrTime, ns); period: its display
    period in seconds; should_render: False when the runtime will not show this frame
    (it is still ended, with no layer); views: each eye's (pose, field of view) in the
    room at that time (None: not located, e.g. no tracking yet)."""

    display_time: int
    period: float
    should_render: bool
    views: tuple[tuple[Pose, Fov], tuple[Pose, Fov]] | None


@dataclass(frozen=True)
class SessionNews:
    """What a poll found, for the panel: ``text`` and whether it is an error (a lost
    session, the runtime gone)."""

    text: str
    error: bool = False




class HeadsetSession:
    """A session of the active runtime on ``ctx`` (current on this thread: the window's).

    ``scale``: the eyes' size as a fraction of the runtime's recommended size (within
    its maximum); ``depth``: submit depth where the runtime takes it. Raises a UserError
    (one line) where no session can be made; after that, nothing raises: see the module
    docstring."""

    def __init__(self, ctx: moderngl.Context, *, scale: float = 1.0, depth: bool = True,
                 make_current: Callable[[], None] | None = None):
        self.ctx = ctx
        #: Makes this context current again after each call into the runtime: SteamVR may
        #: switch the current context (None: nothing to do, e.g. a headless context).
        self.make_current = make_current or (lambda: None)
        self.binding = context_binding()
        self.runtime = XrRuntime(self.binding, depth=depth)
        xr = self.xr = self.runtime.xr
        self.info: RuntimeInfo = self.runtime.info
        self.phase: SessionPhase = "starting"
        self.state = "IDLE"
        self.colour: list[Swapchain] = []
        self.depth: list[Swapchain] = []
        self.session = self.space = None
        #: What the last frame submitted: its projection layer (None: none yet) and each
        #: view's depth info chained to it (kept alive until xrEndFrame read them).
        self.last_layer = None
        self.last_depth_infos: list = []
        self._news: list[SessionNews] = []  # what failed outside a poll, for the next one
        #: Every state the runtime moved the session to, in order (the panel shows the last).
        self.states_seen: list[str] = []
        try:
            self.runtime.opengl_requirements()
            binding = make_binding(xr, self.binding)
            self.session = xr.create_session(self.runtime.instance, xr.SessionCreateInfo(
                system_id=self.runtime.system, next=ctypes.cast(ctypes.pointer(binding), ctypes.c_void_p)))
            self.space = xr.create_reference_space(self.session, xr.ReferenceSpaceCreateInfo(
                reference_space_type=xr.ReferenceSpaceType.LOCAL, pose_in_reference_space=xr.Posef()))
            formats = list(xr.enumerate_swapchain_formats(self.session))
            self.format = choose_format(formats)
            self.sizes = tuple(eye_size(view.recommended, view.maximum, scale) for view in self.info.views[:2])
            self.colour = [Swapchain(xr, self.session, ctx, size=size, format=self.format, depth=False)
                           for size in self.sizes]
            self.depth_format = GL_DEPTH_COMPONENT32F if self.runtime.has_depth and \
                GL_DEPTH_COMPONENT32F in formats else None
            if self.depth_format is not None:
                self.depth = [Swapchain(xr, self.session, ctx, size=size, format=self.depth_format, depth=True)
                              for size in self.sizes]
        except xr.ResultException as exc:
            self.destroy()
            raise UserError(error_line(exc, xr, "starting the headset session") + _context_hint(ctx, exc)) from None
        except BaseException:
            self.destroy()
            raise
        self.formats = tuple(formats)

    @property
    def running(self) -> bool:
        """Whether frames are to be waited for, drawn and submitted."""
        return self.phase == "running"

    @property
    def over(self) -> bool:
        return self.phase == "over"

    # -- lifecycle -----------------------------------------------------------------
    def poll(self) -> list[SessionNews]:
        """Handles every event the runtime has queued (module docstring), after saying
        what failed since the last poll."""
        xr, news = self.xr, self._news
        self._news = []
        while self.runtime.instance is not None:
            try:
                event = xr.poll_event(self.runtime.instance)
            except xr.EventUnavailable:
                break
            except xr.ResultException as exc:
                self._lose(error_line(exc, xr, "reading the runtime's events"))
                break
            kind = xr.StructureType(event.type)
            if kind == xr.StructureType.EVENT_DATA_SESSION_STATE_CHANGED:
                changed = ctypes.cast(ctypes.byref(event), ctypes.POINTER(xr.EventDataSessionStateChanged)).contents
                news.extend(self._state(xr.SessionState(changed.state).name))
            elif kind == xr.StructureType.EVENT_DATA_INSTANCE_LOSS_PENDING:
                self._lose("the OpenXR runtime is going away (it quit, or the headset was unplugged): Enter headset "
                           "tries again")
        return news + self._pop_news()

    def _pop_news(self) -> list[SessionNews]:
        news, self._news = self._news, []
        return news

    def _state(self, state: str) -> list[SessionNews]:
        xr = self.xr
        self.state = state
        self.states_seen.append(state)
        try:
            if state == "READY":
                xr.begin_session(self.session, xr.SessionBeginInfo(
                    primary_view_configuration_type=xr.ViewConfigurationType.PRIMARY_STEREO))
                self.phase = "running"
                return [SessionNews(f"headset: {self.info.describe()}, session running")]
            if state == "STOPPING":
                self.phase = "stopping"
                xr.end_session(self.session)
                return []
            if state == "LOSS_PENDING":
                self._lose("the headset session was lost (the runtime quit or the headset was unplugged): "
                           "Enter headset tries again")
                return []
            if state == "EXITING":
                self.destroy()
                return [SessionNews("left the headset")]
        except xr.ResultException as exc:
            self._lose(error_line(exc, xr, f"following the session to {state}"))
        return []

    def _lose(self, text: str) -> SessionNews:
        """Ends a session that failed; the next :meth:`poll` says why (and so does the return)."""
        self.destroy()
        news = SessionNews(text, error=True)
        self._news.append(news)
        return news

    def request_exit(self) -> None:
        """Asks the runtime to end the session (it goes STOPPING, then EXITING through
        :meth:`poll`); a session not begun yet is destroyed at once."""
        if self.phase in ("running",):
            try:
                self.xr.request_exit_session(self.session)
                return
            except self.xr.ResultException:
                pass
        if self.phase != "stopping":
            self.destroy()

    # -- frames ----------------------------------------------------------------------
    def wait(self) -> HeadsetFrame | None:
        """Waits for the runtime's next frame and begins it (None: not running, or the
        session just failed: :meth:`poll` says why)."""
        if not self.running:
            return None
        xr = self.xr
        try:
            state = xr.wait_frame(self.session)
            xr.begin_frame(self.session)
            views = None
            view_state, located = xr.locate_views(self.session, xr.ViewLocateInfo(
                view_configuration_type=xr.ViewConfigurationType.PRIMARY_STEREO,
                display_time=state.predicted_display_time, space=self.space))
            valid = xr.ViewStateFlags.ORIENTATION_VALID_BIT | xr.ViewStateFlags.POSITION_VALID_BIT
            if (view_state.view_state_flags & valid) == valid and len(located) >= 2:
                views = tuple((pose_of(view.pose), fov_of(view.fov)) for view in located[:2])
            self._took_back()
        except xr.ResultException as exc:
            self._lose(error_line(exc, xr, "waiting for the headset's frame"))
            return None
        return HeadsetFrame(int(state.predicted_display_time), state.predicted_display_period / 1e9,
                            bool(state.should_render), views)

    def acquire(self) -> tuple[list, list] | None:
        """Each eye's colour target and depth image (empty list: no depth) for this frame,
        or None when an image did not come (the frame is then ended with no layer)."""
        if self.session is None:  # lost since the frame began
            return None
        self.ctx.disable_direct(GL_FRAMEBUFFER_SRGB)  # display values stored as they are (module docstring)
        try:
            colour = [chain.acquire() for chain in self.colour]
            depth = [chain.acquire() for chain in self.depth]
            self._took_back()
        except self.xr.ResultException as exc:
            self._release_images()
            self._lose(error_line(exc, self.xr, "acquiring the headset's images"))
            return None
        if any(image is None for image in (*colour, *depth)):
            self._release_images()
            return None
        return colour, depth

    def _release_images(self) -> None:
        for chain in (*self.colour, *self.depth):
            try:
                chain.release()
            except self.xr.ResultException:
                chain.held = None  # a session going away takes its images with it

    def submit(self, frame: HeadsetFrame, *, drawn: bool, depth: bool = False) -> bool:
        """Releases the images and ends ``frame``: with the projection layer of both views
        when ``drawn`` (each view chained to its depth image when ``depth``: values
        ``1 - NEAR_METRES / z``, an infinite far plane), else with none. Returns whether
        a layer went."""
        xr = self.xr
        if self.session is None:  # lost since the frame began: nothing to end
            return False
        try:
            self._release_images()
            layers = []
            if drawn and frame.views is not None:
                views = (xr.CompositionLayerProjectionView * 2)()
                self.last_depth_infos = []
                for side, (pose, fov) in enumerate(frame.views):
                    info = None
                    if self.depth and depth:
                        info = xr.CompositionLayerDepthInfoKHR(
                            sub_image=self.depth[side].sub_image(), min_depth=0.0, max_depth=1.0,
                            near_z=NEAR_METRES, far_z=float("inf"))
                        self.last_depth_infos.append(info)  # alive until xrEndFrame has read it
                    views[side] = xr.CompositionLayerProjectionView(
                        pose=xr_pose(xr, pose), fov=xr.Fovf(fov.left, fov.right, fov.up, fov.down),
                        sub_image=self.colour[side].sub_image(),
                        next=None if info is None else ctypes.cast(ctypes.pointer(info), ctypes.c_void_p))
                self.last_layer = xr.CompositionLayerProjection(space=self.space, views=views)
                layers = [ctypes.byref(self.last_layer)]
            xr.end_frame(self.session, xr.FrameEndInfo(
                display_time=frame.display_time, environment_blend_mode=xr.EnvironmentBlendMode.OPAQUE,
                layers=layers))
            self._took_back()
            return bool(layers)
        except xr.ResultException as exc:
            self._lose(error_line(exc, xr, "submitting the headset's frame"))
            return False

    def _took_back(self) -> None:
        """The context back after the runtime had it: current again, and without the GL
        error SteamVR leaves set behind xrEndFrame (moderngl would take it for its own)."""
        self.make_current()
        _ = self.ctx.error  # reading it clears it

    def destroy(self) -> None:
        """Frees everything, last made first; the session is then over. Idempotent."""
        xr = self.xr
        with kept_stdin():
            for chain in (*self.colour, *self.depth):
                try:
                    chain.destroy()
                except xr.ResultException:
                    pass
            self.colour, self.depth = [], []
            for handle, destroy in ((self.space, xr.destroy_space), (self.session, xr.destroy_session)):
                if handle is not None:
                    try:
                        destroy(handle)
                    except xr.ResultException:
                        pass
            self.space = self.session = None
            self.runtime.destroy()
        self.phase = "over"


def eye_size(recommended: tuple[int, int], maximum: tuple[int, int], scale: float) -> tuple[int, int]:
    """An eye's swapchain size: the runtime's recommended size times ``scale``, within
    1 and the runtime's maximum."""
    return tuple(int(min(max(1, round(r * scale)), max(1, m))) for r, m in zip(recommended, maximum))


def pose_of(pose) -> Pose:
    o, p = pose.orientation, pose.position
    return Pose(np.array([o.x, o.y, o.z, o.w], np.float64), np.array([p.x, p.y, p.z], np.float64))


def fov_of(fov) -> Fov:
    return Fov(float(fov.angle_left), float(fov.angle_right), float(fov.angle_up), float(fov.angle_down))


def xr_pose(xr, pose: Pose):
    x, y, z, w = (float(v) for v in pose.orientation)
    return xr.Posef(orientation=xr.Quaternionf(x, y, z, w), position=xr.Vector3f(*(float(v) for v in pose.position)))


def _context_hint(ctx: moderngl.Context, exc: BaseException) -> str:
    """What the context lacks that a runtime on Linux shares its images through, when a
    session could not be made on it."""
    if type(exc).__name__ not in ("GraphicsDeviceInvalidError", "InitializationFailedError") \
            or not sys.platform.startswith("linux"):
        return ""
    missing = [name for name in ("GL_EXT_memory_object", "GL_EXT_memory_object_fd") if name not in ctx.extensions]
    return f": this OpenGL lacks {' and '.join(missing)}, which the runtime shares images through" if missing else ""
