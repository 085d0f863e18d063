"""``raygs-viewer convert IN OUT``: a scene in any readable format written as INRIA PLY,
``.splat`` or ``.spz``, then read back to report what the target kept and lost; with
filters (a crop box or sphere, a least opacity, a largest size), only the gaussians that
pass every one, in their order.

An INRIA PLY written as PLY is copied row by row from the file (:mod:`scene.ply_rows`):
each kept row bit for bit, extra properties and ``filter_3D`` included; other targets
are written from the scene as read.

The report is measured, not assumed: OUT is loaded like any scene and compared with IN
gaussian by gaussian (:func:`raygs_viewer.scene.compare.attribute_errors`), so a PLY's
float32 rounding and a lossy format's quantisation are both given as numbers. What a
format cannot hold at all (SH beyond the base colour in ``.splat``, a 3D filter as a
separate column) is said in words (:func:`raygs_viewer.scene.writing.writing_notes`).
"""

from __future__ import annotations

import os
from pathlib import Path

from raygs_viewer.capture.edit_file import EditDocument, load_edit_document
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.capture.sidecar import demo_sha256, scene_sha256
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.commands import load_scene_argument, warn_dropped
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import MAX_LOD_LEVELS
from raygs_viewer.scene.compare import attribute_errors, format_errors
from raygs_viewer.scene.filters import CropBox, CropSphere, KeepRule, KeepValues, MaxScale, MinOpacity, apply_rules
from raygs_viewer.scene.io import SCENE_FILES, load_scene
from raygs_viewer.scene.model import FileAxes, Scene
from raygs_viewer.scene.ply_file import PLY_FORMAT
from raygs_viewer.scene.ply_rows import PlyRows, copies_rows, read_count, write_kept
from raygs_viewer.scene.source import DEMO, SceneSource
from raygs_viewer.scene.writing import SPZ_VERSIONS, WRITE_SUFFIXES, writing_notes

#: ``--crop-box -1,-1,-1,1,1,1``: values that start with '-' (``argtypes.join_dash_values``).
DASH_VALUES = {"--crop-box": argtypes.looks_like_numbers, "--crop-sphere": argtypes.looks_like_numbers}

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
    filters = convert.add_argument_group(
        "filters", "keep only the gaussians that pass every filter given, in their order; centres in IN's own "
                   "coordinates, bounds compared in float32 (the values' own precision), edges included")
    filters.add_argument("--crop-box", type=argtypes.number_list(6), metavar="X0,Y0,Z0,X1,Y1,Z1",
                         help="keep centres inside the axis-aligned box from (X0,Y0,Z0) to (X1,Y1,Z1)")
    filters.add_argument("--crop-sphere", type=argtypes.number_list(4), metavar="X,Y,Z,R",
                         help="keep centres within R of (X,Y,Z)")
    filters.add_argument("--min-opacity", type=argtypes.real_number(lambda a: True, "not a number"), metavar="A",
                         help="keep gaussians whose opacity as rendered (after the sigmoid and any 3D filter's "
                              "fusion) is at least A, in 0..1")
    filters.add_argument("--edits", metavar="FILE.json",
                         help="replay the edits the window saved (its deletions and crops), first; refused when IN "
                              "is not the scene they were made on (by SHA-256)")
    filters.add_argument("--max-scale", type=argtypes.real_number(lambda s: True, "not a number"), metavar="S",
                         help="keep gaussians whose largest axis (exp of the largest log-scale) is at most S")


def keep_rules(args) -> list[KeepRule]:
    """The filters given, in the order they are applied; one-line UserError for a value
    out of its range (before anything is read)."""
    makers = (("--crop-box", args.crop_box, lambda v: CropBox(v[:3], v[3:])),
              ("--crop-sphere", args.crop_sphere, lambda v: CropSphere(v[:3], v[3])),
              ("--min-opacity", args.min_opacity, MinOpacity),
              ("--max-scale", args.max_scale, MaxScale))
    rules: list[KeepRule] = []
    for flag, value, make in makers:
        if value is not None:
            try:
                rules.append(make(value))
            except ValueError as exc:
                raise UserError(f"{flag}: {exc}") from None
    return rules


def command_convert(args) -> int:
    source, target = argtypes.scene_source(args, args.input), Path(args.output)
    if not source.is_demo and _same_file(source.path, target):
        raise UserError(f"{target}: is the input too; write to another file")
    check_output_path(target, args.overwrite, WRITE_SUFFIXES)  # before any slow work
    rules = keep_rules(args)
    edits = None if args.edits is None else load_edit_document(args.edits)
    spz = argtypes.spz_encoding(args, source)
    scene = load_scene_argument(source, args.lod)
    warn_dropped(scene)
    print(f"read {source.path}: {scene.format or 'built-in'}{_axes(scene.axes)}, {scene.count:,} gaussians, "
          f"SH degree {scene.sh_degree}")
    rows = PlyRows(source.path, read_count(scene)) if copies_rows(scene, target) else None
    if rules or edits is not None:
        kept = None if edits is None else _replayed(edits, args.edits, scene, source)
        scene = _filtered(scene, rules, source.path, rows, kept)
    copied = write_kept(scene, source.path, target, args.overwrite, rows=rows, spz=spz)
    print(f"wrote {target}: {os.path.getsize(target):,} bytes{', each row as IN has it' if copied else ''}")
    back = load_scene(source.at(target).with_axes(spz.axes))
    print(f"read back {target}: {back.format}{_axes(back.axes)}, {back.count:,} gaussians, "
          f"SH degree {back.sh_degree}")
    for note in [] if copied else writing_notes(scene, target.suffix):
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


def _replayed(edits: EditDocument, file: str, scene: Scene, source: SceneSource):
    """(N,) bool: what the edits in ``file`` keep of ``scene``, read from ``source``;
    printed like a filter's removals."""
    edits.check_scene(demo_sha256() if source.is_demo else scene_sha256(source.path), scene.count, source.path)
    kept = ~edits.replay(scene).deleted
    print(f"edits {file}: {len(edits.operations)} operations, removed {scene.count - int(kept.sum()):,}")
    return kept


def _filtered(scene: Scene, rules: list[KeepRule], path: str, rows: PlyRows | None, kept=None) -> Scene:
    """The gaussians of ``scene`` (read from ``path``) that every rule keeps, of those
    ``kept`` ((N,) bool) where given; prints what each removed. A PLY whose 3D filter
    was fused has its sizes from its own log-scales (``rows``, read here if not given)."""
    log_scales = None
    if scene.filter_fused and scene.format == PLY_FORMAT:
        rows = rows or PlyRows(path, read_count(scene))
        log_scales = rows.log_scales(scene.rows_in_file)
    kept, removed = apply_rules(KeepValues.of_scene(scene, log_scales), rules, kept)
    for step in removed:
        print(f"{step.rule}: removed {step.count:,}")
    count = int(kept.sum())
    if count == 0:
        raise UserError(f"the filters keep none of the {scene.count:,} gaussians; nothing written")
    print(f"kept {count:,} of {scene.count:,} gaussians")
    return scene.rows(kept)


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
