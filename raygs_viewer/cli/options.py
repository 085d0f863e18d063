"""The option groups that ``view``, ``render`` and ``verify`` share, and what they build:
the render settings (:class:`RenderSettings`) and the stereo rig and view.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

from raygs_viewer.camera.lens_model import DEFAULT_LENS
from raygs_viewer.camera.stereo import (
    DEFAULT_HEADSET,
    LAYOUTS,
    PRESETS,
    StereoRig,
    StereoView,
    rig_quantities,
)
from raygs_viewer.cli import argtypes
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ALPHA_THRESHOLD
from raygs_viewer.render.channels import CHANNELS, DEFAULT_CHANNELS, NORMAL_SPACES
from raygs_viewer.render.setting_info import SettingField, settings_table
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.io import SCENE_FILES
from raygs_viewer.scene.source import DEMO


def option_flag(name: str) -> str:
    """The command line's option of a settings or rig field: p_min is --p-min."""
    return "--" + name.replace("_", "-")


#: render's stereo options besides --stereo: (flag, argparse dest).
STEREO_OPTIONS = (*((option_flag(name), name) for name in rig_quantities()),
                  ("--layout", "layout"), ("--lens-preview", "lens_preview"))


# --- the view and its settings ---------------------------------------------------------------------

def add_view_options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """render's and verify's view; the options it adds besides SCENE. Defaults are None
    so that render can tell which were given (--sidecar rejects them);
    :func:`render_settings` and ``commands.choose_camera`` apply the documented defaults."""
    parser.add_argument("scene", nargs="?", help=f"a scene file ({SCENE_FILES}), or '{DEMO}' (default)")
    return [parser.add_argument("--camera", metavar="CAMERAS.json",
                                help="INRIA cameras.json (a list or one camera), or a screenshot's sidecar: its "
                                     "camera, rendered with the settings and size given here"),
            parser.add_argument("--camera-index", type=argtypes.camera_index, metavar="I", help="which camera of the file (default 0)"),
            parser.add_argument("--width", type=argtypes.positive_int, help="image width; fx and cx scale to match"),
            parser.add_argument("--height", type=argtypes.positive_int, help="image height; fy and cy scale to match"),
            *add_settings_options(parser, None, None)]


def add_settings_options(parser: argparse.ArgumentParser, p_min, background,
                         settings_type: type[RenderSettings] = RenderSettings) -> list[argparse.Action]:
    """One option per field of ``settings_type``, made from its Setting
    (render.setting_info), with these defaults for --p-min and --background; the
    options it adds. The others default to None so that render can tell which were
    given (--sidecar rejects them) and one can imply another (:func:`given_settings`)."""
    defaults = {"p_min": p_min, "background": background}
    implied = {row.info.implies[0] for row in settings_table(settings_type) if row.info.implies}
    start = settings_type()
    return [_add_setting_option(parser, row, defaults.get(row.name), getattr(start, row.name) is True
                                or row.name in implied)
            for row in settings_table(settings_type)]


def _add_setting_option(parser: argparse.ArgumentParser, row: SettingField, default, negatable: bool
                        ) -> argparse.Action:
    """``negatable``: a switch that can be on without being given (on by default, or
    implied by another option) also has --no-NAME."""
    flag, info = option_flag(row.name), row.info
    if row.hint is bool:
        action = argparse.BooleanOptionalAction if negatable else "store_true"
        return parser.add_argument(flag, action=action, default=None, help=info.help)
    if info.choices and all(isinstance(choice, str) for choice in info.choices):
        return parser.add_argument(flag, choices=info.choices, default=default, help=info.help)
    return parser.add_argument(flag, type=argtypes.setting_type(row), default=default, metavar=info.metavar,
                               help=info.help)


def given_settings(args, settings_type: type[RenderSettings] = RenderSettings) -> dict:
    """The settings options that were given, and what they imply where the implied
    option was not given itself: --mip-sigma2 and --[no-]mip-modulation imply --mip,
    --order-k implies --order per-pixel (each Setting's ``implies``)."""
    table = settings_table(settings_type)
    given = {row.name: getattr(args, row.name) for row in table if getattr(args, row.name) is not None}
    for row in table:
        if row.info.implies and row.name in given and getattr(args, row.info.implies[0]) is None:
            name, value = row.info.implies
            given[name] = value
    return given


def render_settings(args, settings_type: type[RenderSettings] = RenderSettings) -> RenderSettings:
    """The settings of the settings options, defaults for those not given."""
    return settings_type(**given_settings(args, settings_type))


def settings_with_options(base: RenderSettings, args) -> RenderSettings:
    """``base`` (e.g. what a path file recorded) with the settings options that were
    given put over it, with the same implications as :func:`render_settings`."""
    return replace(base, **given_settings(args, type(base)))


# --- channels (docs/geometry.md) ------------------------------------------------------------------

