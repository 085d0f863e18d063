"""``raygs-viewer bench stereo``: the sharing error and its parts, the both-eyes timing, a
tiny end-to-end run, the report and the command line."""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import re
import shlex
from dataclasses import replace

import numpy as np
import pytest
from testkit import (
    assert_user_error,
    gaussian_columns,
    make_scene,
    random_scene,
    write_ply,
)

from raygs_viewer.bench import accuracy as bench
from raygs_viewer.bench import common as bench_common
from raygs_viewer.bench import stereo as bench_stereo
from raygs_viewer.bench import views as bench_views
from raygs_viewer.camera import stereo
from raygs_viewer.camera.navigation import scene_bounds
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.cli.main import build_parser, main
from raygs_viewer.render.gl import stereo_frame
from raygs_viewer.render.gl.timing import INVALID_ELAPSED
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import SortRequest, SortResult

#: Headset presets small enough for llvmpipe to time in milliseconds; their names are
#: the lines' PRESET tokens.
TINY_PRESETS = {
    "tiny": replace(stereo.custom_preset(24, 20, 100.0, 90.0), name="tiny", label="tiny headset"),
    "narrow": replace(stereo.custom_preset(16, 16, 60.0, 60.0), name="narrow", label="narrow headset"),
}


def parse(*argv) -> argparse.Namespace:
    """What the CLI hands to cli.bench.command for ``raygs-viewer bench stereo ARGV``."""
    parser = argparse.ArgumentParser()
    bench_cli.add_parsers(parser.add_subparsers(dest="command"))
    return parser.parse_args(["bench", "stereo", *map(str, argv)])


@pytest.fixture
def tiny_presets(monkeypatch):
    monkeypatch.setattr(stereo, "PRESETS", dict(TINY_PRESETS))


@pytest.fixture(scope="module")
def demo_sorter(demo):
    """A sorter of the demo, beside the session's ``demo_renderer``."""
    with DepthSorter(demo) as sorter:
        yield sorter


def demo_view(width=96):
    from raygs_viewer.scene.demo import demo_cameras
    return bench_views.training_view(demo_cameras()[0], width)


# --- the sharing error --------------------------------------------------------------------------

def test_demo_sharing_error_at_metre_scale_is_small_and_all_colour(demo_renderer, demo_sorter, gl_ctx):
    errors = bench_stereo.sharing_errors(demo_renderer, demo_sorter, demo_view(), RenderSettings(),
                                         stereo.StereoRig())
    whole, sort_only, colour_only = errors["whole"], errors["sort-only"], errors["colour-only"]
    # The demo has strong view-dependent colour: 63 dB at 320 px; never identical, never large.
    assert 0.0 < whole["max"] < 0.02 and 45.0 < whole["psnr"] < math.inf
    assert whole["max"] >= whole["p99"] >= 0.0
    # The eyes share the midpoint's rotation, so their depths along the axis are the
    # midpoint's: only culling and ties could tell the sorts apart.
    assert sort_only["max"] < 1e-5
    assert colour_only["max"] == pytest.approx(whole["max"], abs=1e-5)


def test_sharing_error_grows_with_the_baseline(demo_renderer, demo_sorter, gl_ctx):
    camera, settings = demo_view(64), RenderSettings()
    near = bench_stereo.sharing_errors(demo_renderer, demo_sorter, camera, settings, stereo.StereoRig())
    small = bench_stereo.sharing_errors(demo_renderer, demo_sorter, camera, settings,
                                        stereo.StereoRig(scene_scale=0.05))
    assert small["whole"]["psnr"] < near["whole"]["psnr"] - 10.0
    assert small["colour-only"]["max"] > 5 * near["colour-only"]["max"]


def test_no_baseline_is_identical(demo_renderer, demo_sorter, gl_ctx):
    errors = bench_stereo.sharing_errors(demo_renderer, demo_sorter, demo_view(64), RenderSettings(),
                                         stereo.StereoRig(ipd=0.0))
    for part in bench_stereo.PARTS:
        assert errors[part] == {"psnr": math.inf, "p99": 0.0, "max": 0.0}, part


