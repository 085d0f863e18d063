"""The command line's argument types and the options every parser shares.

A type raises ``argparse.ArgumentTypeError`` with what is wrong; :class:`Parser` turns
that, and every other parsing error, into a :class:`UserError`, which ``main`` prints as
one line, ``error: <what and where>``, with exit status 2.
"""

from __future__ import annotations

import argparse
import math
import typing
from typing import Callable

from raygs_viewer.capture.screenshot import MAX_SCALE
from raygs_viewer.errors import UserError
from raygs_viewer.render.channels import parse_channels
from raygs_viewer.render.setting_info import SettingField, or_list, setting_field
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.scene.spz_format import SPZ_AXES, SpzEncoding

#: The longest side of an image the benchmarks accept, in pixels.
MAX_SIDE = 16384


class Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, like every other error
        raise UserError(f"{message} (see '{self.prog} --help')")


def whole_number(low: int, high: float, meaning: str | None = None) -> Callable[[str], int]:
    """An argparse type: a whole number in [low, high]; ``meaning`` says the range in
    words (default "outside LOW..HIGH")."""
    meaning = meaning or f"outside {low}..{high}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not a whole number") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{value} is {meaning}")
        return value
    return parse


def real_number(accept: Callable[[float], bool], meaning: str) -> Callable[[str], float]:
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


def short_number(value: float) -> str:
    """``value`` as a message writes it: 0.001, 1e6, 1e-9 (``:g`` without the
    exponent's sign and leading zeros)."""
    mantissa, exponent, power = f"{value:g}".partition("e")
    return f"{mantissa}e{int(power)}" if exponent else mantissa


def real_in(low: float, high: float, unit: str) -> Callable[[str], float]:
    """An argparse type: a finite number in [low, high], in ``unit`` (its message says it)."""
    return real_number(lambda v: low <= v <= high, f"not in [{short_number(low)}, {short_number(high)}] {unit}")


def setting_type(setting: SettingField) -> Callable[[str], object]:
    """The argparse type of a settings field that is neither a switch nor a choice of
    strings, from its Setting (render.setting_info): R,G,B for a colour, a whole number
    among its choices or within its limits, or a number within its limits."""
    name, info, hint = setting
    if hint == tuple[float, float, float]:
        return color_within(info)
    if int in (hint, *typing.get_args(hint)):
        if info.choices:
            return whole_number(min(info.choices), max(info.choices), f"not {or_list(info.choices)}")
        low, high = info.limits
        return whole_number(low, high, f"outside {info.low_words()}..{high}")
    if info.limits is None:
        raise TypeError(f"setting {name}: no command-line type for {hint} without limits")
    return real_number(info.within, f"not in {info.interval()}")


positive_int = whole_number(1, 65536)
#: --camera-index: refused below 0 at once, where Python's counting from the end would
#: otherwise pick a camera nobody asked for (the file's size is checked when it is read).
camera_index = whole_number(0, math.inf, "below 0: --camera-index must be 0..N-1 for a file of N cameras")
frames = whole_number(1, math.inf, "not at least 1")
turntable = real_number(lambda v: abs(v) <= 180, "not between -180 and 180")
screenshot_scale = real_number(lambda v: 0.0 < v <= MAX_SCALE, f"not in (0, {MAX_SCALE:g}]")


def color(text: str) -> tuple[float, float, float]:
    """An argparse type: R,G,B, three finite numbers."""
    try:
        parts = tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not three numbers R,G,B") from None
    if len(parts) != 3 or not all(math.isfinite(p) for p in parts):
        raise argparse.ArgumentTypeError(f"'{text}' is not three finite numbers R,G,B")
    return parts


def color_within(info) -> Callable[[str], tuple[float, float, float]]:
    """An argparse type: :func:`color` with each part within ``info``'s limits (the
    setting's own, so the command line and the settings refuse the same colours)."""
    def parse(text: str) -> tuple[float, float, float]:
        parts = color(text)
        if not all(info.within(p) for p in parts):
            raise argparse.ArgumentTypeError(f"'{text}' is not three numbers R,G,B in {info.interval()}")
        return parts
    return parse


#: The opacity cut-off, as --p-min takes it (bench's --gt-p-min too).
p_min = setting_type(setting_field(RenderSettings, "p_min"))


def size(text: str) -> tuple[int, int]:
    """An argparse type: WIDTHxHEIGHT, two whole numbers (their range is the caller's to check)."""
    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not WIDTHxHEIGHT, e.g. 1832x1920") from None
    return width, height


def resolution(text: str) -> tuple[int, int]:
    """An argparse type: WIDTHxHEIGHT with each side 1..MAX_SIDE."""
    width, height = size(text)
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE):
        raise argparse.ArgumentTypeError(f"'{text}': each side must be 1..{MAX_SIDE} pixels")
    return width, height


