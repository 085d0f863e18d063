"""The window in a headset: entering and leaving an OpenXR session, each headset frame
drawn from the window's own state, the desktop mirroring it, and its screenshots.

While the session runs, ``app.Viewer``'s loop is paced by the runtime (``xrWaitFrame``:
the window's vsync is off) and each iteration is one headset frame: the eyes are
located at the predicted display time and carried into the scene by the room
(:class:`~raygs_viewer.xr.room.Room`); the frame (``frame.Frame``) is made from their
midpoint with both eyes as its cull cameras, so the window's one background sort serves
both eyes; both are drawn into the swapchain images with the panel's settings
(``xr.eyes``) and submitted. The desktop shows the eyes as they were submitted (the
mirror: one eye or both), and the panel stays live: every setting reaches the headset
in the next frame.

The room starts at the desktop view (the eyes' midpoint at the desktop camera, the
scene's up axis up, ``--scene-scale`` metres per scene unit); the controllers move it
(``xr.controls``), and so does the desktop's keyboard and mouse: the desktop camera's
moves (its position and its turn about the up axis, never its pitch, which would tilt
the horizon) carry the room along (:func:`follow_desktop`).

A screenshot in the headset saves each eye exactly as submitted, read back from its
swapchain image before release (``NAME-left.png``, ``NAME-right.png``), each with a
sidecar holding that eye's camera and where its order was sorted from
(``capture.camera_entries.OrderViewpoint``), so ``render --sidecar`` reproduces it to the bit.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import moderngl
import numpy as np

from raygs_viewer.camera.lens import letterbox
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.capture.camera_entries import OrderViewpoint
from raygs_viewer.capture.screenshot import save_screenshots
from raygs_viewer.capture.sidecar import build_sidecar
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.mono_frame import Viewport
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.stereo_frame import StereoPasses
from raygs_viewer.render.gl.targets import FloatTarget, sized
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.sort.request import Order
from raygs_viewer.viewer.frame import Framing
from raygs_viewer.viewer.part import HeadsetAction
from raygs_viewer.viewer.state import HeadsetChoices, Message, done, failed, note
from raygs_viewer.xr.actions import ControllerActions
from raygs_viewer.xr.controls import NO_HAND, Locomotion
from raygs_viewer.xr.eyes import EyeDrawer, EyeImages, HeadsetEyes, headset_eyes
from raygs_viewer.xr.room import Room, midpoint, room_at_view
from raygs_viewer.xr.session import HeadsetFrame, HeadsetSession
from raygs_viewer.xr.swapchain import format_name

#: How many headset frames the statistics average over.
HISTORY = 120


@dataclass
class HeadsetStats:
    """The headset frames so far: ``ended`` (xrEndFrame calls, the frames submitted),
    ``layered`` (with the eyes' layer), ``skipped`` (not to be rendered: the runtime's
    ``shouldRender`` false, or an image it did not give back), ``late`` (the predicted
    display time moved on by more than one and a half periods: a frame missed);
    per frame: the app's seconds outside the runtime's wait (``cpu``: the loop's thread's
    CPU time; ``wall``: wall-clock, waits on the GPU included), each eye's GPU seconds,
    the runtime's display period, and the order's age in headset frames."""

    ended: int = 0
    layered: int = 0
    skipped: int = 0
    late: int = 0
    cpu: deque = field(default_factory=lambda: deque(maxlen=HISTORY))
    wall: deque = field(default_factory=lambda: deque(maxlen=HISTORY))
    gpu: deque = field(default_factory=lambda: deque(maxlen=HISTORY))
    period: float = float("nan")
    order_frames: int = 0
    last_display: int | None = None

    def timed(self, frame: HeadsetFrame) -> None:
        if self.last_display is not None and frame.period > 0 and \
                (frame.display_time - self.last_display) > 1.5 * frame.period * 1e9:
            self.late += 1
        self.last_display, self.period = frame.display_time, frame.period

    def lines(self) -> list[str]:
        """The panel's lines."""
        cpu = np.mean(self.cpu) * 1e3 if self.cpu else float("nan")
        wall = np.mean(self.wall) * 1e3 if self.wall else float("nan")
        gpu = np.asarray(self.gpu, float).reshape(-1, 2)
        read = gpu[np.isfinite(gpu).all(axis=1)]  # the timers' results come a few frames late
        gpu = read.mean(axis=0) * 1e3 if len(read) else (float("nan"),) * 2
        return [f"headset frames: {self.ended} submitted, {self.skipped} skipped, {self.late} late",
                (f"display period {self.period * 1e3:.1f} ms; app CPU {cpu:.1f} ms a frame ({wall:.1f} ms wall) "
                 f"outside the runtime's wait"),
                f"GPU per eye: left {gpu[0]:.1f} ms, right {gpu[1]:.1f} ms",
                f"order age: {self.order_frames} headset frame{'s' if self.order_frames != 1 else ''}"]


