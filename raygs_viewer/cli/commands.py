"""The headless commands: ``info`` (describe a scene), ``render`` (one image, also again
from a screenshot's sidecar) and ``verify`` (GL against the float64 reference).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import Camera, frame_points
from raygs_viewer.capture import screenshot
from raygs_viewer.capture.camera_entries import OrderViewpoint
from raygs_viewer.capture.channel_io import (
    CHANNEL_SUFFIXES,
    colour_channels,
    depth_range_line,
    is_plain_colour,
    picture_view,
    save_channels,
)
from raygs_viewer.capture.edit_file import read_edit_json
from raygs_viewer.capture.image_io import check_output_path, save_image
from raygs_viewer.capture.sidecar import (
    Sidecar,
    load_camera_source,
    load_sidecar,
    resolve_scene,
    verify_scene_hash,
)
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.options import (
    add_channel_options,
    add_stereo_options,
    add_view_options,
    check_normal_space,
    render_settings,
    stereo_view,
)
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import json_text
from raygs_viewer.render import reference
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.channels import DEFAULT_CHANNELS, ChannelImage, needs_geometry
from raygs_viewer.render.gl.context import context_description, create_headless_context
from raygs_viewer.render.gl.memory import scene_fits
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.stereo_frame import render_stereo_view, stereo_order
from raygs_viewer.render.gl.storage import gpu_bytes
from raygs_viewer.render.lod_view import OpenedScene, open_scene
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.setting_info import setting_parts
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order, open_sorter
from raygs_viewer.scene.demo import demo_camera, demo_scene
from raygs_viewer.scene.io import (
    SCENE_FILES,
    describe,
    dropped_summary,
    format_description,
    load_scene,
)
from raygs_viewer.scene.lod_file import lod_summary
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.source import DEMO, SceneSource
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import LodChoice

#: The view options that resize a camera instead of choosing one: with --sidecar they
#: render the screenshot's view at another size.
SIZE_OPTIONS = ("width", "height")
#: render options that set what --sidecar already fixes, (flag, argparse dest): every
#: view option but the size.
SIDECAR_CONFLICTS = tuple(("/".join(action.option_strings), action.dest)
                          for action in add_view_options(argparse.ArgumentParser())
                          if action.dest not in SIZE_OPTIONS)


def add_parsers(commands) -> None:
    """Adds ``info``, ``render`` and ``verify`` to the CLI's subparsers."""
    info = commands.add_parser("info", help="describe a scene file")
    info.add_argument("scene", help=f"a scene file ({SCENE_FILES}), or '{DEMO}'")
    info.add_argument("--json", action="store_true", help="print JSON instead of text")
    argtypes.add_source_options(info)
    info.set_defaults(run=command_info)

    render = commands.add_parser("render", help="render one image headlessly")
    add_view_options(render)
    render.add_argument("--sidecar", metavar="SHOT.json",
                        help="render a screenshot again from its sidecar: scene, camera, settings and size "
                             "come from it (SCENE, if given, replaces the scene file but must have the same "
                             "sha256); --width/--height render its view at another size (the camera scaled "
                             "as for --camera), the other view options cannot be combined with it (to change "
                             "the settings, give the sidecar as --camera instead)")
    render.add_argument("--out", required=True, metavar="OUT.png|OUT.npy|OUT.exr",
                        help=".png: 8-bit RGB (or a picture of the one channel --channels names); .npy: float32 "
                             "HxWx4 (RGB over background, alpha) or HxWxC of --channels; .exr: float32 named "
                             "channels (R, G, B, A unless --channels says otherwise)")
    render.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    argtypes.add_source_options(render, what="the axes a .spz scene that declares none is read in (with "
                                              "--sidecar: the sidecar's)")
    render.set_defaults(run=command_render)
    render.add_argument("--reference", action="store_true", help="use the float64 CPU reference renderer")
    add_channel_options(render)
    add_stereo_options(render)
    argtypes.add_general_option(render)
    argtypes.add_sort_option(render)
    argtypes.add_backend_option(render)

    verify = commands.add_parser("verify", help="render one view with GL and with the float64 reference; "
                                                "print their difference and timings")
    verify.set_defaults(run=command_verify)
    add_view_options(verify)
    argtypes.add_source_options(verify)
    argtypes.add_general_option(verify)
    argtypes.add_backend_option(verify)
    verify.add_argument("--repeat", type=argtypes.positive_int, default=5, metavar="N",
                        help="GL renders to time, after one warm-up (default 5)")


# --- scenes and cameras ---------------------------------------------------------------------------

def load_scene_argument(source: SceneSource, lod: int | None = None) -> Scene:
    """The demo, or the scene file of ``source`` (a streamed SOG's level ``lod``, default
    its finest)."""
    if source.is_demo:
        return demo_scene()
    return load_scene(source, lod=lod)


