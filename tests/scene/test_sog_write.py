"""Writing SOG v2 (scene/sog_write.py): scenes written, read back with the project's reader
(scene/sog_file.py) and checked against bounds computed from what the file says (its mins,
maxs and codebooks), not guessed; the file's own images read with our WebP decoder; the
same bytes every time; write_scene's atomic, never-clobbering dispatch; and a SOG written
here read by PlayCanvas's splat-transform into a PLY (tests/fixtures/README.md), which
must agree with our reading of it.

Bounds of a decoded value against the scene written:

- position, per axis: half a 16-bit step in the log space ``l = sign(x) ln(|x| + 1)``,
  ``h = (maxs - mins) / 131070``, moves x by at most ``(|x| + 1) expm1(h)``; plus the float32
  rounding of the result;
- rotation: each stored component is rounded by at most ``e = sqrt(2) / 510`` (half a byte
  step of ``(byte / 255 - 0.5) sqrt(2)``); the largest, rebuilt as ``sqrt(1 - |c'|^2)``,
  moves by ``| |c'|^2 - |c|^2 | / (q_m + q_m') <= (2 |c| sqrt(3) e + 3 e^2) / (q_m + q_m')``;
- opacity: ``round(255 o) / 255``: half of 1/255;
- scales (in log space), colours and SH values: the distance to their codebook's nearest
  entry (the writer picks the nearest); an SH row decodes as its nearest palette row.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import features
from testkit import assert_user_error

from raygs_viewer.errors import UserError
from raygs_viewer.scene import writing
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sog_write import FLAT_MARGIN, cell_shares, palette_cells, palette_size, sog_bytes, sog_images
from raygs_viewer.scene.webp_image import decode_webp
from raygs_viewer.scene.writing import write_scene, writing_notes

pytestmark = pytest.mark.filterwarnings("error")

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
#: Our writer's SOG of :func:`fixture_scene`, and splat-transform 3.10.2's PLY of it
#: (``splat-transform sog-write.sog sog-write.splat-transform.ply``: tests/fixtures/README.md).
FIXTURE_SOG = FIXTURES / "sog-write.sog"
FIXTURE_PLY = FIXTURES / "sog-write.splat-transform.ply"
#: The libwebp (Pillow's) that compressed the committed SOG: another may pick other bytes
#: for the same pixels, so only under this one are the whole files compared.
FIXTURE_LIBWEBP = "1.6.0"
EPS32 = 2.0 ** -24  # float32's unit roundoff

#: Rotations (w, x, y, z) at and near each of the four components being the largest, with
#: either sign, and ties between two or four of them.
HARD_ROTATIONS = [
    (1, 0, 0, 0), (1, 1e-3, -1e-3, 1e-3), (1e-3, -1, 0, 2e-3), (0, 1e-3, 1, -1e-3), (-1e-3, 0, 1e-3, -1),
    (0, 0, 0, -1), (0.5, 0.5, 0.5, 0.5), (-0.5, 0.5, -0.5, 0.5), (1, 1, 0, 0), (0, -1, 1, 0), (1, 0, 0, -1),
    (0.70710678, 0.70710679, 0, 0),
]


def sog_scene(n: int = 300, degree: int = 3, seed: int = 0, distinct: int | None = None) -> Scene:
    """``n`` gaussians made with numpy; hard values first: huge, tiny and negative
    positions, :data:`HARD_ROTATIONS`, opacity 0, 1 and nearly so, a zero scale. SH rest:
    every row its own, or drawn from ``distinct`` rows (so the palette can be exact)."""
    rng = np.random.default_rng(seed)

    def first(array, rows):  # the hard rows a scene of n has room for
        array[:len(rows)] = np.array(rows, np.float64)[:n]

    positions = rng.normal(size=(n, 3)) * np.array([0.3, 3.0, 40.0])
    first(positions, [(1e30, -2e25, 7e20), (1e-30, -1e-38, 0.0), (-0.0, -1e-6, -5.0), (-3e4, -0.5, 1e-3)])
    rotations = rng.normal(size=(n, 4))
    first(rotations, HARD_ROTATIONS)
    rotations /= np.linalg.norm(rotations, axis=1)[:, None]
    scales = np.exp(rng.uniform(-7.0, 0.5, (n, 3)))
    first(scales[:, 1], [1.0] * 4 + [0.0])
    opacities = rng.uniform(0.0, 1.0, n)
    first(opacities, [0.0, 1.0, 1e-7, 1 - 1e-7])
    sh = np.zeros((n, sh_coefficient_count(degree), 3))
    sh[:, 0] = rng.normal(scale=0.8, size=(n, 3))
    if degree:
        # Rows of very different sizes (some gaussians far more view-dependent than others):
        # the codebook is then coarse for the palette, and labels must follow it.
        count = distinct or n
        sizes = np.exp(rng.normal(scale=1.5, size=(count, 1, 1)))
        rows = rng.normal(scale=0.2, size=(count, sh.shape[1] - 1, 3)) * sizes
        sh[:, 1:] = rows[rng.integers(0, distinct, n)] if distinct else rows
    f32 = np.float32
    return Scene(positions.astype(f32), rotations.astype(f32), scales.astype(f32), opacities.astype(f32),
                 sh.astype(f32), degree)


def fixture_scene() -> Scene:
    """The scene of the committed fixtures: 300 gaussians of SH degree 3 whose SH rest
    takes about 155 distinct rows, so the palette is exact and needs no k-means (the file
    stays the same whatever scipy is installed) and spans three rows of the centroids image."""
    return sog_scene(n=300, degree=3, seed=2024, distinct=200)


def members(path) -> tuple[dict, dict[str, np.ndarray]]:
    """meta.json and every image of a .sog, decoded with our WebP reader to (H * W, 4)."""
    with zipfile.ZipFile(path) as archive:
        meta = json.loads(archive.read("meta.json"))
        images = {name: decode_webp(name, archive.read(name), lambda w, h: True, "")
                  for name in archive.namelist() if name.endswith(".webp")}
    return meta, images


def log_transform(x):
    return np.sign(x) * np.log1p(np.abs(x))


def nearest_distance(values, book):
    """Each value's distance to the nearest entry of ``book``."""
    return np.abs(np.asarray(values, np.float64)[..., None] - np.asarray(book)).min(axis=-1)