@pytest.mark.parametrize("degree", [0, 3])
def test_colour_only_is_zero_exactly_when_colour_ignores_the_view(gl_ctx, degree):
    from raygs_viewer.camera.pinhole import look_at
    scene = random_scene(n=120, seed=4, degree=degree, spread=0.5)
    camera = look_at((0.0, 0.0, -1.6), (0.0, 0.0, 0.0), width=48, height=36)
    with bench_common.scene_renderer(gl_ctx, scene) as (renderer, sorter):  # a large baseline: colour shows
        errors = bench_stereo.sharing_errors(renderer, sorter, camera, RenderSettings(),
                                             stereo.StereoRig(scene_scale=0.1))
    if degree == 0:
        assert errors["colour-only"] == {"psnr": math.inf, "p99": 0.0, "max": 0.0}
    else:
        assert errors["colour-only"]["max"] > 1e-3
        assert errors["whole"]["max"] > 1e-3


def test_one_metre_scale_is_the_inverse_of_the_robust_diagonal():
    rng = np.random.default_rng(0)
    scene = make_scene(rng.uniform(0.0, 2.0, (4000, 3)), 0.01)
    scale, extent = bench_stereo.one_metre_scale(scene)
    assert extent == pytest.approx(2 * scene_bounds(scene.positions)[1])
    assert extent == pytest.approx(1.96 * math.sqrt(3.0), rel=0.02)  # the 1st..99th percentile box's diagonal
    assert scale * extent == pytest.approx(1.0)


# --- the frame budget ---------------------------------------------------------------------------

def test_budget_text():
    assert bench_stereo.budget_text(4.2) == "×4.2 over"
    assert bench_stereo.budget_text(0.63) == "fits, 63 %"
    assert bench_stereo.budget_text(1.0) == "fits, 100 %"
    assert bench_stereo.budget_text(math.nan) == "nan"


class _Log:
    """Stand-ins for the context, the renderer and the sorter that record, in one list,
    every sort, the timer query's span and every eye drawn."""

    def __init__(self, ctx, renderer, sorter, invalid_frames=()):
        self.events, self.ctx, self.renderer, self.sorter = [], ctx, renderer, sorter
        self.invalid_frames, self.frame = set(invalid_frames), 0

    # sorter
    def sort(self, request: SortRequest) -> SortResult:
        self.events.append(("sort", request))
        return self.sorter.sort(request)

    def close(self) -> None:
        pass  # the sorter is the test's

    # renderer
    def render_into(self, target, camera, settings, order, frame=None, color_origin=None, view=None):
        self.events.append(("eye", target.size, camera, order, color_origin))
        return self.renderer.render_into(target, camera, settings, order, frame=frame, color_origin=color_origin,
                                         view=view)

    # context
    def framebuffer(self, *args, **kwargs):
        return self.ctx.framebuffer(*args, **kwargs)

    def texture(self, *args, **kwargs):
        return self.ctx.texture(*args, **kwargs)

    @property
    def info(self):
        return self.ctx.info

    def query(self, **kwargs):
        real, log = self.ctx.query(**kwargs), self

        class Query:
            def __enter__(self):
                log.events.append(("begin",))
                real.__enter__()

            def __exit__(self, *exc):
                real.__exit__(*exc)
                log.events.append(("end",))

            @property
            def elapsed(self):
                value = real.elapsed
                log.frame += 1
                return INVALID_ELAPSED if log.frame - 1 in log.invalid_frames else value

        return Query()


def _same_camera(a, b) -> bool:
    return (a.width, a.height, a.fx, a.fy, a.cx, a.cy) == (b.width, b.height, b.fx, b.fy, b.cx, b.cy) \
        and np.array_equal(a.R, b.R) and np.array_equal(a.t, b.t)


