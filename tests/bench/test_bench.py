"""``raygs-viewer bench accuracy``: view builders, metrics, a tiny end-to-end run, the report."""

from __future__ import annotations

import argparse
import math
import re
import shlex
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image
from testkit import LineSink, assert_user_error, gaussian_columns, listing, make_scene, write_ply

from raygs_viewer.bench import accuracy as bench
from raygs_viewer.bench import accuracy_report as bench_report
from raygs_viewer.bench import common as bench_common
from raygs_viewer.bench import views as bench_views
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.errors import UserError
from raygs_viewer.render import reference
from raygs_viewer.render.settings import ACCURACY_PRESETS


def parse(*argv) -> argparse.Namespace:
    """What the CLI hands to cli.bench.command for ``raygs-viewer bench accuracy ARGV``."""
    parser = argparse.ArgumentParser()
    bench_cli.add_parsers(parser.add_subparsers(dest="command"))
    return parser.parse_args(["bench", "accuracy", *map(str, argv)])


# --- view classes ------------------------------------------------------------------------

@pytest.mark.parametrize("centre", [(0.0, 0.0, 5.0), (1.5, -0.7, 3.0)])
def test_far_view_is_twice_as_far_along_the_axis_at_a_quarter_of_the_resolution(centre):
    camera = look_at((0.2, -0.3, -1.0), (0.0, 0.0, 4.0), width=320, height=240)
    far = bench_views.far_view(camera, np.array(centre))
    distance = np.linalg.norm(camera.center - centre)
    assert np.linalg.norm(far.center - centre) == pytest.approx(2 * distance, rel=1e-9)
    back = far.center - camera.center
    assert np.allclose(back / np.linalg.norm(back), -camera.R[2])  # straight back along the optical axis
    assert np.array_equal(far.R, camera.R)
    assert (far.width, far.height) == (80, 60)
    assert (far.fx, far.fy, far.cx, far.cy) == pytest.approx((camera.fx / 4, camera.fy / 4, camera.cx / 4, camera.cy / 4))


def test_training_view_keeps_the_aspect_ratio():
    camera = look_at((0, 0, -3), (0, 0, 0), width=640, height=480)
    view = bench_views.training_view(camera, 160)
    assert (view.width, view.height) == (160, 120)
    assert view.fx == pytest.approx(camera.fx / 4)


def cluster_scene(blocker: bool):
    """Twenty small gaussians around (0, 0, 5), optionally a big one in front of them on the axis."""
    rng = np.random.default_rng(3)
    positions = np.concatenate([rng.normal(0, 0.15, (20, 2)), 5 + rng.normal(0, 0.05, (20, 1))], axis=1)
    scales = np.full((20, 3), 0.03)
    if blocker:
        positions = np.vstack([positions, [0.0, 0.0, 4.6]])
        scales = np.vstack([scales, [0.3, 0.3, 0.3]])
    return make_scene(positions, scales, opacities=0.8)


@pytest.mark.parametrize("blocker", [False, True])
def test_close_view_is_nearer_and_outside_every_support(blocker):
    scene = cluster_scene(blocker)
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), width=64, height=48)
    close = bench_views.close_view(camera, scene)
    assert np.array_equal(close.R, camera.R) and close.width == camera.width
    step = close.center - camera.center
    assert np.allclose(step / np.linalg.norm(step), camera.R[2])  # forward along the optical axis
    assert bench_views.central_depth(close, scene, bench.DEFAULT_P_MIN) < bench_views.central_depth(camera, scene, bench.DEFAULT_P_MIN)
    assert not bench_views.inside_support(scene, close.center, bench.DEFAULT_P_MIN).any()
    assert not bench_views.inside_support(scene, close.center, bench.DEFAULT_P_MIN, bench_views.CLOSE_SUPPORT_MARGIN).any()
    if blocker:  # it had to stop in front of the big gaussian, well short of 5 % of the way
        assert close.center[2] < 4.6 - 0.3 * math.sqrt(-2 * math.log(bench.DEFAULT_P_MIN / 0.8))
    else:  # 5 % of the depth of the cluster's near side is left
        depth = bench_views.central_depth(camera, scene, bench.DEFAULT_P_MIN)
        assert close.center[2] == pytest.approx(depth * (1 - bench_views.CLOSE_FRACTION))


def test_close_view_of_an_empty_view_is_the_camera_itself():
    scene = make_scene([[0.0, 0.0, -5.0]], 0.1)  # behind the camera
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), width=32, height=24)
    assert bench_views.close_view(camera, scene) is camera


def test_view_cameras_of_the_demo(demo):
    from raygs_viewer.scene.demo import demo_cameras
    views = bench_views.view_cameras(demo, demo_cameras()[0], 160)
    assert [(v.width, v.height) for v in views.values()] == [(160, 120), (40, 30), (160, 120)]
    assert not bench_views.inside_support(demo, views["close"].center, bench.DEFAULT_P_MIN).any()


