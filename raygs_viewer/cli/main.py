"""The ``raygs-viewer`` command line: ``view`` (the window), ``info``, ``render``, ``verify``
and ``bench``.

Without a command the window opens: ``raygs-viewer`` shows the demo, and
``raygs-viewer SCENE.ply [view options]`` or ``raygs-viewer --frames 3`` mean
``raygs-viewer view ...``. ``render --sidecar SHOT.json`` renders a screenshot of the
window again from the JSON sidecar saved beside it.

Bad input ends in one line, ``error: <what and where>``, and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

from raygs_viewer import __version__
from raygs_viewer.errors import UserError

DEMO = "demo"
COMMANDS = ("view", "info", "render", "verify", "bench")
# Arguments that keep their meaning at the top level instead of starting the window.
TOP_LEVEL_OPTIONS = ("-h", "--help", "--version")
SCENE_SUFFIXES = (".ply", ".splat")
# The same axes as controls.UP_AXES (kept here so parsing options imports no window code).
UP_AXES = ("-y", "+y", "+z", "-z", "+x", "-x")
DEFAULT_BACKGROUND = (0.0, 0.0, 0.0)
# render options that set what --sidecar already fixes: (flag, argparse dest).
SIDECAR_CONFLICTS = (("--camera", "camera"), ("--camera-index", "camera_index"), ("--width", "width"),
                     ("--height", "height"), ("--p-min", "p_min"), ("--background", "background"),
                     ("--sh-degree", "sh_degree"), ("--mode", "mode"), ("--mip/--no-mip", "mip"),
                     ("--mip-sigma2", "mip_sigma2"), ("--mip-modulation/--no-mip-modulation", "mip_modulation"),
                     ("--gs-compensation", "gs_compensation"), ("--supersample", "supersample"),
                     ("--alpha-clamp", "alpha_clamp"), ("--transmittance-cutoff", "transmittance_cutoff"))


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, like every other error
        raise UserError(f"{message} (see '{self.prog} --help')")


def _whole_number(low: int, high: float, meaning: str):
    """An argparse type: a whole number in [low, high]; ``meaning`` says the range in words."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{value} is {meaning}")
        return value
    return parse


