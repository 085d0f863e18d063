"""The panel's Path section: the camera path's keyframes (add the view, training
cameras, an orbit or a dolly; select, go to, delete, reorder, retime, field of view),
the path's loop, duration and frame rate, playback (play, pause, step, scrub), the
path's file (save, load, export) and Render video with its progress.

It draws the :class:`~raygs_viewer.viewer.path_widget.PathWidget` and edits it only
through the widget's methods and its form fields; it returns what the widget said.
"""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.camera.path import FOV_RANGE
from raygs_viewer.viewer.panel.widgets import (
    beside,
    checkbox,
    choice,
    file_row,
    header,
    labelled_progress,
    line,
    note,
    slider,
    tooltip,
)
from raygs_viewer.viewer.frame import NO_VIEWPORT
from raygs_viewer.viewer.part import Reply
from raygs_viewer.viewer.path_widget import PathScene, PathWidget
from raygs_viewer.viewer.video_job import VIDEO_SIZES, progress_text

LIST_ROWS = 6


def draw_path_section(widget: PathWidget, at: PathScene) -> Reply:
    """The section, for the view and the scene ``at``."""
    if not header("Path"):
        return Reply()
    said: list = []
    _generators(widget, at, said)
    _keyframes(widget, said)
    _timing(widget, said)
    _playback(widget)
    _files(widget, at, said)
    _video(widget, at, said)
    return Reply.of(*said)


def _generators(widget: PathWidget, at: PathScene, said: list) -> None:
    if imgui.button("Add view (K)"):
        said.append(widget.add_view(at.view))
    tooltip("the current view as a keyframe, after the selected one (or at the end)")
    imgui.same_line()
    training = bool(at.loaded.cameras)
    imgui.begin_disabled(not training)
    if imgui.button("Add training cameras"):
        said.append(widget.add_training_cameras(at.view, at.loaded))
    imgui.end_disabled()
    tooltip("every training camera, in order" if training else "this scene has no training cameras")
    imgui.same_line()
    if imgui.button("Clear##path"):
        said.append(widget.clear())
    if imgui.button("Orbit"):
        said.append(widget.orbit(at.view, view_aspect(at)))
    tooltip("replace the path by a turntable lap around the scene's centre, from the current heading")
    imgui.same_line()
    if imgui.button("Dolly"):
        said.append(widget.dolly(at.view))
    tooltip("replace the path by a straight move from the current view along its direction "
            "(negative: backwards)")
    imgui.same_line()
    imgui.set_next_item_width(120)
    _, widget.dolly_distance = imgui.input_float("units##dolly", widget.dolly_distance, 0.0, 0.0, "%.3g")


def _keyframes(widget: PathWidget, said: list) -> None:
    path = widget.path
    times = path.keyframe_times()
    rows = min(max(len(path.keyframes), 1), LIST_ROWS)
    if imgui.begin_list_box("##keyframes", (-1, rows * imgui.get_text_line_height_with_spacing() + 6)):
        for i, keyframe in enumerate(path.keyframes):
            timing = "auto" if keyframe.time is None else "set"
            label = f"{i}: {times[i]:.2f} s ({timing}), {keyframe.fov_y_degrees:.1f} deg##keyframe{i}"
            if imgui.selectable(label, widget.selected == i)[0]:
                widget.select(i)
        if not path.keyframes:
            note("no keyframes: Add view (K), or a generator above")
        imgui.end_list_box()
    index = widget.selected
    if index is None or index >= len(path.keyframes):
        return
    keyframe = path.keyframes[index]
    for label, action in (("Go to", lambda: widget.go_to(index)),
                          ("Delete", lambda: widget.delete(index)),
                          ("Up", lambda: widget.move(index, -1)),
                          ("Down", lambda: widget.move(index, +1))):
        if imgui.button(f"{label}##keyframe"):
            said.append(action())
        imgui.same_line()
    imgui.new_line()
    auto = checkbox("auto time", keyframe.time is None,
                    help_text="placed by the path's even pacing; off: at the time typed beside it")
    if auto != (keyframe.time is None):
        said.append(widget.set_time(index, None if auto else float(times[index])))
    imgui.same_line()
    imgui.begin_disabled(auto)
    imgui.set_next_item_width(120)
    changed, seconds = imgui.input_float("s##keyframe time", float(times[index]), 0.0, 0.0, "%.3f",
                                         imgui.InputTextFlags_.enter_returns_true.value)
    imgui.end_disabled()
    if changed and not auto:
        said.append(widget.set_time(index, seconds))
    fov = slider("fov##keyframe", keyframe.fov_y_degrees, *FOV_RANGE, "%.1f deg")
    if fov is not None:
        said.append(widget.set_fov(index, min(max(fov, FOV_RANGE[0]), FOV_RANGE[1])))


