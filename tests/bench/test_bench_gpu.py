"""``raygs-viewer bench gpu``: the generated outdoor scene, one measured case, the --quick
run CI makes (its lines, report and options), and its refusals."""

from __future__ import annotations

import argparse
import math
import re
import shlex

import numpy as np
import pytest
from testkit import assert_one_line_error, run_cli

from raygs_viewer.bench import gpu as bench_gpu
from raygs_viewer.bench.common import count_label
from raygs_viewer.camera.stereo import StereoRig
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import sort_request
from raygs_viewer.sort.depth import DepthSorter


def parse(*argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    bench_cli.add_parsers(parser.add_subparsers(dest="command"))
    return parser.parse_args(["bench", "gpu", *map(str, argv)])


def test_the_outdoor_scene_is_an_object_in_its_surroundings():
    scene = bench_gpu.outdoor_scene(20_000, seed=1)
    assert scene.count == 20_000 and scene.sh_degree == 3
    radius = np.linalg.norm(scene.positions, axis=1)
    assert np.mean(radius <= 1.0) == pytest.approx(0.55, abs=0.01)
    assert radius.max() <= 12.0 and np.mean(radius >= 3.0) == pytest.approx(0.45, abs=0.01)
    assert np.mean(scene.opacities < 0.2) == pytest.approx(1 / 3, abs=0.03)
    # Farther gaussians are larger, as training leaves the background.
    assert np.median(scene.scales[radius > 6]) > 3 * np.median(scene.scales[radius < 1])
    camera = bench_gpu.outdoor_camera(320, 180)
    with DepthSorter(scene) as sorter:
        visible = sorter.cull(sort_request(camera, RenderSettings())).size
    assert 0.4 < visible / scene.count < 0.95  # some of the surroundings are behind the camera


def test_a_measured_case_counts_its_fragments_and_times_every_option(gl_ctx):
    scene = bench_gpu.outdoor_scene(3_000, seed=2)
    for case in (bench_gpu.GpuCase("tiny", scene, bench_gpu.outdoor_camera(96, 54), "mono"),
                 bench_gpu.GpuCase("tiny", scene, bench_gpu.outdoor_camera(48, 52), "stereo", StereoRig())):
        result = bench_gpu.measure_case(gl_ctx, case, frames=1, drained=True)
        assert 0 < result.visible <= scene.count
        assert 0 < result.kept <= result.rasterized
        for value in (result.sort_ms, result.preprocess_ms, result.draw_ms, result.floor_ms, result.gs_ms):
            assert math.isfinite(value) and value > 0
        assert set(result.frame_ms) == {bench_gpu.TODAY, *(name for name, _, _ in bench_gpu.OPTIONS)}
        assert all(math.isfinite(result.ratio(name)) for name, _, _ in bench_gpu.OPTIONS)
        assert result.fill_rate == pytest.approx(result.rasterized / (result.draw_ms / 1e3))
        # Every layout draws today's image to the bit; a narrow blend does not, within its error.
        for name, changes, layout in bench_gpu.OPTIONS:
            if not changes:
                assert result.max_error[name] == 0 and result.psnr[name] == math.inf, name
            else:
                assert 0 < result.max_error[name] < 0.05 and result.psnr[name] > 35, name


def test_each_option_draws_through_a_plan_of_its_own_layout_leaving_the_renderer_as_made(gl_ctx, monkeypatch):
    """What each option measures is planned with its layout; the renderer's own layout,
    which other renders take, is never changed on the way (nor changed back)."""
    renderers = []

    class Watched(GLRenderer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.planned = set()
            renderers.append(self)

        def __setattr__(self, name, value):
            if name == "draw_layout" and name in self.__dict__:
                raise AssertionError(f"the renderer's draw layout was set to {value}")
            super().__setattr__(name, value)

        def plan(self, *args, **kwargs):
            plan = super().plan(*args, **kwargs)
            self.planned.add(plan.draw)
            return plan

    monkeypatch.setattr(bench_gpu, "GLRenderer", Watched)
    scene = bench_gpu.outdoor_scene(1_000, seed=2)
    bench_gpu.measure_case(gl_ctx, bench_gpu.GpuCase("tiny", scene, bench_gpu.outdoor_camera(48, 32), "mono"),
                           frames=1, drained=True)
    assert len(renderers) == 1
    assert renderers[0].planned == {layout for _, _, layout in bench_gpu.OPTIONS}


def test_the_stereo_case_counts_both_eyes(gl_ctx):
    scene = bench_gpu.outdoor_scene(2_000, seed=3)
    camera = bench_gpu.outdoor_camera(64, 64)
    mono = bench_gpu.measure_case(gl_ctx, bench_gpu.GpuCase("a", scene, camera, "mono"), 1, True, options=())
    pair = bench_gpu.measure_case(gl_ctx, bench_gpu.GpuCase("a", scene, camera, "stereo", StereoRig()), 1, True,
                                  options=())
    assert pair.rasterized == pytest.approx(2 * mono.rasterized, rel=0.1)


COUNT = 5_000


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """``bench gpu --quick --out`` as CI makes it, on a smaller scene and one timed frame
    (``--counts``, ``--frames``: the same cases, options and report, a sixth of the work;
    what --quick itself chooses is test_options_and_the_recorded_command's)."""
    import contextlib
    import io

    from raygs_viewer.cli.main import main

    out = tmp_path_factory.mktemp("gpu") / "gpu.md"
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = main(["bench", "gpu", "--quick", "--counts", str(COUNT), "--frames", "1", "--out", str(out)])
    return code, printed.getvalue(), out


def test_quick_run_prints_every_case_option_and_median(quick_run):
    code, printed, out = quick_run
    assert code == 0
    assert re.search(r"^clock: CPU, GL drained", printed, re.M)  # llvmpipe: the drained clock, and said so
    labels = [f"outdoor-{count_label(COUNT)}-{view}" for view in ("mono", "stereo")]
    for label in labels:
        assert re.search(rf"^fragments-per-second@{label} [0-9.e+]+$", printed, re.M)
        for name, _, _ in bench_gpu.OPTIONS:
            assert re.search(rf"^{re.escape(name)}@{label} [0-9.]+$", printed, re.M), name
    for name, _, _ in bench_gpu.OPTIONS:
        assert re.search(rf"^{re.escape(name)} [0-9.]+$", printed, re.M), name
    report = out.read_text()
    assert report.startswith("# GPU frame figures (generated)")
    assert f"`raygs-viewer bench gpu --quick --counts {COUNT} --frames 1 --out " in report
    for heading in ("## Today's path", "## Each option against today's path", "## What each option draws",
                    "## VR budget"):
        assert heading in report
    assert "| outdoor 5k | stereo 258×276 ×2 |" in report


def test_options_and_the_recorded_command(tmp_path):
    options = bench_cli.gpu_options(parse("--quick"))
    assert options.counts == bench_gpu.QUICK_COUNTS and options.scenes == ()
    assert options.mono == bench_gpu.QUICK_MONO and options.eye_shrink == bench_gpu.QUICK_EYE_SHRINK
    full = bench_cli.gpu_options(parse("--counts", "1000", "1000", "--scenes", "demo", "--frames", "3"))
    assert full.counts == (1000,) and full.scenes == ("demo",) and full.frames == 3
    assert full.mono == bench_gpu.MONO and full.eye_shrink == 1
    assert shlex.split(full.command_line) == ["raygs-viewer", "bench", "gpu", "--counts", "1000", "1000",
                                              "--scenes", "demo", "--frames", "3"]
    assert bench_cli.gpu_options(parse("--counts", "--scenes", "demo")).counts == ()
    with pytest.raises(bench_cli.UserError, match="nothing to measure"):
        bench_cli.gpu_options(parse("--counts", "--scenes"))


def test_refusals_come_before_any_work(capsys, tmp_path):
    code, _, err = run_cli(capsys, "bench", "gpu", "--quick", "--scenes", tmp_path / "missing.ply")
    assert_one_line_error(code, err)
    assert "missing.ply: no such file" in err
    existing = tmp_path / "gpu.md"
    existing.write_text("mine")
    code, _, err = run_cli(capsys, "bench", "gpu", "--quick", "--out", existing)
    assert_one_line_error(code, err)
    assert existing.read_text() == "mine"
    code, _, err = run_cli(capsys, "bench", "gpu", "--frames", "0")
    assert_one_line_error(code, err)