def _real_number(accept, meaning: str):
    """An argparse type: a finite number that ``accept`` takes; ``meaning`` says which in words."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
        if not (math.isfinite(value) and accept(value)):
            raise argparse.ArgumentTypeError(f"{text} is {meaning}")
        return value
    return parse


_positive_int = _whole_number(1, 65536, "outside 1..65536")
_sh_degree = _whole_number(0, 3, "not 0, 1, 2 or 3")
_frames = _whole_number(1, math.inf, "not at least 1")
_p_min = _real_number(lambda v: 0.0 < v < 1.0, "not in (0, 1)")
_turntable = _real_number(lambda v: abs(v) <= 180, "not between -180 and 180")


def _supersample(text: str) -> int:
    from raygs_viewer.render.settings import MAX_SUPERSAMPLE
    return _whole_number(1, MAX_SUPERSAMPLE, f"outside 1..{MAX_SUPERSAMPLE}")(text)


def _mip_sigma2(text: str) -> float:
    from raygs_viewer.render.settings import MAX_MIP_SIGMA2
    return _real_number(lambda v: 0.0 <= v <= MAX_MIP_SIGMA2, f"not in [0, {MAX_MIP_SIGMA2:g}] px^2")(text)


def _screenshot_scale(text: str) -> float:
    from raygs_viewer.capture.screenshot import MAX_SCALE
    return _real_number(lambda v: 0.0 < v <= MAX_SCALE, f"not in (0, {MAX_SCALE:g}]")(text)


def _color(text: str) -> tuple[float, float, float]:
    try:
        parts = tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not three numbers R,G,B") from None
    if len(parts) != 3 or not all(math.isfinite(p) for p in parts):
        raise argparse.ArgumentTypeError(f"'{text}' is not three finite numbers R,G,B")
    return parts


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="raygs-viewer",
        description="Ray-based Gaussian splatting (RayGS) viewer. Without a command it opens the window: "
                    "'raygs-viewer [SCENE] [view options]' is short for 'raygs-viewer view [SCENE] [view options]', "
                    "and plain 'raygs-viewer' shows the built-in demo.")
    parser.add_argument("--version", action="version", version=f"raygs-viewer {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    view = commands.add_parser("view", help="open the interactive window (the default command)")
    _add_viewer_options(view)

    info = commands.add_parser("info", help="describe a scene file")
    info.add_argument("scene", help=f"a .ply or .splat file, or '{DEMO}'")
    info.add_argument("--json", action="store_true", help="print JSON instead of text")

    render = commands.add_parser("render", help="render one image headlessly")
    _add_view_options(render)
    render.add_argument("--sidecar", metavar="SHOT.json",
                        help="render a screenshot again from its sidecar: scene, camera, settings and size "
                             "come from it (SCENE, if given, replaces the scene file but must have the same "
                             "sha256); the view options above cannot be combined with it")
    render.add_argument("--out", required=True, metavar="OUT.png|OUT.npy",
                        help=".png: 8-bit RGB; .npy: float32 HxWx4 (RGB over background, alpha)")
    render.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    render.add_argument("--reference", action="store_true", help="use the float64 CPU reference renderer")
    _add_stereo_options(render)
    _add_general_option(render)
    _add_backend_option(render)

    verify = commands.add_parser("verify", help="render one view with GL and with the float64 reference; "
                                                "print their difference and timings")
    _add_view_options(verify)
    _add_general_option(verify)
    _add_backend_option(verify)
    verify.add_argument("--repeat", type=_positive_int, default=5, metavar="N",
                        help="GL renders to time, after one warm-up (default 5)")

    from raygs_viewer.bench import accuracy as bench
    bench.add_parser(commands)
    return parser


_STEREO_OPTIONS = (("--ipd", "ipd"), ("--convergence", "convergence"), ("--scene-scale", "scene_scale"),
                   ("--layout", "layout"), ("--lens-preview", "lens_preview"))
_HEADSET_OPTIONS = (("--headset", "headset"), ("--headset-size", "headset_size"), ("--headset-fov", "headset_fov"))


def _add_stereo_options(parser: argparse.ArgumentParser, window: bool = False) -> None:
    """render's stereo options; ``window``: view's, which add the headset preset (the
    eyes' size and field of view) and start the panel's stereo controls even without
    --stereo."""
    from raygs_viewer.camera.stereo import (
        DEFAULT_CONVERGENCE,
        DEFAULT_IPD,
        DEFAULT_SCENE_SCALE,
        LAYOUTS,
    )
    if window:
        parser.add_argument("--stereo", action="store_true",
                            help="open the stereo preview (the panel's Stereo section also switches it); the "
                                 "stereo options below set its start values either way")
    else:
        parser.add_argument("--stereo", action="store_true",
                            help="render the two eyes around the camera (which is their midpoint), each at the "
                                 "camera's size; the image is both eyes side by side unless --layout says "
                                 "otherwise")
    parser.add_argument("--ipd", type=_real_number(lambda v: 0.0 <= v <= 1.0, "not in [0, 1] metres"),
                        metavar="METRES", help=f"distance between the eyes (default {DEFAULT_IPD})")
    parser.add_argument("--convergence", type=_real_number(lambda v: 1e-3 <= v <= 1e6, "not in [0.001, 1e6] metres"),
                        metavar="METRES", help=f"distance of zero disparity (default {DEFAULT_CONVERGENCE})")
    parser.add_argument("--scene-scale", type=_real_number(lambda v: 1e-9 <= v <= 1e9, "not a positive scale"),
                        metavar="METRES_PER_UNIT", help=f"metres per scene unit (default {DEFAULT_SCENE_SCALE})")
    parser.add_argument("--layout", choices=LAYOUTS,
                        help="sbs: left eye on the left (default); cross: for cross-eyed viewing; "
                             "anaglyph: red/cyan; left or right: one eye")
    parser.add_argument("--lens-preview", action="store_true", default=None,
                        help="apply the barrel distortion and chromatic aberration correction a headset's "
                             "compositor applies, to each eye")
    if window:
        from raygs_viewer.camera.stereo import DEFAULT_HEADSET, PRESETS
        parser.add_argument("--headset", choices=(*PRESETS, "custom"),
                            help=f"per-eye resolution and field of view (default {DEFAULT_HEADSET}: "
                                 + "; ".join(f"{p.name} {p.width}x{p.height} {p.fov_x:g}x{p.fov_y:g} deg"
                                             for p in PRESETS.values())
                                 + "; custom: --headset-size and --headset-fov)")
        parser.add_argument("--headset-size", type=_size, metavar="WxH",
                            help="the custom headset's per-eye resolution (implies --headset custom)")
        parser.add_argument("--headset-fov", type=_fov_pair, metavar="H,V",
                            help="the custom headset's per-eye field of view in degrees (implies --headset custom)")


def _size(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not WIDTHxHEIGHT, e.g. 1832x1920") from None
    return width, height


def _fov_pair(text: str) -> tuple[float, float]:
    try:
        horizontal, vertical = (float(p) for p in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not two angles H,V in degrees, e.g. 100,95") from None
    return horizontal, vertical


def _stereo_view(args):
    """render's StereoView from --stereo and its options; None without --stereo (and
    then the stereo options are an error, not silently ignored)."""
    given = [flag for flag, dest in _STEREO_OPTIONS if getattr(args, dest) is not None]
    if not args.stereo:
        if given:
            raise UserError(f"{', '.join(given)} need{'s' if len(given) == 1 else ''} --stereo")
        return None
    if args.reference:
        raise UserError("--stereo renders with GL (the eyes share one sort and the midpoint's colour); "
                        "drop --reference")
    if args.sidecar is not None:
        raise UserError("--sidecar already says whether the image is stereo; drop --stereo")
    from raygs_viewer.camera.lens_model import DEFAULT_LENS
    from raygs_viewer.camera.stereo import StereoView
    return StereoView(_stereo_rig(args), args.layout or "sbs", DEFAULT_LENS if args.lens_preview else None)


def _stereo_rig(args):
    from raygs_viewer.camera.stereo import StereoRig
    return StereoRig(**{dest: getattr(args, dest) for dest in ("ipd", "convergence", "scene_scale")
                        if getattr(args, dest) is not None})


def _viewer_stereo_options(args):
    """The stereo preview's start value (app.StereoPreview; the panel's, for switching
    it on later too)."""
    from raygs_viewer.viewer import app  # the window's imports (glfw, imgui) only when it opens
    rig = _stereo_rig(args)  # checks the values before the window opens
    return app.StereoPreview.of(_headset(args), on=args.stereo, rig=rig, layout=args.layout or "sbs",
                                lens_preview=bool(args.lens_preview), save_eyes=args.save_eyes)


def _headset(args):
    """view's headset preset: --headset, or custom when --headset-size/--headset-fov are given."""
    from raygs_viewer.camera.stereo import DEFAULT_HEADSET, PRESETS, custom_preset
    custom = args.headset_size is not None or args.headset_fov is not None
    if args.headset not in (None, "custom") and custom:
        raise UserError(f"--headset-size and --headset-fov describe a custom headset; drop --headset {args.headset}")
    if custom or args.headset == "custom":
        if args.headset_size is None or args.headset_fov is None:
            raise UserError("a custom headset needs both --headset-size WxH and --headset-fov H,V")
        return custom_preset(*args.headset_size, *args.headset_fov)
    return PRESETS[args.headset or DEFAULT_HEADSET]