def _timing(widget: PathWidget, said: list) -> None:
    path = widget.path
    loop = checkbox("loop", path.interpolation.loop,
                    help_text="back from the last keyframe to the first, and around again")
    if loop != path.interpolation.loop:
        said.append(widget.set_loop(loop))
    imgui.same_line()
    widget.show = checkbox("show path", widget.show,
                           help_text="draw the path and its keyframes' frustums over the view")
    enter = imgui.InputTextFlags_.enter_returns_true.value
    imgui.set_next_item_width(100)
    changed, seconds = imgui.input_float("duration (s)", path.duration, 0.0, 0.0, "%.2f", enter)
    if changed:
        said.append(widget.set_duration(seconds))
    beside(70 + imgui.get_style().item_inner_spacing.x + imgui.calc_text_size("fps").x)
    imgui.set_next_item_width(70)
    changed, fps = imgui.input_float("fps", path.fps, 0.0, 0.0, "%.3g", enter)
    if changed:
        said.append(widget.set_fps(fps))
    note(f"{len(path.keyframes)} keyframes, {path.frame_count} frames")


def _playback(widget: PathWidget) -> None:
    path, playback = widget.path, widget.playback
    imgui.begin_disabled(not path.keyframes)
    if imgui.button("Pause###play" if playback.playing else "Play###play"):
        if playback.playing:
            widget.pause()
        else:
            widget.play()
    imgui.same_line()
    if imgui.arrow_button("##step back", imgui.Dir.left):
        widget.step(-1)
    tooltip("one frame back")
    imgui.same_line()
    if imgui.arrow_button("##step forward", imgui.Dir.right):
        widget.step(+1)
    tooltip("one frame on")
    imgui.same_line()
    imgui.set_next_item_width(-1)
    scrub = slider("##scrub", min(playback.time, path.duration), 0.0, path.duration, "%.2f s")
    imgui.end_disabled()
    if scrub is not None:
        widget.seek(scrub)
    if path.keyframes:
        line(f"{playback.time:.2f} / {path.duration:.2f} s, "
                   f"frame {playback.frame_number(path) + 1} / {path.frame_count}")


def _files(widget: PathWidget, at: PathScene, said: list) -> None:
    widget.file, save, load = file_row("path", widget.file, "path.json", bool(widget.path.keyframes), room=190)
    if save:
        said.append(widget.save(at))
    if load:
        said.append(widget.load(at.loaded))
    tooltip("a path JSON saved here, or a nerfstudio camera_path file")
    imgui.begin_disabled(not widget.path.keyframes)
    if imgui.button("Export nerfstudio"):
        said.append(widget.export_nerfstudio(at))
    imgui.end_disabled()
    tooltip("save the path as a nerfstudio camera_path file (every frame, and the keyframes for its viewer)")
    imgui.same_line()
    widget.overwrite = checkbox("overwrite", widget.overwrite,
                                help_text="let Save replace an existing file")


def _video(widget: PathWidget, at: PathScene, said: list) -> None:
    video = widget.video
    if video.running:
        progress = video.job.progress
        labelled_progress(0.0 if progress is None else progress.fraction, progress_text(progress), room=80)
        imgui.same_line()
        if imgui.button("Cancel##video"):
            widget.cancel_video()
        return
    imgui.begin_disabled(not widget.path.keyframes)
    if imgui.button("Render video"):
        said.append(widget.render_video(at))
    imgui.end_disabled()
    tooltip("render-path in the background: the path and the current render settings, saved as "
            "<folder>/raygs-<time>.json and .mp4")
    imgui.same_line()
    imgui.set_next_item_width(110)
    video.size = choice("##video size", video.size, {"view": "view's size", **{size: size for size in VIDEO_SIZES}})
    tooltip("each frame's size (each eye's in the stereo preview)")
    imgui.same_line()
    imgui.set_next_item_width(-1)
    _, video.folder = imgui.input_text("##video folder", video.folder)


def view_aspect(at: PathScene) -> float:
    """The last frame's viewport's width / height."""
    _, _, width, height = NO_VIEWPORT if at.shown is None else at.shown.viewport
    return width / height