def open_scene_argument(source: SceneSource, settings: RenderSettings, ctx=None) -> OpenedScene:
    """The demo, or the scene file of ``source`` opened for ``settings`` (a streamed SOG:
    its level or the levels the GPU of ``ctx`` holds, render/lod_view.py); warns about
    what it dropped and what it left unread."""
    fits = None if ctx is None or source.is_demo else scene_fits(ctx)[0]
    opened = open_scene(source, settings, fits=fits)
    warn_dropped(opened.scene)
    if opened.note:
        print(f"warning: {opened.note}", file=sys.stderr)
    return opened


def edited(opened: OpenedScene, edits: dict | None, sha256: str, where: str) -> OpenedScene:
    """``opened`` as the window's ``edits`` (a sidecar's or a path file's "edits", in the
    file ``where``) left it: the gaussians deleted there left out of every sort, as the
    window hid them (a streamed SOG's levels keep their rows, so its choices stay the
    window's). ``sha256``: the scene file's, which must be the one the edits were made on."""
    if edits is None:
        return opened
    document = read_edit_json(edits, f"{where}: 'edits'")
    document.check_scene(sha256, opened.scene.count, where)
    return replace(opened, deleted=DeletedRows.of(document.replay(opened.scene).deleted))


def warn_dropped(scene: Scene) -> None:
    for line in dropped_summary(scene):
        print(f"warning: {line}", file=sys.stderr)


def choose_camera(positions: np.ndarray, source: SceneSource, *, camera_file: str | None, index: int | None,
                  width: int | None, height: int | None) -> Camera:
    """The camera of ``--camera``/``--camera-index`` (a cameras.json or a screenshot's
    sidecar), else the demo's or one framing the scene's ``positions``; resized to
    --width/--height (:func:`sized`)."""
    if camera_file is not None:
        camera = load_camera_source(camera_file, 0 if index is None else index)
    elif source.is_demo:
        camera = demo_camera()
    else:
        camera = frame_points(positions)
    return sized(camera, width, height)


def sized(camera: Camera, width: int | None, height: int | None) -> Camera:
    """``camera`` at --width/--height: fx and cx scale with the width, fy and cy with the
    height; one alone keeps the aspect ratio, neither keeps the camera."""
    if not (width or height):
        return camera
    width = width or max(1, round(height * camera.width / camera.height))
    height = height or max(1, round(width * camera.height / camera.width))
    return camera.resized(width, height)


def _scene_and_camera(args, settings: RenderSettings, ctx) -> tuple[OpenedScene, Camera]:
    """The scene of render's or verify's options and its camera."""
    source = argtypes.scene_source(args, args.scene or DEMO)
    opened = open_scene_argument(source, settings, ctx)
    return opened, choose_camera(opened.framed, source, camera_file=args.camera, index=args.camera_index,
                                 width=args.width, height=args.height)


# --- the commands ---------------------------------------------------------------------------------

def command_info(args) -> int:
    source = argtypes.scene_source(args, args.scene)
    scene = load_scene_argument(source)
    warn_dropped(scene)
    description = describe(scene)
    description["gpu_bytes"] = gpu_bytes(scene.count, scene.sh_degree)
    if not source.is_demo:
        description["lod"] = lod = lod_summary(args.scene)  # a streamed SOG: its levels (the figures above: level 0's)
        if lod is not None:  # what the window and a per-view render hold: every level
            lod["gpu_bytes"] = gpu_bytes(sum(lod["counts"]) + (lod["environment"] or 0), scene.sh_degree)
    if args.json:
        sys.stdout.write(json_text(description))
    else:
        print(format_description(description))
    return 0