def _add_view_options(parser: argparse.ArgumentParser) -> None:
    """render's and verify's view. Defaults are None so that render can tell which were
    given (--sidecar rejects them); :func:`_settings` and :func:`choose_camera` apply
    the documented defaults."""
    parser.add_argument("scene", nargs="?", help=f"a .ply or .splat file, or '{DEMO}' (default)")
    parser.add_argument("--camera", metavar="CAMERAS.json", help="INRIA cameras.json (a list or one camera)")
    parser.add_argument("--camera-index", type=int, metavar="I", help="which camera of the file (default 0)")
    parser.add_argument("--width", type=_positive_int, help="image width; fx and cx scale to match")
    parser.add_argument("--height", type=_positive_int, help="image height; fy and cy scale to match")
    _add_settings_options(parser, None, None)


def _add_settings_options(parser: argparse.ArgumentParser, p_min, background) -> None:
    parser.add_argument("--p-min", type=_p_min, default=p_min, metavar="P",
                        help="opacity cut-off, sets kappa = -2 ln(P/o) (default 1/255)")
    parser.add_argument("--background", type=_color, default=background, metavar="R,G,B",
                        help="background colour, 0..1 each (default 0,0,0)")
    parser.add_argument("--sh-degree", type=_sh_degree, metavar="D",
                        help="highest spherical-harmonics band to evaluate, 0..3, capped at the scene's "
                             "(default: all the scene has)")
    # The accuracy options default to None so that render can tell which were given
    # (--sidecar rejects them) and --mip can be implied; see _accuracy_settings.
    from raygs_viewer.render.settings import RENDER_MODES
    parser.add_argument("--mode", choices=RENDER_MODES,
                        help="raygs: RayGS (default); raygs-exact-mip: RayGS with the exact, per-pixel MIP "
                             "filter; gs: EWA splatting as INRIA 3DGS renders (0.3 px^2 dilation)")
    parser.add_argument("--mip", action=argparse.BooleanOptionalAction, default=None,
                        help="RayGS mode: the pixel-invariant MIP filter (Eq. 17) (default off)")
    parser.add_argument("--mip-sigma2", type=_mip_sigma2, metavar="S",
                        help="the MIP filter's variance in px^2 of the rendered image (default 0.1); "
                             "implies --mip unless --no-mip is given")
    parser.add_argument("--mip-modulation", action=argparse.BooleanOptionalAction, default=None,
                        help="scale opacity so a filtered gaussian keeps its total opacity (default on); "
                             "either form implies --mip unless --no-mip is given")
    parser.add_argument("--gs-compensation", action="store_true", default=None,
                        help="gs mode: scale opacity by sqrt(det(S) / det(S + dilation)), as Mip-Splatting does")
    parser.add_argument("--supersample", type=_supersample, metavar="K",
                        help="render K x K samples per pixel and average them, K = 1..4 (default 1)")
    parser.add_argument("--alpha-clamp", action="store_true", default=None,
                        help="clamp every splat's alpha to 0.99, as INRIA and GOF do")
    parser.add_argument("--transmittance-cutoff", action="store_true", default=None,
                        help="stop compositing a pixel before its transmittance falls below 1e-4, "
                             "as INRIA and GOF do")


