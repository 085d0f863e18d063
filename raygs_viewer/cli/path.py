"""``render-path``: a camera path rendered to an MP4 video or a folder of PNG frames.

The path is the window's path JSON, a nerfstudio ``camera_path`` file, or ``orbit``: a
turntable around the scene's centre, framed as the window's Reset view frames it. Every frame
is rendered offscreen with its own exact sort, as a screenshot is, so the video does
not depend on how fast the machine is. Options on the command line replace what the
path file recorded (its size, frame rate, render settings, stereo view).

Ctrl-C stops between frames: an MP4 is closed so it plays the frames it has, a PNG
folder keeps the frames written; exit status 130.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from raygs_viewer.camera.navigation import UP_AXES, framing_distance, framing_pose, scene_bounds, up_vector
from raygs_viewer.camera.path import FPS_RANGE, MAX_DURATION, CameraPath, orbit_path
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.capture.path_file import PathDocument, load_path_document, scene_mismatch
from raygs_viewer.capture.path_render import (
    cameras_of_entries,
    frame_camera_entries,
    frame_size,
    render_frames,
    write_cameras_json,
)
from raygs_viewer.capture.progress import MODES, Progress, TerminalProgress
from raygs_viewer.capture.video import VIDEO_SUFFIX, ExrFolderSink, check_video_output, open_sink
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.commands import edited, warn_dropped
from raygs_viewer.cli.options import (
    add_channel_options,
    add_settings_options,
    add_stereo_options,
    check_normal_space,
    settings_with_options,
    stereo_view,
)
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.context import create_headless_context
from raygs_viewer.render.channels import needs_geometry
from raygs_viewer.render.gl.memory import scene_fits
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.lod_view import OpenedScene, for_settings, levels_to_read, refuse_lod_settings
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import open_sorter
from raygs_viewer.scene.io import SCENE_FILES
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.source import DEMO

#: The PATH argument that asks for a turntable instead of a path file, and its defaults.
ORBIT = "orbit"
ORBIT_SIZE = (1280, 720)
ORBIT_FOV = 50.0


def add_parsers(commands) -> None:
    """Adds ``render-path`` to the CLI's subparsers."""
    parser = commands.add_parser(
        "render-path", help="render a camera path to an MP4 or a folder of PNG frames",
        description="Renders every frame of a camera path (a path JSON saved by the window, or a nerfstudio "
                    "camera_path file) offscreen with its own exact sort. Options given here replace what the "
                    "path file recorded.")
    parser.add_argument("scene", help=f"a scene file ({SCENE_FILES}), or '{DEMO}'")
    parser.add_argument("path", metavar="PATH.json|orbit",
                        help="the window's path JSON, a nerfstudio camera_path, or 'orbit': one lap around the "
                             f"scene's centre (10 s at 30 fps, {ORBIT_SIZE[0]}x{ORBIT_SIZE[1]} unless --duration, "
                             "--fps or --size say otherwise)")
    parser.add_argument("--out", required=True, metavar="fly.mp4|frames/",
                        help=".mp4: H.264 video (yuv420p; an odd size is padded to even); anything else: a "
                             "folder of numbered PNG frames")
    parser.add_argument("--fps", type=argtypes.real_number(lambda v: FPS_RANGE[0] <= v <= FPS_RANGE[1],
                                                           f"not in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}]"),
                        metavar="F", help="frames per second (default: the path's); the duration stays")
    parser.add_argument("--duration", type=argtypes.real_number(lambda v: 0 < v <= MAX_DURATION,
                                                                f"not in (0, {MAX_DURATION:g}] seconds"),
                        metavar="SECONDS", help="the path's length in time (default: the path's); keyframes with "
                                                "times of their own keep them, so it must not cut them off")
    parser.add_argument("--up-axis", choices=UP_AXES,
                        help="orbit: the scene's up axis, the turntable's axis (default -y, as in the window)")
    parser.add_argument("--size", type=argtypes.resolution, metavar="WxH",
                        help="each frame's camera size (default: the path's); side by side stereo doubles the width")
    add_settings_options(parser, None, None)
    add_stereo_options(parser)
    add_channel_options(parser, picture=False)
    parser.add_argument("--overwrite", action="store_true", help="replace OUT (and --cameras-out) if it exists")
    argtypes.add_source_options(parser, what="the axes a .spz scene that declares none is read in (default: what "
                                              "the path file recorded, else rub)")
    parser.add_argument("--cameras-out", metavar="CAMERAS.json",
                        help="also write every frame's camera as an INRIA cameras.json (render --camera CAMERAS.json "
                             "--camera-index K reproduces frame K)")
    parser.add_argument("--progress", choices=MODES, default="auto",
                        help="auto: a progress bar on a terminal (default); json: one JSON line per frame on stdout")
    argtypes.add_general_option(parser)
    argtypes.add_sort_option(parser, default="auto")
    argtypes.add_backend_option(parser)
    parser.set_defaults(reference=False, sidecar=None)  # what stereo_view checks for render
    parser.set_defaults(run=command_render_path)