# --- metrics -----------------------------------------------------------------------------

def test_psnr():
    assert bench_common.psnr(0.01) == pytest.approx(20.0)
    assert bench_common.psnr(1.0) == 0.0
    assert bench_common.psnr(0.0) == math.inf


def test_error_metrics_on_known_arrays():
    truth = np.zeros((10, 10, 4))
    image = truth.copy()
    image[..., 3] = 0.7  # alpha is not compared
    assert bench_common.error_metrics(image, truth) == {"psnr": math.inf, "p99": 0.0, "max": 0.0}
    image[..., :3] = 0.1  # every RGB value off by 0.1: MSE 0.01
    image[0, 0, 1] = -0.4  # one value off by 0.4, negative: no clipping
    metrics = bench_common.error_metrics(image.astype(np.float32), truth)
    assert metrics["max"] == pytest.approx(0.4)
    assert metrics["p99"] == pytest.approx(0.1, rel=1e-6)  # one value in 300 is above the 99th percentile
    assert metrics["psnr"] == pytest.approx(10 * math.log10(1 / ((299 * 0.01 + 0.16) / 300)), rel=1e-6)
    with pytest.raises(ValueError):
        bench_common.error_metrics(np.zeros((4, 4, 4)), np.zeros((5, 4, 4)))


def test_slug():
    assert bench.slug("RayGS + MIP, no modulation") == "raygs-mip-no-modulation"
    assert bench.slug("RayGS p_min e^-4") == "raygs-p-min-e-4"
    slugs = [bench.slug(name) for name in ACCURACY_PRESETS]
    assert len(set(slugs)) == len(slugs) and all(re.fullmatch(r"[a-z0-9-]+", s) for s in slugs)


def test_every_configuration_has_a_colour_and_a_marker_of_its_own():
    """Fifteen configurations share one plot: no two may look alike, in colour or (for a
    greyscale print) in shape; the scenes differ by fill."""
    from raygs_viewer.bench.plot import group_fills, series_styles
    styles = series_styles(list(ACCURACY_PRESETS))
    assert list(styles) == list(ACCURACY_PRESETS)
    assert len({style.color for style in styles.values()}) == len(ACCURACY_PRESETS)
    assert len({style.marker for style in styles.values()}) == len(ACCURACY_PRESETS)
    many = series_styles([f"series {i}" for i in range(60)])  # past the lists: still one pair each
    assert len({(style.color, style.marker) for style in many.values()}) == 60
    fills = group_fills(["a", "b", "c", "d"])
    assert len(set(fills.values())) == 4 and fills["a"] == "full"


# --- the whole benchmark, tiny --------------------------------------------------------------

TINY = ["--width", "16", "--repeat", "2", "--gt-samples", "1"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, gl_session_ctx):
    """One run over the demo and a small PLY at 16 px: (args, stdout, report text, results)."""
    gl_ctx = gl_session_ctx
    gl_ctx.__enter__()
    folder = tmp_path_factory.mktemp("bench")
    ply = write_ply(folder / "blobs.ply", gaussian_columns(n=30, degree=0, seed=1))
    args = parse("--scenes", "demo", ply, *TINY, "--report", folder / "acc.md", "--plot", folder / "acc.png")
    captured = []
    options = bench_cli.accuracy_options(args)
    results = bench.run_accuracy(options, ctx=gl_ctx, out=LineSink(captured))
    bench_report.write_outputs(results, options.report, options.plot, options.overwrite)
    return args, "".join(captured), (folder / "acc.md").read_text(encoding="utf-8"), results


def test_tiny_run_covers_every_configuration_and_view(tiny_run):
    args, out, report, results = tiny_run
    assert [(c.scene, c.view) for c in results.cases] == [
        (scene, view) for scene in ("demo", "blobs") for view in bench_views.VIEW_CLASSES]
    for case in results.cases:
        assert list(case.rows) == list(ACCURACY_PRESETS)
        assert case.rows["RayGS"].ratio == 1.0
        for row in case.rows.values():
            assert len(row.times_ms) == 2 and all(t > 0 for t in row.times_ms)
            assert row.gpu_ms > 0 and row.ratio > 0 and row.max_error >= row.p99 >= 0
    far = next(c for c in results.cases if c.view == "far")
    assert (far.width, far.height, far.gt_samples) == (4, 3, 2)
    # Machine-readable lines: one per key, scene, view and configuration.
    for scene in ("demo", "blobs"):
        for view in bench_views.VIEW_CLASSES:
            assert f"ratio {scene} {view} raygs 1\n" in out
            for name in ACCURACY_PRESETS:
                assert re.search(rf"^psnr {scene} {view} {re.escape(bench.slug(name))} \S+$", out, re.M)