def written_and_read(scene: Scene, path):
    assert write_scene(scene, path) == path
    back = load_scene(path)
    assert (back.count, back.sh_degree, back.format, back.dropped) == (scene.count, scene.sh_degree, "SOG v2", {})
    return back, *members(path)


# --------------------------------------------------------------------------- read back


def assert_positions_within_a_log_step(scene, back, meta):
    x = scene.positions.astype(np.float64)
    mins, maxs = np.array(meta["means"]["mins"]), np.array(meta["means"]["maxs"])
    # mins and maxs are the log transform of the lowest and highest coordinate of each axis.
    np.testing.assert_array_equal(mins, log_transform(x.min(axis=0)))
    np.testing.assert_array_equal(maxs, log_transform(x.max(axis=0)))
    half_step = np.where(maxs > mins, maxs - mins, 1.0) / 131070 * (1 + 1e-9)
    bound = (np.abs(x) + 1) * np.expm1(half_step) + np.abs(x) * 2 * EPS32
    error = np.abs(back.positions - x)
    assert np.all(error <= bound)
    assert np.max(error / bound) > 0.4  # the bound is not vacuous


def assert_rotations_within_a_byte(scene, back, images):
    n = scene.count
    q = scene.rotations.astype(np.float64)
    q /= np.linalg.norm(q, axis=1)[:, None]
    rows = np.arange(n)
    largest = images["quats.webp"][:n, 3].astype(np.int64) - 252
    assert np.all((largest >= 0) & (largest <= 3))
    assert np.all(np.abs(q[rows, largest]) == np.abs(q).max(axis=1))  # the dropped one is a largest
    d = back.rotations.astype(np.float64)
    d *= np.sign(np.sum(d * q, axis=1))[:, None]  # q and -q are the same rotation
    e = math.sqrt(2) / 510
    others = np.ones((n, 4), bool)
    others[rows, largest] = False
    rounding = 4 * EPS32  # float32 results, normalised once more by the reader
    assert np.all(np.abs(d - q)[others] <= e + rounding)
    c = np.linalg.norm(np.where(others, q, 0.0), axis=1)
    bound = (2 * c * math.sqrt(3) * e + 3 * e * e) / np.abs(q[rows, largest] + d[rows, largest])
    assert np.all(np.abs(d - q)[rows, largest] <= bound + rounding)
    assert np.max(np.abs(d - q)[others]) > 0.5 * e