def command_render_path(args: argparse.Namespace) -> int:
    # Every check that needs no rendering comes first: a typo must not cost a long render.
    out = check_video_output(args.out, args.overwrite)
    if args.channels is not None and out.suffix.lower() == VIDEO_SUFFIX:
        raise UserError(f"{out}: a video carries 8-bit colour only; --channels writes EXR frames into a folder "
                        "(give --out a folder name)")
    check_normal_space(args.channels or (), args.normal_space)
    cameras_out = None if args.cameras_out is None else \
        check_output_path(args.cameras_out, args.overwrite, suffixes=(".json",))
    if cameras_out is not None and cameras_out.resolve() == out.resolve():
        raise UserError("--cameras-out and --out name the same file")
    document = None if args.path == ORBIT else read_document(args)
    settings = settings_with_options(document.settings if document and document.settings else RenderSettings(),
                                     args)
    stereo = stereo_view(args) if args.stereo else document.stereo if document else None
    if stereo is not None and args.channels is not None and needs_geometry(args.channels):
        raise UserError("--stereo composes colour; its frames cannot carry depth or normals")
    path = None if document is None else retimed(document.path, args)

    ctx = create_headless_context(args.gl_backend)
    try:
        return _render_scene(ctx, args, _Job(document, settings, stereo, path, out, cameras_out))
    finally:
        ctx.release()


@dataclass(frozen=True)
class _Job:
    """render-path's options once checked, before anything is read: the path file
    (None: the orbit, made once the scene is read), the settings, the stereo view (None:
    mono), the path at --fps and --duration (None with the orbit), the frames' output
    and where the cameras go (None: nowhere)."""

    document: PathDocument | None
    settings: RenderSettings
    stereo: StereoView | None
    path: CameraPath | None
    out: Path
    cameras_out: Path | None


def _render_scene(ctx, args, job: _Job) -> int:
    """render-path once its options are checked: the scene read (a streamed SOG: the
    levels the GPU of ``ctx`` holds, chosen for each frame), the frames rendered."""
    document, settings, path = job.document, job.settings, job.path
    source = argtypes.scene_source(args, args.scene, recorded=document and document.scene_axes,
                                   levels=levels_to_read(settings))
    with TerminalProgress(args.scene) as loading:  # the scene's hash is taken while it is read
        loaded = load_now(source, progress=loading, fits=scene_fits(ctx)[0])
    if loaded.lod is None:
        refuse_lod_settings("the demo scene" if source.is_demo else args.scene, settings)
    opened = OpenedScene(loaded.scene) if loaded.lod is None else for_settings(loaded.lod, settings)
    if document is not None:  # the window's deletions, on the very scene they were made on
        opened = edited(opened, document.edits, loaded.sha256, args.scene)
    scene = opened.scene
    warn_dropped(scene)
    if opened.note:
        print(f"warning: {opened.note}", file=sys.stderr)
    if document is None:
        document = orbit_document(opened.framed, args.up_axis or "-y", *(args.size or ORBIT_SIZE))
        path = retimed(document.path, args)
    else:
        mismatch = scene_mismatch(document, args.scene, loaded.sha256)
        if mismatch:
            print(f"warning: {mismatch}", file=sys.stderr)
    width, height = args.size or (document.width, document.height)
    entries = frame_camera_entries(path, width, height)
    cameras = cameras_of_entries(entries)  # what render --camera loads from the entries
    renderer = GLRenderer(ctx, scene, general=args.general)
    try:
        sorter = open_sorter(args.sort, ctx, scene)
    except BaseException:
        renderer.release()
        raise
    try:
        problem = renderer.supports(settings)
        if problem:
            raise UserError(problem)
        if job.cameras_out is not None:
            write_cameras_json(entries, job.cameras_out, args.overwrite)
        return _render(renderer, sorter, cameras, job, image_size=frame_size(width, height, job.stereo),
                       fps=path.fps, args=args, opened=opened)
    finally:
        sorter.close()
        renderer.release()


