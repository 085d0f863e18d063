"""``raygs-viewer bench perf``: the generated cases, the floor pass and the fragment count,
one measured case, a tiny end-to-end run, the report and the command line."""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import re
import shlex

import numpy as np
import pytest
from testkit import assert_user_error, make_scene

from raygs_viewer.bench import common as bench_common
from raygs_viewer.bench import perf as bench_perf
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.cli.main import build_parser, main
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order, sort_request
from raygs_viewer.sort.depth import DepthSorter


def parse(*argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    bench_cli.add_parsers(parser.add_subparsers(dest="command"))
    return parser.parse_args(["bench", "perf", *map(str, argv)])


# --- the generated cases --------------------------------------------------------------------------

@pytest.mark.parametrize("size", list(bench_perf.SIZES))
@pytest.mark.parametrize("resolution", bench_perf.RESOLUTIONS)
def test_generated_gaussians_are_all_in_view_at_their_size(size, resolution):
    scene = bench_perf.generated_scene(3000, size, seed=1)
    camera = bench_perf.generated_camera(*resolution)
    settings = RenderSettings()
    with DepthSorter(scene) as sorter:
        visible = sorter.cull(sort_request(camera, settings))
    assert visible.size == scene.count
    # Their mean standard deviation on screen, at 720 rows, is the size's.
    depth = scene.positions @ camera.R[2].astype(np.float32) + np.float32(camera.t[2])
    pixels = scene.scales.mean(axis=1) * camera.fy / depth * 720 / camera.height
    assert np.median(pixels) == pytest.approx(bench_perf.SIZES[size], rel=0.1)
    assert scene.sh_degree == bench_perf.GENERATED_SH_DEGREE


def test_unknown_size_is_a_user_error():
    with pytest.raises(bench_perf.UserError, match="unknown footprint 'huge'"):
        bench_perf.generated_scene(10, "huge")


def test_nudged_turns_about_the_camera_centre():
    camera = look_at((1.0, 2.0, -3.0), (0.0, 0.0, 0.0), width=64, height=48)
    turned = bench_perf.nudged(camera, 0.1)
    assert np.allclose(turned.center, camera.center, atol=1e-12)
    cos = np.clip(np.dot(turned.R[2], camera.R[2]), -1, 1)
    assert math.degrees(math.acos(cos)) == pytest.approx(0.1, rel=1e-6)


def test_at_resolution_keeps_the_vertical_field_of_view():
    camera = look_at((0.0, 0.0, -3.0), (0.0, 0.0, 0.0), width=100, height=80, fov_y_degrees=50)
    wide = bench_perf.at_resolution(camera, 1920, 1080)
    assert (wide.width, wide.height, wide.cx, wide.cy) == (1920, 1080, 960, 540)
    assert wide.fx == wide.fy and 2 * math.degrees(math.atan(540 / wide.fy)) == pytest.approx(50)
    assert np.array_equal(wide.R, camera.R) and np.array_equal(wide.t, camera.t)


@pytest.mark.parametrize("count, expected", [(10_000, "10k"), (1_000_000, "1M"), (2_500, "2.5k"), (7, "7")])
def test_count_labels(count, expected):
    assert bench_perf.count_label(count) == expected


# --- the floor pass and the fragment count --------------------------------------------------------

def _raygs_and_floor(ctx, scene, camera):
    """(fragments kept, alpha) of the RayGS draw and (fragments rasterized, alpha) of the
    floor pass, with one order."""
    renderer = GLRenderer(ctx, scene)
    settings = RenderSettings()
    with DepthSorter(scene) as sorter:
        order = exact_order(sorter, camera, settings)
    try:
        return (*_samples(ctx, renderer, camera, settings, order, floor=False),
                *_samples(ctx, renderer, camera, settings, order, floor=True))
    finally:
        renderer.release()


def _samples(ctx, renderer, camera, settings, order, floor):
    target = ctx.framebuffer(color_attachments=[ctx.texture((camera.width, camera.height), 4, dtype="f4")])
    query = ctx.query(samples=True)
    try:
        target.use()
        target.clear()
        plan = renderer.plan(settings)
        renderer.preprocess(camera, plan)
        with query:
            renderer.draw(camera, plan, order, floor=floor)
        alpha = np.frombuffer(target.read(components=4, dtype="f4"), np.float32).reshape(-1, 4)[:, 3]
        return query.samples, alpha
    finally:
        target.color_attachments[0].release()
        target.release()


def test_the_kept_fraction_of_a_round_splat_is_a_circle_in_its_square(gl_ctx):
    # One isotropic gaussian straight ahead: its quad is the square around its round
    # support, so the fragments above p_min are pi/4 of those rasterized.
    scene = make_scene([[0.0, 0.0, 5.0]], [[0.3, 0.3, 0.3]], opacities=[0.8])
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), width=200, height=200, fov_y_degrees=40)
    kept, alpha, rasterized, floor_alpha = _raygs_and_floor(gl_ctx, scene, camera)
    assert rasterized > 2000  # a big splat: the fraction is not decided by a few edge pixels
    assert kept == np.count_nonzero(alpha > 0)
    assert rasterized == np.count_nonzero(floor_alpha > 0)
    assert kept / rasterized == pytest.approx(math.pi / 4, abs=0.02)
    # The floor covers every pixel the splat reaches: the same quad.
    assert np.all(floor_alpha[alpha > 0] > 0)


