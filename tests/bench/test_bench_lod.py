"""``bench lod``: a tiny streamed scene end to end, the numbers that can be checked
exactly (the finest level against itself and a budget that holds it, the budget never
exceeded unless the coarsest level alone does, fewer gaussians at 10 % than at 25 %),
and the command line's scenes. No timing is asserted."""

from __future__ import annotations

import math

import pytest
from lod_kit import random_gaussians, write_streamed_sog
from testkit import assert_one_line_error, run_cli

from raygs_viewer.bench import lod as bench_lod
from raygs_viewer.cli import bench as bench_cli
from raygs_viewer.cli.main import build_parser

#: Gaussians of each leaf at levels 0, 1, 2: the coarsest holds 1/12 of the finest
#: (below the 10 % budget), a step to level 1 costs 20 (one fits in 25 %, none in 10 %).
PER_LEVEL = (48, 24, 4)
LEAVES = 4
ENVIRONMENT = 8


@pytest.fixture(scope="module")
def streamed(tmp_path_factory):
    """Four leaves side by side along x, three levels each, and an environment."""
    leaves = [[random_gaussians(n, centre=(3.0 * k, 0.0, 0.0), spread=0.5, scale=0.08, seed=10 * k + level)
               for level, n in enumerate(PER_LEVEL)] for k in range(LEAVES)]
    environment = random_gaussians(ENVIRONMENT, spread=30.0, scale=0.5, seed=99)
    return write_streamed_sog(tmp_path_factory.mktemp("lod"), leaves, environment=environment)


def _run(path, gl_ctx, distance):
    options = bench_lod.LodOptions((str(path),), width=32, repeat=1, distance=distance, command_line="bench lod")
    return bench_lod.run_lod(options, gl_ctx)


def test_every_leaf_near_the_budgets_against_the_finest_level(streamed, gl_ctx, capsys):
    # A first level distance beyond the scene: every leaf wants level 0 in every view.
    results = _run(streamed, gl_ctx, distance=1e6)
    (info,) = results.scenes
    finest_count = LEAVES * PER_LEVEL[0]
    assert info.counts == tuple(LEAVES * n for n in PER_LEVEL) and info.environment == ENVIRONMENT
    assert info.finest == 0 and info.leaves == LEAVES and not info.unread
    assert [v.view for v in results.views] == list(bench_lod.VIEWS)
    budgets = {"100%": finest_count + ENVIRONMENT, "50%": finest_count // 2 + ENVIRONMENT,
               "25%": finest_count // 4 + ENVIRONMENT, "10%": round(0.1 * finest_count) + ENVIRONMENT}
    coarsest = LEAVES * PER_LEVEL[-1] + ENVIRONMENT
    for view in results.views:
        assert [row.case for row in view.rows] == list(bench_lod.CASES)
        finest, full = view.row(bench_lod.FINEST), view.row("100%")
        assert finest.chosen == finest_count + ENVIRONMENT and finest.per_level == (LEAVES, 0, 0)
        assert finest.psnr == math.inf and finest.max_abs == 0 and finest.ratios["drawn"] == 1
        # The finest level fits its own budget: the same gaussians, the same image.
        assert full.per_level == (LEAVES, 0, 0) and full.chosen == finest.chosen and full.drawn == finest.drawn
        assert full.psnr == math.inf and full.max_abs == 0 and full.ratios["drawn"] == 1
        for row in view.rows[1:]:
            assert row.budget == budgets[row.case]
            assert row.drawn <= row.chosen and row.counted <= row.chosen
            assert row.over_budget == (coarsest > row.budget)
            if not row.over_budget:
                assert row.counted <= row.budget
        ten, quarter = view.row("10%"), view.row("25%")
        assert not ten.over_budget and ten.chosen == coarsest and ten.per_level == (0, 0, LEAVES)
        assert ten.chosen < quarter.chosen and ten.drawn < quarter.drawn
        assert 0 < ten.psnr < math.inf and ten.max_abs > 0
    out = capsys.readouterr().out
    assert f"lod {info.name} framing 100% psnr inf" in out and f"lod {info.name} closer 10% drawn " in out
    report = bench_lod.format_report(results)
    assert report.count("| finest level |") == len(bench_lod.VIEWS) and "| 10% |" in report


def test_a_budget_under_the_coarsest_level_draws_it_and_says_so(streamed, gl_ctx):
    results = bench_lod.run_lod(bench_lod.LodOptions((str(streamed),), width=24, repeat=1, command_line="x"),
                                gl_ctx)
    for view in results.views:
        for row in view.rows[1:]:
            if row.over_budget:  # the coarsest levels alone: drawn anyway, and only they
                assert row.counted > row.budget and row.per_level[-1] > 0
            else:
                assert row.counted <= row.budget


def test_the_command_line_takes_streamed_scenes_only(streamed, tmp_path, capsys, monkeypatch):
    args = build_parser().parse_args(["bench", "lod", "--quick", "--scenes", str(streamed.parent),
                                      "--lod-distance", "2.5"])
    options = bench_cli.lod_options(args)
    assert options.width == bench_lod.QUICK_WIDTH and options.repeat == bench_lod.QUICK_REPEAT
    assert options.distance == 2.5 and options.scenes == (str(streamed.parent),)
    assert options.command_line.startswith("raygs-viewer bench lod --quick --scenes ")
    plain = tmp_path / "plain.ply"
    plain.write_text("ply\n")
    err = assert_one_line_error(*run_cli(capsys, "bench", "lod", "--scenes", plain)[::2])
    assert "not a streamed SOG" in err
    empty = tmp_path / "shared" / "scenes"
    empty.mkdir(parents=True)
    monkeypatch.setattr(bench_cli, "shared_scenes_dir", lambda: empty)
    err = assert_one_line_error(*run_cli(capsys, "bench", "lod")[::2])
    assert "pass --scenes" in err
    (empty / "sub").mkdir()
    (empty / "sub" / "lod-meta.json").write_text("{}")
    found = bench_cli.lod_options(build_parser().parse_args(["bench", "lod"]))
    assert [s.replace("\\", "/").endswith("sub/lod-meta.json") for s in found.scenes] == [True]
