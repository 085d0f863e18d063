"""``raygs-viewer view``: the interactive window, the default command.

Parsing its options imports no window code: glfw and imgui load only when the window
opens.
"""

from __future__ import annotations

from raygs_viewer.camera.navigation import UP_AXES as NAVIGATION_UP_AXES
from raygs_viewer.camera.stereo import (
    DEFAULT_HEADSET,
    PRESETS,
    custom_preset,
)
from raygs_viewer.capture.progress import TerminalProgress
from raygs_viewer.capture.screenshot import check_screenshot_path
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.options import (
    add_settings_options,
    add_stereo_options,
    render_settings,
    stereo_rig,
)
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import DEFAULT_BACKGROUND, DEFAULT_P_MIN
from raygs_viewer.scene.io import SCENE_FILES
from raygs_viewer.scene.source import DEMO
from raygs_viewer.viewer.state import (
    MIRRORS,
    TURNS,
    HeadsetChoices,
    NavigationChoices,
    ScreenshotOptions,
    StereoPreview,
    ViewerOptions,
)

#: --up-axis's choices, in the navigation's order.
UP_AXES = tuple(NAVIGATION_UP_AXES)


def add_parsers(commands) -> None:
    """Adds ``view`` to the CLI's subparsers: the fields of viewer.state.ViewerOptions."""
    parser = commands.add_parser("view", help="open the interactive window (the default command)")
    parser.set_defaults(run=command_view)
    parser.add_argument("scene", nargs="?", default=DEMO, help=f"a scene file ({SCENE_FILES}), or '{DEMO}' (default)")
    argtypes.add_source_options(parser, what="the axes a .spz scene that declares none is read in (the panel "
                                              "switches them)")
    parser.add_argument("--cameras", metavar="CAMERAS.json",
                        help="the scene's training cameras (default: a cameras.json found next to the scene)")
    parser.add_argument("--images", metavar="DIR",
                        help="the training photos, for the Photo view at a training camera (default: the "
                             "images folder the model folder's cfg_args names)")
    parser.add_argument("--camera", metavar="CAMERAS.json|SHOT.json",
                        help="start at a camera of this INRIA cameras.json, or at a screenshot's view (its sidecar)")
    parser.add_argument("--camera-index", type=argtypes.camera_index, default=0, metavar="I",
                        help="which camera of --camera to start at (default 0)")
    parser.add_argument("--width", type=argtypes.positive_int, default=1280, help="window width (default 1280)")
    parser.add_argument("--height", type=argtypes.positive_int, default=720, help="window height (default 720)")
    measured_precision(add_settings_options(parser, DEFAULT_P_MIN, DEFAULT_BACKGROUND))
    parser.add_argument("--frames", type=argtypes.frames, metavar="N", help="quit after drawing N frames")
    parser.add_argument("--screenshot", metavar="PATH.png",
                        help="save the last frame there, with a .json sidecar beside it (never replaces a file)")
    parser.add_argument("--screenshot-dir", default="screenshots", metavar="DIR",
                        help="where F12 and the panel save screenshots (default ./screenshots)")
    parser.add_argument("--screenshot-scale", type=argtypes.screenshot_scale, default=1.0, metavar="K",
                        help="screenshots render offscreen at K times the window size, 0 < K <= 8 (default 1)")
    parser.add_argument("--no-vsync", action="store_true", help="draw as fast as possible")
    parser.add_argument("--orbit", action="store_true", help="start in orbit navigation instead of fly")
    parser.add_argument("--window-screenshot", metavar="PATH.png",
                        help="with --frames: save the whole window, panel included, after the last frame")
    parser.add_argument("--turntable", type=argtypes.turntable, default=0.0, metavar="DEG",
                        help="orbit about the up axis by DEG degrees every frame (a reproducible "
                             "fly-around, e.g. to measure the frame rate with --frames)")
    # No default here: an axis given is told apart from none, which the window takes from the cameras.
    parser.add_argument("--up-axis", choices=UP_AXES,
                        help="world up, for navigation (default: the training cameras' mean up, snapped to "
                             "an axis; without cameras -y, the OpenCV/COLMAP convention)")
    parser.add_argument("--window-platform", choices=("auto", "x11", "wayland", "null"), default="auto",
                        help="GLFW platform (default auto: null without a display)")
    add_stereo_options(parser, window=True)
    argtypes.add_general_option(parser)
    argtypes.add_sort_option(parser, default="auto")
    parser.add_argument("--save-eyes", action="store_true",
                        help="stereo screenshots also save each eye on its own (-left, -right), besides the pair")
    headset = parser.add_argument_group("headset (OpenXR: docs/xr.md; needs pip install 'raygs-viewer[xr]')")
    headset.add_argument("--xr", action="store_true",
                         help="open a session in the active OpenXR runtime's headset at the start (the panel's "
                              "Enter headset); with --frames N: N headset frames, then one line about them")
    headset.add_argument("--xr-scale", type=argtypes.real_in(0.1, 2.0, "times the runtime's recommended size"),
                         default=1.0, metavar="K",
                         help="each eye's size as K times the runtime's recommended size, 0.1..2 (default 1)")
    headset.add_argument("--xr-depth", action="store_true",
                         help="also submit each eye's median depth (XR_KHR_composition_layer_depth) for the runtime's "
                              "positional reprojection; it costs several colour frames (docs/xr.md)")
    headset.add_argument("--xr-mirror", choices=MIRRORS, default="both",
                         help="what the window shows of the headset's eyes (default both)")
    headset.add_argument("--xr-turn", choices=TURNS, default="snap",
                         help="the right stick turns in steps of 30 degrees (snap, default) or smoothly")
    parser.add_argument("--eyes-at-headset-size", action="store_true",
                        help="the stereo preview draws each eye at the headset's per-eye resolution, shrunk to fit "
                             "(default: at the size the window shows them, faster); screenshots and videos are at "
                             "the headset's size either way")