def fov_pair(text: str) -> tuple[float, float]:
    """An argparse type: H,V, two angles in degrees."""
    try:
        horizontal, vertical = (float(p) for p in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not two angles H,V in degrees, e.g. 100,95") from None
    return horizontal, vertical


def channel_list(text: str) -> tuple[str, ...]:
    """An argparse type: channels separated by commas (render.channels.parse_channels)."""
    try:
        return parse_channels(text)
    except UserError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def number_list(count: int) -> Callable[[str], tuple[float, ...]]:
    """An argparse type: ``count`` finite numbers separated by commas."""
    def parse(text: str) -> tuple[float, ...]:
        try:
            numbers = tuple(float(p) for p in text.split(","))
        except ValueError:
            numbers = ()
        if len(numbers) != count or not all(math.isfinite(v) for v in numbers):
            raise argparse.ArgumentTypeError(f"'{text}' is not {count} finite numbers separated by commas")
        return numbers
    return parse


def looks_like_numbers(text: str) -> bool:
    """Whether ``text`` is numbers separated by commas (``-1,0,2``), not an option."""
    try:
        for part in text.split(","):
            float(part)
    except ValueError:
        return False
    return True


def join_dash_values(argv: list[str], accepts: dict[str, Callable[[str], bool]]) -> list[str]:
    """``--flag -v`` -> ``--flag=-v`` for each flag of ``accepts`` whose next argument it
    accepts as a value: argparse takes a value starting with '-' (``--up-axis -y``,
    ``--crop-box -1,-1,-1,1,1,1``) for an option and would report the value missing.
    Stops at ``--``."""
    joined, i = [], 0
    while i < len(argv):
        if argv[i] == "--":
            joined.extend(argv[i:])
            break
        accept = accepts.get(argv[i])
        if accept is not None and i + 1 < len(argv) and accept(argv[i + 1]):
            joined.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            joined.append(argv[i])
            i += 1
    return joined


def depth_range(text: str) -> tuple[float, float]:
    """An argparse type: NEAR,FAR, two finite numbers, NEAR < FAR."""
    try:
        near, far = (float(p) for p in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not two numbers NEAR,FAR, e.g. 0.5,20") from None
    if not (math.isfinite(near) and math.isfinite(far) and near < far):
        raise argparse.ArgumentTypeError(f"'{text}' is not two finite numbers with NEAR < FAR")
    return near, far


def add_general_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--general", action="store_true",
                        help="draw with the one all-features shader variant (features switched by uniforms) "
                             "instead of the variant specialised to the scene and settings; the same image, "
                             "slower: it shows what specialising saves")


def add_sort_option(parser: argparse.ArgumentParser, default: str = "cpu") -> None:
    measured = ("auto: the one this GL measured faster at the scene's size (the window measures a GL it has not "
                "seen in its first seconds, `raygs-viewer doctor` too; remembered in "
                "$XDG_CONFIG_HOME/raygs-viewer/gl-profile.json; the CPU sort until then)")
    parser.add_argument("--sort", choices=("auto", "cpu", "gpu"), default=default,
                        help=f"{measured}; cpu: cull and sort on the CPU; gpu: in OpenGL 4.3 compute shaders, the "
                             "same order, kept on the GPU (no order crosses the bus; the draw uses the order of its "
                             f"own frame). All give the same images (default {default})")


def add_backend_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--gl-backend", choices=("auto", "egl", "osmesa"),
                        help="headless OpenGL (default: $RAYGS_GL_BACKEND or auto: EGL, else OSMesa)")


# The scene-reading options: what a command's SceneSource takes from its command line.

def add_source_options(parser: argparse.ArgumentParser,
                       what: str = "the axes a .spz scene that declares none is read in") -> None:
    """The options of how a scene is read (``--spz-axes``); :func:`scene_source` reads them."""
    add_axes_option(parser, "--spz-axes", what)


def add_axes_option(parser: argparse.ArgumentParser, flag: str, what: str) -> argparse.Action:
    """``FLAG rub|rdf``, a .spz's axes. Its default is None, so that a command can tell it
    was not given (render --sidecar, render-path take the recorded one)."""
    return parser.add_argument(flag, choices=SPZ_AXES, default=None,
                               help=f"{what}: rub, the .spz specification's (Niantic's spz, Scaniverse; the "
                                    f"default), or rdf, the PLY's own (PlayCanvas splat-transform, SuperSplat)")


def scene_source(args: argparse.Namespace, path: str, *, recorded: FileAxes | None = None,
                 cameras: str | None = None, levels: tuple[int, ...] | None = None) -> SceneSource:
    """The scene ``path`` (or the demo) as the options of :func:`add_source_options` read
    it: their axes if given, else those ``recorded`` (a path file's), else the default."""
    return SceneSource(path, cameras, levels=levels).with_axes(recorded).with_axes(args.spz_axes)


def source_options_given(args: argparse.Namespace) -> list[str]:
    """The scene-reading options given, as flags (a sidecar records its own)."""
    return ["--spz-axes"] if args.spz_axes is not None else []


def spz_encoding(args: argparse.Namespace, read: SceneSource) -> SpzEncoding:
    """How convert writes OUT when it is a .spz: ``--spz-version``, and ``--out-spz-axes``,
    by default the axes IN was read in."""
    return SpzEncoding(args.spz_version, args.out_spz_axes or read.spz_axes)