def assert_codebook_values_nearest(original, decoded, book, slack):
    """Each decoded value is an entry of ``book`` and as near the original as any entry."""
    book = np.asarray(book, np.float64)
    assert book.shape == (256,)
    assert np.all(nearest_distance(decoded, book) <= slack)
    assert np.all(np.abs(np.asarray(decoded, np.float64) - original) <= nearest_distance(original, book) + slack)


def assert_sh_rest_as_the_palette_allows(scene, back, meta, images):
    n, k = scene.count, sh_coefficient_count(scene.sh_degree) - 1
    rows = scene.sh[:, 1:].reshape(n, -1).astype(np.float64)
    shn = meta["shN"]
    assert shn["bands"] == scene.sh_degree and shn["files"] == ["shN_centroids.webp", "shN_labels.webp"]
    book = np.array(shn["codebook"])
    labels_px = images["shN_labels.webp"][:n]
    labels = labels_px[:, 0].astype(np.int64) | labels_px[:, 1].astype(np.int64) << 8
    centroids = images["shN_centroids.webp"].reshape(-1, k, 4)[:, :, :3]
    palette = book[centroids[: shn["count"]]].astype(np.float32).reshape(shn["count"], -1)
    assert labels.max() < shn["count"] <= palette_size(n)
    np.testing.assert_array_equal(back.sh[:, 1:].reshape(n, -1), palette[labels])
    distinct = np.unique(rows, axis=0)
    if len(distinct) <= palette_size(n):
        # Exact: one palette row per distinct row, each value its codebook's nearest.
        assert shn["count"] == len(distinct)
        assert len(np.unique(np.column_stack([rows, labels]), axis=0)) == len(distinct) == len(np.unique(labels))
        assert_codebook_values_nearest(rows, back.sh[:, 1:].reshape(n, -1), book, 1e-12)
    else:
        # k-means in two levels: each cell of rows learns its share of the palette (or its
        # distinct rows, where fewer), and each gaussian has the nearest row, as decoded,
        # of its cell's entries; the palette fits.
        stored = scene.sh[:, 1:].reshape(n, -1)
        cells = palette_cells(stored, palette_size(n))
        sizes = [min(share, len(np.unique(stored[members], axis=0)))
                 for members, share in zip(cells, cell_shares(palette_size(n), cells))]
        assert shn["count"] == sum(sizes) <= palette_size(n) and sorted(np.concatenate(cells)) == list(range(n))
        p = palette.astype(np.float64)
        squared = (rows ** 2).sum(axis=1)[:, None] - 2 * rows @ p.T + (p ** 2).sum(axis=1)[None]
        for members, first, size in zip(cells, np.cumsum([0] + sizes[:-1]), sizes):
            own = squared[members, first:first + size]
            assert np.all((labels[members] >= first) & (labels[members] < first + size))
            assert np.all(squared[members, labels[members]] <= own.min(axis=1) * (1 + 1e-5) + 1e-9)
        chosen = squared[np.arange(n), labels]
        assert chosen.mean() < 0.25 * ((rows - rows.mean(axis=0)) ** 2).sum(axis=1).mean()