def measured_precision(actions) -> None:
    """The window's --precision also takes auto, its default: the narrowest blend this GL
    measured faster by 10 % within the accuracy study's error (``render.gl.profile``).
    Screenshots' sidecars record the blend used, so they re-render to the bit."""
    action = next(a for a in actions if a.dest == "precision")
    action.choices, action.default = (*action.choices, "auto"), "auto"
    action.help = ("auto (default): the narrowest blend this GL measured at least 10 %% faster than float32 within "
                   "the accuracy study's error (float16 1e-2, 8bit 4e-2 per channel), else float32; " + action.help)


#: ``--up-axis -y``: a value that starts with '-' (``argtypes.join_dash_values``).
DASH_VALUES = {"--up-axis": UP_AXES.__contains__}


def _viewer_stereo_options(args) -> StereoPreview:
    """The stereo preview's start value (the panel's, for switching it on later too)."""
    rig = stereo_rig(args)  # checks the values before the window opens
    return StereoPreview.of(_headset(args), on=args.stereo, rig=rig, layout=args.layout or "sbs",
                            lens_preview=bool(args.lens_preview), save_eyes=args.save_eyes,
                            headset_size=args.eyes_at_headset_size)


def _headset(args):
    """view's headset preset: --headset, or custom when --headset-size/--headset-fov are given."""
    custom = args.headset_size is not None or args.headset_fov is not None
    if args.headset not in (None, "custom") and custom:
        raise UserError(f"--headset-size and --headset-fov describe a custom headset; drop --headset {args.headset}")
    if custom or args.headset == "custom":
        if args.headset_size is None or args.headset_fov is None:
            raise UserError("a custom headset needs both --headset-size WxH and --headset-fov H,V")
        return custom_preset(*args.headset_size, *args.headset_fov)
    return PRESETS[args.headset or DEFAULT_HEADSET]


def command_view(args) -> int:
    # The window's imports (glfw, imgui) only when it opens.
    from raygs_viewer.viewer.app import run_viewer

    if args.screenshot is not None:
        check_screenshot_path(args.screenshot)  # before the window opens and the scene loads
    auto_precision = args.precision == "auto"
    if auto_precision:
        args.precision = None  # the settings' own default until this GL's profile says otherwise
    options = ViewerOptions(
        source=argtypes.scene_source(args, args.scene, cameras=args.cameras), camera=args.camera,
        camera_index=args.camera_index,
        width=args.width, height=args.height, settings=render_settings(args), frames=args.frames,
        screenshot=args.screenshot, window_screenshot=args.window_screenshot,
        screenshots=ScreenshotOptions(folder=args.screenshot_dir, scale=args.screenshot_scale),
        vsync=not args.no_vsync, platform=args.window_platform, general=args.general,
        navigation=NavigationChoices(mode="orbit" if args.orbit else "fly", up_axis=args.up_axis,
                                     turntable=args.turntable),
        stereo=_viewer_stereo_options(args), images=args.images, sort=args.sort,
        auto_precision=auto_precision,
        headset=HeadsetChoices(enter=args.xr, scale=args.xr_scale, depth=args.xr_depth,
                               mirror=args.xr_mirror, turn=args.xr_turn))
    with TerminalProgress(options.source.path) as progress:  # a multi-GB scene takes seconds before the window
        return run_viewer(options, progress)
