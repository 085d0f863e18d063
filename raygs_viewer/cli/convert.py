"""``raygs-viewer convert IN OUT``: a scene in any readable format written as INRIA PLY,
``.splat`` or ``.spz``, then read back to report what the target kept and lost.

The report is measured, not assumed: OUT is loaded like any scene and compared with IN
gaussian by gaussian (:func:`raygs_viewer.scene.compare.attribute_errors`), so a PLY's
float32 rounding and a lossy format's quantisation are both given as numbers. What a
format cannot hold at all (SH beyond the base colour in ``.splat``, a 3D filter as a
separate column) is said in words (:func:`raygs_viewer.scene.writing.writing_notes`).
"""

from __future__ import annotations

import os
from pathlib import Path

from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.commands import load_scene_argument, warn_dropped
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import MAX_LOD_LEVELS
from raygs_viewer.scene.compare import attribute_errors, format_errors
from raygs_viewer.scene.io import SCENE_FILES, load_scene
from raygs_viewer.scene.source import DEMO
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.writing import SPZ_VERSIONS, WRITE_SUFFIXES, write_scene, writing_notes

#: Targets that hold every attribute as float32 (up to rounding of the activations).
LOSSLESS_SUFFIXES = (".ply",)


def add_parsers(commands) -> None:
    """Adds ``convert`` to the CLI's subparsers."""
    convert = commands.add_parser(
        "convert", help="write a scene as INRIA PLY, .splat or .spz, and report what the target lost",
        description=f"Reads IN ({SCENE_FILES}, or '{DEMO}'), writes OUT in the format its suffix names "
                    f"({', '.join(WRITE_SUFFIXES)}), reads OUT back and prints the largest error per attribute. "
                    f"Never replaces an existing OUT without --overwrite.")
    convert.add_argument("input", metavar="IN", help=f"the scene to read (any readable format, or '{DEMO}')")
    convert.add_argument("output", metavar="OUT", help=f"the file to write: {', '.join(WRITE_SUFFIXES)}")
    convert.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    convert.set_defaults(run=command_convert)
    convert.add_argument("--spz-version", type=int, choices=SPZ_VERSIONS, default=SPZ_VERSIONS[0],
                         help=f"the .spz version written (default {SPZ_VERSIONS[0]})")
    convert.add_argument("--lod", type=argtypes.whole_number(0, MAX_LOD_LEVELS - 1), metavar="N",
                         help="IN a streamed SOG (lod-meta.json): write its level N (0 the finest, the default) "
                              "with its environment")
    argtypes.add_source_options(convert, what="the axes IN, when a .spz that declares none, is read in")
    argtypes.add_axes_option(convert, "--out-spz-axes", "the axes OUT, when a .spz, is written in (default: "
                                                            "--spz-axes; rub and rdf re-label a file for the "
                                                            "other convention's tools)")


def command_convert(args) -> int:
    source, target = argtypes.scene_source(args, args.input), Path(args.output)
    if not source.is_demo and _same_file(source.path, target):
        raise UserError(f"{target}: is the input too; write to another file")
    check_output_path(target, args.overwrite, WRITE_SUFFIXES)  # before any slow work
    out_axes = argtypes.written_axes(args, source)
    scene = load_scene_argument(source, args.lod)
    warn_dropped(scene)
    print(f"read {source.path}: {scene.format or 'built-in'}{_axes(scene.axes)}, {scene.count:,} gaussians, "
          f"SH degree {scene.sh_degree}")
    write_scene(scene, target, args.overwrite, args.spz_version, out_axes)
    print(f"wrote {target}: {os.path.getsize(target):,} bytes")
    back = load_scene(source.at(target).with_axes(out_axes))
    print(f"read back {target}: {back.format}{_axes(back.axes)}, {back.count:,} gaussians, "
          f"SH degree {back.sh_degree}")
    for note in writing_notes(scene, target.suffix):
        print(f"note: {note}")
    try:
        errors = attribute_errors(scene, back)
    except ValueError:
        raise UserError(f"{target}: read back {back.count:,} of the {scene.count:,} gaussians written; "
                        f"cannot compare them") from None
    if target.suffix.lower() in LOSSLESS_SUFFIXES:
        print("lossless (to float32 rounding of log/exp and logit/sigmoid); largest errors read back:")
    else:
        print("quantised; largest errors read back:")
    for line in format_errors(errors):
        print(line)
    return 0


def _axes(axes: FileAxes | None) -> str:
    """", RDF axes" for a .spz (", RUB axes declared" when the file said so); "" otherwise."""
    return "" if axes is None else f", {axes.stored} axes{' declared' if axes.declared else ''}"


def _same_file(source: str, target: Path) -> bool:
    """Whether ``target`` names the file ``source`` does (the same path, a link to it)."""
    try:
        if target.exists() and Path(source).exists():
            return os.path.samefile(source, target)
    except OSError:
        pass
    return Path(source).resolve() == target.resolve()
