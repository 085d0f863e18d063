"""bench.loading: the generated PLY the load benchmark reads, and its measurement in a
fresh process (tiny counts here; the figures themselves are never asserted)."""

from __future__ import annotations

import numpy as np
import pytest
from plyfile import PlyData

from raygs_viewer.bench.loading import (
    LoadFigures,
    count_label,
    format_load_lines,
    measure_generated_loads,
    measure_load,
    ply_property_names,
    write_generated_ply,
)
from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import load_scene


@pytest.mark.parametrize("sh_degree", [0, 3])
def test_generated_ply_is_an_inria_file_written_in_chunks(tmp_path, monkeypatch, sh_degree):
    monkeypatch.setattr("raygs_viewer.bench.loading.GENERATE_CHUNK_ROWS", 7)  # 150 rows: 22 chunks
    path = write_generated_ply(tmp_path / "g.ply", 150, sh_degree=sh_degree, seed=3)
    vertex = PlyData.read(str(path))["vertex"]
    assert [p.name for p in vertex.properties] == ply_property_names(sh_degree)
    assert len(ply_property_names(3)) == 62 and vertex.count == 150
    assert all(p.val_dtype == "f4" for p in vertex.properties)
    scene = load_scene(path)
    assert scene.count == 150 and scene.sh_degree == sh_degree and not scene.dropped
    assert len({tuple(p) for p in scene.positions}) == 150  # every chunk its own random rows
    again = write_generated_ply(tmp_path / "again.ply", 150, sh_degree=sh_degree, seed=3)
    assert again.read_bytes() == path.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again.ply", "g.ply"]  # no temporaries left


def test_generated_ply_never_clobbers(tmp_path):
    path = tmp_path / "taken.ply"
    path.write_bytes(b"mine")
    with pytest.raises(UserError, match="already exists"):
        write_generated_ply(path, 10)
    assert path.read_bytes() == b"mine"
    write_generated_ply(path, 10, overwrite=True)
    assert load_scene(path).count == 10
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken.ply"]


def test_measure_load_runs_the_load_in_another_process(tmp_path):
    path = write_generated_ply(tmp_path / "m.ply", 2000, sh_degree=1)
    figures = measure_load(path)
    assert figures.file_bytes == path.stat().st_size
    assert figures.seconds > 0 and figures.peak_bytes >= 0
    with pytest.raises(UserError, match="measuring the load failed"):
        measure_load(tmp_path / "missing.ply")


def test_measure_generated_loads_leaves_nothing_behind(tmp_path):
    lines = []
    rows = measure_generated_loads([300, 1000], sh_degree=0, folder=tmp_path, log=lines.append)
    assert [count for count, _ in rows] == [300, 1000]
    assert rows[0][1].file_bytes < rows[1][1].file_bytes
    assert len(lines) == 2 and list(tmp_path.iterdir()) == []


def test_load_lines():
    figures = LoadFigures(seconds=3.4149, peak_bytes=978 << 20, file_bytes=int((978 << 20) / 1.32))
    assert format_load_lines([(3_000_000, figures)]) == ["load@3M 3.41 s, peak 1.32x file (978 MiB)"]
    assert [count_label(n) for n in (100_000, 1_000_000, 1_500_000, 6_000_000, 512)] == \
        ["100k", "1M", "1.5M", "6M", "512"]
    assert np.isclose(figures.peak_ratio, 1.32, atol=1e-3)
