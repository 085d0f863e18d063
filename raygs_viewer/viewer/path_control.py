"""The window's camera path as one part of the viewer: editing (:class:`PathEditor`),
playback (:class:`Playback`), the path drawn over the view (``path_overlay``) and the
video rendered in the background (``video_job``).

The viewer calls :meth:`PathControl.frame` once a frame before it makes the frame's
camera, :meth:`PathControl.draw` while imgui draws, and hands the panel's Path section
:meth:`PathControl.actions`. What only the viewer knows (the scene, the view's size,
the render settings) comes in as arguments, or as the ``document`` callback that makes
the path's :class:`PathDocument`.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable

from raygs_viewer.camera.path import path_through_cameras
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.capture.path_file import (
    PathDocument,
    export_nerfstudio,
    load_path_document,
    save_path_document,
    scene_mismatch,
)
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.panel.path import PathActions
from raygs_viewer.viewer.path_overlay import DrawnPath, draw_path_overlay
from raygs_viewer.viewer.paths import (
    MAX_PLAY_DT,
    VIDEO_SIZES,
    PathEditor,
    Playback,
    current_keyframe,
    dolly_from_view,
    orbit_around_scene,
)
from raygs_viewer.viewer.state import PanelState
from raygs_viewer.viewer.video_job import VideoJob, render_path_command, write_video_document
from raygs_viewer.viewer.view_control import ViewControl

#: The frustums drawn at keyframes, and the near plane the overlay is cut at, as
#: fractions of the scene's radius.
FRUSTUM_SIZE = 0.05
OVERLAY_NEAR = 1e-3


class PathControl:
    """``editor``: the path and its selection; ``playback``; ``video``: the video being
    rendered (None: none); ``video_command(scene, document, out)``: the command that
    renders it (tests run stand-ins); ``drawn``: the overlay as drawn last frame (tests)."""

    def __init__(self, panel: PanelState):
        self.panel = panel
        self.editor = PathEditor(panel)
        self.playback = Playback()
        self.video: VideoJob | None = None
        self.video_command: Callable[[str, Path, Path], list[str]] = render_path_command
        self.drawn = DrawnPath()

    # -- the frame ---------------------------------------------------------------------
    def frame(self, view: ViewControl, dt: float | None, frame_time: float) -> None:
        """Plays the path (after the user's input, before the frame's camera is made) and
        takes the video's news. ``dt``: the viewer's fixed frame time, if any; else the
        last frame's real time moves playback on (up to MAX_PLAY_DT: a stall skips ahead
        at most that far), not the navigator's dt, which is clamped to keep key moves small."""
        self.playback.follow(self.editor.path, view, dt if dt is not None else min(frame_time, MAX_PLAY_DT))
        self._poll_video()

    def draw(self, camera: Camera, viewport: tuple[int, int, int, int], radius: float, stereo: bool) -> None:
        """The path over the view, when shown; not in the stereo preview, whose image
        shows two eyes rather than ``camera``'s view."""
        self.drawn = DrawnPath() if not self.editor.show or stereo else draw_path_overlay(
            self.editor.path, camera, viewport, self.editor.selected, FRUSTUM_SIZE * radius, OVERLAY_NEAR * radius)

    def actions(self, view: ViewControl, loaded: LoadedScene, aspect: float,
                document: Callable[[], PathDocument]) -> PathActions:
        """The Path section's buttons for this frame's view and scene."""
        return PathActions(
            add_view=lambda: self.add_view(view),
            add_training=(lambda: self.add_cameras(loaded, view)) if loaded.cameras else None,
            orbit=lambda: self.editor.edit(lambda path: orbit_around_scene(view, aspect, path), select=None),
            dolly=lambda distance: self.editor.edit(lambda path: dolly_from_view(view, distance, path), select=None),
            save=lambda file, overwrite: self.save(document(), file, overwrite),
            export_nerfstudio=lambda file, overwrite: self.save(document(), file, overwrite, export_nerfstudio),
            load=lambda file: self.load(file, loaded),
            render_video=lambda: self.render_video(document(), loaded),
            cancel_video=self.cancel_video)

    # -- keyframes ---------------------------------------------------------------------
    def add_view(self, view: ViewControl) -> None:
        """The current view as a keyframe, after the selected one (or at the end)."""
        self.editor.add([current_keyframe(view)], view.navigator.up_vector)

    def add_cameras(self, loaded: LoadedScene, view: ViewControl) -> None:
        """Every training camera, in order, after the selected keyframe (or at the end)."""
        self.editor.add(list(path_through_cameras(loaded.cameras).keyframes), view.navigator.up_vector)

    # -- files -------------------------------------------------------------------------
    def save(self, document: PathDocument, file: str, overwrite: bool = False,
             writer: Callable[..., Path] = save_path_document) -> None:
        """``document`` written to ``file`` by ``writer``: the path JSON, or export_nerfstudio."""
        try:
            saved = writer(document, file, overwrite=overwrite)
        except UserError as exc:
            self.panel.error = f"error: path not saved: {one_line(exc)}"
            return
        self.panel.message, self.panel.error = f"saved {saved}", ""

    def load(self, file: str, loaded: LoadedScene) -> None:
        """A path JSON (or a nerfstudio camera_path file) becomes the path; the view and
        the render settings stay."""
        try:
            document = load_path_document(file)
        except UserError as exc:
            self.panel.error = f"error: path not loaded: {one_line(exc)}"
            return
        self.playback.pause()
        self.playback.time = 0.0
        self.editor.replace_path(document.path)
        notes = [*document.notes, scene_mismatch(document, scene_argument(loaded), loaded.sha256)]
        self.panel.message = "; ".join([f"loaded {file}: {len(document.path.keyframes)} keyframes, "
                                        f"{document.path.duration:g} s", *filter(None, notes)])
        self.panel.error = ""

    # -- video -------------------------------------------------------------------------
    def render_video(self, document: PathDocument, loaded: LoadedScene) -> None:
        """Saves ``document`` into the videos folder and renders it beside it with
        render-path, in the background."""
        if self.video is not None and self.video.running:
            return
        if not document.path.keyframes:
            self.panel.error = "error: the path has no keyframes (add the view with K)"
            return
        if self.editor.video_size in VIDEO_SIZES:
            width, height = VIDEO_SIZES[self.editor.video_size]
            document = replace(document, width=width, height=height)
        try:
            saved, out = write_video_document(document, self.editor.video_folder)
            self.video = VideoJob(self.video_command(scene_argument(loaded), saved, out), out, saved)
        except UserError as exc:
            self.panel.error = f"error: video not started: {one_line(exc)}"
            return
        self.panel.message, self.panel.error = f"rendering {out} ...", ""

    def cancel_video(self) -> None:
        if self.video is not None:
            self.video.cancel()

    def close(self) -> None:
        """Stops a video still rendering: it would outlive the window."""
        if self.video is not None:
            self.video.close()

    def _poll_video(self) -> None:
        result = None if self.video is None else self.video.poll()
        if result is None:
            return
        self.video = None
        if result.kind == "error":
            self.panel.error = result.message
        else:
            self.panel.message, self.panel.error = result.message, ""


def scene_argument(loaded: LoadedScene) -> str:
    """The loaded scene as render-path's SCENE argument and a path file's scene: "demo",
    or the file's absolute path (the window's working folder is not render-path's)."""
    return loaded.path if loaded.path == "demo" else str(Path(loaded.path).absolute())
