"""The window's camera path as one widget (:class:`PathWidget`): the path, the keyframe
selected, the panel's fields for it, and every action on them, from a key (K adds the
view), the panel's Path section (:mod:`raygs_viewer.viewer.panel.path`, which draws
the widget and calls only its methods) or the frame.

The path is one immutable :class:`~raygs_viewer.camera.path.CameraPath`, replaced whole
on every edit, like the render settings. An edit the path refuses (a UserError or
ValueError from its checks) leaves the path as it was and stands in the panel's error
line until an edit succeeds.

The widget owns three collaborators: its playback
(:class:`~raygs_viewer.viewer.path_playback.Playback`), the overlay drawn over the view
(:mod:`raygs_viewer.viewer.path_overlay`) and Render video
(:class:`~raygs_viewer.viewer.video_job.VideoRender`). What only the window knows (the
view, the scene, the render settings) it is handed with each action (:class:`PathScene`),
and it returns what the panel says of it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from raygs_viewer.camera.navigation import framing_distance, scene_bounds
from raygs_viewer.camera.path import (
    FOV_RANGE,
    FPS_RANGE,
    MAX_DURATION,
    CameraPath,
    Keyframe,
    dolly_path,
    orbit_path,
    path_through_cameras,
)
from raygs_viewer.capture.path_file import (
    PathDocument,
    export_nerfstudio,
    load_path_document,
    save_path_document,
    scene_mismatch,
)
from raygs_viewer.errors import UserError, checked_number
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.frame import NO_VIEWPORT, Frame
from raygs_viewer.viewer.path_overlay import DrawnPath, draw_path_overlay
from raygs_viewer.viewer.path_playback import MAX_PLAY_DT, Playback
from raygs_viewer.viewer.part import NO_REPLY, Part, Pointing, Reply, SceneView, Shown
from raygs_viewer.viewer.state import Message, done, failed, mended, saved
from raygs_viewer.viewer.video_job import VideoRender
from raygs_viewer.viewer.view_control import ViewControl

#: The shortest path the panel takes, seconds (a path of 0 s has no speed).
MIN_DURATION = 0.01
#: The frustums drawn at keyframes, and the near plane the overlay is cut at, as
#: fractions of the scene's radius.
FRUSTUM_SIZE = 0.05
OVERLAY_NEAR = 1e-3


@dataclass(frozen=True, eq=False)
class PathScene:
    """What the path widget is handed for an action: the view's controls (their pose,
    field of view and up axis), the scene as read, the render settings (the left
    side's), the last frame (None before the first), and what makes the edit document's
    JSON where a gaussian is deleted (None: nothing deleted;
    ``edit_tool.EditTool.sidecar_entry``), asked only when a document is written."""

    view: ViewControl
    loaded: LoadedScene
    settings: RenderSettings
    shown: Frame | None
    edits: Callable[[], dict | None] = lambda: None


class PathWidget(Part):
    """``path`` and the keyframe ``selected`` (None: none); the panel's fields: ``show``
    (draw the path over the view), ``file`` (the path's file) and ``overwrite`` (Save may
    replace it), ``dolly_distance`` (scene units); ``playback``; ``video`` (Render
    video's folder, size and job); ``drawn``: the overlay as drawn last frame (tests).
    Each action returns what the panel says of it (None: nothing)."""

    def __init__(self) -> None:
        self.path = CameraPath()
        self.selected: int | None = None
        self.show = True
        self.file = "path.json"
        self.overwrite = False
        self.dolly_distance = 1.0
        self.playback = Playback()
        self.video = VideoRender()
        self.drawn = DrawnPath()

    # -- each frame --------------------------------------------------------------------
    def scene_shown(self, loaded: LoadedScene, grown: bool) -> Reply:
        """A scene opened: Dolly moves by its radius until the field says otherwise."""
        if not grown:
            self.dolly_distance = float(scene_bounds(loaded.framed)[1])
        return NO_REPLY

    def act(self, shown: Shown, mouse_free: bool) -> Reply:
        """The video's news."""
        result = self.video.poll()
        if result is None:
            return NO_REPLY
        return Reply.of(Message("error", result.message) if result.kind == "error" else done(result.message))

    def follow(self, view: ViewControl, frame_time: float) -> None:
        """Plays the path (after the user's input has moved ``view``, before the frame's
        camera is made): the last frame's time moves playback on, up to MAX_PLAY_DT (a
        stall skips ahead at most that far), not the navigator's step, which is clamped
        to keep key moves small."""
        self.playback.follow(self.path, view, min(frame_time, MAX_PLAY_DT))

    def overlay(self, frame: Frame, scene: SceneView, pointing: Pointing) -> Reply:
        """The path over ``frame``'s view, when shown; not in the stereo preview, whose
        image shows two eyes rather than the frame's camera's view."""
        radius = scene.radius
        self.drawn = DrawnPath() if not self.show or frame.stereo is not None else draw_path_overlay(
            self.path, frame.camera, frame.viewport, selected=self.selected, size=FRUSTUM_SIZE * radius,
            near=OVERLAY_NEAR * radius)
        return NO_REPLY

    def document(self, at: PathScene) -> PathDocument:
        """The path with what renders it as the window shows it: the view's size (in
        stereo, the headset's per eye), the render settings (the left side's), the
        stereo view when the preview is on, the scene and its edits (what is deleted)."""
        frame, loaded = at.shown, at.loaded
        width, height = NO_VIEWPORT[2:] if frame is None else (frame.full_camera.width, frame.full_camera.height)
        return PathDocument(self.path, width, height, at.settings, None if frame is None else frame.stereo,
                            scene_argument(loaded), loaded.content_sha256,
                            scene_axes=loaded.scene.axes,  # a .spz's: render-path reads it in the same axes
                            edits=at.edits())

    # -- the one way an edit happens ----------------------------------------------------
    def edit(self, change: Callable[[CameraPath], CameraPath], select: int | None = -1) -> Message:
        """Replaces the path by ``change(path)``; ``select``: the keyframe to select
        afterwards (-1: keep the selection, kept within the path). A change the path
        refuses leaves it as it was, and its error stands in the panel until an edit
        succeeds."""
        try:
            path = change(self.path)
        except (UserError, ValueError) as exc:
            return failed(exc, source="path")
        self.path = path
        count = len(path.keyframes)
        chosen = self.selected if select == -1 else select
        self.selected = None if chosen is None or count == 0 else min(max(chosen, 0), count - 1)
        return mended("path")

    # -- keyframes ----------------------------------------------------------------------
    def select(self, index: int | None) -> None:
        self.selected = index

    def add(self, keyframes: Sequence[Keyframe], up: np.ndarray | None = None) -> Message | None:
        """Inserts ``keyframes`` after the selected keyframe (or at the end) and selects
        the last of them; ``up``: the world's up axis the path keeps from now on."""
        if not keyframes:
            return None
        index = len(self.path.keyframes) if self.selected is None else self.selected + 1

        def change(path: CameraPath) -> CameraPath:
            for offset, keyframe in enumerate(keyframes):
                path = path.with_keyframe(keyframe, index + offset)
            if up is not None:
                path = replace(path, interpolation=replace(path.interpolation, up=tuple(float(u) for u in up)))
            return path
        return self.edit(change, select=index + len(keyframes) - 1)

    def add_view(self, view: ViewControl) -> Message | None:
        """The current view as a keyframe, after the selected one (or at the end)."""
        return self.add([current_keyframe(view)], view.navigator.up_vector)

    def add_training_cameras(self, view: ViewControl, loaded: LoadedScene) -> Message | None:
        """Every training camera, in order, after the selected keyframe (or at the end)."""
        if not loaded.cameras:
            return None
        return self.add(list(path_through_cameras(loaded.cameras).keyframes), view.navigator.up_vector)

    def delete(self, index: int) -> Message:
        """Deletes keyframe ``index``; the selection stays on the same keyframe, or on
        the one that takes the deleted one's place."""
        selected = self.selected
        if selected is not None and index < selected:
            selected -= 1
        return self.edit(lambda path: path.without_keyframe(index), select=selected)

    def move(self, index: int, step: int) -> Message | None:
        """Moves keyframe ``index`` ``step`` places later (negative: earlier) in the
        flight order; it stays selected."""
        to = index + step
        if not 0 <= to < len(self.path.keyframes):
            return None
        return self.edit(lambda path: path.moved(index, to), select=to)

    def set_time(self, index: int, time: float | None) -> Message:
        """Keyframe ``index`` at ``time`` seconds, or placed by the pacing (None)."""
        def change(path: CameraPath) -> CameraPath:
            value = None if time is None else checked_number(time, 0.0, MAX_DURATION, "a keyframe's time (s)")
            return path.with_keyframe_changed(index, time=value)
        return self.edit(change)

    def set_fov(self, index: int, fov_y_degrees: float) -> Message:
        return self.edit(lambda path: path.with_keyframe_changed(
            index, fov_y_degrees=checked_number(fov_y_degrees, *FOV_RANGE, "a keyframe's field of view (degrees)")))

    # -- the whole path -----------------------------------------------------------------
    def set_loop(self, loop: bool) -> Message:
        return self.edit(lambda path: replace(path, interpolation=replace(path.interpolation, loop=bool(loop))))

    def set_duration(self, seconds: float) -> Message:
        return self.edit(lambda path: replace(path, duration=checked_number(seconds, MIN_DURATION, MAX_DURATION,
                                                                            "the path's duration (s)")))

    def set_fps(self, fps: float) -> Message:
        return self.edit(lambda path: replace(path, fps=checked_number(fps, *FPS_RANGE, "the frame rate (fps)")))

    def clear(self) -> Message:
        return self.edit(lambda path: replace(path, keyframes=()), select=None)

    def orbit(self, view: ViewControl, aspect: float) -> Message:
        """Replaces the path by a turntable lap around the scene, from the current view
        (``aspect``: the viewport's width / height)."""
        return self.edit(lambda path: orbit_around_scene(view, aspect, path), select=None)

    def dolly(self, view: ViewControl) -> Message:
        """Replaces the path by a straight move of ``dolly_distance`` from the current view."""
        return self.edit(lambda path: dolly_from_view(view, self.dolly_distance, path), select=None)

    # -- playback -----------------------------------------------------------------------
    def play(self) -> None:
        self.playback.play(self.path)

    def pause(self) -> None:
        self.playback.pause()

    def step(self, frames: int) -> None:
        """Pauses and moves ``frames`` video frames on (negative: back)."""
        self.playback.step(self.path, frames)

    def seek(self, time: float) -> None:
        """Pauses and shows the path at ``time`` seconds."""
        self.playback.seek(self.path, time)

    def go_to(self, index: int) -> None:
        """Pauses at keyframe ``index`` and shows exactly its view."""
        self.playback.show_keyframe(self.path, index)

    # -- files --------------------------------------------------------------------------
    def save(self, at: PathScene) -> Message:
        """The path document written to ``file`` (replacing it only with ``overwrite``)."""
        return saved("path", lambda: save_path_document(self.document(at), self.file, self.overwrite))

    def export_nerfstudio(self, at: PathScene) -> Message:
        """The path at the view's size written to ``file`` as a nerfstudio camera_path."""
        return saved("path", lambda: export_nerfstudio(self.document(at), self.file, self.overwrite))

    def load(self, loaded: LoadedScene) -> tuple[Message, ...]:
        """The path JSON (or nerfstudio camera_path file) in ``file`` becomes the path,
        nothing selected; the view and the render settings stay. A file of another scene
        than ``loaded`` loads with a warning."""
        try:
            document = load_path_document(self.file)
        except UserError as exc:
            return (failed(exc, "path not loaded"),)
        self.playback.pause()
        self.playback.time = 0.0
        edited = self.edit(lambda _: document.path, select=None)
        notes = [*document.notes, scene_mismatch(document, scene_argument(loaded), loaded.content_sha256)]
        return edited, done("; ".join([f"loaded {self.file}: {len(document.path.keyframes)} keyframes, "
                                       f"{document.path.duration:g} s", *filter(None, notes)]))

    # -- video --------------------------------------------------------------------------
    def render_video(self, at: PathScene) -> Message | None:
        """Saves the path document into the videos folder and renders it beside it with
        render-path, in the background."""
        if self.video.running:
            return None
        if not self.path.keyframes:
            return failed("the path has no keyframes (add the view with K)")
        try:
            out = self.video.start(self.document(at), scene_argument(at.loaded))
        except UserError as exc:
            return failed(exc, "video not started")
        return done(f"rendering {out} ...")

    def cancel_video(self) -> None:
        self.video.cancel()

    def close(self) -> None:
        """Stops a video still rendering: it would outlive the window."""
        self.video.close()


def scene_argument(loaded: LoadedScene) -> str:
    """The loaded scene as render-path's SCENE argument and a path file's scene: "demo",
    or the file's absolute path (the window's working folder is not render-path's)."""
    return loaded.path if loaded.source.is_demo else str(Path(loaded.path).absolute())


def current_keyframe(view: ViewControl) -> Keyframe:
    """The view as a keyframe: the navigator's pose and the lens's vertical field of
    view (a training camera's own when flown to one)."""
    fov = min(max(view.lens.fov_y_degrees, FOV_RANGE[0]), FOV_RANGE[1])
    return Keyframe(view.navigator.pose, fov)


def orbit_around_scene(view: ViewControl, aspect: float, path: CameraPath) -> CameraPath:
    """A turntable around the scene's centre (its bounds', see camera.navigation.scene_bounds),
    starting at the current heading, far enough out that the scene's bounding sphere
    fills the view as Reset view frames it; the path's duration and rate are kept."""
    fov = current_keyframe(view).fov_y_degrees
    return orbit_path(view.center, framing_distance(view.radius, fov, aspect), view.navigator.up_vector,
                      start=view.navigator.pose, duration=path.duration, fps=path.fps, fov_y_degrees=fov)


def dolly_from_view(view: ViewControl, distance: float, path: CameraPath) -> CameraPath:
    """A straight move of ``distance`` scene units from the current view along its view
    direction; the path's duration and rate are kept, the up axis is the navigator's."""
    keyframe = current_keyframe(view)
    dolly = dolly_path(keyframe.pose, distance, duration=path.duration, fps=path.fps,
                       fov_y_degrees=keyframe.fov_y_degrees)
    up = tuple(float(u) for u in view.navigator.up_vector)  # keyframes added later keep the scene's up
    return replace(dolly, interpolation=replace(dolly.interpolation, up=up))
