"""``raygs-viewer bench order``: the camera sweeps, the popping measure, the choice of
the window within 1 dB, a tiny end-to-end run and the command line."""

from __future__ import annotations

import math

import numpy as np
import pytest
from testkit import random_scene, run_cli

from raygs_viewer.bench import order as bench_order
from raygs_viewer.bench.common import BenchScene
from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.cli.main import build_parser


def _start():
    return look_at((0.0, 0.0, -5.0), (0.0, 0.0, 0.0), width=32, height=24)


def test_a_turn_keeps_the_centre_and_turns_half_a_degree_a_frame():
    cameras = bench_order.sweep_cameras(_start(), "turn", 5, radius=2.0)
    for frame, camera in enumerate(cameras):
        np.testing.assert_allclose(camera.center, cameras[0].center, atol=1e-12)
        np.testing.assert_allclose(camera.R @ camera.R.T, np.eye(3), atol=1e-12)
        cosine = np.clip(np.dot(camera.R[2], cameras[0].R[2]), -1, 1)
        assert math.degrees(math.acos(cosine)) == pytest.approx(0.5 * frame, abs=1e-9)
        np.testing.assert_allclose(camera.R[1], cameras[0].R[1], atol=1e-12)  # about the camera's vertical


def test_a_flight_moves_forward_one_percent_of_the_radius_a_frame():
    cameras = bench_order.sweep_cameras(_start(), "fly", 4, radius=3.0)
    for frame, camera in enumerate(cameras):
        np.testing.assert_allclose(camera.R, cameras[0].R)
        np.testing.assert_allclose(camera.center - cameras[0].center, cameras[0].R[2] * 0.03 * frame, atol=1e-12)
    with pytest.raises(ValueError):
        bench_order.sweep_cameras(_start(), "roll", 2, 1.0)


def test_popping_is_the_mean_p99_of_the_error_flicker():
    still = [np.full((10, 10, 3), 0.2)] * 4
    assert bench_order.popping(still) == 0.0  # wrong the same way every frame: no popping
    flicker = [np.zeros((10, 10, 3)) for _ in range(3)]
    flicker[1][:5, :, 1] = 0.5  # half the pixels change by 0.5 in one channel, then back
    assert bench_order.popping(flicker) == pytest.approx(0.5)
    one_pixel = [np.zeros((10, 10, 3)), np.zeros((10, 10, 3))]
    one_pixel[1][0, 0] = 1.0  # 1 % of the pixels: the 99th percentile sits at the border
    assert 0.0 < bench_order.popping(one_pixel) < 1.0
    assert math.isnan(bench_order.popping(still[:1]))


def _rows(psnrs):
    return {name: bench_order.ModeRow(name, 1.0, 1.0, psnr, {}, {}) for name, psnr in psnrs.items()}


def test_the_window_within_one_db_is_the_smallest_that_reaches_it():
    psnrs = {f"per-pixel K={k}": value for k, value in zip(bench_order.WINDOWS, (30.0, 33.5, 34.2, 35.0, 35.1))}
    psnrs[bench_order.EXACT] = 35.1
    assert bench_order.within_exact(_rows(psnrs)) == "per-pixel K=4"
    psnrs[bench_order.EXACT] = 40.0
    assert bench_order.within_exact(_rows(psnrs)) is None


def test_options_and_recorded_command(tmp_path):
    args = build_parser().parse_args(["bench", "order", "--quick", "--scenes", "demo", "--frames", "3"])
    options = bench_cli.order_options(args)
    assert (options.width, options.frames, options.repeat) == (bench_order.QUICK_WIDTH, 3, bench_order.QUICK_REPEAT)
    assert options.command_line == "raygs-viewer bench order --quick --scenes demo --frames 3"


@pytest.mark.parametrize("argv", [["--frames", "1"], ["--width", "2"], ["--gt-samples", "0"]])
def test_bad_options_are_one_line_errors(capsys, argv):
    code, _, err = run_cli(capsys, "bench", "order", *argv)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1


def test_a_tiny_run_measures_every_mode(gl_ctx, monkeypatch):
    scene = random_scene(60, seed=7, degree=0, spread=0.6, log_scale=(-2.5, -1.2))
    item = BenchScene("tiny", scene, look_at((0.0, 0.0, -3.0), (0.0, 0.0, 0.0), width=48, height=36), "tiny")
    monkeypatch.setattr(bench_order.common, "load_scenes", lambda specs: [item])
    options = bench_order.OrderOptions(scenes=("tiny",), width=24, frames=3, repeat=1, gt_samples=1)
    results = bench_order.run_order(options, gl_ctx, out=open("/dev/null", "w"))
    assert [(v.scene, v.view) for v in results.views] == [("tiny", "training"), ("tiny", "close")]
    for view in results.views:
        assert set(view.rows) == set(bench_order.MODES)
        exact = view.rows[bench_order.EXACT]
        assert exact.popping == {"turn": 0.0, "fly": 0.0} and math.isinf(exact.psnr["turn"])
        assert view.exact_vs_reference_psnr > 60  # the GL exact order is the reference's
        assert view.rows["depth"].ratio == 1.0 and view.fragments_per_pixel > 1
        # One sample per pixel: the integrated truth is the exact order itself.
        assert exact.psnr_integrated > 60
    report = bench_order.format_report(results)
    assert "## tiny: training (24x18)" in report and "| per-pixel K=4 |" in report