def test_tiny_report_has_every_table(tiny_run):
    args, out, report, results = tiny_run
    assert "`raygs-viewer bench accuracy --scenes demo" in report and "--width 16 --repeat 2" in report
    assert "llvmpipe" in report or "Machine:" in report
    assert bench_report.HUMAN_VERDICT_BEGIN in report and bench_report.HUMAN_VERDICT_END in report
    assert "![PSNR against GPU time ratio to RayGS, per view class](acc.png)" in report
    for scene in ("demo", "blobs"):
        for view in bench_views.VIEW_CLASSES:
            section = report.split(f"### {scene}: {bench_views.VIEW_TITLES[view]}\n", 1)[1].split("\n### ", 1)[0]
            rows = [line for line in section.splitlines() if line.startswith("| ") and "---" not in line][1:]
            assert [row.split(" | ")[0][2:] for row in rows] == list(ACCURACY_PRESETS)
            baseline = next(row for row in rows if row.startswith("| RayGS |"))
            assert baseline.split(" | ")[2] == "1.00"
    for view in bench_views.VIEW_CLASSES:
        assert f"#### {bench_views.VIEW_TITLES[view]}" in report
    assert "cheapest within 0.5 dB" in report


def test_tiny_plot_is_a_png_with_every_configuration(tiny_run):
    """Two rows of three panels (per scene, mean over scenes) and a legend; every
    configuration's colour is drawn (the mean panels draw each one filled)."""
    from raygs_viewer.bench.plot import series_styles
    args = tiny_run[0]
    with Image.open(args.plot) as image:
        image.load()
        assert image.format == "PNG" and 1200 <= image.width <= 2000 and 600 <= image.height <= 1100
        colours = {rgb for _, rgb in image.convert("RGB").getcolors(1 << 20)}
    for style in series_styles(list(ACCURACY_PRESETS)).values():
        assert tuple(int(style.color[i:i + 2], 16) for i in (1, 3, 5)) in colours, style


def test_report_is_never_replaced_without_overwrite(tiny_run, monkeypatch):
    args = tiny_run[0]
    monkeypatch.setattr(bench, "run_accuracy", lambda *a, **k: pytest.fail("ran before refusing"))
    assert_user_error(lambda: bench_cli.command(parse("--scenes", "demo", "--report", args.report, "--plot",
                                                  args.plot + ".new.png")),
                      args.report, "already exists", "--overwrite")
    assert_user_error(lambda: bench_cli.command(parse("--scenes", "demo", "--report", args.report + ".new.md",
                                                  "--plot", args.plot)),
                      args.plot, "already exists")


def test_overwrite_replaces_the_numbers_and_keeps_the_human_verdict(tiny_run, tmp_path, monkeypatch):
    args, out, report, results = tiny_run
    drawn = bench_report.draw_plot(results)  # the same bytes three times: drawing is tiny_run's test
    monkeypatch.setattr(bench_report, "draw_plot", lambda _: drawn)
    path = tmp_path / "acc.md"
    plot = tmp_path / "acc.png"
    bench_report.write_outputs(results, path, plot, overwrite=False)
    with pytest.raises(UserError, match="already exists"):
        bench_report.write_outputs(results, path, plot, overwrite=False)
    edited = path.read_text(encoding="utf-8").replace(bench_report.HUMAN_VERDICT_PLACEHOLDER, "GS is not worth it.")
    path.write_text(edited.replace("| RayGS | ", "| RayGS-old | "), encoding="utf-8")
    bench_report.write_outputs(results, path, plot, overwrite=True)
    rewritten = path.read_text(encoding="utf-8")
    assert "GS is not worth it." in rewritten and "RayGS-old" not in rewritten
    assert not list(tmp_path.glob(".*partial"))  # no temporary files left behind


def test_the_recorded_command_line_reproduces_the_options(tiny_run):
    args = tiny_run[0]
    command = bench_cli.accuracy_command_line(args)
    again = parse(*shlex.split(command)[3:])
    assert vars(again) == vars(args)


def test_bad_scene_path_is_a_one_line_error(tmp_path):
    missing = tmp_path / "missing.ply"
    assert_user_error(lambda: bench_cli.command(parse("--scenes", "demo", missing, *TINY, "--report",
                                                  tmp_path / "a.md", "--plot", tmp_path / "a.png")),
                      missing, "no such file")
    assert not (tmp_path / "a.md").exists()


def test_bad_outputs_fail_before_any_work(tmp_path):
    assert_user_error(lambda: bench_cli.accuracy_options(parse("--report", tmp_path / "a.txt", "--plot", tmp_path / "a.png")),
                      "a.txt", ".md")
    assert_user_error(lambda: bench_cli.accuracy_options(parse("--report", tmp_path / "no" / "a.md",
                                                            "--plot", tmp_path / "a.png")), "a.md", "does not exist")
    assert_user_error(lambda: bench_cli.accuracy_options(parse("--report", tmp_path / "a.md",
                                                            "--plot", tmp_path / "a.md")), "a.md", "different")


