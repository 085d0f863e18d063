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
view, the scene, the render settings) it reads from its :class:`PathHost`.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable, Protocol, Sequence

import numpy as np

from raygs_viewer.camera.navigation import framing_distance
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
from raygs_viewer.errors import UserError, checked_number, one_line
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.frame import NO_VIEWPORT, Frame
from raygs_viewer.viewer.path_overlay import DrawnPath, draw_path_overlay
from raygs_viewer.viewer.path_playback import MAX_PLAY_DT, Playback
from raygs_viewer.viewer.state import PanelState
from raygs_viewer.viewer.video_job import VideoRender
from raygs_viewer.viewer.view_control import ViewControl

#: The shortest path the panel takes, seconds (a path of 0 s has no speed).
MIN_DURATION = 0.01
#: The frustums drawn at keyframes, and the near plane the overlay is cut at, as
#: fractions of the scene's radius.
FRUSTUM_SIZE = 0.05
OVERLAY_NEAR = 1e-3


class EditsRecord(Protocol):
    """The edit tool as the path sees it: its edit document's JSON where a gaussian is
    deleted, None otherwise (``edit_tool.EditTool.sidecar_entry``)."""

    def sidecar_entry(self) -> dict | None: ...


class PathHost(Protocol):
    """The window as the path widget sees it (the viewer): the camera's controls and the
    scene, both replaced when a scene loads, the render settings (the left side's), the
    last frame (None before the first), read at each action, and the scene's edits."""

    view: ViewControl
    loaded: LoadedScene
    settings: RenderSettings
    shown: Frame | None
    edit_tool: EditsRecord