# 300 SH-3 rows and a palette of 256: k-means; 40 distinct rows: an exact palette; 1500: labels
# past 255 (both bytes) and clusters of several rows; 1: a flat axis and a palette of one.
@pytest.mark.parametrize("n,degree,distinct", [(300, 0, None), (300, 3, None), (300, 3, 40), (1500, 1, None),
                                               (1, 2, None)])
def test_written_scenes_read_back_within_the_quantisation(tmp_path, n, degree, distinct):
    scene = sog_scene(n=n, degree=degree, seed=degree + n, distinct=distinct)
    back, meta, images = written_and_read(scene, tmp_path / "scene.sog")
    assert meta["version"] == 2 and meta["count"] == n
    if n > 1:
        assert_positions_within_a_log_step(scene, back, meta)
        assert_rotations_within_a_byte(scene, back, images)
    else:
        np.testing.assert_array_equal(back.positions, scene.positions)  # a flat axis decodes to its one value
    # round(255 o) / 255, then float32: 0 and 1 exact.
    assert np.all(np.abs(back.opacities - scene.opacities.astype(np.float64)) <= 0.5 / 255 + EPS32)
    np.testing.assert_array_equal(back.opacities[scene.opacities == 0], 0.0)
    np.testing.assert_array_equal(back.opacities[scene.opacities == 1], 1.0)
    # Scales, in log space: exp of the entry is rounded to float32 (a relative EPS32).
    logs = np.log(scene.scales.astype(np.float64), where=scene.scales > 0, out=np.full((n, 3), -np.inf))
    finite = np.isfinite(logs)
    scale_book = meta["scales"]["codebook"]
    assert_codebook_values_nearest(logs[finite], np.log(back.scales[finite].astype(np.float64)), scale_book,
                                   2 * EPS32)
    assert_codebook_values_nearest(scene.sh[:, 0].astype(np.float64), back.sh[:, 0], meta["sh0"]["codebook"], 1e-12)
    if degree:
        assert_sh_rest_as_the_palette_allows(scene, back, meta, images)
    else:
        assert "shN" not in meta and not any(name.startswith("shN") for name in images)


def test_a_zero_scale_reads_back_flat_not_dropped(tmp_path):
    scene = sog_scene(n=50, degree=0, seed=3)
    assert scene.scales[4, 1] == 0
    back, meta, _ = written_and_read(scene, tmp_path / "flat.sog")
    book = np.array(meta["scales"]["codebook"])
    smallest = np.log(scene.scales[scene.scales > 0].astype(np.float64)).min()
    assert book[0] == np.float32(smallest - FLAT_MARGIN)
    assert back.scales[4, 1] == np.float32(np.exp(book[0])) and back.scales[4, 1] > 0
    assert " ".join(writing_notes(scene, ".sog")).count("1 gaussians have a scale of 0") == 1


def test_the_images_are_the_pixels_written_and_lossless(tmp_path):
    """Every image comes back through our WebP reader exactly as the writer made it (RGB
    under sh0's zero alpha included), in splat-transform's sizes."""
    scene = sog_scene(n=300, degree=2, seed=5)
    meta, images = sog_images(scene)
    path = tmp_path / "scene.sog"
    path.write_bytes(sog_bytes(scene))
    read_meta, read_images = members(path)
    assert read_meta == meta
    assert list(read_images) == list(images) == ["means_l.webp", "means_u.webp", "quats.webp", "scales.webp",
                                                 "sh0.webp", "shN_centroids.webp", "shN_labels.webp"]
    for name, rgba in images.items():
        np.testing.assert_array_equal(read_images[name], rgba.reshape(-1, 4), err_msg=name)
        # 300 gaussians: 20 x 16 pixels; 256 palette entries of 8 coefficients: 4 rows of 64.
        assert rgba.shape == ((4, 64 * 8, 4) if name == "shN_centroids.webp" else (16, 20, 4)), name
    sh0 = images["sh0.webp"].reshape(-1, 4)[:300]
    assert np.any(sh0[sh0[:, 3] == 0, :3])  # colour under opacity 0, which libwebp would clear unless told


