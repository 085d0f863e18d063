"""``raygs-viewer bench sort``: the window's sort timeline, the motions, the fitted
scaling, the 1 dB crossing, the summary line, a tiny end-to-end run and the command line."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from testkit import run_cli

from raygs_viewer.bench import cube, freshness, sort_timing
from raygs_viewer.bench import sort as bench_sort
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.cli.main import build_parser
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import SortRequest

FRAME = 1 / 60


def frames_of(times) -> list[int]:
    """View times as whole frame numbers."""
    return [int(Fraction(t).limit_denominator(1000) * 60) for t in times]


def test_the_timeline_draws_the_newest_finished_order():
    """26 ms sorts at 60 fps (frames every 16.7 ms), by hand: frame 1 asks for view 1
    (ready at 42.7 ms); frame 2's request waits, starts at 42.7 (ready 68.7); frame 3's
    waits and frame 4's replaces it, starting at 68.7 (ready 94.7); 5 starts at 94.7
    (ready 120.7); 6 is replaced by 7, which starts at 120.7. Each frame draws the
    newest order finished by its time."""
    drawn = frames_of(freshness.drawn_views(0.026, 60.0, 9))
    assert drawn == [0, 0, 0, 1, 1, 2, 4, 4, 5]


def test_a_sort_faster_than_a_frame_is_drawn_one_frame_late_and_an_instant_one_at_once():
    assert frames_of(freshness.drawn_views(0.004, 60.0, 6)) == [0, 0, 1, 2, 3, 4]
    assert frames_of(freshness.drawn_views(0.0, 60.0, 4)) == [0, 1, 2, 3]


def test_a_slow_sort_skips_views_and_the_age_stays_between_one_and_two_latencies():
    latency = 0.1
    drawn = freshness.drawn_views(latency, 60.0, 120)
    assert drawn == sorted(drawn)
    ages = [frame * FRAME - view for frame, view in enumerate(drawn)][12:]
    assert min(ages) >= latency - 1e-9 and max(ages) <= 2 * latency + FRAME + 1e-9
    assert 18 <= len(set(drawn)) <= 21  # one new order every 100 ms or so


def test_the_motions_turn_in_place_and_fly_forward():
    start = cube.view_camera(32, 24)
    turned = cube.moved(start, "turn", 0.5)
    np.testing.assert_allclose(turned.center, start.center, atol=1e-12)
    cosine = np.dot(turned.R[2], start.R[2])
    assert math.degrees(math.acos(np.clip(cosine, -1, 1))) == pytest.approx(45.0)
    flown = cube.moved(start, "fly", 2.0)
    np.testing.assert_allclose(flown.center - start.center, start.R[2] * cube.SCENE_RADIUS, atol=1e-12)
    with pytest.raises(ValueError):
        cube.moved(start, "roll", 1.0)


def test_the_view_sees_the_whole_generated_scene():
    scene = cube.generated_scene(2000, seed=1)
    assert scene.count == 2000 and scene.sh_degree == 0
    assert 0.1 <= scene.opacities.min() and scene.opacities.max() <= 0.9
    with DepthSorter(scene, 1) as sorter:
        visible = sorter.cull(SortRequest(cube.view_camera(64, 36), sort_timing.P_MIN))
    assert visible.size == scene.count


def test_amdahl_fits_serial_and_parallel_parts():
    assert sort_timing.amdahl({1: 10.0, 2: 6.0}, 16) == pytest.approx(2.0 + 8.0 / 16)
    # Better than linear (a cache effect): no serial part, the mean work of the counts.
    assert sort_timing.amdahl({1: 10.0, 2: 4.0}, 16) == pytest.approx(9.0 / 16)
    assert sort_timing.amdahl({1: 10.0}, 16) == 10.0


def test_the_one_db_crossing_is_interpolated_or_bounded():
    assert freshness.crossing([(10.0, 0.5), (30.0, 1.5)]) == "20"
    assert freshness.crossing([(10.0, 0.2), (30.0, 0.9)]) == ">30"
    assert freshness.crossing([(10.0, 2.0), (30.0, 3.0)]) == "<10"
    assert freshness.crossing([(10.0, 0.5), (20.0, math.nan)]) == ">10"
    assert freshness.crossing([(20.0, math.nan)]) == "n/a"


def test_summary_lines_read_like_the_issue():
    assert sort_timing.summary_line(1_000_000, 18.34) == "cull+sort@1M 18.3 ms"
    assert sort_timing.summary_line(3_000_000, 52.0) == "cull+sort@3M 52.0 ms"
    assert sort_timing.summary_line(100_000, 1.25) == "cull+sort@100k 1.2 ms"
    assert (sort_timing.summary_line(3_000_000, 31.3, 240.0)
            == "cull+sort@3M 31.3 ms (0.13x the naive one-liner's 240 ms)")


def test_the_naive_one_liner_keeps_what_is_in_front_farthest_first_ties_in_scene_order():
    from raygs_viewer.camera.pinhole import look_at

    positions = np.array([[0, 0, 1], [0, 0, 3], [0, 0, -5], [5, 0, 3], [0, 0, 2], [0, 0, 3]], np.float32)
    camera = look_at((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), width=8, height=8)
    # depths 2, 4, -4 (behind: dropped), 4, 3, 4: the three at 4 in scene order, then 3, 2
    np.testing.assert_array_equal(sort_timing.naive_order(positions, camera), [1, 3, 5, 4, 0])


def test_the_drawn_order_is_as_old_as_the_sort_makes_it():
    assert freshness.frames_old(0.0, 60.0) == 0.0      # the frame's own order (the GPU sort)
    assert freshness.frames_old(0.005, 60.0) == pytest.approx(1.0)  # faster than a frame: drawn one late
    assert freshness.frames_old(0.005, 90.0) == pytest.approx(1.0)
    slow = freshness.frames_old(0.1, 60.0)
    assert 6 <= slow <= 2 * 6 + 1 and freshness.frames_old(0.1, 90.0) > slow  # more frames at 90 Hz


def test_a_tiny_run_times_every_worker_count_and_measures_every_order(gl_ctx, monkeypatch):
    monkeypatch.setattr(freshness, "RENDER_SIZE", (40, 30))
    monkeypatch.setattr(bench_sort, "worker_counts", lambda: (1, 2))
    monkeypatch.setattr(bench_sort, "LOAD_MIN", 2000)  # loads measured from 2k up: this run's 3k and 5k
    options = bench_sort.SortOptions(counts=(1000, 3000, 5000), repeat=2, sample_times=(0.1,), ladder_frames=(4,),
                                     freshness_max=3000)
    with open("/dev/null", "w") as out:
        results = bench_sort.run_sort(options, gl_ctx, out=out)
    small, scene, large = results.scenes
    assert (small.count, large.count) == (1000, 5000) and large.timings[1].visible == 5000
    assert small.freshness and not large.freshness  # the freshness up to freshness_max only
    [(count, load), (five, _)] = results.loads
    assert five == 5000
    assert count == 3000 and load.seconds > 0 and load.peak_bytes > 0
    assert 3000 * 62 * 4 < load.file_bytes < 3000 * 62 * 4 + 4096  # the rows and a header
    assert set(scene.timings) == {1, 2} and scene.timings[1].visible == 3000
    for timing in (*scene.timings.values(), scene.one_thread):
        assert timing.total > 0 and timing.sort > 0 and timing.distance_turn > 0 and timing.keys >= 0
    assert scene.upload_ms > 0
    rows = {(r.sweep, r.mode, r.cores) for r in scene.freshness}
    for sweep in cube.SWEEPS:
        for mode in freshness.MODES:
            assert {(sweep, mode, cores) for cores in ("1", "2", "16 (projected)")} <= rows
        assert {(sweep, mode, "ladder") for mode in freshness.MODES} <= rows
    ladder = [r for r in scene.freshness if r.cores == "ladder" and r.mode == "depth" and r.sweep == "turn"][0]
    assert ladder.latency_ms == pytest.approx(1e3 * 4 / 60) and ladder.age_ms > 60
    assert ladder.psnr_vs_fresh < 60  # four frames of a 90 deg/s turn change the image
    assert all(math.isnan(r.loss_db) for r in scene.freshness if r.mode == "per-pixel")
    report = bench_sort.format_report(results)
    assert "## Loading" in report and "\nload@3k " in report
    assert "| 3k | 2 on one thread |" in report and "\ncull+sort@3k " in report and "speed-up@3k " in report
    assert "1db-age@3k/turn/depth" in report and "1db-age@5k" not in report and "\ncull+sort@5k " in report
    # The naive one-liner beside it, the GPU sort (the same order: it is checked), the age.
    assert scene.naive_ms > 0 and scene.naive_ratio == pytest.approx(scene.timings[2].total / scene.naive_ms)
    assert scene.gpu_note == "" and scene.gpu_ms > 0
    assert "the naive one-liner's" in report and "\ngpu-sort@3k " in report and "(GPU timer " in report
    assert "\norder-age@3k/60Hz cpu " in report and "\norder-age@3k/90Hz cpu " in report and ", gpu 0" in report


def test_options_and_recorded_command():
    args = build_parser().parse_args(["bench", "sort", "--quick", "--repeat", "3"])
    options = bench_cli.sort_options(args)
    assert options.counts == bench_sort.QUICK_COUNTS and options.counts[-1] == 3_000_000
    assert options.repeat == 3 and options.freshness
    # --quick keeps the times and loads of every size (cull+sort@1M and @3M) but renders the
    # motions of the small scene only: those of 1M and 3M take over 20 minutes on two cores.
    assert options.freshness_max == 100_000 and options.loads
    assert options.sample_times == freshness.QUICK_SAMPLE_TIMES
    assert options.command_line == "raygs-viewer bench sort --quick --repeat 3"
    full = bench_cli.sort_options(build_parser().parse_args(["bench", "sort", "--no-freshness"]))
    assert full.counts == bench_sort.COUNTS and full.counts[-1] == 6_000_000 and not full.freshness
    assert (full.freshness_max, full.repeat) == (None, bench_sort.DEFAULT_REPEAT)
    assert full.sample_times == freshness.SAMPLE_TIMES and full.ladder_frames == freshness.LADDER_FRAMES


def test_the_command_prints_the_summary(capsys, monkeypatch):
    monkeypatch.setattr(bench_sort, "worker_counts", lambda: (1, 2))
    code, out, _ = run_cli(capsys, "bench", "sort", "--counts", "2000", "--repeat", "1", "--no-freshness")
    assert code == 0 and "\ncull+sort@2k " in out and "cull+sort-2-workers@2k " in out


@pytest.mark.parametrize("argv", [["--counts", "0"], ["--repeat", "0"]])
def test_bad_options_are_one_line_errors(capsys, argv):
    code, _, err = run_cli(capsys, "bench", "sort", *argv)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