def read_document(args: argparse.Namespace) -> PathDocument:
    """The path file (printing its notes)."""
    if args.up_axis is not None:
        raise UserError("--up-axis is for 'orbit'; a path file has its own up axis")
    document = load_path_document(args.path)
    for note in document.notes:  # e.g. a nerfstudio crop box this viewer does not apply
        print(f"note: {note}", file=sys.stderr)
    return document


def retimed(path: CameraPath, args: argparse.Namespace) -> CameraPath:
    """``path`` at --fps and --duration where given (UserError for a duration that
    would cut off a keyframe's own time)."""
    return replace(path, fps=args.fps or path.fps, duration=args.duration or path.duration)


def orbit_document(positions: np.ndarray, up: str, width: int, height: int) -> PathDocument:
    """One lap around the centre of ``positions`` (the scene's, without a streamed SOG's
    environment; their bounds', as the window's Reset view finds them), from the side the
    window's Reset view looks from, at the distance that fits their bounding sphere in
    the view, 20 degrees above the horizon of ``up``."""
    center, radius = scene_bounds(positions)
    aspect = width / height
    start = framing_pose(center, radius, up, ORBIT_FOV, aspect)
    path = orbit_path(center, framing_distance(radius, ORBIT_FOV, aspect), up_vector(up), start=start,
                      fov_y_degrees=ORBIT_FOV)
    return PathDocument(path, width, height)


def _render(renderer, sorter, cameras, job: _Job, *, image_size: tuple[int, int], fps: float, args,
            opened: OpenedScene) -> int:
    """The frames of ``cameras`` rendered into ``job.out`` at ``image_size`` (width,
    height; a stereo frame's pair), ``fps``; the exit status (130: interrupted)."""
    settings, stereo, out = job.settings, job.stereo, job.out
    if args.channels is not None:
        sink = ExrFolderSink(out, *image_size, args.channels, overwrite=args.overwrite, frames=len(cameras))
    else:
        sink = open_sink(out, *image_size, fps, overwrite=args.overwrite, frames=len(cameras))
    if sink.note:
        print(f"note: {sink.note}", file=sys.stderr)
    progress = Progress(len(cameras), args.progress, label=out.name)
    if args.progress == "json":
        # The reader of JSON progress (the window's Render video) stops the render with
        # SIGINT. A process started in the background of a script inherits SIGINT
        # ignored, and Python then leaves it so: Cancel would do nothing.
        signal.signal(signal.SIGINT, signal.default_int_handler)
    timed = TimedSink(sink)
    start = time.perf_counter()
    try:
        render_frames(renderer, sorter, cameras, settings, timed, stereo=stereo, progress=progress,
                      channels=args.channels, normal_space=check_normal_space(args.channels or (), args.normal_space),
                      lod=opened.lod, deleted=opened.deleted)
        written = timed.finish()
    except KeyboardInterrupt:
        kept = sink.abort()
        progress.interrupted(sink.frames_written, kept)
        if kept is None:
            print(f"interrupted: no frame was finished, {out} not written", file=sys.stderr)
        else:
            print(f"interrupted: {kept} holds the first {sink.frames_written} of {len(cameras)} frames",
                  file=sys.stderr)
        return 130
    except BaseException:
        sink.abort()
        raise
    elapsed = time.perf_counter() - start
    count = len(cameras)
    progress.finish(written)
    if args.progress != "json":
        print(f"{written}: {count} frames, {image_size[0]}x{image_size[1]} at {fps:g} fps ({count / fps:.1f} s), "
              f"{_size_of(written)}; {count / elapsed:.2f} frames/s (a frame: render "
              f"{(elapsed - timed.seconds) / count * 1000:.1f} ms, {'encode' if written.is_file() else 'write'} "
              f"{timed.seconds / count * 1000:.1f} ms)")
    return 0


class TimedSink:
    """A sink's writes and finish, timed: the encoder's (or PNG writer's) share of the
    time, for the summary line."""

    def __init__(self, sink):
        self.sink, self.seconds = sink, 0.0

    @property
    def frames_written(self) -> int:
        return self.sink.frames_written

    def write(self, frame) -> None:
        start = time.perf_counter()
        self.sink.write(frame)
        self.seconds += time.perf_counter() - start

    def finish(self) -> Path:
        start = time.perf_counter()
        written = self.sink.finish()
        self.seconds += time.perf_counter() - start
        return written


def _size_of(path: Path) -> str:
    """The output's size on disk, in MB (kB below 1 MB)."""
    files = [path] if path.is_file() else [*path.glob("*.png"), *path.glob("*.exr")]
    size = sum(f.stat().st_size for f in files)
    return f"{size / 1e6:.1f} MB" if size >= 1e6 else f"{size / 1e3:.0f} kB"