def test_the_same_scene_gives_the_same_bytes():
    first = sog_bytes(sog_scene(n=300, degree=3, seed=9))
    assert sog_bytes(sog_scene(n=300, degree=3, seed=9)) == first
    with zipfile.ZipFile(io.BytesIO(first)) as archive:
        assert {info.date_time for info in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}
        assert archive.namelist()[-1] == "meta.json"
    assert sog_bytes(sog_scene(n=300, degree=3, seed=10)) != first


@pytest.mark.parametrize("degree", [0, 3])
def test_an_empty_scene_writes_a_valid_empty_sog(tmp_path, degree):
    back, meta, images = written_and_read(sog_scene(n=0, degree=degree), tmp_path / "empty.sog")
    assert back.count == 0 and meta["count"] == 0
    assert ("shN" in meta) == bool(degree) and meta.get("shN", {"count": 0})["count"] == 0


# --------------------------------------------------------------------------- bad input, notes


@pytest.mark.parametrize("field,row,value,what", [
    ("positions", (3, 1), np.nan, "non-finite positions"),
    ("positions", (0, 2), np.inf, "non-finite positions"),
    ("scales", (2, 0), np.inf, "scales"),
    ("scales", (2, 2), -1.0, "scales"),
    ("rotations", 5, 0.0, "zero or non-finite rotations"),
    ("opacities", 7, 1.5, "opacities outside 0..1"),
    ("sh", (1, 3, 2), np.nan, "non-finite colours or SH"),
])
def test_what_sog_cannot_hold_is_one_line_and_leaves_no_file(tmp_path, field, row, value, what):
    scene = sog_scene(n=20, degree=1, seed=1)
    array = getattr(scene, field).copy()
    array[row] = value
    bad = Scene(**{**{f: getattr(scene, f) for f in ("positions", "rotations", "scales", "opacities", "sh")},
                   field: array}, sh_degree=1)
    with pytest.raises(UserError, match=f"^cannot write .sog: the scene has {what}") as info:
        write_scene(bad, tmp_path / "bad.sog")
    assert "\n" not in str(info.value)
    assert list(tmp_path.iterdir()) == []  # not even a temporary


def test_writing_notes_say_what_sog_quantises():
    notes = writing_notes(sog_scene(n=300, degree=3, seed=1), ".SOG")
    assert len(notes) == 2  # what SOG quantises, and the zero scale
    assert all(words in notes[0] for words in ("16 bits", "log space", "256-entry codebooks", "opacity to 8 bits",
                                               "k-means palette of at most 256"))
    degree_0 = writing_notes(sog_scene(n=300, degree=0, seed=1), ".sog")
    assert "palette" not in degree_0[0] and "scale of 0" in degree_0[1]
    assert not any("SOG" in note for note in writing_notes(sog_scene(n=30, degree=0), ".ply"))


# --------------------------------------------------------------------------- write_scene


@pytest.mark.parametrize("name", ["there.sog", "there.SOG"])
def test_write_scene_never_clobbers_and_refuses_before_any_work(tmp_path, monkeypatch, name):
    path = tmp_path / name
    path.write_bytes(b"the user's file")
    scene = sog_scene(n=30, degree=1, seed=2)
    calls = []
    monkeypatch.setattr(writing, "sog_bytes", lambda s: calls.append(s.count) or sog_bytes(s))
    assert_user_error(lambda: write_scene(scene, path), path, "already exists", "--overwrite")
    assert path.read_bytes() == b"the user's file" and calls == []
    write_scene(scene, path, overwrite=True)
    assert calls == [30] and load_scene(path).count == 30
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # no temporary left


