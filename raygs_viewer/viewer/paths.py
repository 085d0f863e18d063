"""The window's camera path: the path being edited with the keyframe selected
(:class:`PathEditor`), and its playback, which flies the window's camera along it
(:class:`Playback`).

The path is one immutable :class:`~raygs_viewer.camera.path.CameraPath`, replaced whole
on every edit, like the render settings. An edit the path refuses (a UserError or
ValueError from its checks) leaves the path as it was and stands in the panel's error
line until an edit succeeds.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from raygs_viewer.camera.navigation import Pose, framing_distance
from raygs_viewer.camera.path import (
    FOV_RANGE,
    FPS_RANGE,
    MAX_DURATION,
    CameraPath,
    Keyframe,
    PathPose,
    dolly_path,
    orbit_path,
)
from raygs_viewer.errors import UserError, checked_number, one_line
from raygs_viewer.viewer.state import PanelState
from raygs_viewer.viewer.view_control import ViewControl

#: The shortest path the panel takes, seconds (a path of 0 s has no speed).
MIN_DURATION = 0.01
#: Render video's sizes besides the view's own ("view"), "WxH" -> (width, height) per
#: frame (per eye in the stereo preview).
VIDEO_SIZES = {"1280x720": (1280, 720), "1920x1080": (1920, 1080), "3840x2160": (3840, 2160)}
#: Longest frame time playback advances by at once: a stall (a scene loading) skips
#: ahead at most this far instead of jumping to the end.
MAX_PLAY_DT = 1.0


class PathEditor:
    """The path being edited, the keyframe selected (None: none), whether the path is
    drawn in the view, and the panel's fields for it: the path's file (and whether Save
    may replace it), the videos folder and the videos' size ("view" or a VIDEO_SIZES
    key), the dolly's distance (scene units). ``panel`` shows what an edit refused."""

    def __init__(self, panel: PanelState):
        self.panel = panel
        self.path = CameraPath()
        self.selected: int | None = None
        self.show = True
        self.file = "path.json"
        self.overwrite = False
        self.video_folder = "videos"
        self.video_size = "view"
        self.dolly_distance = 1.0

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

    def replace_path(self, path: CameraPath) -> None:
        """A whole new path (loaded, generated), nothing selected."""
        self.edit(lambda _: path, select=None)

    # -- keyframes ----------------------------------------------------------------------
    def insert_at(self) -> int:
        """Where a new keyframe goes: after the selected one, else at the end."""
        return len(self.path.keyframes) if self.selected is None else self.selected + 1

    def add(self, keyframes: Sequence[Keyframe], up: np.ndarray | None = None) -> bool:
        """Inserts ``keyframes`` after the selected keyframe (or at the end) and selects
        the last of them; ``up``: the world's up axis the path keeps from now on."""
        index = self.insert_at()

        def change(path: CameraPath) -> CameraPath:
            for offset, keyframe in enumerate(keyframes):
                path = path.with_keyframe(keyframe, index + offset)
            if up is not None:
                path = replace(path, interpolation=replace(path.interpolation, up=tuple(float(u) for u in up)))
            return path
        return bool(keyframes) and self.edit(change, select=index + len(keyframes) - 1)

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


def frame_step(path: CameraPath) -> float:
    """Seconds between two frames of ``path`` (its frame_times' spacing; 0 for one frame)."""
    count = path.frame_count
    if count <= 1:
        return 0.0
    return path.duration / (count if path.interpolation.loop else count - 1)


class Playback:
    """Plays the path in the window: ``time`` (seconds) advances by each frame's time
    while ``playing``; every frame that plays, or that follows a seek, sets the
    navigator's pose and the lens's field of view from ``path.pose_at(time)``.

    An open path stops at its end; a loop wraps. Anything else that moves the camera or
    changes its field of view (keys, mouse, the panel) between two frames of playback
    pauses it, and the user's view stays."""

    def __init__(self):
        self.playing = False
        self.time = 0.0
        self._fresh = False             # the first frame of playback shows ``time`` unchanged
        self._pending: PathPose | None = None   # to show next frame (a seek while paused)
        self._shown: tuple[Pose, float] | None = None   # what playback set last frame

    def play(self, path: CameraPath) -> None:
        if not path.keyframes:
            return
        if path.interpolation.loop:
            self.time %= path.duration
        elif self.time >= path.duration:
            self.time = 0.0  # Play at the end starts again
        self.playing, self._fresh, self._shown = True, True, None

    def pause(self) -> None:
        self.playing = False
        self._shown = None

    def toggle(self, path: CameraPath) -> None:
        if self.playing:
            self.pause()
        else:
            self.play(path)

    def seek(self, path: CameraPath, time: float) -> None:
        """Pauses and shows the path at ``time`` (clamped to the path) from the next frame."""
        self.pause()
        if not path.keyframes or not math.isfinite(time):
            return
        self.time = min(max(float(time), 0.0), path.duration)
        self._pending = path.pose_at(self.time)

    def show_keyframe(self, path: CameraPath, index: int) -> None:
        """Pauses at keyframe ``index``'s time and shows exactly its view next frame."""
        self.pause()
        keyframe = path.keyframes[index]
        self.time = float(path.keyframe_times()[index])
        self._pending = PathPose(keyframe.pose, keyframe.fov_y_degrees)

    def step(self, path: CameraPath, frames: int) -> None:
        """Pauses and moves ``frames`` video frames on (negative: back) from the frame
        nearest to ``time``; a loop wraps, an open path stops at its ends."""
        count, step = path.frame_count, frame_step(path)
        if count == 0:
            return
        index = self.frame_number(path) + frames
        index = index % count if path.interpolation.loop else min(max(index, 0), count - 1)
        self.seek(path, index * step)

    def frame_number(self, path: CameraPath) -> int:
        """The video frame nearest to ``time`` (0-based)."""
        count, step = path.frame_count, frame_step(path)
        if step <= 0:
            return 0
        index = int(round(self.time / step))
        return index % count if path.interpolation.loop else min(max(index, 0), count - 1)

    def follow(self, path: CameraPath, view: ViewControl, dt: float) -> None:
        """One frame: called after the user's input has moved the camera (or not), before
        the frame's camera is made."""
        if self.playing:
            if not path.keyframes:
                self.pause()
                return
            if self._shown is not None and self._moved(view):
                self.pause()  # the user took the camera
                self._pending = None
                return
            if self._fresh:
                self._fresh = False
            elif math.isfinite(dt) and dt > 0:
                self.time += float(dt)
            end = path.duration
            if path.interpolation.loop:
                self.time = self.time % end if end > 0 else 0.0
            elif self.time >= end:
                self.time, self.playing = end, False
            self._pending = path.pose_at(self.time)
        if self._pending is None:
            return
        pose = self._pending
        self._pending = None
        view.navigator.set_pose(pose.pose)
        view.set_fov(pose.fov_y_degrees)
        self._shown = (view.navigator.pose, view.lens.fov_y_degrees) if self.playing else None

    def _moved(self, view: ViewControl) -> bool:
        pose, fov = self._shown
        now = view.navigator.pose
        return (view.navigator.animating or view.lens.source is not None or view.lens.fov_y_degrees != fov
                or not np.array_equal(now.position, pose.position) or not np.array_equal(now.R, pose.R))