def _add_viewer_options(parser: argparse.ArgumentParser) -> None:
    """The fields of app.ViewerOptions."""
    from raygs_viewer.render.settings import DEFAULT_P_MIN
    parser.add_argument("scene", nargs="?", default=DEMO, help=f"a .ply or .splat file, or '{DEMO}' (default)")
    parser.add_argument("--cameras", metavar="CAMERAS.json",
                        help="the scene's training cameras (default: a cameras.json found next to the scene)")
    parser.add_argument("--camera", metavar="CAMERAS.json", help="start at a camera of this INRIA cameras.json")
    parser.add_argument("--camera-index", type=int, default=0, metavar="I",
                        help="which camera of --camera to start at (default 0)")
    parser.add_argument("--width", type=_positive_int, default=1280, help="window width (default 1280)")
    parser.add_argument("--height", type=_positive_int, default=720, help="window height (default 720)")
    _add_settings_options(parser, DEFAULT_P_MIN, DEFAULT_BACKGROUND)
    parser.add_argument("--frames", type=_frames, metavar="N", help="quit after drawing N frames")
    parser.add_argument("--screenshot", metavar="PATH.png",
                        help="save the last frame there, with a .json sidecar beside it (never replaces a file)")
    parser.add_argument("--screenshot-dir", default="screenshots", metavar="DIR",
                        help="where F12 and the panel save screenshots (default ./screenshots)")
    parser.add_argument("--screenshot-scale", type=_screenshot_scale, default=1.0, metavar="K",
                        help="screenshots render offscreen at K times the window size, 0 < K <= 8 (default 1)")
    parser.add_argument("--no-vsync", action="store_true", help="draw as fast as possible")
    parser.add_argument("--orbit", action="store_true", help="start in orbit navigation instead of fly")
    parser.add_argument("--window-screenshot", metavar="PATH.png",
                        help="with --frames: save the whole window, panel included, after the last frame")
    parser.add_argument("--turntable", type=_turntable, default=0.0, metavar="DEG",
                        help="orbit about the up axis by DEG degrees every frame (a reproducible "
                             "fly-around, e.g. to measure the frame rate with --frames)")
    parser.add_argument("--up-axis", choices=UP_AXES, default="-y",
                        help="world up, for navigation (default -y, the OpenCV/COLMAP convention)")
    parser.add_argument("--window-platform", choices=("auto", "x11", "wayland", "null"), default="auto",
                        help="GLFW platform (default auto: null without a display)")
    _add_stereo_options(parser, window=True)
    _add_general_option(parser)
    parser.add_argument("--save-eyes", action="store_true",
                        help="stereo screenshots also save each eye on its own (-left, -right), besides the pair")