def test_a_failed_write_keeps_the_old_file(tmp_path, monkeypatch):
    """Atomic: the old file stays whole when the new one fails part way, even with overwrite."""
    path = tmp_path / "old.sog"
    write_scene(sog_scene(n=30, degree=0, seed=2), path)
    before = path.read_bytes()

    def failing(scene):
        raise UserError("cannot write .sog: the disk gave up")

    monkeypatch.setattr(writing, "sog_bytes", failing)
    with pytest.raises(UserError, match="the disk gave up"):
        write_scene(sog_scene(n=40, degree=0, seed=3), path, overwrite=True)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["old.sog"]


# --------------------------------------------------------------------------- splat-transform


def test_our_sog_is_the_committed_one():
    """The committed SOG is our writer's file of fixture_scene(): the same meta.json and
    pixels always, the same bytes under the libwebp that made it."""
    ours = sog_bytes(fixture_scene())
    committed = FIXTURE_SOG.read_bytes()
    if features.version("webp") == FIXTURE_LIBWEBP:
        assert ours == committed
    with zipfile.ZipFile(FIXTURE_SOG) as old, zipfile.ZipFile(io.BytesIO(ours)) as new:
        assert old.namelist() == new.namelist()
        assert old.read("meta.json") == new.read("meta.json")
        for name in new.namelist()[:-1]:
            np.testing.assert_array_equal(decode_webp(name, old.read(name), lambda w, h: True, ""),
                                          decode_webp(name, new.read(name), lambda w, h: True, ""), err_msg=name)


def test_splat_transform_reads_our_sog_as_we_do():
    """splat-transform read the committed SOG and wrote a PLY; our PLY reader's scene of that
    must be our SOG reader's, gaussian by gaussian. Tolerances, and why:

    - SH (DC and rest): exact: both look the same float32 codebook entries up.
    - scales: one float32 rounding (the PLY holds the entry, a float32 log; the SOG reader
      takes exp in float64 and rounds once, the PLY reader likewise): 2 EPS32 relative.
    - positions: one float32 ulp, and near 0 splat-transform's ``exp(a) - 1`` (not expm1)
      loses up to about 2^-52 absolute before rounding to float32.
    - opacity: splat-transform clamps A / 255 to [1e-6, 1 - 1e-6] before its logit, rounded
      to float32 in the PLY: o(1-o)|x| EPS32 + o EPS32 back through the sigmoid, plus 1e-6.
    - rotations: splat-transform does not normalise (a float32 rounding of each
      component), our readers do: 4 EPS32.
    """
    ours, theirs = load_scene(FIXTURE_SOG), load_scene(FIXTURE_PLY)
    assert (theirs.count, theirs.sh_degree, theirs.dropped) == (ours.count, ours.sh_degree, {}) == (300, 3, {})
    np.testing.assert_array_equal(theirs.sh, ours.sh)
    np.testing.assert_allclose(theirs.scales, ours.scales, rtol=2 * EPS32, atol=0)
    x = ours.positions.astype(np.float64)
    assert np.all(np.abs(theirs.positions - x) <= np.spacing(np.abs(ours.positions)) + 4 * 2.0 ** -52 * (1 + np.abs(x)))
    o = ours.opacities.astype(np.float64)
    e = np.clip(o, 1e-6, 1 - 1e-6)
    logit = np.log(e / (1 - e))
    assert np.all(np.abs(theirs.opacities - o) <= (e * (1 - e) * np.abs(logit) + e) * EPS32 * 1.01 + 1e-6)
    np.testing.assert_allclose(theirs.rotations, ours.rotations, rtol=0, atol=4 * EPS32)
    # The same gaussians in the same order: compared against the scene written, too.
    scene = fixture_scene()
    assert np.all(np.abs(theirs.positions - scene.positions) <= 1e-3 * (1 + np.abs(scene.positions)))