def test_the_floor_pass_covers_what_raygs_draws_for_a_random_scene(gl_ctx):
    scene = bench_perf.generated_scene(300, "large", seed=3)
    camera = bench_perf.generated_camera(160, 90)
    kept, alpha, rasterized, floor_alpha = _raygs_and_floor(gl_ctx, scene, camera)
    assert 0 < kept < rasterized
    assert np.all(floor_alpha[alpha > 0] > 0)


def test_there_is_no_floor_pass_for_ewa_splatting(gl_ctx):
    scene = make_scene([[0.0, 0.0, 5.0]], [[0.3, 0.3, 0.3]], opacities=[0.8])
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), width=32, height=32)
    renderer = GLRenderer(gl_ctx, scene)
    settings = RenderSettings(mode="gs")
    plan = renderer.plan(settings)
    renderer.preprocess(camera, plan)
    with DepthSorter(scene) as sorter, pytest.raises(ValueError, match="floor"):
        renderer.draw(camera, plan, exact_order(sorter, camera, settings), floor=True)
    renderer.release()


# --- one case -------------------------------------------------------------------------------------

def test_a_measured_case_runs_every_stage_every_frame(gl_ctx):
    made = []

    class Recording(GLRenderer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)

    scene = bench_perf.generated_scene(400, "small", seed=2)
    case = bench_perf.PerfCase("400 small", scene, bench_perf.generated_camera(96, 54), "small")
    frames = 3
    result = bench_perf.measure_case(gl_ctx, case, frames, renderer_type=Recording)
    assert [r.general for r in made] == [False, True]
    specialised, general = made
    # Every frame (and the warm-up) ran its own preprocessing for RayGS, for GS and for
    # RayGS with the geometry records (once: the median's pass and the depth view reuse
    # them), and uploaded a new order for RayGS and GS: the view changed every frame.
    assert specialised.counters.preprocessed == 3 * (frames + 1)
    assert specialised.counters.preprocess_skipped == 2 * (frames + 1)
    assert general.counters.preprocessed == frames + 1 and general.counters.preprocess_skipped == 0
    assert specialised.counters.uploads == 2 * (frames + 1)
    assert result.visible == result.count == 400 and result.frames == frames
    assert set(result.stages) == set(bench_perf.STAGES)
    assert all(math.isfinite(v) and v > 0 for v in result.stages.values())
    assert all(math.isfinite(v) and v > 0 for v in result.other.values())
    assert set(result.ratios) == set(bench_perf.RATIOS)
    assert 0.0 < result.ratios["fragments-kept"] < 1.0
    assert result.ratios["RayGS/GS"] == pytest.approx(result.other["raygs"] / result.other["gs"])
    assert result.ratios["RayGS/quads"] == pytest.approx(result.stages["draw"] / result.other["quads"])
    assert result.ratios["specialised/general"] == pytest.approx(result.other["raygs"] / result.other["general"])
    assert result.ratios["geometry/colour"] == pytest.approx(result.other["geometry"] / result.other["raygs"])
    assert result.ratios["median/colour"] == pytest.approx(result.other["median"] / result.other["raygs"])
    assert result.ratios["depth-view/colour"] == pytest.approx(result.other["depth view"] / result.other["raygs"])
    assert result.ratios["radix/argsort"] == pytest.approx(result.other["radix"] / result.other["argsort"])
    assert result.frame_ms == pytest.approx(sum(result.stages.values()))