def test_both_eyes_are_drawn_with_one_order_under_one_query(demo_renderer, demo_sorter, gl_ctx):
    camera = TINY_PRESETS["tiny"].camera(demo_view())
    rig = stereo.StereoRig()
    log = _Log(gl_ctx, demo_renderer, demo_sorter, invalid_frames={2})
    gpu, sort = bench_stereo.time_both_eyes(log, log, log, camera, RenderSettings(), rig=rig, repeat=3)
    assert len(gpu) == len(sort) == 3  # the warm-up frame is not kept
    assert math.isnan(gpu[1]) and all(t > 0 for i, t in enumerate(gpu) if i != 1)  # frame 2: the invalid one
    assert all(t > 0 for t in sort)
    left, right = stereo.eye_cameras(camera, rig)
    frames = [log.events[i:i + 5] for i in range(0, len(log.events), 5)]
    assert len(frames) == 4 and len(log.events) == 20
    for sorted_, begin, first, second, end in frames:  # the sort before the query, untimed by it
        assert sorted_[0] == "sort" and begin == ("begin",) and end == ("end",)
        assert _same_camera(sorted_[1].camera, camera) and first[3].answers(sorted_[1])
        assert _same_camera(first[2], left) and _same_camera(second[2], right)
        assert first[1] == second[1] == (24, 20)  # eye-sized targets ...
        assert first[3] is second[3]  # ... one order for both eyes ...
        for eye in (first, second):  # ... colour from the midpoint
            assert np.array_equal(eye[4], camera.center)
    expected = stereo_frame.stereo_order(demo_sorter, camera, RenderSettings(), rig)
    assert np.array_equal(frames[0][2][3].indices, expected.indices)


# --- the whole benchmark, tiny ------------------------------------------------------------------

TINY = ["--width", "16", "--repeat", "2", "--presets", "tiny", "narrow"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, gl_session_ctx):
    """One command over the demo and a small PLY with the tiny presets: (args, stdout)."""
    gl_session_ctx.__enter__()
    folder = tmp_path_factory.mktemp("bench_stereo")
    ply = write_ply(folder / "blobs.ply", gaussian_columns(n=30, degree=1, seed=2))
    args = parse("--scenes", "demo", ply, *TINY, "--out", folder / "stereo.md")
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(printed):
        patch.setattr(stereo, "PRESETS", dict(TINY_PRESETS))
        assert bench_cli.command(args, gl_session_ctx) == 0
    return args, printed.getvalue()


def _value(out, line_head):
    match = re.search(rf"^{re.escape(line_head)} (\S+)$", out, re.M)
    assert match, f"no line '{line_head} VALUE'"
    return float(match.group(1))


def test_tiny_run_prints_every_machine_line(tiny_run):
    out = tiny_run[1]
    for scene in ("demo", "blobs"):
        for preset in TINY_PRESETS:
            ms = _value(out, f"stereo-budget {scene} {preset} ms")
            assert ms > 0 and _value(out, f"stereo-budget {scene} {preset} sort-ms") > 0
            for rate in stereo.REFRESH_RATES:
                assert _value(out, f"stereo-budget {scene} {preset} fraction-of-{rate}Hz") == \
                    pytest.approx(ms * rate / 1000, rel=1e-4)
        for view in bench_stereo.VIEWS:
            for scale in bench_stereo.SCALES:
                for prefix in bench_stereo.PARTS.values():
                    psnr = _value(out, f"stereo-error {scene} {view} {scale} {prefix}psnr")
                    worst = _value(out, f"stereo-error {scene} {view} {scale} {prefix}max")
                    assert worst >= _value(out, f"stereo-error {scene} {view} {scale} {prefix}p99") >= 0
                    assert (psnr == math.inf) == (worst == 0.0)
        assert _value(out, f"stereo-error {scene} training 1m-across scene-scale") > 0
    assert len(re.findall(r"^stereo-budget ", out, re.M)) == 2 * 2 * (2 + len(stereo.REFRESH_RATES))


def test_tiny_report_has_both_tables(tiny_run):
    args, out = tiny_run
    report = open(args.out, encoding="utf-8").read()
    assert report.strip() in out  # the file is what was printed
    assert f"- Command: `{bench_cli.stereo_command_line(args)}`" in report
    assert re.search(r"^- Machine: .+, OpenGL .+, \d+ CPU cores$", report, re.M)
    budget = [line for line in report.split("## Frame budget", 1)[1].splitlines() if line.startswith("| ")][1:]
    assert [row.split(" | ")[:3] for row in budget] == [
        [f"| {scene}", preset.label, f"{preset.width}×{preset.height}"]
        for scene in ("demo", "blobs") for preset in TINY_PRESETS.values()]
    for row in budget:
        cells = row.strip("| ").split(" | ")
        assert len(cells) == 5 + len(stereo.REFRESH_RATES)
        assert all(re.fullmatch(r"×\d+\.\d over|fits, \d+ %", cell) for cell in cells[5:]), row
    sharing = report.split("## What sharing costs", 1)[1].split("## Frame budget", 1)[0]
    rows = [line for line in sharing.splitlines() if line.startswith("| ")][1:]
    assert len(rows) == 2 * len(bench_stereo.VIEWS) * len(bench_stereo.SCALES)
    assert sum("(1 m across)" in row for row in rows) == len(rows) // 2


