"""The panel's Path section: the camera path's keyframes (add the view, training
cameras, an orbit or a dolly; select, go to, delete, reorder, retime, field of view),
the path's loop, duration and frame rate, playback (play, pause, step, scrub), the
path's file (save, load) and Render video with its progress.

The path is edited through the :class:`~raygs_viewer.viewer.paths.PathEditor` (each
edit replaces it whole); what needs the rest of the window goes through
:class:`PathActions`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.camera.path import FOV_RANGE
from raygs_viewer.viewer.panel.widgets import checkbox, choice, header, remember, slider, tooltip
from raygs_viewer.viewer.paths import VIDEO_SIZES, PathEditor, Playback
from raygs_viewer.viewer.video_job import VideoJob, progress_text

LIST_ROWS = 6


@dataclass(frozen=True)
class PathActions:
    """What the section's buttons do beyond editing the path. ``add_training``: None
    when the scene has no training cameras."""

    add_view: Callable[[], None]
    add_training: Callable[[], None] | None
    orbit: Callable[[], None]
    dolly: Callable[[float], None]
    save: Callable[[str, bool], None]     # file, overwrite
    export_nerfstudio: Callable[[str, bool], None]   # file, overwrite
    load: Callable[[str], None]
    render_video: Callable[[], None]
    cancel_video: Callable[[], None]


def draw_path_section(editor: PathEditor, playback: Playback, job: VideoJob | None, actions: PathActions) -> None:
    """``editor``: the path, the selection, the file field; ``playback``: play, step and
    scrub; ``job``: the video being rendered (None: none)."""
    if not header("Path"):
        return
    _generators(editor, actions)
    _keyframes(editor, playback)
    _timing(editor)
    _playback(editor, playback)
    _files(editor, actions)
    _video(editor, job, actions)


def _generators(editor: PathEditor, actions: PathActions) -> None:
    if imgui.button("Add view (K)"):
        actions.add_view()
    remember("Add view")
    tooltip("the current view as a keyframe, after the selected one (or at the end)")
    imgui.same_line()
    imgui.begin_disabled(actions.add_training is None)
    if imgui.button("Add training cameras") and actions.add_training is not None:
        actions.add_training()
    imgui.end_disabled()
    remember("Add training cameras")
    tooltip("every training camera, in order" if actions.add_training else "this scene has no training cameras")
    imgui.same_line()
    if imgui.button("Clear##path"):
        editor.clear()
    remember("Clear path")
    if imgui.button("Orbit"):
        actions.orbit()
    remember("Orbit")
    tooltip("replace the path by a turntable lap around the scene's centre, from the current heading")
    imgui.same_line()
    if imgui.button("Dolly"):
        actions.dolly(editor.dolly_distance)
    remember("Dolly")
    tooltip("replace the path by a straight move from the current view along its direction "
            "(negative: backwards)")
    imgui.same_line()
    imgui.set_next_item_width(120)
    _, editor.dolly_distance = imgui.input_float("units##dolly", editor.dolly_distance, 0.0, 0.0, "%.3g")
    remember("dolly distance")


def _keyframes(editor: PathEditor, playback: Playback) -> None:
    path = editor.path
    times = path.keyframe_times()
    rows = min(max(len(path.keyframes), 1), LIST_ROWS)
    if imgui.begin_list_box("##keyframes", (-1, rows * imgui.get_text_line_height_with_spacing() + 6)):
        for i, keyframe in enumerate(path.keyframes):
            timing = "auto" if keyframe.time is None else "set"
            label = f"{i}: {times[i]:.2f} s ({timing}), {keyframe.fov_y_degrees:.1f} deg##keyframe{i}"
            if imgui.selectable(label, editor.selected == i)[0]:
                editor.selected = i
            remember(f"keyframe {i}")
        if not path.keyframes:
            imgui.text_disabled("no keyframes: Add view (K), or a generator above")
        imgui.end_list_box()
    index = editor.selected
    if index is None or index >= len(path.keyframes):
        return
    keyframe = path.keyframes[index]
    for label, tag, action in (("Go to", "Go to keyframe", lambda: playback.show_keyframe(path, index)),
                               ("Delete", "Delete keyframe", lambda: editor.delete(index)),
                               ("Up", "Keyframe up", lambda: editor.move(index, -1)),
                               ("Down", "Keyframe down", lambda: editor.move(index, +1))):
        if imgui.button(f"{label}##keyframe"):
            action()
        remember(tag)
        imgui.same_line()
    imgui.new_line()
    auto = checkbox("auto time", keyframe.time is None, "auto time",
                    help_text="placed by the path's even pacing; off: at the time typed beside it")
    if auto != (keyframe.time is None):
        editor.set_time(index, None if auto else float(times[index]))
    imgui.same_line()
    imgui.begin_disabled(auto)
    imgui.set_next_item_width(120)
    changed, seconds = imgui.input_float("s##keyframe time", float(times[index]), 0.0, 0.0, "%.3f",
                                         imgui.InputTextFlags_.enter_returns_true.value)
    imgui.end_disabled()
    remember("keyframe time")
    if changed and not auto:
        editor.set_time(index, seconds)
    fov = slider("fov##keyframe", keyframe.fov_y_degrees, *FOV_RANGE, "%.1f deg")
    remember("keyframe fov")
    if fov is not None:
        editor.set_fov(index, min(max(fov, FOV_RANGE[0]), FOV_RANGE[1]))


def _timing(editor: PathEditor) -> None:
    path = editor.path
    loop = checkbox("loop", path.interpolation.loop, "loop",
                    help_text="back from the last keyframe to the first, and around again")
    if loop != path.interpolation.loop:
        editor.set_loop(loop)
    imgui.same_line()
    editor.show = checkbox("show path", editor.show, "show path",
                           help_text="draw the path and its keyframes' frustums over the view")
    enter = imgui.InputTextFlags_.enter_returns_true.value
    imgui.set_next_item_width(120)
    changed, seconds = imgui.input_float("duration (s)", path.duration, 0.0, 0.0, "%.2f", enter)
    remember("duration")
    if changed:
        editor.set_duration(seconds)
    imgui.same_line()
    imgui.set_next_item_width(80)
    changed, fps = imgui.input_float("fps", path.fps, 0.0, 0.0, "%.3g", enter)
    remember("fps")
    if changed:
        editor.set_fps(fps)
    imgui.text_disabled(f"{len(path.keyframes)} keyframes, {path.frame_count} frames")


def _playback(editor: PathEditor, playback: Playback) -> None:
    path = editor.path
    imgui.begin_disabled(not path.keyframes)
    if imgui.button("Pause###play" if playback.playing else "Play###play"):
        playback.toggle(path)
    remember("Play")
    imgui.same_line()
    if imgui.arrow_button("##step back", imgui.Dir.left):
        playback.step(path, -1)
    remember("Step back")
    tooltip("one frame back")
    imgui.same_line()
    if imgui.arrow_button("##step forward", imgui.Dir.right):
        playback.step(path, +1)
    remember("Step forward")
    tooltip("one frame on")
    imgui.same_line()
    imgui.set_next_item_width(-1)
    scrub = slider("##scrub", min(playback.time, path.duration), 0.0, path.duration, "%.2f s")
    remember("Scrub")
    imgui.end_disabled()
    if scrub is not None:
        playback.seek(path, scrub)
    if path.keyframes:
        imgui.text(f"{playback.time:.2f} / {path.duration:.2f} s, "
                   f"frame {playback.frame_number(path) + 1} / {path.frame_count}")


def _files(editor: PathEditor, actions: PathActions) -> None:
    imgui.set_next_item_width(-190)
    _, editor.file = imgui.input_text_with_hint("##path file", "path.json", editor.file)
    remember("path file")
    imgui.same_line()
    imgui.begin_disabled(not editor.path.keyframes)
    if imgui.button("Save##path"):
        actions.save(editor.file, editor.overwrite)
    imgui.end_disabled()
    remember("Save path")
    imgui.same_line()
    if imgui.button("Load##path"):
        actions.load(editor.file)
    remember("Load path")
    tooltip("a path JSON saved here, or a nerfstudio camera_path file")
    imgui.begin_disabled(not editor.path.keyframes)
    if imgui.button("Export nerfstudio"):
        actions.export_nerfstudio(editor.file, editor.overwrite)
    imgui.end_disabled()
    remember("Export nerfstudio")
    tooltip("save the path as a nerfstudio camera_path file (every frame, and the keyframes for its viewer)")
    imgui.same_line()
    editor.overwrite = checkbox("overwrite", editor.overwrite, "overwrite path",
                                help_text="let Save replace an existing file")


def _video(editor: PathEditor, job: VideoJob | None, actions: PathActions) -> None:
    if job is not None and job.running:
        progress = job.progress
        imgui.progress_bar(0.0 if progress is None else progress.fraction, (-80, 0), progress_text(progress))
        remember("video progress")
        imgui.same_line()
        if imgui.button("Cancel##video"):
            actions.cancel_video()
        remember("Cancel video")
        return
    imgui.begin_disabled(not editor.path.keyframes)
    if imgui.button("Render video"):
        actions.render_video()
    imgui.end_disabled()
    remember("Render video")
    tooltip("render-path in the background: the path and the current render settings, saved as "
            "<folder>/raygs-<time>.json and .mp4")
    imgui.same_line()
    imgui.set_next_item_width(110)
    editor.video_size = choice("##video size", editor.video_size,
                               {"view": "view's size", **{size: size for size in VIDEO_SIZES}}, "video size")
    tooltip("each frame's size (each eye's in the stereo preview)")
    imgui.same_line()
    imgui.set_next_item_width(-1)
    _, editor.video_folder = imgui.input_text("##video folder", editor.video_folder)
    remember("video folder")