def test_quick_defaults(tmp_path):
    options = bench_cli.accuracy_options(parse("--quick", "--report", tmp_path / "a.md", "--plot", tmp_path / "a.png"))
    assert (options.width, options.repeat, options.gt_samples) == (160, 10, 4)
    assert options.scenes[0] == "demo" and len(options.scenes) <= 2
    full = bench_cli.accuracy_options(parse("--report", tmp_path / "a.md", "--plot", tmp_path / "a.png", "--repeat", "12"))
    assert (full.width, full.repeat, full.gt_samples) == (320, 12, 8)
    if bench_common.shared_scenes_dir() is not None:
        assert any("fruit" in s for s in options.scenes)
        assert not any(s.startswith("/") for s in options.scenes)  # paths stay relative


def test_run_as_documented_from_any_folder_prints_and_writes_nothing(tmp_path, monkeypatch, capsys):
    """``raygs-viewer bench accuracy`` with no paths, from a folder without docs/: the
    report is printed, no file is written (the docs' files are named explicitly)."""
    results = synthetic_results({("demo", "training"): {"RayGS": (1.0, 40.0), "GS": (0.8, 30.0)}})
    monkeypatch.setattr(bench, "run_accuracy", lambda options, ctx=None, **kw: results)
    monkeypatch.chdir(tmp_path)
    assert bench_cli.command(parse("--scenes", "demo")) == 0
    out = capsys.readouterr().out
    assert "# Accuracy against time" in out and "| RayGS |" in out and "wrote" not in out
    assert list(tmp_path.iterdir()) == []
    # Asked for, the report is written (and says so) without the plot.
    assert bench_cli.command(parse("--scenes", "demo", "--report", "acc.md")) == 0
    assert "wrote acc.md" in capsys.readouterr().out and listing(tmp_path) == ["acc.md"]


def synthetic_results(table):
    """BenchResults from {(scene, view): {config: (ratio, psnr)}} (other fields filler)."""
    cases = [bench.CaseResult(scene, view, 8, 6, 1, 0.0,
                              {c: bench.ConfigResult(c, 10.0 * r, r, p, 0.0, 0.0) for c, (r, p) in rows.items()})
             for (scene, view), rows in table.items()]
    return bench.AccuracyResults(cases, "test", 2, "cmd", "today", 2, 8, [])


def test_verdict_facts():
    results = synthetic_results({
        ("a", "far"): {"RayGS": (1.0, 30.0), "MIP": (1.05, 35.0), "exact": (1.8, 35.05), "SS": (2.0, 36.0),
                       "slow": (1.5, 29.0), "mixed": (1.5, 31.0)},
        ("b", "far"): {"RayGS": (1.0, 70.0), "MIP": (1.05, 75.0), "exact": (1.8, 75.0), "SS": (2.0, 90.0),
                       "slow": (1.5, 29.0), "mixed": (1.5, 20.0)},
    })
    summaries = {s.config: s for s in bench_report.summarize(results, "far")}
    # PSNRs above VERDICT_PSNR_CAP count as the cap: scene b's gains are all 0 or losses.
    assert summaries["MIP"].gain_db == pytest.approx(2.5) and summaries["SS"].gain_db == pytest.approx(3.0)
    assert summaries["SS"].ratio == pytest.approx(2.0) and summaries["RayGS"].ratio == 1.0
    # exact is no better than MIP (within the tolerance) and slower: off the front.
    assert [c for c, s in summaries.items() if s.pareto] == ["RayGS", "MIP", "SS"]
    lines = bench_report.verdict_lines(list(summaries.values()))
    assert lines[0].startswith("most accurate: SS") and lines[1].startswith("cheapest within 0.5 dB of it: MIP")
    # "mixed" is more accurate in one scene, "slow" in none.
    assert lines[-1].endswith("no more accurate in any scene: slow")
    notes = bench_report.case_notes(results.cases[1])
    assert notes["SS"] == "best" and notes["RayGS"] == "baseline, cheapest near best"


def test_the_ground_truth_composites_every_ray_in_its_own_order(gl_ctx, tmp_path):
    seen = []

    def truth(scene, camera, settings, samples):
        seen.append(settings.order)
        return reference.ground_truth(scene, camera, settings, samples)

    options = bench_cli.accuracy_options(parse("--scenes", "demo", *TINY, "--report", tmp_path / "a.md",
                                               "--plot", tmp_path / "a.png"))
    bench.run_accuracy(replace(options, configs=("RayGS",)), ctx=gl_ctx, out=LineSink([]), ground_truth=truth)
    assert seen == ["per-pixel"] * 3  # one per view class
