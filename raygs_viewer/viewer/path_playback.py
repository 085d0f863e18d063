"""Playback of the window's camera path: it flies the window's camera along the path,
in real time or frame by frame (:class:`Playback`)."""

from __future__ import annotations

import math

import numpy as np

from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.path import CameraPath, PathPose
from raygs_viewer.viewer.view_control import ViewControl

#: Longest frame time playback advances by at once: a stall (a scene loading) skips
#: ahead at most this far instead of jumping to the end.
MAX_PLAY_DT = 1.0


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