def command_render(args) -> int:
    if args.sidecar is not None:
        given = [flag for flag, dest in SIDECAR_CONFLICTS if getattr(args, dest) is not None]
        if given:
            raise UserError(f"--sidecar already sets the view (--width/--height may resize it; --camera SHOT.json "
                            f"takes its camera alone); drop {', '.join(given)}")
        if argtypes.source_options_given(args):
            raise UserError("--sidecar records the axes its .spz scene was read in; drop --spz-axes")
    stereo = stereo_view(args)
    out = check_output_path(args.out, args.overwrite, CHANNEL_SUFFIXES)  # fail before any slow work
    shot = None if args.sidecar is None else load_sidecar(args.sidecar)
    output = channel_output(args, out, shot)
    if needs_geometry(output.channels) and (stereo is not None or (shot is not None and shot.stereo is not None)):
        raise UserError(("--stereo" if shot is None else f"{shot.path}: the stereo image") + " composes colour: "
                        f"{', '.join(c for c in output.channels if needs_geometry((c,)))} need one camera "
                        "(render each eye with --camera)")
    ctx = None if args.reference else create_headless_context(args.gl_backend)
    try:
        if shot is not None:
            scene_name = resolve_scene(shot, args.scene)
            verify_scene_hash(shot, scene_name)
            camera, settings, stereo = sized(shot.camera, args.width, args.height), shot.settings, shot.stereo
            opened = edited(open_scene_argument(shot.source(scene_name), settings, ctx), shot.edits,
                            shot.scene_sha256, str(shot.path))
        else:
            settings = render_settings(args)
            opened, camera = _scene_and_camera(args, settings, ctx)
        start = time.perf_counter()
        image, drawn = render_image(args, ctx, opened, camera, settings, stereo=stereo, channels=output.channels,
                                    viewpoint=None if shot is None else shot.viewpoint)
        elapsed = time.perf_counter() - start
    finally:
        if ctx is not None:
            ctx.release()
    if isinstance(image, np.ndarray) and is_plain_colour(output.channels, out.suffix):
        save_image(out, image, args.overwrite)  # what render always wrote, byte for byte
        height, width = image.shape[:2]
    else:
        channels = image if isinstance(image, ChannelImage) else colour_channels(image)
        channels = channels.in_space(output.normal_space, camera)
        used = save_channels(out, channels, output.channels, output.view, args.overwrite)
        height, width = channels.alpha.shape
        if output.view is not None and output.view.channel in ("depth", "median_depth"):
            print(depth_range_line(output.view, used))
    print(f"{out}: {width}x{height}, {drawn}, "
          f"{'reference' if args.reference else 'GL'} render {elapsed * 1000:.0f} ms"
          + (f", {','.join(output.channels)}" if output.channels != DEFAULT_CHANNELS else "")
          + (f", view from {args.sidecar}" if args.sidecar is not None else ""))
    return 0


@dataclass(frozen=True)
class ChannelOutput:
    """What render writes: the channels, the normals' space, and for a .png the picture."""

    channels: tuple[str, ...]
    normal_space: str
    view: ChannelView | None


def channel_output(args, out: Path, shot: Sidecar | None) -> ChannelOutput:
    """--channels, --normal-space, --depth-range and --alpha-threshold checked against
    OUT's format; those
    not given come from the picture a sidecar recorded (a screenshot of a depth view
    renders again as that depth picture), else the defaults (colour and alpha)."""
    recorded = None if shot is None else shot.channel_view
    channels = args.channels or ((recorded.channel,) if recorded is not None else DEFAULT_CHANNELS)
    normal_space = args.normal_space
    if normal_space is None and recorded is not None and "normal" in channels:
        normal_space = recorded.normal_space
    normal_space = check_normal_space(channels, normal_space)
    depth_range, alpha_threshold = args.depth_range, args.alpha_threshold
    if recorded is not None and out.suffix.lower() == ".png" and channels == (recorded.channel,):
        depth_range = recorded.depth_range if depth_range is None else depth_range
        alpha_threshold = recorded.alpha_threshold if alpha_threshold is None else alpha_threshold
    return ChannelOutput(channels, normal_space,
                         picture_view(channels, out.suffix, depth_range, normal_space, alpha_threshold))


def render_image(args, ctx, opened: OpenedScene, camera: Camera, settings: RenderSettings, *, stereo,
                 channels: tuple[str, ...], viewpoint: OrderViewpoint | None = None
                 ) -> tuple[np.ndarray | ChannelImage, str]:
    """The render: a ChannelImage (camera-space normals) when ``channels`` need geometry,
    else the (H, W, 4) RGBA image render always made (float64 from the reference), of
    the pair when ``stereo`` (a StereoView) is given; and what it drew, in words.
    ``ctx``: the GL context (None with --reference). ``viewpoint``: a sidecar's "order"
    (a headset eye): the order is sorted from its camera, culled for its cameras, and
    the colour evaluated from its origin, as the window drew the image (mono; the
    float64 reference draws its colour the same way)."""
    geometry = needs_geometry(channels)
    if args.reference:
        if viewpoint is None:
            scene, choice = opened.drawn(camera)
            if geometry:
                return reference.render_reference_channels(scene, camera, settings), drawn_words(opened, choice)
            return render_reference(scene, camera, settings), drawn_words(opened, choice)
        if geometry:
            raise UserError("the float64 reference of an image sorted from another viewpoint (a headset eye) "
                            "draws its colour only")
        # The rows the sort's camera chose, sorted and culled where the window sorted them.
        scene, choice = opened.drawn(viewpoint.camera)
        order = exact_order(DepthSorter(scene), viewpoint.camera, settings, cull_cameras=viewpoint.cull_cameras)
        return (render_reference(scene, camera, settings, order.indices, color_origin=viewpoint.color_origin),
                drawn_words(opened, choice))
    renderer = GLRenderer(ctx, opened.scene, general=args.general)
    try:
        sorter = open_sorter(args.sort, ctx, opened.scene)
    except BaseException:
        renderer.release()
        raise
    try:
        if stereo is not None:  # the eyes' midpoint chooses the levels
            order = stereo_order(sorter, camera, settings, stereo.rig, levels=opened.lod, deleted=opened.deleted)
            return render_stereo_view(renderer, order, camera, settings, stereo)[0], drawn_words(opened, order.choice)
        # Tiled like the window's screenshots: the same pixels, and sizes beyond
        # the GPU's largest render target.
        if viewpoint is None:
            order, origin = exact_order(sorter, camera, settings, levels=opened.lod, deleted=opened.deleted), None
        else:  # the sort's camera also chooses the levels, as it did in the window
            order = exact_order(sorter, viewpoint.camera, settings, cull_cameras=viewpoint.cull_cameras,
                                levels=opened.lod, deleted=opened.deleted)
            origin = viewpoint.color_origin
        if geometry:
            return (screenshot.render_tiled_channels(renderer, sorter, order, camera, settings,
                                                     median="median_depth" in channels, color_origin=origin),
                    drawn_words(opened, order.choice))
        return (screenshot.render_tiled(renderer, sorter, order, camera, settings, color_origin=origin),
                drawn_words(opened, order.choice))
    finally:
        sorter.close()
        renderer.release()


