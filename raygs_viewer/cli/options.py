"""The option groups that ``view``, ``render`` and ``verify`` share, and what they build:
the render settings (:class:`RenderSettings`) and the stereo rig and view.
"""

from __future__ import annotations

import argparse
from dataclasses import fields, replace

from raygs_viewer.camera.lens_model import DEFAULT_LENS
from raygs_viewer.camera.stereo import (
    DEFAULT_CONVERGENCE,
    DEFAULT_HEADSET,
    DEFAULT_IPD,
    DEFAULT_SCENE_SCALE,
    LAYOUTS,
    PRESETS,
    StereoRig,
    StereoView,
)
from raygs_viewer.cli import argtypes
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import (
    ACCURACY_FIELDS,
    DEFAULT_P_MIN,
    ORDERS,
    RENDER_MODES,
    RenderSettings,
)
from raygs_viewer.scene.io import SCENE_FILES
from raygs_viewer.scene.loader import DEMO

DEFAULT_BACKGROUND = (0.0, 0.0, 0.0)
#: render's stereo options besides --stereo: (flag, argparse dest).
STEREO_OPTIONS = (("--ipd", "ipd"), ("--convergence", "convergence"), ("--scene-scale", "scene_scale"),
                  ("--layout", "layout"), ("--lens-preview", "lens_preview"))


# --- the view and its settings ---------------------------------------------------------------------

def add_view_options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """render's and verify's view; the options it adds besides SCENE. Defaults are None
    so that render can tell which were given (--sidecar rejects them);
    :func:`render_settings` and ``commands.choose_camera`` apply the documented defaults."""
    parser.add_argument("scene", nargs="?", help=f"a scene file ({SCENE_FILES}), or '{DEMO}' (default)")
    return [parser.add_argument("--camera", metavar="CAMERAS.json", help="INRIA cameras.json (a list or one camera)"),
            parser.add_argument("--camera-index", type=int, metavar="I", help="which camera of the file (default 0)"),
            parser.add_argument("--width", type=argtypes.positive_int, help="image width; fx and cx scale to match"),
            parser.add_argument("--height", type=argtypes.positive_int, help="image height; fy and cy scale to match"),
            *add_settings_options(parser, None, None)]


def add_settings_options(parser: argparse.ArgumentParser, p_min, background) -> list[argparse.Action]:
    """The RenderSettings options, with these defaults for --p-min and --background; the
    options it adds."""
    added = [
        parser.add_argument("--p-min", type=argtypes.p_min, default=p_min, metavar="P",
                            help="opacity cut-off, sets kappa = -2 ln(P/o) (default 1/255)"),
        parser.add_argument("--background", type=argtypes.color, default=background, metavar="R,G,B",
                            help="background colour, 0..1 each (default 0,0,0)"),
        parser.add_argument("--sh-degree", type=argtypes.sh_degree, metavar="D",
                            help="highest spherical-harmonics band to evaluate, 0..3, capped at the scene's "
                                 "(default: all the scene has)"),
    ]
    # The accuracy options default to None so that render can tell which were given
    # (--sidecar rejects them) and --mip can be implied; see accuracy_settings.
    return added + [
        parser.add_argument("--mode", choices=RENDER_MODES,
                            help="raygs: RayGS (default); raygs-exact-mip: RayGS with the exact, per-pixel MIP "
                                 "filter; gs: EWA splatting as INRIA 3DGS renders (0.3 px^2 dilation)"),
        parser.add_argument("--mip", action=argparse.BooleanOptionalAction, default=None,
                            help="RayGS mode: the pixel-invariant MIP filter (Eq. 17) (default off)"),
        parser.add_argument("--mip-sigma2", type=argtypes.mip_sigma2, metavar="S",
                            help="the MIP filter's variance in px^2 of the rendered image (default 0.1); "
                                 "implies --mip unless --no-mip is given"),
        parser.add_argument("--mip-modulation", action=argparse.BooleanOptionalAction, default=None,
                            help="scale opacity so a filtered gaussian keeps its total opacity (default on); "
                                 "either form implies --mip unless --no-mip is given"),
        parser.add_argument("--gs-compensation", action="store_true", default=None,
                            help="gs mode: scale opacity by sqrt(det(S) / det(S + dilation)), as Mip-Splatting does"),
        parser.add_argument("--supersample", type=argtypes.supersample, metavar="K",
                            help="render K x K samples per pixel and average them, K = 1..4 (default 1)"),
        parser.add_argument("--alpha-clamp", action="store_true", default=None,
                            help="clamp every splat's alpha to 0.99, as INRIA and GOF do"),
        parser.add_argument("--transmittance-cutoff", action="store_true", default=None,
                            help="stop compositing a pixel before its transmittance falls below 1e-4, "
                                 "as INRIA and GOF do"),
        parser.add_argument("--order", choices=ORDERS,
                            help="how each pixel orders its gaussians: depth (one global sort by the centres' "
                                 "view depth, the default), distance (by their distance from the camera), "
                                 "per-pixel (each pixel sorts its own by where its ray meets them; RayGS modes)"),
        parser.add_argument("--order-k", type=argtypes.order_k, metavar="K",
                            help="per-pixel order: 0 sorts every fragment exactly (default); K re-orders them "
                                 "through a window of K per pixel (a k-buffer), for speed; implies "
                                 "--order per-pixel"),
    ]


