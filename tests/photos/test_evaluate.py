"""evaluate() and its reports on datasets made on the fly (each layout), whose photos are
GL renders plus known noise: the reported metrics equal those computed directly from
the same arrays; skipped photos, Ctrl-C, the report formats."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from noisy_kit import NOISE, write_noisy_dataset
from raygs_viewer.errors import UserError
from raygs_viewer.photos import report
from raygs_viewer.photos.dataset import open_dataset, select_split
from raygs_viewer.photos.evaluate import EvaluationResult, SkippedView, ViewScore, evaluate
from raygs_viewer.photos.metrics import SSIM_KIND, flip, psnr, ssim_3dgs
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.io import load_scene


def stem(name: str) -> str:
    return Path(name).stem


@pytest.fixture
def renderer_of(gl_ctx):
    made = []

    def make(scene_path):
        made.append(GLRenderer(gl_ctx, load_scene(scene_path)))
        return made[-1]

    yield make
    for renderer in made:
        renderer.release()


@pytest.mark.parametrize("layout", ["inria", "colmap", "nerfstudio"])
def test_reported_metrics_equal_those_of_the_same_arrays(tmp_path, gl_render, renderer_of, layout):
    data = write_noisy_dataset(tmp_path, layout, gl_render)
    dataset = open_dataset(data.path)
    views = select_split(dataset.views, "all")
    result = evaluate(dataset, views, renderer_of(data.scene), RenderSettings())
    assert not result.skipped and not result.interrupted and result.total == len(data.names)
    assert [stem(score.name) for score in result.scores] == data.names
    for score, photo, render in zip(result.scores, data.photos, data.renders):
        assert score.psnr == pytest.approx(psnr(photo, render), abs=1e-4)
        assert score.ssim == pytest.approx(ssim_3dgs(photo, render), abs=1e-5)
        assert score.flip == pytest.approx(flip(photo, render), abs=1e-4)
        assert score.lpips is None
    # The noise sets the PSNR: about -20 log10(NOISE), less where clipping at 0 cuts it.
    mean = result.mean()
    assert mean["psnr"] == pytest.approx(np.mean([s.psnr for s in result.scores]))
    assert -20 * math.log10(NOISE) - 0.5 < mean["psnr"] < -20 * math.log10(NOISE) + 4
    assert 0.0 < mean["ssim"] < 0.99 and mean["lpips"] is None


def test_the_test_split_is_every_eighth_view(tmp_path, gl_render, renderer_of):
    data = write_noisy_dataset(tmp_path, "inria", gl_render)
    dataset = open_dataset(data.path)
    result = evaluate(dataset, select_split(dataset.views, "test"), renderer_of(data.scene), RenderSettings())
    assert [stem(score.name) for score in result.scores] == [data.names[0], data.names[8]]


def test_a_missing_photo_is_skipped_with_its_reason_and_the_rest_goes_on(tmp_path, gl_render, renderer_of):
    data = write_noisy_dataset(tmp_path, "colmap", gl_render)
    (data.images / "view_003.png").unlink()
    dataset = open_dataset(data.path)
    views = select_split(dataset.views, "all")
    result = evaluate(dataset, views, renderer_of(data.scene), RenderSettings())
    assert len(result.scores) == len(views) - 1 and result.done == result.total == len(views)
    (skipped,) = result.skipped
    assert stem(skipped.name) == "view_003" and "view_003" in skipped.reason and "\n" not in skipped.reason


def test_ctrl_c_keeps_the_views_done(tmp_path, gl_render, renderer_of):
    data = write_noisy_dataset(tmp_path, "nerfstudio", gl_render)
    dataset = open_dataset(data.path)
    seen = []

    def progress(done, total, name):
        seen.append((done, total))
        if done == 3:
            raise KeyboardInterrupt

    result = evaluate(dataset, select_split(dataset.views, "all"), renderer_of(data.scene), RenderSettings(),
                      progress=progress)
    assert result.interrupted and len(result.scores) == 3 and seen == [(1, 9), (2, 9), (3, 9)]
    document = report.report_document(result)
    assert document["interrupted"] is True and len(document["views"]) == 3
    assert "interrupted" in report.report_markdown(result)


def test_settings_change_the_render_and_the_background_is_the_datasets(tmp_path, gl_render, renderer_of):
    data = write_noisy_dataset(tmp_path, "inria", gl_render)
    dataset = open_dataset(data.path)
    views = select_split(dataset.views, "test")
    renderer = renderer_of(data.scene)
    raygs = evaluate(dataset, views, renderer, RenderSettings())
    gs = evaluate(dataset, views, renderer, RenderSettings(mode="gs"))
    assert [a.psnr for a in raygs.scores] != pytest.approx([b.psnr for b in gs.scores], abs=1e-3)
    # A background given in the settings yields to the model's (black here).
    grey = evaluate(dataset, views, renderer, RenderSettings(background=(0.5, 0.5, 0.5)))
    assert grey.settings.background == (0.0, 0.0, 0.0)
    assert [a.psnr for a in grey.scores] == pytest.approx([a.psnr for a in raygs.scores])


# --- reports, without rendering ------------------------------------------------------------------

def made_result() -> EvaluationResult:
    result = EvaluationResult(RenderSettings(mode="gs"), total=4)
    result.scores += [ViewScore("a.png", 30.0, 0.9, 0.1), ViewScore("b.png", 20.0, 0.7, 0.3),
                      ViewScore("same.png", math.inf, 1.0, 0.0)]
    result.skipped.append(SkippedView("c.png", "images/c.png: not found"))
    result.lpips_note = "LPIPS: not installed (pip install raygs-viewer[lpips])"
    return result


def test_json_report_has_the_contract_fields(tmp_path):
    path = report.write_report(tmp_path / "r.json", made_result(), {"split": "all"})
    document = json.loads(path.read_text())
    assert [view["name"] for view in document["views"]] == ["a.png", "b.png", "same.png"]
    assert document["views"][0] == {"name": "a.png", "psnr": 30.0, "ssim": 0.9, "flip": 0.1, "lpips": None}
    assert document["views"][2]["psnr"] is None  # infinite: JSON has no infinity
    assert document["mean"]["psnr"] is None and document["mean"]["ssim"] == pytest.approx(2.6 / 3)
    assert document["skipped"] == [{"name": "c.png", "reason": "images/c.png: not found"}]
    assert document["settings"]["mode"] == "gs" and document["ssim_kind"] == SSIM_KIND
    assert document["split"] == "all" and "not installed" in document["lpips_note"]


def test_csv_and_markdown_reports(tmp_path):
    result = made_result()
    rows = list(csv.DictReader(io.StringIO(report.report_csv(result))))
    assert [row["name"] for row in rows] == ["a.png", "b.png", "same.png", "c.png", "(mean)"]
    assert rows[1]["psnr"] == "20.000" and rows[2]["psnr"] == "inf" and rows[3]["skipped"].endswith("not found")
    text = report.report_markdown(result, sheet=tmp_path / "r.worst.png")
    worst = text[text.index("worst views"):]
    assert worst.index("b.png") < worst.index("a.png") < worst.index("same.png")  # by PSNR, worst first
    assert "r.worst.png" in text and "c.png: images/c.png: not found" in text and "not installed" in text


def test_reports_are_never_written_over_an_existing_file(tmp_path):
    (tmp_path / "r.md").write_text("mine")
    with pytest.raises(UserError, match="already exists"):
        report.check_report_paths(tmp_path / "r.md")
    with pytest.raises(UserError, match="already exists"):
        report.write_report(tmp_path / "r.md", made_result())
    assert (tmp_path / "r.md").read_text() == "mine"
    report.write_report(tmp_path / "r.md", made_result(), overwrite=True)
    assert "Evaluation" in (tmp_path / "r.md").read_text()
    with pytest.raises(UserError, match="must end in"):
        report.check_report_paths(tmp_path / "r.txt")


def test_contact_sheet_shows_photo_render_and_heat_map(tmp_path):
    photo = np.full((24, 32, 3), 0.5)
    render = photo.copy()
    render[:, 16:] = 0.9  # the right half is wrong
    path = report.write_contact_sheet(tmp_path / "r.worst.png", [("one", photo, render), ("two", photo, photo)])
    sheet = np.asarray(Image.open(path).convert("RGB")).astype(int)
    label = report.LABEL_HEIGHT
    assert sheet.shape == (2 * (label + 24), 3 * 32, 3)
    assert np.all(sheet[label:label + 24, :32] == 128) and np.all(sheet[label:label + 24, 48:64] == 230)
    heat = sheet[label:label + 24, 64:]
    assert np.ptp(heat[:, :16].reshape(-1, 3), axis=0).max() == 0  # no error: one colour
    assert np.abs(heat[:, 16:].mean(axis=(0, 1)) - heat[:, :16].mean(axis=(0, 1))).sum() > 100