def test_the_recorded_command_line_reproduces_the_options(tiny_run):
    args = tiny_run[0]
    again = parse(*shlex.split(bench_cli.stereo_command_line(args))[3:])
    assert vars(again) == vars(args)


def test_out_is_never_replaced_without_overwrite(tiny_run, monkeypatch, tiny_presets):
    args = tiny_run[0]
    before = open(args.out, encoding="utf-8").read()
    monkeypatch.setattr(bench_stereo, "run_stereo", lambda *a, **k: pytest.fail("ran before refusing"))
    assert_user_error(lambda: bench_cli.command(parse("--scenes", "demo", *TINY, "--out", args.out)),
                      args.out, "already exists", "--overwrite")
    assert open(args.out, encoding="utf-8").read() == before
    assert_user_error(lambda: bench_cli.command(parse("--out", args.out + ".txt")), "stereo.md.txt", ".md")


def test_overwrite_replaces_the_report(gl_ctx, tmp_path, tiny_presets, capsys):
    path = tmp_path / "stereo.md"
    path.write_text("old", encoding="utf-8")
    assert bench_cli.command(parse("--scenes", "demo", *TINY, "--out", path, "--overwrite"), gl_ctx) == 0
    text = path.read_text(encoding="utf-8")
    assert text.startswith("# Stereo") and "--overwrite" in text
    assert not list(tmp_path.glob(".*partial"))
    capsys.readouterr()


# --- errors and the command line -----------------------------------------------------------------

def test_unknown_preset_is_a_one_line_error_before_any_work(monkeypatch, capsys):
    monkeypatch.setattr(bench_stereo, "run_stereo", lambda *a, **k: pytest.fail("ran before refusing"))
    message = assert_user_error(lambda: bench_cli.command(parse("--presets", "quest3", "vive")),
                                "vive", "unknown headset preset", "quest3, index, generic90")
    assert "'vive'" in message
    assert main(["bench", "stereo", "--presets", "vive"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: unknown headset preset 'vive'") and err.count("\n") == 1


def test_missing_scene_is_a_one_line_error(tmp_path, tiny_presets):
    missing = tmp_path / "missing.ply"
    assert_user_error(lambda: bench_cli.command(parse("--scenes", "demo", missing, *TINY)), missing, "no such file")


def test_cli_parses_quick():
    args = build_parser().parse_args(["bench", "stereo", "--quick"])
    assert (args.command, args.bench, args.quick) == ("bench", "stereo", True)
    options = bench_cli.stereo_options(args)
    assert options.scenes == ("demo",) and options.repeat == bench_stereo.QUICK_REPEAT == 3
    assert options.presets == tuple(stereo.PRESETS) and options.width == 320 and options.out is None
    assert options.command_line == "raygs-viewer bench stereo --quick"
    full = bench_cli.stereo_options(build_parser().parse_args(["bench", "stereo", "--presets", "index", "index"]))
    assert full.repeat == 10 and full.presets == ("index",) and full.scenes[0] == "demo"
    if bench_common.shared_scenes_dir() is not None:
        assert len(full.scenes) == 1 + len(bench.REAL_SCENES) - len(full.notes)


def test_cli_runs_it(capsys, tiny_presets, restore_gl_ctx):
    assert main(["bench", "stereo", "--scenes", "demo", *TINY[:4], "--presets", "narrow"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^stereo-budget demo narrow fraction-of-90Hz \S+$", out, re.M)
    assert "| demo | narrow headset | 16×16 |" in out


def test_bench_help_names_stereo(capsys):
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    assert "stereo" in capsys.readouterr().out
