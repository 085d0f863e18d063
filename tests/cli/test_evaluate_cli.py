"""``raygs-viewer evaluate``: the contract command's JSON, the report formats and the
contact sheet, settings options, skipped photos, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from noisy_kit import write_noisy_dataset
from testkit import assert_one_line_error, listing, run_cli

from raygs_viewer.photos.metrics import LPIPS_MISSING, psnr, ssim_3dgs


@pytest.fixture
def inria(tmp_path, gl_render):
    return write_noisy_dataset(tmp_path / "data", "inria", gl_render)


def test_the_contract_command_writes_views_and_means(tmp_path, capsys, inria):
    out = tmp_path / "r.json"
    code, stdout, stderr = run_cli(capsys, "evaluate", inria.path, "--images", inria.images, "--split", "all",
                                   "--out", out)
    assert code == 0, stderr
    document = json.loads(out.read_text())
    views = document["views"]
    assert [Path(view["name"]).stem for view in views] == inria.names
    for view, photo, render in zip(views, inria.photos, inria.renders):
        assert view["psnr"] == pytest.approx(psnr(photo, render), abs=1e-4)
        assert view["ssim"] == pytest.approx(ssim_3dgs(photo, render), abs=1e-5)
        assert 0.0 < view["flip"] < 1.0 and view["lpips"] is None
    assert document["mean"]["psnr"] == pytest.approx(np.mean([view["psnr"] for view in views]))
    assert document["mean"]["ssim"] == pytest.approx(np.mean([view["ssim"] for view in views]))
    assert document["skipped"] == [] and document["split"] == "all"
    assert f"{len(views)} views: PSNR {document['mean']['psnr']:.3f} dB" in stdout
    assert f"evaluate: {len(views)}/{len(views)}" in stderr and LPIPS_MISSING in stderr
    assert listing(tmp_path) == ["data", "r.json", "r.worst.png"]


def test_markdown_report_and_settings_options(tmp_path, capsys, inria):
    code, _, stderr = run_cli(capsys, "evaluate", inria.path, "--out", tmp_path / "raygs.md")
    assert code == 0, stderr
    code, _, stderr = run_cli(capsys, "evaluate", inria.path, "--mode", "gs", "--out", tmp_path / "gs.md")
    assert code == 0, stderr
    raygs, gs = (tmp_path / "raygs.md").read_text(), (tmp_path / "gs.md").read_text()
    assert "view_000" in raygs and "view_008" in raygs and "view_001" not in raygs  # the test split
    assert "raygs.worst.png" in raygs and "mode gs" in gs
    assert raygs.split("## ")[0].replace("raygs", "") != gs.split("## ")[0].replace("gs", "")
    # Written once: again without --overwrite is refused before any work.
    code, _, err = run_cli(capsys, "evaluate", inria.path, "--out", tmp_path / "gs.md")
    assert "already exists" in assert_one_line_error(code, err)
    code, _, err = run_cli(capsys, "evaluate", inria.path, "--out", tmp_path / "gs.md", "--overwrite",
                           "--limit", "1")
    assert code == 0, err
    assert "view_008" not in (tmp_path / "gs.md").read_text()


def test_a_missing_photo_is_skipped_and_counted(tmp_path, capsys, gl_render):
    data = write_noisy_dataset(tmp_path / "data", "nerfstudio", gl_render)
    (data.images / "view_008.png").unlink()
    out = tmp_path / "r.csv"
    code, stdout, stderr = run_cli(capsys, "evaluate", data.path, "--scene", data.scene, "--out", out)
    assert code == 0, stderr
    assert "1 views (1 skipped)" in stdout and "skipped: " in stderr and "view_008" in stderr
    rows = out.read_text().splitlines()
    assert rows[0] == "name,psnr,ssim,flip,lpips,skipped" and "view_008" in rows[2] and rows[-1].startswith("(mean)")


def test_bad_input_is_one_line(tmp_path, capsys, gl_render):
    data = write_noisy_dataset(tmp_path / "data", "colmap", gl_render)
    code, _, err = run_cli(capsys, "evaluate", data.path, "--out", tmp_path / "r.json")
    assert "--scene" in assert_one_line_error(code, err)
    code, _, err = run_cli(capsys, "evaluate", tmp_path / "nowhere")
    assert "nowhere" in assert_one_line_error(code, err)
    code, _, err = run_cli(capsys, "evaluate", data.path, "--scene", data.scene, "--out", tmp_path / "r.txt")
    assert "r.txt" in assert_one_line_error(code, err)
    for image in data.images.iterdir():
        image.unlink()
    code, _, err = run_cli(capsys, "evaluate", data.path, "--scene", data.scene, "--split", "test")
    # Each skipped view is named on its own line first; the error is the last line.
    assert code == 2 and err.count("skipped: ") == 2
    assert err.splitlines()[-1].startswith("error: none of the 2 views could be evaluated")
    assert "--images FOLDER" in err.splitlines()[-1]  # says how to point at the photos


def test_an_unusable_out_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """The report's folder is checked (exists, is a folder, may be written in) before the
    dataset is read or anything rendered. The unwritable folder is simulated: these tests
    may run as root, whom permission bits do not stop."""
    import os

    import raygs_viewer.cli.evaluate as cli

    monkeypatch.setattr(cli, "open_dataset", lambda *a, **k: pytest.fail("dataset read before --out was checked"))
    locked, a_file = tmp_path / "locked", tmp_path / "file"
    locked.mkdir()
    a_file.write_text("")
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if Path(p) == locked else real_access(p, mode))
    for out, fragment in ((locked / "r.json", "not writable"), (a_file / "r.json", "(it is a file)"),
                          (tmp_path / "no" / "r.json", "does not exist")):
        code, _, err = run_cli(capsys, "evaluate", tmp_path / "model", "--out", out)
        assert fragment in assert_one_line_error(code, err) and str(out) in err