def _add_general_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--general", action="store_true",
                        help="draw with the one all-features shader variant (features switched by uniforms) "
                             "instead of the variant specialised to the scene and settings; the same image, "
                             "slower: it shows what specialising saves")


def _add_backend_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--gl-backend", choices=("auto", "egl", "osmesa"),
                        help="headless OpenGL (default: $RAYGS_GL_BACKEND or auto: EGL, else OSMesa)")


def load_scene_argument(name: str):
    if name == DEMO:
        from raygs_viewer.scene.demo import demo_scene
        return demo_scene()
    from raygs_viewer.scene.io import load_scene
    return load_scene(name)


def _warn_dropped(scene) -> None:
    from raygs_viewer.scene.io import dropped_summary
    for line in dropped_summary(scene):
        print(f"warning: {line}", file=sys.stderr)


def _command_info(args) -> int:
    from raygs_viewer.scene.io import describe, format_description
    scene = load_scene_argument(args.scene)
    _warn_dropped(scene)
    description = describe(scene)
    print(json.dumps(description, indent=2) if args.json else format_description(description))
    return 0


def _accuracy_settings(args) -> dict:
    """The RenderSettings fields beyond p_min, background and sh_degree from the options
    (defaults for those not given). --mip-sigma2 and --[no-]mip-modulation imply --mip
    unless --no-mip was given."""
    from raygs_viewer.render.settings import RenderSettings
    defaults = RenderSettings()
    mip = args.mip
    if mip is None:
        mip = True if (args.mip_sigma2 is not None or args.mip_modulation is not None) else defaults.mip
    values = {"mip": mip}
    for name in ("mode", "mip_sigma2", "mip_modulation", "gs_compensation", "supersample", "alpha_clamp",
                 "transmittance_cutoff"):
        value = getattr(args, name)
        values[name] = getattr(defaults, name) if value is None else value
    return values