class PathWidget:
    """``path`` and the keyframe ``selected`` (None: none); the panel's fields: ``show``
    (draw the path over the view), ``file`` (the path's file) and ``overwrite`` (Save may
    replace it), ``dolly_distance`` (scene units); ``playback``; ``video`` (Render
    video's folder, size and job); ``drawn``: the overlay as drawn last frame (tests)."""

    def __init__(self, panel: PanelState, host: PathHost):
        self.panel, self.host = panel, host
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
    def frame(self, dt: float | None, frame_time: float) -> None:
        """Plays the path (after the user's input, before the frame's camera is made) and
        takes the video's news. ``dt``: the viewer's fixed frame time, if any; else the
        last frame's real time moves playback on (up to MAX_PLAY_DT: a stall skips ahead
        at most that far), not the navigator's dt, which is clamped to keep key moves small."""
        self.playback.follow(self.path, self.host.view, dt if dt is not None else min(frame_time, MAX_PLAY_DT))
        result = self.video.poll()
        if result is not None and result.kind == "error":
            self.panel.error = result.message
        elif result is not None:
            self.panel.message, self.panel.error = result.message, ""

    def draw_overlay(self, frame: Frame, radius: float) -> None:
        """The path over ``frame``'s view, when shown; not in the stereo preview, whose
        image shows two eyes rather than the frame's camera's view."""
        self.drawn = DrawnPath() if not self.show or frame.stereo is not None else draw_path_overlay(
            self.path, frame.camera, frame.viewport, self.selected, FRUSTUM_SIZE * radius, OVERLAY_NEAR * radius)

    def document(self) -> PathDocument:
        """The path with what renders it as the window shows it: the view's size (in
        stereo, the headset's per eye), the render settings (the left side's), the
        stereo view when the preview is on, the scene and its edits (what is deleted)."""
        frame, loaded = self.host.shown, self.host.loaded
        width, height = NO_VIEWPORT[2:] if frame is None else (frame.full_camera.width, frame.full_camera.height)
        return PathDocument(self.path, width, height, self.host.settings, None if frame is None else frame.stereo,
                            scene_argument(loaded), loaded.content_sha256,
                            scene_axes=loaded.scene.axes,  # a .spz's: render-path reads it in the same axes
                            edits=self.host.edit_tool.sidecar_entry())

    def view_aspect(self) -> float:
        """The viewport's width / height."""
        _, _, width, height = NO_VIEWPORT if self.host.shown is None else self.host.shown.viewport
        return width / height

    # -- the one way an edit happens ----------------------------------------------------
    def edit(self, change: Callable[[CameraPath], CameraPath], select: int | None = -1) -> bool:
        """Replaces the path by ``change(path)``; ``select``: the keyframe to select
        afterwards (-1: keep the selection, kept within the path). False, and the error
        in the panel, when the change is refused."""
        try:
            path = change(self.path)
        except (UserError, ValueError) as exc:
            self.panel.stand("path", f"error: {one_line(exc)}")
            return False
        self.panel.mend("path")
        self.path = path
        count = len(path.keyframes)
        chosen = self.selected if select == -1 else select
        self.selected = None if chosen is None or count == 0 else min(max(chosen, 0), count - 1)
        return True

    # -- keyframes ----------------------------------------------------------------------
    def select(self, index: int | None) -> None:
        self.selected = index

    def add(self, keyframes: Sequence[Keyframe], up: np.ndarray | None = None) -> bool:
        """Inserts ``keyframes`` after the selected keyframe (or at the end) and selects
        the last of them; ``up``: the world's up axis the path keeps from now on."""
        index = len(self.path.keyframes) if self.selected is None else self.selected + 1

        def change(path: CameraPath) -> CameraPath:
            for offset, keyframe in enumerate(keyframes):
                path = path.with_keyframe(keyframe, index + offset)
            if up is not None:
                path = replace(path, interpolation=replace(path.interpolation, up=tuple(float(u) for u in up)))
            return path
        return bool(keyframes) and self.edit(change, select=index + len(keyframes) - 1)

    def add_view(self) -> None:
        """The current view as a keyframe, after the selected one (or at the end)."""
        view = self.host.view
        self.add([current_keyframe(view)], view.navigator.up_vector)

    @property
    def has_training_cameras(self) -> bool:
        return bool(self.host.loaded.cameras)

    def add_training_cameras(self) -> None:
        """Every training camera, in order, after the selected keyframe (or at the end)."""
        if self.has_training_cameras:
            self.add(list(path_through_cameras(self.host.loaded.cameras).keyframes), self.host.view.navigator.up_vector)

    def delete(self, index: int) -> bool:
        """Deletes keyframe ``index``; the selection stays on the same keyframe, or on
        the one that takes the deleted one's place."""
        selected = self.selected
        if selected is not None and index < selected:
            selected -= 1
        return self.edit(lambda path: path.without_keyframe(index), select=selected)

    def move(self, index: int, step: int) -> bool:
        """Moves keyframe ``index`` ``step`` places later (negative: earlier) in the
        flight order; it stays selected."""
        to = index + step
        if not 0 <= to < len(self.path.keyframes):
            return False
        return self.edit(lambda path: path.moved(index, to), select=to)

    def set_time(self, index: int, time: float | None) -> bool:
        """Keyframe ``index`` at ``time`` seconds, or placed by the pacing (None)."""
        def change(path: CameraPath) -> CameraPath:
            value = None if time is None else checked_number(time, 0.0, MAX_DURATION, "a keyframe's time (s)")
            return path.with_keyframe_changed(index, time=value)
        return self.edit(change)

    def set_fov(self, index: int, fov_y_degrees: float) -> bool:
        return self.edit(lambda path: path.with_keyframe_changed(
            index, fov_y_degrees=checked_number(fov_y_degrees, *FOV_RANGE, "a keyframe's field of view (degrees)")))

    # -- the whole path -----------------------------------------------------------------
    def set_loop(self, loop: bool) -> bool:
        return self.edit(lambda path: replace(path, interpolation=replace(path.interpolation, loop=bool(loop))))

    def set_duration(self, seconds: float) -> bool:
        return self.edit(lambda path: replace(path, duration=checked_number(seconds, MIN_DURATION, MAX_DURATION,
                                                                            "the path's duration (s)")))

    def set_fps(self, fps: float) -> bool:
        return self.edit(lambda path: replace(path, fps=checked_number(fps, *FPS_RANGE, "the frame rate (fps)")))

    def clear(self) -> bool:
        return self.edit(lambda path: replace(path, keyframes=()), select=None)

    def orbit(self) -> bool:
        """Replaces the path by a turntable lap around the scene, from the current view."""
        return self.edit(lambda path: orbit_around_scene(self.host.view, self.view_aspect(), path), select=None)

    def dolly(self) -> bool:
        """Replaces the path by a straight move of ``dolly_distance`` from the current view."""
        return self.edit(lambda path: dolly_from_view(self.host.view, self.dolly_distance, path), select=None)

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
    def save(self) -> None:
        """The path document written to ``file`` (replacing it only with ``overwrite``)."""
        self._write(save_path_document)

    def export_nerfstudio(self) -> None:
        """The path at the view's size written to ``file`` as a nerfstudio camera_path."""
        self._write(export_nerfstudio)

    def _write(self, writer: Callable[[PathDocument, str, bool], Path]) -> None:
        self.panel.saved("path", lambda: writer(self.document(), self.file, self.overwrite))

    def load(self) -> None:
        """The path JSON (or nerfstudio camera_path file) in ``file`` becomes the path,
        nothing selected; the view and the render settings stay."""
        try:
            document = load_path_document(self.file)
        except UserError as exc:
            self.panel.error = f"error: path not loaded: {one_line(exc)}"
            return
        self.playback.pause()
        self.playback.time = 0.0
        self.edit(lambda _: document.path, select=None)
        loaded = self.host.loaded
        notes = [*document.notes, scene_mismatch(document, scene_argument(loaded), loaded.content_sha256)]
        self.panel.message = "; ".join([f"loaded {self.file}: {len(document.path.keyframes)} keyframes, "
                                        f"{document.path.duration:g} s", *filter(None, notes)])
        self.panel.error = ""

    # -- video --------------------------------------------------------------------------
    def render_video(self) -> None:
        """Saves the path document into the videos folder and renders it beside it with
        render-path, in the background."""
        if self.video.running:
            return
        if not self.path.keyframes:
            self.panel.error = "error: the path has no keyframes (add the view with K)"
            return
        try:
            out = self.video.start(self.document(), scene_argument(self.host.loaded))
        except UserError as exc:
            self.panel.error = f"error: video not started: {one_line(exc)}"
            return
        self.panel.message, self.panel.error = f"rendering {out} ...", ""

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
