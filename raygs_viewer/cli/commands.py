"""The headless commands: ``info`` (describe a scene), ``render`` (one image, also again
from a screenshot's sidecar) and ``verify`` (GL against the float64 reference).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from raygs_viewer.camera.pinhole import Camera, frame_points, load_camera
from raygs_viewer.capture import screenshot
from raygs_viewer.capture.image_io import check_output_path, save_image
from raygs_viewer.capture.sidecar import load_sidecar, resolve_scene, verify_scene_hash
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.options import (
    add_stereo_options,
    add_view_options,
    render_settings,
    stereo_view,
)
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import json_text
from raygs_viewer.render.gl.context import context_description, create_headless_context
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.stereo_frame import render_stereo_view
from raygs_viewer.render.gl.storage import gpu_bytes
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.setting_info import setting_parts
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.demo import demo_camera, demo_scene
from raygs_viewer.scene.io import (
    SCENE_FILES,
    describe,
    dropped_summary,
    format_description,
    load_scene,
)
from raygs_viewer.scene.loader import DEMO
from raygs_viewer.scene.model import Scene

#: render options that set what --sidecar already fixes, (flag, argparse dest): every
#: view option.
SIDECAR_CONFLICTS = tuple(("/".join(action.option_strings), action.dest)
                          for action in add_view_options(argparse.ArgumentParser()))


def add_parsers(commands) -> None:
    """Adds ``info``, ``render`` and ``verify`` to the CLI's subparsers."""
    info = commands.add_parser("info", help="describe a scene file")
    info.add_argument("scene", help=f"a scene file ({SCENE_FILES}), or '{DEMO}'")
    info.add_argument("--json", action="store_true", help="print JSON instead of text")
    info.set_defaults(run=command_info)

    render = commands.add_parser("render", help="render one image headlessly")
    add_view_options(render)
    render.add_argument("--sidecar", metavar="SHOT.json",
                        help="render a screenshot again from its sidecar: scene, camera, settings and size "
                             "come from it (SCENE, if given, replaces the scene file but must have the same "
                             "sha256); the view options above cannot be combined with it")
    render.add_argument("--out", required=True, metavar="OUT.png|OUT.npy",
                        help=".png: 8-bit RGB; .npy: float32 HxWx4 (RGB over background, alpha)")
    render.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    render.set_defaults(run=command_render)
    render.add_argument("--reference", action="store_true", help="use the float64 CPU reference renderer")
    add_stereo_options(render)
    argtypes.add_general_option(render)
    argtypes.add_backend_option(render)

    verify = commands.add_parser("verify", help="render one view with GL and with the float64 reference; "
                                                "print their difference and timings")
    verify.set_defaults(run=command_verify)
    add_view_options(verify)
    argtypes.add_general_option(verify)
    argtypes.add_backend_option(verify)
    verify.add_argument("--repeat", type=argtypes.positive_int, default=5, metavar="N",
                        help="GL renders to time, after one warm-up (default 5)")


# --- scenes and cameras ---------------------------------------------------------------------------

def load_scene_argument(name: str) -> Scene:
    return demo_scene() if name == DEMO else load_scene(name)


def warn_dropped(scene: Scene) -> None:
    for line in dropped_summary(scene):
        print(f"warning: {line}", file=sys.stderr)


def choose_camera(scene: Scene, scene_name: str, camera_file: str | None, index: int | None, width: int | None,
                  height: int | None) -> Camera:
    """The camera of ``--camera``/``--camera-index``, else the demo's or one framing the
    scene; resized when --width/--height are given (one alone keeps the aspect ratio)."""
    if camera_file is not None:
        camera = load_camera(camera_file, index or 0)
    elif scene_name == DEMO:
        camera = demo_camera()
    else:
        camera = frame_points(scene.positions)
    if width or height:
        width = width or max(1, round(height * camera.width / camera.height))
        height = height or max(1, round(width * camera.height / camera.width))
        camera = camera.resized(width, height)
    return camera


def _scene_and_camera(args) -> tuple[Scene, Camera]:
    """The scene of render's or verify's options (warning about what it dropped) and its camera."""
    scene_name = args.scene or DEMO
    scene = load_scene_argument(scene_name)
    warn_dropped(scene)
    return scene, choose_camera(scene, scene_name, args.camera, args.camera_index, args.width, args.height)


# --- the commands ---------------------------------------------------------------------------------

def command_info(args) -> int:
    scene = load_scene_argument(args.scene)
    warn_dropped(scene)
    description = describe(scene)
    description["gpu_bytes"] = gpu_bytes(scene.count, scene.sh_degree)
    if args.json:
        sys.stdout.write(json_text(description))
    else:
        print(format_description(description))
    return 0


def command_render(args) -> int:
    if args.sidecar is not None:
        given = [flag for flag, dest in SIDECAR_CONFLICTS if getattr(args, dest) is not None]
        if given:
            raise UserError(f"--sidecar already sets the view; drop {', '.join(given)}")
    stereo = stereo_view(args)
    out = check_output_path(args.out, args.overwrite)  # fail before any slow work
    if args.sidecar is not None:
        shot = load_sidecar(args.sidecar)
        scene_name = resolve_scene(shot, args.scene)
        verify_scene_hash(shot, scene_name)
        camera, settings, stereo = shot.camera, shot.settings, shot.stereo
        scene = load_scene_argument(scene_name)
        warn_dropped(scene)
    else:
        settings = render_settings(args)
        scene, camera = _scene_and_camera(args)
    start = time.perf_counter()
    if args.reference:
        image = render_reference(scene, camera, settings)
    else:
        ctx = create_headless_context(args.gl_backend)
        try:
            renderer = GLRenderer(ctx, scene, general=args.general)
            if stereo is not None:
                image = render_stereo_view(renderer, camera, settings, stereo)[0]
            else:
                # Tiled like the window's screenshots: the same pixels, and sizes beyond
                # the GPU's largest render target.
                image = screenshot.render_tiled(renderer, camera, settings)
            renderer.release()
        finally:
            ctx.release()
    elapsed = time.perf_counter() - start
    save_image(out, image, args.overwrite)
    print(f"{out}: {image.shape[1]}x{image.shape[0]}, {scene.count} gaussians, "
          f"{'reference' if args.reference else 'GL'} render {elapsed * 1000:.0f} ms"
          + (f", view from {args.sidecar}" if args.sidecar is not None else ""))
    return 0


def command_verify(args) -> int:
    settings = render_settings(args)
    scene, camera = _scene_and_camera(args)
    ctx = create_headless_context(args.gl_backend)
    try:
        renderer = GLRenderer(ctx, scene, general=args.general)
        image = renderer.render(camera, settings)  # warm-up: shader compilation, first upload
        gl_times = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            image = renderer.render(camera, settings)
            gl_times.append(time.perf_counter() - start)
        renderer.release()
        device = context_description(ctx)
    finally:
        ctx.release()
    start = time.perf_counter()
    reference = render_reference(scene, camera, settings)
    reference_time = time.perf_counter() - start
    error = np.abs(image.astype(np.float64) - reference)
    mse = float(np.mean(error[..., :3] ** 2))
    gl_time = float(np.median(gl_times))
    print(f"scene       {scene.source} ({scene.count} gaussians, SH degree {scene.sh_degree})")
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