# --- the whole benchmark, tiny --------------------------------------------------------------------

TINY = ["--counts", "200", "500", "--sizes", "small", "large", "--resolutions", "64x36", "80x45", "--frames", "2"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, gl_session_ctx):
    gl_session_ctx.__enter__()
    folder = tmp_path_factory.mktemp("bench_perf")
    args = parse(*TINY, "--scenes", "demo", "--report", folder / "perf.md", "--plot", folder / "perf.png")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert bench_cli.command(args, gl_session_ctx) == 0
    return args, printed.getvalue()


def _lines(out: str, name: str) -> dict[str, float]:
    return {m.group(1): float(m.group(2)) for m in re.finditer(rf"^{re.escape(name)}@(\S+) (\S+)$", out, re.M)}


def test_tiny_run_prints_every_ratio_per_case_and_their_medians(tiny_run):
    out = tiny_run[1]
    cases = [f"{n}-{s}-{r}" for n in ("200", "500") for s in ("small", "large") for r in ("64x36", "80x45")]
    cases += ["demo-64x36", "demo-80x45"]
    for name in bench_perf.RATIOS:
        per_case = _lines(out, name)
        assert sorted(per_case) == sorted(cases), name
        assert all(math.isfinite(v) and v > 0 for v in per_case.values())
        headline = re.findall(rf"^{re.escape(name)} (\S+)$", out, re.M)
        # printed as the run ends, and again in the report's machine-readable block
        assert len(headline) == 2 and headline[0] == headline[1], headline
        assert float(headline[0]) == pytest.approx(float(np.median(list(per_case.values()))), abs=1.5e-3)
    assert all(0 < v <= 1 for v in _lines(out, "fragments-kept").values())
    for case in cases:
        assert re.search(rf"^{re.escape(case)}: [\d,]+ of [\d,]+ visible; cull .* ms; frame .* fps\)$", out, re.M)


def test_tiny_report_and_plot(tiny_run):
    args, out = tiny_run
    report = open(args.report, encoding="utf-8").read()
    assert f"`{bench_cli.perf_command_line(args)}`" in report and "llvmpipe" in report or "OpenGL" in report
    for table in ("## Stages", "## Side by side", "## Ratios"):
        assert table in report
    stage_rows = [line for line in report.split("## Stages", 1)[1].split("##", 1)[0].splitlines()
                  if line.startswith("| ") and not line.startswith("| case")]
    assert len(stage_rows) == 10
    for name in bench_perf.RATIOS:  # the medians, as printed
        assert re.search(rf"^{re.escape(name)} \S+$", report, re.M)
    from PIL import Image

    from raygs_viewer.bench.plot import series_styles
    with Image.open(args.plot) as image:
        assert image.format == "PNG" and 600 <= image.width <= 2000 and 300 <= image.height <= 800
        colours = {rgb for _, rgb in image.convert("RGB").getcolors(1 << 20)}
    for style in series_styles(["small", "large"]).values():  # both footprints' RayGS points, filled
        assert tuple(int(style.color[i:i + 2], 16) for i in (1, 3, 5)) in colours, style