def accuracy_settings(args) -> dict:
    """The RenderSettings fields beyond p_min, background and sh_degree from the options
    (defaults for those not given). --mip-sigma2 and --[no-]mip-modulation imply --mip
    unless --no-mip was given; --order-k implies --order per-pixel."""
    defaults = RenderSettings()
    values = {name: getattr(defaults, name) if getattr(args, name) is None else getattr(args, name)
              for name in ACCURACY_FIELDS}
    if args.mip is None and (args.mip_sigma2 is not None or args.mip_modulation is not None):
        values["mip"] = True
    if args.order is None and args.order_k is not None:
        values["order"] = "per-pixel"
    return values


def render_settings(args) -> RenderSettings:
    """RenderSettings from the settings options, defaults for those not given."""
    return RenderSettings(p_min=DEFAULT_P_MIN if args.p_min is None else args.p_min,
                          background=DEFAULT_BACKGROUND if args.background is None else args.background,
                          sh_degree=args.sh_degree, **accuracy_settings(args))


def settings_with_options(base: RenderSettings, args) -> RenderSettings:
    """``base`` (e.g. what a path file recorded) with the settings options that were
    given put over it, with the same implications as :func:`accuracy_settings`."""
    given = {name: getattr(args, name) for name in ("p_min", "background", "sh_degree", *ACCURACY_FIELDS)
             if getattr(args, name) is not None}
    if args.mip is None and (args.mip_sigma2 is not None or args.mip_modulation is not None):
        given["mip"] = True
    if args.order is None and args.order_k is not None:
        given["order"] = "per-pixel"
    return replace(base, **given)


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
    parser.add_argument("--ipd", type=argtypes.real_number(lambda v: 0.0 <= v <= 1.0, "not in [0, 1] metres"),
                        metavar="METRES", help=f"distance between the eyes (default {DEFAULT_IPD})")
    parser.add_argument("--convergence",
                        type=argtypes.real_number(lambda v: 1e-3 <= v <= 1e6, "not in [0.001, 1e6] metres"),
                        metavar="METRES", help=f"distance of zero disparity (default {DEFAULT_CONVERGENCE})")
    parser.add_argument("--scene-scale", type=argtypes.real_number(lambda v: 1e-9 <= v <= 1e9, "not a positive scale"),
                        metavar="METRES_PER_UNIT", help=f"metres per scene unit (default {DEFAULT_SCENE_SCALE})")
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
    given = {f.name: getattr(args, f.name) for f in fields(StereoRig)}  # --ipd is dest "ipd", and so on
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
