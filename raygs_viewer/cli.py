"""The ``raygs-viewer`` command line: ``info``, ``render`` and ``verify`` (the window comes later).

Bad input ends in one line, ``error: <what and where>``, and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

from raygs_viewer import __version__
from raygs_viewer.errors import UserError

DEMO = "demo"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, like every other error
        raise UserError(f"{message} (see '{self.prog} --help')")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
    if not 1 <= value <= 65536:
        raise argparse.ArgumentTypeError(f"{value} is outside 1..65536")
    return value


def _p_min(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"{text} is not in (0, 1)")
    return value


def _color(text: str) -> tuple[float, float, float]:
    try:
        parts = tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not three numbers R,G,B") from None
    if len(parts) != 3 or not all(math.isfinite(p) for p in parts):
        raise argparse.ArgumentTypeError(f"'{text}' is not three finite numbers R,G,B")
    return parts


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="raygs-viewer", description="Ray-based Gaussian splatting (RayGS) viewer.")
    parser.add_argument("--version", action="version", version=f"raygs-viewer {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    info = commands.add_parser("info", help="describe a scene file")
    info.add_argument("scene", help=f"a .ply or .splat file, or '{DEMO}'")
    info.add_argument("--json", action="store_true", help="print JSON instead of text")

    render = commands.add_parser("render", help="render one image headlessly")
    _add_view_options(render)
    render.add_argument("--out", required=True, metavar="OUT.png|OUT.npy",
                        help=".png: 8-bit RGB; .npy: float32 HxWx4 (RGB over background, alpha)")
    render.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    render.add_argument("--reference", action="store_true", help="use the float64 CPU reference renderer")
    _add_backend_option(render)

    verify = commands.add_parser("verify", help="render one view with GL and with the float64 reference; "
                                                "print their difference and timings")
    _add_view_options(verify)
    _add_backend_option(verify)
    verify.add_argument("--repeat", type=_positive_int, default=5, metavar="N",
                        help="GL renders to time, after one warm-up (default 5)")
    return parser


def _add_view_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", nargs="?", default=DEMO, help=f"a .ply or .splat file, or '{DEMO}' (default)")
    parser.add_argument("--camera", metavar="CAMERAS.json", help="INRIA cameras.json (a list or one camera)")
    parser.add_argument("--camera-index", type=int, default=0, metavar="I", help="which camera of the file (default 0)")
    parser.add_argument("--width", type=_positive_int, help="image width; fx and cx scale to match")
    parser.add_argument("--height", type=_positive_int, help="image height; fy and cy scale to match")
    parser.add_argument("--p-min", type=_p_min, default=1 / 255, metavar="P",
                        help="opacity cut-off, sets kappa = -2 ln(P/o) (default 1/255)")
    parser.add_argument("--background", type=_color, default=(0.0, 0.0, 0.0), metavar="R,G,B",
                        help="background colour, 0..1 each (default 0,0,0)")


def _add_backend_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--gl-backend", choices=("auto", "egl", "osmesa"),
                        help="headless OpenGL (default: $RAYGS_GL_BACKEND or auto: EGL, else OSMesa)")


def load_scene_argument(name: str):
    if name == DEMO:
        from raygs_viewer.demo import demo_scene
        return demo_scene()
    from raygs_viewer.scene_io import load_scene
    return load_scene(name)


def _warn_dropped(scene) -> None:
    from raygs_viewer.scene_io import dropped_summary
    for line in dropped_summary(scene):
        print(f"warning: {line}", file=sys.stderr)


def _command_info(args) -> int:
    from raygs_viewer.scene_io import describe, format_description
    scene = load_scene_argument(args.scene)
    _warn_dropped(scene)
    description = describe(scene)
    print(json.dumps(description, indent=2) if args.json else format_description(description))
    return 0


def choose_camera(scene, scene_name: str, camera_file: str | None, index: int, width: int | None,
                  height: int | None):
    """The camera of ``--camera``/``--camera-index``, else the demo's or one framing the
    scene; resized when --width/--height are given (one alone keeps the aspect ratio)."""
    from raygs_viewer.camera import frame_points, load_camera
    if camera_file is not None:
        camera = load_camera(camera_file, index)
    elif scene_name == DEMO:
        from raygs_viewer.demo import demo_camera
        camera = demo_camera()
    else:
        camera = frame_points(scene.positions)
    if width or height:
        width = width or max(1, round(height * camera.width / camera.height))
        height = height or max(1, round(width * camera.height / camera.width))
        camera = camera.resized(width, height)
    return camera


def _command_render(args) -> int:
    from raygs_viewer.imageio import check_output_path, save_image
    from raygs_viewer.settings import RenderSettings

    out = check_output_path(args.out, args.overwrite)  # fail before any slow work
    settings = RenderSettings(p_min=args.p_min, background=args.background)
    scene = load_scene_argument(args.scene)
    _warn_dropped(scene)
    camera = choose_camera(scene, args.scene, args.camera, args.camera_index, args.width, args.height)
    start = time.perf_counter()
    if args.reference:
        from raygs_viewer.reference import render_reference
        image = render_reference(scene, camera, settings)
    else:
        from raygs_viewer.render.context import create_headless_context
        from raygs_viewer.render.renderer import GLRenderer
        ctx = create_headless_context(args.gl_backend)
        try:
            renderer = GLRenderer(ctx, scene)
            image = renderer.render(camera, settings)
            renderer.release()
        finally:
            ctx.release()
    elapsed = time.perf_counter() - start
    save_image(out, image, args.overwrite)
    print(f"{out}: {camera.width}x{camera.height}, {scene.count} gaussians, "
          f"{'reference' if args.reference else 'GL'} render {elapsed * 1000:.0f} ms")
    return 0


def _command_verify(args) -> int:
    import numpy as np

    from raygs_viewer.reference import render_reference
    from raygs_viewer.render.context import context_description, create_headless_context
    from raygs_viewer.render.renderer import GLRenderer
    from raygs_viewer.settings import RenderSettings

    settings = RenderSettings(p_min=args.p_min, background=args.background)
    scene = load_scene_argument(args.scene)
    _warn_dropped(scene)
    camera = choose_camera(scene, args.scene, args.camera, args.camera_index, args.width, args.height)
    ctx = create_headless_context(args.gl_backend)
    try:
        renderer = GLRenderer(ctx, scene)
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


def main(argv: list[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
        commands = {"info": _command_info, "render": _command_render, "verify": _command_verify}
        return commands[args.command](args)
    except UserError as exc:
        print(f"error: {str(exc).splitlines()[0] if str(exc) else 'failed'}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
