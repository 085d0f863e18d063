"""``render-path``: a camera path rendered to an MP4 video or a folder of PNG frames.

The path is the window's path JSON or a nerfstudio ``camera_path`` file. Every frame
is rendered offscreen with its own exact sort, as a screenshot is, so the video does
not depend on how fast the machine is. Options on the command line replace what the
path file recorded (its size, frame rate, render settings, stereo view).

Ctrl-C stops between frames: an MP4 is closed so it plays the frames it has, a PNG
folder keeps the frames written; exit status 130.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

from raygs_viewer.camera.path import FPS_RANGE, MAX_FRAMES
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.capture.path_file import load_path_document, scene_mismatch
from raygs_viewer.capture.path_render import (
    cameras_of_entries,
    frame_camera_entries,
    frame_size,
    render_frames,
    write_cameras_json,
)
from raygs_viewer.capture.progress import Progress
from raygs_viewer.capture.video import check_video_output, open_sink
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.commands import load_scene_argument, warn_dropped
from raygs_viewer.cli.options import (
    add_settings_options,
    add_stereo_options,
    settings_with_options,
    stereo_view,
)
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.context import create_headless_context
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import DEMO, TerminalProgress

PROGRESS_MODES = ("auto", "bar", "json", "none")


def add_parser(commands) -> None:
    parser = commands.add_parser(
        "render-path", help="render a camera path to an MP4 or a folder of PNG frames",
        description="Renders every frame of a camera path (a path JSON saved by the window, or a nerfstudio "
                    "camera_path file) offscreen with its own exact sort. Options given here replace what the "
                    "path file recorded.")
    parser.add_argument("scene", help=f"a .ply or .splat file, or '{DEMO}'")
    parser.add_argument("path", metavar="PATH.json", help="the window's path JSON, or a nerfstudio camera_path")
    parser.add_argument("--out", required=True, metavar="fly.mp4|frames/",
                        help=".mp4: H.264 video (yuv420p; an odd size is padded to even); anything else: a "
                             "folder of numbered PNG frames")
    parser.add_argument("--fps", type=argtypes.real_number(lambda v: FPS_RANGE[0] <= v <= FPS_RANGE[1],
                                                           f"not in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}]"),
                        metavar="F", help="frames per second (default: the path's); the duration stays")
    parser.add_argument("--size", type=argtypes.resolution, metavar="WxH",
                        help="each frame's camera size (default: the path's); side by side stereo doubles the width")
    add_settings_options(parser, None, None)
    add_stereo_options(parser)
    parser.add_argument("--overwrite", action="store_true", help="replace OUT (and --cameras-out) if it exists")
    parser.add_argument("--cameras-out", metavar="CAMERAS.json",
                        help="also write every frame's camera as an INRIA cameras.json (render --camera CAMERAS.json "
                             "--camera-index K reproduces frame K)")
    parser.add_argument("--progress", choices=PROGRESS_MODES, default="auto",
                        help="auto: a progress bar on a terminal (default); json: one JSON line per frame on stdout")
    argtypes.add_general_option(parser)
    argtypes.add_backend_option(parser)
    parser.set_defaults(reference=False, sidecar=None)  # what stereo_view checks for render


def command_render_path(args: argparse.Namespace) -> int:
    # Every check that needs no rendering comes first: a typo must not cost a long render.
    out = check_video_output(args.out, args.overwrite)
    cameras_out = None if args.cameras_out is None else \
        check_output_path(args.cameras_out, args.overwrite, suffixes=(".json",))
    if cameras_out is not None and cameras_out.resolve() == out.resolve():
        raise UserError("--cameras-out and --out name the same file")
    document = load_path_document(args.path)
    for note in document.notes:  # e.g. a nerfstudio crop box this viewer does not apply
        print(f"note: {note}", file=sys.stderr)
    mismatch = scene_mismatch(document, args.scene)
    if mismatch:
        print(f"warning: {mismatch}", file=sys.stderr)
    settings = settings_with_options(document.settings or RenderSettings(), args)
    stereo = stereo_view(args) if args.stereo else document.stereo
    path = document.path if args.fps is None else replace(document.path, fps=args.fps)
    width, height = args.size or (document.width, document.height)
    if path.frame_count > MAX_FRAMES:
        raise UserError(f"{path.frame_count} frames is more than {MAX_FRAMES}; lower --fps")
    entries = frame_camera_entries(path, width, height)
    cameras = cameras_of_entries(entries)  # what render --camera loads from the entries

    with TerminalProgress(args.scene) as loading:
        scene = load_scene_argument(args.scene, loading)
    warn_dropped(scene)
    ctx = create_headless_context(args.gl_backend)
    try:
        renderer = GLRenderer(ctx, scene, general=args.general)
        try:
            problem = renderer.supports(settings)
            if problem:
                raise UserError(problem)
            if cameras_out is not None:
                write_cameras_json(entries, cameras_out, args.overwrite)
            return _render(renderer, cameras, settings, stereo, out, frame_size(width, height, stereo), path.fps,
                           args)
        finally:
            renderer.release()
    finally:
        ctx.release()


def _render(renderer, cameras, settings, stereo, out: Path, image_size, fps: float, args) -> int:
    sink = open_sink(out, *image_size, fps, args.overwrite, frames=len(cameras))
    if sink.note:
        print(f"note: {sink.note}", file=sys.stderr)
    progress = Progress(len(cameras), args.progress, label=out.name)
    start = time.perf_counter()
    try:
        render_frames(renderer, cameras, settings, stereo, sink, progress)
        written = sink.finish()
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
    progress.finish(written)
    if args.progress != "json":
        print(f"{written}: {len(cameras)} frames, {image_size[0]}x{image_size[1]} at {fps:g} fps "
              f"({len(cameras) / fps:.1f} s), {_size_of(written)}; rendered {len(cameras) / elapsed:.2f} frames/s")
    return 0


def _size_of(path: Path) -> str:
    """The output's size on disk, in MB."""
    files = [path] if path.is_file() else list(path.glob("*.png"))
    return f"{sum(f.stat().st_size for f in files) / 1e6:.1f} MB"