def add_channel_options(parser: argparse.ArgumentParser, picture: bool = True) -> None:
    """--channels and --normal-space; ``picture``: render's --depth-range and
    --alpha-threshold too (a PNG of a depth or normal channel). Defaults are None so
    that a sidecar's recorded picture can fill them."""
    listed = f"separated by commas, from {', '.join(CHANNELS)}"
    if picture:
        what = (f"what to write, {listed} (default {','.join(DEFAULT_CHANNELS)}): .npy gets float32 HxWxC in the "
                "order listed (rgb and normal 3 each), .exr named channels (R,G,B A Z Z.median N.X,N.Y,N.Z), .png a "
                "picture of one channel")
    else:
        what = f"write each frame as an EXR of these channels, {listed}, named like the PNG frames (OUT: a folder)"
    parser.add_argument("--channels", type=argtypes.channel_list, metavar="LIST", help=what)
    parser.add_argument("--normal-space", choices=NORMAL_SPACES,
                        help="the normal channel's axes: the camera's (OpenCV: x right, y down, z forward; "
                             "default) or the scene's")
    if picture:
        parser.add_argument("--depth-range", type=argtypes.depth_range, metavar="NEAR,FAR",
                            help="a .png of depth or median_depth: the depths the colour map spans, near bright, "
                                 "far dark (default: automatic, the 1st to 99th percentile; printed)")
        parser.add_argument("--alpha-threshold", type=argtypes.real_number(lambda v: 0.0 <= v <= 1.0,
                                                                           "not an alpha from 0 to 1"),
                            metavar="A",
                            help="a .png of depth, median_depth or normal: pixels whose alpha is below A are "
                                 f"black, as undefined, so faint haze does not paint (default {ALPHA_THRESHOLD:g}; "
                                 "0: off). .npy and .exr keep every value")


def check_normal_space(channels, normal_space: str | None) -> str:
    """The normals' space (default camera); UserError for --normal-space without normals."""
    if normal_space is not None and "normal" not in channels:
        raise UserError("--normal-space is for the normal channel; add normal to --channels")
    return normal_space or "camera"


# --- stereo -------------------------------------------------------------------------------------------

def add_stereo_options(parser: argparse.ArgumentParser, window: bool = False) -> None:
    """render's stereo options; ``window``: view's, which add the headset preset (the
    eyes' size and field of view) and start the panel's stereo controls even without
    --stereo."""
    if window:
        parser.add_argument("--stereo", action="store_true",
                            help="open the stereo preview (the panel's Stereo section also switches it); the "
                                 "stereo options below set its start values either way")
    else:
        parser.add_argument("--stereo", action="store_true",
                            help="render the two eyes around the camera (which is their midpoint), each at the "
                                 "camera's size; the image is both eyes side by side unless --layout says "
                                 "otherwise")
    start = StereoRig()
    for name, quantity in rig_quantities().items():  # the rig's fields, and their limits, are the rig's
        parser.add_argument(option_flag(name), type=argtypes.real_in(quantity.low, quantity.high, quantity.unit),
                            metavar=quantity.metavar, help=f"{quantity.meaning} (default {getattr(start, name)})")
    parser.add_argument("--layout", choices=LAYOUTS,
                        help="sbs: left eye on the left (default); cross: for cross-eyed viewing; "
                             "anaglyph: red/cyan; left or right: one eye")
    parser.add_argument("--lens-preview", action="store_true", default=None,
                        help="apply the barrel distortion and chromatic aberration correction a headset's "
                             "compositor applies, to each eye")
    if window:
        parser.add_argument("--headset", choices=(*PRESETS, "custom"),
                            help=f"per-eye resolution and field of view (default {DEFAULT_HEADSET}: "
                                 + "; ".join(f"{p.name} {p.width}x{p.height} {p.fov_x:g}x{p.fov_y:g} deg"
                                             for p in PRESETS.values())
                                 + "; custom: --headset-size and --headset-fov)")
        parser.add_argument("--headset-size", type=argtypes.size, metavar="WxH",
                            help="the custom headset's per-eye resolution (implies --headset custom)")
        parser.add_argument("--headset-fov", type=argtypes.fov_pair, metavar="H,V",
                            help="the custom headset's per-eye field of view in degrees (implies --headset custom)")


def stereo_rig(args) -> StereoRig:
    """The rig of --ipd, --convergence and --scene-scale (defaults for those not given)."""
    given = {name: getattr(args, name) for name in rig_quantities()}  # --ipd is dest "ipd", and so on
    return StereoRig(**{name: value for name, value in given.items() if value is not None})


def stereo_view(args) -> StereoView | None:
    """render's StereoView from --stereo and its options; None without --stereo (and
    then the stereo options are an error, not silently ignored)."""
    given = [flag for flag, dest in STEREO_OPTIONS if getattr(args, dest) is not None]
    if not args.stereo:
        if given:
            raise UserError(f"{', '.join(given)} need{'s' if len(given) == 1 else ''} --stereo")
        return None
    if args.reference:
        raise UserError("--stereo renders with GL (the eyes share one sort and the midpoint's colour); "
                        "drop --reference")
    if args.sidecar is not None:
        raise UserError("--sidecar already says whether the image is stereo; drop --stereo")
    return StereoView(stereo_rig(args), args.layout or "sbs", DEFAULT_LENS if args.lens_preview else None)