def drawn_words(opened: OpenedScene, choice: LodChoice | None) -> str:
    """"N gaussians", or for a level-of-detail choice what it drew of what was read; and
    how many are deleted where a screenshot's edits hide some."""
    deleted = 0 if opened.deleted is None else int(opened.deleted.mask.sum())
    deleted_words = f" ({deleted} deleted)" if deleted else ""
    if choice is None:
        return f"{opened.scene.count - deleted} gaussians{deleted_words}"
    per_level = ", ".join(f"{n} at level {level}" for level, n in enumerate(choice.per_level(opened.lod.lod.levels))
                          if n)
    over = "; the coarsest levels alone exceed the budget" if choice.over_budget else ""
    return f"{choice.count} of {opened.scene.count} gaussians (parts: {per_level}{over}){deleted_words}"


def command_verify(args) -> int:
    settings = render_settings(args)
    ctx = create_headless_context(args.gl_backend)
    try:
        opened, camera = _scene_and_camera(args, settings, ctx)
        renderer = GLRenderer(ctx, opened.scene, general=args.general)
        sorter = DepthSorter(opened.scene)
        levels = None if opened.lod is None else opened.lod.choose(camera)  # one choice, made before the clock
        # The warm-up: shader compilation, first upload.
        image = renderer.render(camera, settings, exact_order(sorter, camera, settings, levels=levels))
        gl_times = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            image = renderer.render(camera, settings, exact_order(sorter, camera, settings, levels=levels))
            gl_times.append(time.perf_counter() - start)
        sorter.close()
        renderer.release()
        device = context_description(ctx)
    finally:
        ctx.release()
    scene, choice = opened.drawn(camera)  # the reference draws what the GL renderer was restricted to
    start = time.perf_counter()
    reference = render_reference(scene, camera, settings)
    reference_time = time.perf_counter() - start
    error = np.abs(image.astype(np.float64) - reference)
    mse = float(np.mean(error[..., :3] ** 2))
    gl_time = float(np.median(gl_times))
    print(f"scene       {scene.source} ({drawn_words(opened, choice)}, SH degree {scene.sh_degree})")
    print(f"image       {camera.width}x{camera.height}, p_min {settings.p_min:.6g}")
    print(f"settings    {describe_accuracy(settings)}")
    print(f"device      {device}")
    print(f"max error   {error.max():.3g}  (RGBA, linear 0..1)")
    print(f"p99.9 error {np.quantile(error, 0.999):.3g}")
    print(f"mean error  {error.mean():.3g}")
    print(f"PSNR        {'inf' if mse == 0 else f'{10 * math.log10(1 / mse):.1f}'} dB (RGB)")
    print(f"pixels > 1e-3  {(error.max(axis=-1) > 1e-3).mean() * 100:.3f} %")
    print(f"GL time     {gl_time * 1000:.1f} ms (median of {args.repeat}: sort, preprocess, draw, read back)")
    print(f"reference   {reference_time * 1000:.0f} ms (float64 numpy)")
    print(f"reference/GL {reference_time / gl_time:.1f}")
    return 0


def describe_accuracy(settings: RenderSettings) -> str:
    """One line of the accuracy options, for verify's report: each field's ``line``
    (render.setting_info) where it applies, so a new setting shows up here by itself."""
    return ", ".join(setting_parts(settings, "line", changes_only=False))