@dataclass(frozen=True)
class EyeShot:
    """What a headset screenshot saves of one frame: the images as submitted, the eye
    cameras, the settings, the order drawn (its request says where it was sorted from)
    and the point SH colour was seen from."""

    images: EyeImages
    eyes: HeadsetEyes
    settings: RenderSettings
    order: Order


def follow_desktop(room: Room, before: Camera, after: Camera, up: np.ndarray) -> Room:
    """``room`` carried along by the desktop camera's move from ``before`` to ``after``:
    its translation, and its turn about the world's ``up`` (pitch and roll left out, so
    the headset's horizon stays level)."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    turn = _heading_angle(after, up) - _heading_angle(before, up)
    rotation = _about(up, turn)
    origin = rotation @ (room.origin - before.center) + after.center
    return replace(room, rotation=rotation @ room.rotation, origin=origin)


def _heading_angle(camera: Camera, up: np.ndarray) -> float:
    """The camera's forward's angle about ``up`` (any fixed zero)."""
    forward = np.asarray(camera.R, np.float64)[2]
    x = np.cross(up, [1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.cross(up, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(up, x)
    return float(np.arctan2(forward @ y, forward @ x))


def _about(axis: np.ndarray, angle: float) -> np.ndarray:
    """The rotation by ``angle`` about the unit ``axis`` (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def mirror_framing(eyes: HeadsetEyes, area: Viewport, mirror: str) -> Framing:
    """A headset frame's framing: its one sort from the eyes' midpoint, culled for both
    eyes, and where the desktop shows the mirror (both eyes side by side, or the left)
    letterboxed in the view ``area``."""
    left, right = eyes.cameras
    both = mirror == "both" and (left.width, left.height) == (right.width, right.height)
    ax, ay, width, height = area
    x, y, w, h = letterbox(width, height, left.width * (2 if both else 1) / left.height)
    return Framing(eyes.midpoint, (ax + x, ay + y, w, h), eyes.cameras)


class HeadsetMode:
    """The headset side of the window (module docstring). ``choices``: the panel's
    (resolution scale, depth, mirror, turning); ``make_current``: makes the window's
    context current again (after the runtime's calls). Not entered until :meth:`enter`."""

    def __init__(self, ctx: moderngl.Context, choices: HeadsetChoices, make_current: Callable[[], None]):
        self.ctx, self.make_current = ctx, make_current
        self.choices = replace(choices)
        self.session: HeadsetSession | None = None
        self.actions: ControllerActions | None = None
        self.eye_drawer = EyeDrawer(ctx)
        self.locomotion = Locomotion()
        self.room: Room | None = None
        self.desktop: Camera | None = None     # the desktop camera the room last followed
        self.metres_per_unit: float | None = None  # the stereo rig's scale the room was placed with
        self.frame: HeadsetFrame | None = None
        self.eyes: HeadsetEyes | None = None
        self.stats = HeadsetStats()
        #: Read the next frame's eyes back (a screenshot's): :attr:`last_shot`.
        self.capture_asked = False
        self.last_shot: EyeShot | None = None
        self._passes = StereoPasses(ctx)
        self._mirror: FloatTarget | None = None
        self._waited_at = (time.perf_counter(), time.thread_time())  # (wall, this thread's CPU)

    # -- entering and leaving -----------------------------------------------------------
    @property
    def active(self) -> bool:
        """Whether a session exists (starting, running or stopping)."""
        return self.session is not None and not self.session.over

    @property
    def running(self) -> bool:
        return self.session is not None and self.session.running

    def enter(self) -> Message:
        """Opens a session on the window's context; a failure is the panel's one line."""
        if self.active:
            return note("already in the headset")
        self.room, self.stats, self.locomotion, self.last_shot = None, HeadsetStats(), Locomotion(), None
        try:
            # Depth swapchains wherever the runtime takes depth, so the panel's toggle acts at once.
            self.session = HeadsetSession(self.ctx, scale=self.choices.scale, depth=True,
                                          make_current=self.make_current)
            try:
                self.actions = ControllerActions.create(self.session.runtime.instance)
                self.actions.attach(self.session.session)
            except (UserError, self.session.xr.ResultException) as exc:  # the headset works without them
                self.actions = None
                return note(f"headset: {self.session.info.describe()}; no controllers ({one_line(exc)})")
        except UserError as exc:
            self.session = None
            return failed(one_line(exc), source="headset")
        size = self.session.sizes[0]
        return done(f"headset: {self.session.info.describe()}, {size[0]}x{size[1]} per eye")

    def leave(self) -> None:
        """Asks the runtime to end the session (:meth:`poll` sees it end)."""
        if self.session is not None:
            self.session.request_exit()
            if self.session.over:
                self._ended()

    def poll(self) -> list[Message]:
        """The runtime's news since the last frame, as the panel's lines."""
        if self.session is None:
            return []
        said = [failed(news.text, source="headset") if news.error else note(news.text)
                for news in self.session.poll()]
        if self.session.over:
            self._ended()
        return said

    def _ended(self) -> None:
        if self.actions is not None:
            try:
                self.actions.destroy()
            except self.actions.xr.ResultException:
                pass  # the instance went with the runtime, and its actions with it
            self.actions = None
        self.session = None
        self.frame = self.eyes = None

    # -- each headset frame ------------------------------------------------------------------
    def wait(self, desktop: Camera, up: np.ndarray, metres_per_unit: float, dt: float) -> HeadsetEyes | None:
        """Waits for the runtime's next frame (it paces the loop) and places its eyes in
        the scene: the room follows the desktop camera and the controllers. None: no
        frame to draw (not running, or the eyes were not located: the frame is then
        ended with no layer at :meth:`submit_empty`)."""
        self.eyes = None
        if not self.running:
            self.frame = None
            return None
        self.frame = frame = self.session.wait()
        self._waited_at = (time.perf_counter(), time.thread_time())
        if frame is None:
            return None
        self.stats.timed(frame)
        if frame.views is None:
            return None
        head = midpoint(frame.views[0][0], frame.views[1][0])
        units_per_metre = 1.0 / metres_per_unit
        if self.room is None or metres_per_unit != self.metres_per_unit:
            # The start, a recentre, or a new scale in the panel: the room at the desktop view.
            self.room = room_at_view(desktop, head, up, units_per_metre)
        else:
            self.room = follow_desktop(self.room, self.desktop, desktop, up)
        self.desktop, self.metres_per_unit = desktop, metres_per_unit
        left, right = NO_HAND, NO_HAND
        if self.actions is not None:
            try:
                left, right = self.actions.read(self.session.session, self.session.space, frame.display_time)
            except self.session.xr.ResultException:  # a runtime that refuses a sync this frame: no input
                left, right = NO_HAND, NO_HAND
        self.room, recentre = self.locomotion.step(self.room, head, left, right, dt, turn=self.choices.turn)
        if recentre:
            self.room = room_at_view(desktop, head, up, units_per_metre)
        self.eyes = headset_eyes(frame, self.room, self.session.sizes)
        return self.eyes

    def recentre(self) -> None:
        """The room goes back to the desktop view at the next frame."""
        self.room = None

    def act(self, action: HeadsetAction) -> Message | None:
        """What the Headset section's button ``action`` asks (``part.Headset``), and what it says."""
        actions: dict[HeadsetAction, Callable[[], Message | None]] = {
            "enter": self.enter, "leave": self.leave, "recentre": self.recentre}
        return actions[action]()

    def draw(self, renderer: GLRenderer, settings: RenderSettings, order: Order, *, order_age: int
             ) -> FloatTarget | None:
        """Draws the frame's eyes with ``order`` and submits them; returns the mirror's
        image for the desktop (None: nothing drawn this frame)."""
        session, frame, eyes = self.session, self.frame, self.eyes
        if session is None or frame is None:
            return None
        images = None if eyes is None or not frame.should_render else session.acquire()
        if images is None:
            self._end(frame, drawn=False)
            return None
        colours, depths = images
        depth = self.choices.depth and bool(depths)
        try:
            read = self.eye_drawer.draw(renderer, colours, depths, eyes, settings=settings, order=order,
                                        depth=depth, units_per_metre=self.room.units_per_metre,
                                        capture=bool(self.capture_asked))
        except UserError:
            self._end(frame, drawn=False)
            raise
        mirror = self._compose_mirror([chain.plain[chain.held] for chain in session.colour])
        if read is not None:
            self.last_shot = EyeShot(read, eyes, settings, order)
        self.stats.order_frames = order_age
        self.stats.gpu.append(self.eye_drawer.seconds())
        self._end(frame, drawn=True, depth=depth)
        return mirror

    def submit_empty(self) -> None:
        """Ends a frame that draws nothing (no eyes located)."""
        if self.session is not None and self.frame is not None:
            self._end(self.frame, drawn=False)

    def _end(self, frame: HeadsetFrame, *, drawn: bool, depth: bool = False) -> None:
        wall, cpu = self._waited_at
        self.stats.wall.append(time.perf_counter() - wall)
        self.stats.cpu.append(time.thread_time() - cpu)
        layered = self.session.submit(frame, drawn=drawn, depth=depth)
        self.stats.ended += 1
        self.stats.layered += layered
        self.stats.skipped += not layered
        self.frame = None

    def _compose_mirror(self, images: list[moderngl.Texture]) -> FloatTarget:
        """The desktop's copy of the eyes (``images``: each swapchain image's plain view,
        read as stored), side by side or the left alone."""
        left, right = images
        layout = "sbs" if self.choices.mirror == "both" and left.size == right.size else "left"
        width, height = left.size
        self._mirror = sized(self._mirror, self.ctx, width * (2 if layout == "sbs" else 1), height, dtype="f1")
        self._passes.compose(left, right, self._mirror.fbo, layout)
        return self._mirror

    def summary(self) -> str:
        """The scripted run's line: the runtime, the headset, the eyes' size and the frames."""
        session, stats = self.session, self.stats
        width, height = session.sizes[0]
        depth = "with depth" if self.choices.depth and session.depth else "no depth"
        return (f"xr: {session.info.describe()}, {width}x{height} per eye ({session.binding.upper()}, "
                f"{format_name(session.format)}, {depth}), {stats.ended} frames submitted, "
                f"{stats.skipped} without a layer, {stats.late} late")

    # -- screenshots --------------------------------------------------------------------------
    def save_shot(self, loaded: LoadedScene, *, extra: dict, edits: dict | None, levels,
                  path: str | Path | None, folder: str | Path) -> list[tuple[Path, Path]]:
        """Saves the eyes of the last captured frame (``NAME-left.png``, ``NAME-right.png``,
        each with its sidecar); never replaces a file."""
        shot = self.last_shot
        if shot is None:
            raise UserError("no headset frame has been captured yet")
        order = shot.order
        request = order.request
        if request is None:
            raise UserError("the headset has drawn no order yet")
        viewpoint = OrderViewpoint(request.camera, request.cull_cameras, shot.eyes.midpoint.center)
        shots = []
        for side, (tag, image, eye) in enumerate(zip(("left", "right"), shot.images.colour, shot.eyes.cameras)):
            sidecar = build_sidecar(scene_path=loaded.source.recorded_path, scene_sha256=loaded.content_sha256,
                                    scene=loaded.scene, camera=eye, settings=shot.settings, scale=1.0,
                                    extra={**extra, "headset_eye": tag}, levels=levels, edits=edits,
                                    viewpoint=viewpoint)
            shots.append((image.astype(np.float32) / np.float32(255.0), sidecar, tag))
        if path is not None:
            return save_screenshots(shots, path=Path(path))
        return save_screenshots(shots, folder=Path(folder))

    def abandon(self) -> None:
        """Ends a session still there at once, without waiting for the runtime (a
        scripted run's end when the runtime does not end it, the window closing)."""
        if self.session is not None:
            self.session.destroy()
            self._ended()

    def close(self) -> None:
        """Ends a session still open (the window is closing) and frees the GPU objects."""
        self.abandon()
        self._passes.release()
        if self._mirror is not None:
            self._mirror.release()
            self._mirror = None


__all__ = ["EyeShot", "HeadsetMode", "HeadsetStats", "follow_desktop", "mirror_framing"]