def test_the_recorded_command_line_reproduces_the_options(tiny_run):
    args = tiny_run[0]
    again = parse(*shlex.split(bench_cli.perf_command_line(args))[3:])
    assert vars(again) == vars(args)


def test_outputs_are_never_replaced_without_overwrite(tiny_run, monkeypatch):
    args = tiny_run[0]
    before = open(args.report, encoding="utf-8").read()
    monkeypatch.setattr(bench_perf, "run_perf", lambda *a, **k: pytest.fail("ran before refusing"))
    assert_user_error(lambda: bench_cli.command(parse(*TINY, "--report", args.report)), args.report,
                      "already exists", "--overwrite")
    assert_user_error(lambda: bench_cli.command(parse(*TINY, "--plot", args.plot)), args.plot, "already exists")
    assert open(args.report, encoding="utf-8").read() == before
    assert_user_error(lambda: bench_cli.command(parse(*TINY, "--report", str(args.report) + ".txt")),
                      "perf.md.txt", ".md")


def test_overwrite_replaces_the_report(gl_ctx, tmp_path, capsys):
    path = tmp_path / "perf.md"
    path.write_text("old", encoding="utf-8")
    args = parse("--counts", "100", "--sizes", "small", "--resolutions", "32x18", "--frames", "1", "--scenes",
                 "--report", path, "--overwrite")
    assert bench_cli.command(args, gl_ctx) == 0
    text = path.read_text(encoding="utf-8")
    assert text.startswith("# Performance figures") and "--overwrite" in text
    assert not list(tmp_path.glob(".*partial"))
    capsys.readouterr()


@pytest.mark.parametrize("argv, fragment", [
    (["--resolutions", "64by36"], "not WIDTHxHEIGHT"),
    (["--resolutions", "0x36"], "1..16384"),
    (["--counts", "0"], "outside 1.."),
    (["--sizes", "huge"], "invalid choice"),
])
def test_bad_options_are_one_line_errors(argv, fragment, capsys, monkeypatch):
    monkeypatch.setattr(bench_perf, "run_perf", lambda *a, **k: pytest.fail("ran before refusing"))
    assert main(["bench", "perf", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and fragment in err and err.count("\n") == 1


def test_the_report_and_the_plot_must_differ(tmp_path, monkeypatch):
    monkeypatch.setattr(bench_perf, "run_perf", lambda *a, **k: pytest.fail("ran before refusing"))
    # Different suffixes are required anyway; the same path fails on the suffix first.
    assert_user_error(lambda: bench_cli.command(parse("--report", tmp_path / "x.md", "--plot", tmp_path / "x.md")),
                      "x.md", ".png")


def test_missing_scene_is_a_one_line_error(tmp_path):
    missing = tmp_path / "missing.ply"
    assert_user_error(lambda: bench_cli.command(parse("--counts", "10", "--sizes", "small", "--resolutions", "8x8",
                                                  "--frames", "1", "--scenes", missing)), missing, "no such file")


def test_cli_parses_quick_and_the_defaults():
    quick = bench_cli.perf_options(build_parser().parse_args(["bench", "perf", "--quick"]))
    assert quick.counts == (10_000, 100_000) and quick.resolutions == ((1280, 720),)
    assert quick.sizes == ("small", "large") and quick.frames == 10
    assert quick.command_line == "raygs-viewer bench perf --quick"
    full = bench_cli.perf_options(build_parser().parse_args(["bench", "perf"]))
    assert full.counts == (10_000, 100_000, 1_000_000) and full.resolutions == ((1280, 720), (1920, 1080))
    assert full.frames >= 10 and full.report is None and full.plot is None
    if bench_common.shared_scenes_dir() is not None:
        assert len(full.scenes) + len(full.notes) == len(bench_perf.REAL_SCENES)
        assert len(quick.scenes) + len(quick.notes) == len(bench_perf.QUICK_REAL_SCENES)


def test_bench_help_names_perf(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    assert "perf" in capsys.readouterr().out