def _settings(args):
    """RenderSettings from the settings options, defaults for those not given."""
    from raygs_viewer.render.settings import DEFAULT_P_MIN, RenderSettings
    return RenderSettings(p_min=DEFAULT_P_MIN if args.p_min is None else args.p_min,
                          background=DEFAULT_BACKGROUND if args.background is None else args.background,
                          sh_degree=args.sh_degree, **_accuracy_settings(args))


def choose_camera(scene, scene_name: str, camera_file: str | None, index: int | None, width: int | None,
                  height: int | None):
    """The camera of ``--camera``/``--camera-index``, else the demo's or one framing the
    scene; resized when --width/--height are given (one alone keeps the aspect ratio)."""
    from raygs_viewer.camera.pinhole import frame_points, load_camera
    if camera_file is not None:
        camera = load_camera(camera_file, index or 0)
    elif scene_name == DEMO:
        from raygs_viewer.scene.demo import demo_camera
        camera = demo_camera()
    else:
        camera = frame_points(scene.positions)
    if width or height:
        width = width or max(1, round(height * camera.width / camera.height))
        height = height or max(1, round(width * camera.height / camera.width))
        camera = camera.resized(width, height)
    return camera


def _command_render(args) -> int:
    from raygs_viewer.capture.image_io import check_output_path, save_image

    if args.sidecar is not None:
        given = [flag for flag, dest in SIDECAR_CONFLICTS if getattr(args, dest) is not None]
        if given:
            raise UserError(f"--sidecar already sets the view; drop {', '.join(given)}")
    stereo = _stereo_view(args)
    out = check_output_path(args.out, args.overwrite)  # fail before any slow work
    if args.sidecar is not None:
        from raygs_viewer.capture.sidecar import (
            load_sidecar,
            resolve_scene,
            verify_scene_hash,
        )
        shot = load_sidecar(args.sidecar)
        scene_name = resolve_scene(shot, args.scene)
        verify_scene_hash(shot, scene_name)
        camera, settings, stereo = shot.camera, shot.settings, shot.stereo
        scene = load_scene_argument(scene_name)
        _warn_dropped(scene)
    else:
        settings = _settings(args)
        scene_name = args.scene or DEMO
        scene = load_scene_argument(scene_name)
        _warn_dropped(scene)
        camera = choose_camera(scene, scene_name, args.camera, args.camera_index, args.width, args.height)
    start = time.perf_counter()
    if args.reference:
        from raygs_viewer.render.reference import render_reference
        image = render_reference(scene, camera, settings)
    else:
        from raygs_viewer.capture.screenshot import render_tiled
        from raygs_viewer.render.gl.context import create_headless_context
        from raygs_viewer.render.gl.renderer import GLRenderer
        ctx = create_headless_context(args.gl_backend)
        try:
            renderer = GLRenderer(ctx, scene, general=args.general)
            if stereo is not None:
                from raygs_viewer.render.gl.stereo_frame import render_stereo_view
                image = render_stereo_view(renderer, camera, settings, stereo)[0]
            else:
                # Tiled like the window's screenshots: the same pixels, and sizes beyond
                # the GPU's largest render target.
                image = render_tiled(renderer, camera, settings)
            renderer.release()
        finally:
            ctx.release()
    elapsed = time.perf_counter() - start
    save_image(out, image, args.overwrite)
    print(f"{out}: {image.shape[1]}x{image.shape[0]}, {scene.count} gaussians, "
          f"{'reference' if args.reference else 'GL'} render {elapsed * 1000:.0f} ms"
          + (f", view from {args.sidecar}" if args.sidecar is not None else ""))
    return 0


def _command_verify(args) -> int:
    import numpy as np

    from raygs_viewer.render.gl.context import (
        context_description,
        create_headless_context,
    )
    from raygs_viewer.render.gl.renderer import GLRenderer
    from raygs_viewer.render.reference import render_reference

    settings = _settings(args)
    scene_name = args.scene or DEMO
    scene = load_scene_argument(scene_name)
    _warn_dropped(scene)
    camera = choose_camera(scene, scene_name, args.camera, args.camera_index, args.width, args.height)
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
    print(f"settings    {_describe_accuracy(settings)}")
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


