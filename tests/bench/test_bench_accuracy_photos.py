"""``bench accuracy --photos MODEL``: the photos of a model's test views as a second truth,
on an INRIA model folder made on the fly whose photos are renders with known noise."""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np
import pytest
from datasets_kit import write_dataset
from testkit import LineSink, random_scene

from raygs_viewer.bench import accuracy as bench
from raygs_viewer.bench import accuracy_report as bench_report
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.photos.dataset import load_photo, open_dataset, select_split
from raygs_viewer.photos.metrics import psnr, ssim_3dgs
from raygs_viewer.render.settings import DEFAULT_P_MIN, RenderSettings, apply_preset
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.source import SceneSource

CONFIGS = ("RayGS", "RayGS + MIP")


def parse(*argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    bench_cli.add_parsers(parser.add_subparsers(dest="command"))
    return parser.parse_args(["bench", "accuracy", *map(str, argv)])


@pytest.fixture(scope="module")
def photo_run(tmp_path_factory, gl_session_ctx, gl_render):
    """A model of 9 views (test views: 0 and 8) at 32x24, photos the renders plus noise of
    0.05, measured at 16 px wide: (model, results, stdout, report)."""
    gl_session_ctx.__enter__()
    folder = tmp_path_factory.mktemp("photos")
    scene = random_scene(n=60, seed=5, degree=0)
    cameras = [look_at((4 * math.sin(a), -0.5, -4 * math.cos(a)), (0, 0, 0), width=32, height=24, fov_y_degrees=50)
               for a in np.linspace(-0.6, 0.6, 9)]
    rng = np.random.default_rng(1)
    photos = [np.clip(gl_render(scene, c)[..., :3] + rng.normal(0, 0.05, (24, 32, 3)), 0, 1) for c in cameras]
    model = write_dataset(folder / "data", "inria", cameras, photos, scene=scene)
    args = parse("--scenes", "demo", "--width", "16", "--repeat", "2", "--gt-samples", "1", "--photos", model,
                 "--photos-views", "2", "--report", folder / "acc.md", "--plot", folder / "acc.png")
    options = replace(bench_cli.accuracy_options(args), configs=CONFIGS)
    captured = []
    results = bench.run_accuracy(options, ctx=gl_session_ctx, out=LineSink(captured))
    bench_report.write_outputs(results, options.report, options.plot, options.overwrite)
    return model, results, "".join(captured), (folder / "acc.md").read_text(encoding="utf-8")


def test_photo_cases_equal_a_direct_computation(photo_run, gl_render):
    model, results, out, report = photo_run
    photo_cases = [c for c in results.cases if c.photo]
    dataset = open_dataset(model)
    views = select_split(dataset.views, "test")
    assert [c.photo for c in photo_cases] == [v.name for v in views[:2]] == ["view_000", "view_008"]
    for case, view in zip(photo_cases, views):
        camera = view.camera.resized(16, 12)
        assert (case.width, case.height) == (16, 12)
        photo = load_photo(replace(view, camera=camera), dataset.background)
        for name in CONFIGS:
            settings = apply_preset(RenderSettings(p_min=DEFAULT_P_MIN, background=dataset.background), name)
            render = np.clip(gl_render(open_scene(dataset), camera, settings)[..., :3], 0, 1)
            row = case.rows[name]
            assert row.photo_psnr == pytest.approx(psnr(render, photo), abs=1e-3)
            assert row.photo_ssim == pytest.approx(ssim_3dgs(render, photo), abs=1e-4)
            assert 15 < row.photo_psnr < 40 and math.isfinite(row.psnr) and row.gpu_ms > 0
            assert f"photo_psnr point_cloud photo-{view.name.replace('_', '-')} {bench.slug(name)} " in out
    # The view classes are measured as without --photos, with no photo numbers.
    assert {c.view for c in results.cases if not c.photo} == {"training", "far", "close"}
    assert all(math.isnan(r.photo_psnr) for c in results.cases if not c.photo for r in c.rows.values())


def test_report_puts_the_photo_columns_beside_the_truth(photo_run):
    model, results, out, report = photo_run
    assert "--photos" in report and "--photos-views 2" in report
    assert "#### Against the photos" in report
    assert "| configuration | GPU ms | ratio to RayGS | PSNR (dB) | p99 error | max error | PSNR photo (dB) | " \
           "SSIM photo | note |" in report
    case = next(c for c in results.cases if c.photo)
    row = case.rows["RayGS + MIP"]
    assert f"### point_cloud: test view {case.photo} against its photo" in report
    assert f"| {row.photo_psnr:.2f} | {row.photo_ssim:.4f} |" in report
    summary = {s.config: s for s in bench_report.summarize_photos(results)}
    photo_rows = [c.rows["RayGS + MIP"] for c in results.cases if c.photo]
    assert summary["RayGS + MIP"].photo_psnr == pytest.approx(np.mean([r.photo_psnr for r in photo_rows]))
    assert summary["RayGS"].photo_gain_db == 0.0
    # Without --photos the tables keep their columns.
    plain = replace(results, cases=[c for c in results.cases if not c.photo], photos="")
    text = bench_report.format_report(plain, None)
    assert "PSNR photo" not in text and "Against the photos" not in text


def open_scene(dataset):
    return load_now(SceneSource(dataset.scene_path)).scene
