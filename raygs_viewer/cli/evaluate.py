"""``evaluate``: a trained model's renders against the photos of its capture
(docs/evaluation.md): PSNR, SSIM (the 3DGS training code's), FLIP and LPIPS (where its
extra is installed) per view, their means, the worst views, a contact sheet.

MODEL is an INRIA model folder (its point cloud is the scene), or a COLMAP folder or
nerfstudio transforms.json with ``--scene``. Any render setting is an option, so
``--mode gs``, ``--mip`` or ``--order per-pixel`` compare settings on the same photos.
Progress goes to stderr, one line a view; Ctrl-C keeps the views done (the report
says it was interrupted; exit status 130).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from raygs_viewer.capture.progress import TerminalProgress
from raygs_viewer.cli import argtypes
from raygs_viewer.cli.commands import warn_dropped
from raygs_viewer.cli.options import add_settings_options, render_settings
from raygs_viewer.errors import UserError
from raygs_viewer.photos.dataset import SPLITS, load_photo, open_dataset, select_split
from raygs_viewer.photos.evaluate import METRICS, EvaluationResult, evaluate, render_view
from raygs_viewer.photos.metrics import open_lpips
from raygs_viewer.photos.report import WORST_COUNT, check_report_paths, write_contact_sheet, write_report
from raygs_viewer.render.gl.context import create_headless_context
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.scene.loader import load_now

NAMES = {"psnr": "PSNR", "ssim": "SSIM", "flip": "FLIP", "lpips": "LPIPS"}


def add_parsers(commands) -> None:
    """Adds ``evaluate`` to the CLI's subparsers."""
    parser = commands.add_parser(
        "evaluate", help="measure a trained model's renders against its photos (PSNR, SSIM, FLIP, LPIPS)",
        description="Renders every view of a split at its training camera and compares it with the photo: PSNR, "
                    "SSIM as the 3DGS training code computes it (11x11 gaussian window, sigma 1.5, zero padding), "
                    "FLIP, and LPIPS (VGG) where the lpips extra is installed. Prints the means; --out writes a "
                    "report and a contact sheet of the worst views beside it.")
    parser.add_argument("model", metavar="MODEL",
                        help="an INRIA model folder (cameras.json, cfg_args, point_cloud/), a COLMAP folder "
                             "(sparse/0) or a nerfstudio transforms.json (these two need --scene)")
    parser.add_argument("--images", metavar="DIR", help="the photos' folder (default: what the dataset names)")
    parser.add_argument("--split", choices=SPLITS, default="test",
                        help="test: every 8th view, as the 3DGS paper holds them out (default); train: the "
                             "others; all")
    parser.add_argument("--scene", metavar="PLY", help="the trained scene (default: the INRIA folder's latest "
                                                       "point_cloud/iteration_*/point_cloud.ply)")
    parser.add_argument("--out", metavar="report.md|.csv|.json",
                        help="write the report (its format by the suffix) and NAME.worst.png, the worst views' "
                             "photo, render and error heat map, beside it")
    parser.add_argument("--limit", type=argtypes.whole_number(1, float("inf")), metavar="N",
                        help="evaluate only the first N views of the split")
    add_settings_options(parser, None, None)
    parser.add_argument("--overwrite", action="store_true", help="replace the report and contact sheet if they exist")
    argtypes.add_backend_option(parser)
    argtypes.add_source_options(parser, what="the axes a .spz --scene that declares none is read in")
    parser.set_defaults(run=command_evaluate)


def command_evaluate(args: argparse.Namespace) -> int:
    # Every check that needs no rendering comes first: a typo must not cost a long run.
    paths = None if args.out is None else check_report_paths(args.out, args.overwrite)
    settings = render_settings(args)
    dataset = open_dataset(args.model, args.images)
    if args.background is not None:  # the user's over the model's, for photos and renders alike
        dataset = replace(dataset, background=tuple(args.background))
    scene_path = args.scene or dataset.scene_path
    if scene_path is None:
        raise UserError(f"{args.model}: a {dataset.layout} dataset names no trained model; give it with --scene PLY")
    views = select_split(dataset.views, args.split)[:args.limit]
    if not views:
        raise UserError(f"{args.model}: no views in the {args.split} split of its {len(dataset.views)}")
    lpips, lpips_note = open_lpips()
    if lpips_note:
        print(f"note: {lpips_note}", file=sys.stderr)

    with TerminalProgress(str(scene_path)) as loading:
        scene = load_now(argtypes.scene_source(args, scene_path), progress=loading).scene
    warn_dropped(scene)
    ctx = create_headless_context(args.gl_backend)
    try:
        renderer = GLRenderer(ctx, scene)
        try:
            problem = renderer.supports(settings)
            if problem:
                raise UserError(problem)
            result = evaluate(dataset, views, renderer, settings, progress=print_progress, lpips=lpips,
                              lpips_note=lpips_note)
            print_summary(result)
            about = {"dataset": str(dataset.root), "layout": dataset.layout, "split": args.split,
                     "scene": str(scene_path)}
            if paths is not None:
                write_outputs(paths, result, about, args.overwrite, dataset=dataset, views=views, renderer=renderer)
        finally:
            renderer.release()
    finally:
        ctx.release()
    if result.interrupted:
        print(f"interrupted: {result.done} of {result.total} views evaluated", file=sys.stderr)
        return 130
    if not result.scores:
        raise UserError(f"none of the {result.total} views could be evaluated ({result.skipped[0].reason})")
    return 0


def print_progress(done: int, total: int, name: str) -> None:
    print(f"evaluate: {done}/{total} {name}", file=sys.stderr, flush=True)


def print_summary(result: EvaluationResult) -> None:
    """The means on stdout, and the skipped views' reasons on stderr."""
    for skip in result.skipped:
        print(f"skipped: {skip.reason}", file=sys.stderr)
    means = result.mean()
    shown = [f"{NAMES[m]} {means[m]:.4f}" if m != "psnr" else f"PSNR {means[m]:.3f} dB"
             for m in METRICS if means[m] is not None]
    print(f"{len(result.scores)} views" + (f" ({len(result.skipped)} skipped)" if result.skipped else "")
          + (": " + ", ".join(shown) if shown else ""))


def write_outputs(paths, result: EvaluationResult, about: dict, overwrite: bool, *, dataset, views,
                  renderer) -> None:
    """The report, then the contact sheet of its worst views (rendered again: keeping
    every view's images through a long run would cost memory for five pictures): the
    views of ``dataset`` that were evaluated, ``views``, rendered by ``renderer``."""
    report, sheet = paths
    worst = result.worst(WORST_COUNT)
    write_report(report, result, about, overwrite, sheet if worst else None)
    print(f"{report}: written", file=sys.stderr)
    if worst:
        by_name = {view.name: view for view in views}
        rows = []
        with DepthSorter(renderer.scene) as sorter:
            for score in worst:
                view = by_name[score.name]
                rows.append((f"{score.name}  PSNR {score.psnr:.2f} dB", load_photo(view, dataset.background),
                             render_view(renderer, sorter, view, result.settings)))
        write_contact_sheet(sheet, rows, overwrite)
        print(f"{sheet}: written", file=sys.stderr)