def _describe_accuracy(settings) -> str:
    """One line of the accuracy options, for verify's report."""
    parts = [f"mode {settings.mode}"]
    if settings.mode == "raygs":
        parts.append(f"MIP {'on' if settings.mip else 'off'}")
    if settings.mip_active:
        parts.append(f"sigma^2 {settings.mip_sigma2:g} px^2, modulation {'on' if settings.mip_modulation else 'off'}")
    if settings.mode == "gs":
        parts.append(f"compensation {'on' if settings.gs_compensation else 'off'}")
    parts.append(f"supersample {settings.supersample}x{settings.supersample}")
    parts.append(f"alpha clamp {'on' if settings.alpha_clamp else 'off'}")
    parts.append(f"transmittance cut-off {'on' if settings.transmittance_cutoff else 'off'}")
    return ", ".join(parts)


def _command_view(args) -> int:
    # Each command imports what it needs when it runs: --help and the other commands start fast.
    from raygs_viewer.capture.screenshot import check_screenshot_path
    from raygs_viewer.viewer import app  # the window's imports (glfw, imgui) only when it opens

    if args.screenshot is not None:
        check_screenshot_path(args.screenshot)  # before the window opens and the scene loads
    options = app.ViewerOptions(
        scene=args.scene, cameras=args.cameras, camera=args.camera, camera_index=args.camera_index,
        width=args.width, height=args.height, settings=_settings(args), frames=args.frames,
        screenshot=args.screenshot, window_screenshot=args.window_screenshot,
        screenshots=app.ScreenshotOptions(folder=args.screenshot_dir, scale=args.screenshot_scale),
        vsync=not args.no_vsync, platform=args.window_platform, general=args.general,
        navigation=app.NavigationChoices(mode="orbit" if args.orbit else "fly", up_axis=args.up_axis,
                                         turntable=args.turntable),
        stereo=_viewer_stereo_options(args))
    return app.run_viewer(options)


def route(argv: list[str]) -> list[str]:
    """The argument list with the implied ``view`` made explicit: no arguments, a scene
    as the first argument, or an option other than -h/--help/--version first."""
    if not argv:
        return ["view"]
    first = argv[0]
    if first in COMMANDS or first in TOP_LEVEL_OPTIONS:
        return argv
    if first.startswith("-") or first == DEMO or os.path.exists(first) \
            or Path(first).suffix.lower() in SCENE_SUFFIXES:
        return ["view", *argv]
    raise UserError(f"'{first}' is neither a command ({', '.join(COMMANDS)}) nor a scene file "
                    f"(see 'raygs-viewer --help')")


def join_up_axis(argv: list[str]) -> list[str]:
    """``--up-axis -y`` -> ``--up-axis=-y``: argparse takes a value starting with '-' for
    an option and would report the axis missing."""
    joined, i = [], 0
    while i < len(argv):
        if argv[i] == "--":
            joined.extend(argv[i:])
            break
        if argv[i] == "--up-axis" and i + 1 < len(argv) and argv[i + 1] in UP_AXES:
            joined.append(f"--up-axis={argv[i + 1]}")
            i += 2
        else:
            joined.append(argv[i])
            i += 1
    return joined


def main(argv: list[str] | None = None) -> int:
    try:
        argv = join_up_axis(route(list(sys.argv[1:] if argv is None else argv)))
        args = build_parser().parse_args(argv)
        from raygs_viewer.bench import accuracy as bench
        commands = {"view": _command_view, "info": _command_info, "render": _command_render,
                    "verify": _command_verify, "bench": bench.command}
        return commands[args.command](args)
    except UserError as exc:
        print(f"error: {str(exc).splitlines()[0] if str(exc) else 'failed'}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
