"""The SOG v2 reader (scene/sog_file.py): PlayCanvas's shared sample, files written here by
a small encoder built from the specification (tests/sog_kit.py: bundled and unbundled, with
and without SH), and hostile files.

The encoder is the test's own reading of the format (developer.playcanvas.com's SOG page and
splat-transform's writer): it rounds to the nearest code where splat-transform truncates,
uses plain linspace codebooks and a palette of the distinct SH rows, and lays images out with
any width, so the reader is checked against the format, not against itself. Quantisation
bounds of a decoded scene against the scene encoded:

- position, per axis: |dx| <= (|x| + 1) (exp(d) - 1), d = (max' - min') / 131070 (half a
  16-bit step in the log space x' = sign(x) ln(|x| + 1)), plus float32 rounding;
- scale: |d ln s| <= half a codebook step, (max - min) / 510 of the log-scales;
- f_dc and SH rest: half a step of their codebooks; opacity: 0.5 / 255;
- rotation: at most 1.1 degrees: each stored component is off by at most
  e = sqrt(2) / 510, the rebuilt largest one (>= 1/2) by at most 3e, so |dq| <= sqrt(12) e
  and the angle 2 |dq| <= 0.0192 rad.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import struct
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from sog_kit import bundle_bytes, encode_sog, gaussians, inverse_log, webp_bytes, write_bundle, write_folder
from testkit import SHARED_SCENES, assert_user_error, run_cli

from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.content_hash import file_sha256

pytestmark = pytest.mark.filterwarnings("error")

SAMPLE = SHARED_SCENES / "formats" / "pcwc-angel-kneeling.sog"
ROTATION_BOUND_DEG = 1.1


def rotation_angles_deg(a, b):
    a = a / np.linalg.norm(a, axis=1)[:, None]
    b = b / np.linalg.norm(b, axis=1)[:, None]
    dot = np.clip(np.abs(np.sum(a * b, axis=1)), 0.0, 1.0)
    return np.degrees(2 * np.arccos(dot))


def assert_within_quantisation(scene, raw, meta):
    positions, log_scales, rotations, opacities, f_dc, f_rest = raw
    mins, maxs = np.array(meta["means"]["mins"]), np.array(meta["means"]["maxs"])
    step = np.where(maxs > mins, maxs - mins, 1.0) / 131070
    bound = (np.abs(positions) + 1) * np.expm1(step) + np.abs(positions) * 2.0 ** -23 + 1e-30
    assert np.all(np.abs(scene.positions - positions) <= bound)
    scale_step = (log_scales.max() - log_scales.min()) / 510
    assert np.all(np.abs(np.log(scene.scales.astype(np.float64)) - log_scales) <= scale_step + 1e-6)
    assert np.all(np.abs(scene.opacities - opacities) <= 0.5 / 255 + 1e-7)
    dc_step = (f_dc.max() - f_dc.min()) / 510
    assert np.all(np.abs(scene.sh[:, 0, :] - f_dc) <= dc_step + 1e-6)
    angles = rotation_angles_deg(scene.rotations.astype(np.float64), rotations)
    assert angles.max() <= ROTATION_BOUND_DEG, angles.max()
    assert np.allclose(np.linalg.norm(scene.rotations, axis=1), 1.0, atol=1e-6)
    if f_rest is not None:
        rest_step = (f_rest.max() - f_rest.min()) / 510
        assert np.all(np.abs(scene.sh[:, 1:, :] - f_rest) <= rest_step + 1e-6)
    return angles


def assert_exact_dequantisation(scene, codes, meta):
    """The decoded values are exactly the codebook entries (and byte / 255) encoded."""
    assert np.array_equal(scene.scales, np.exp(codes["scale_book"][codes["scales"]]).astype(np.float32))
    assert np.array_equal(scene.sh[:, 0, :], codes["dc_book"][codes["sh0"]].astype(np.float32))
    assert np.array_equal(scene.opacities, (codes["alpha"] / 255.0).astype(np.float32))
    mins, maxs = np.array(meta["means"]["mins"]), np.array(meta["means"]["maxs"])
    expected = inverse_log(mins + np.where(maxs > mins, maxs - mins, 1.0) * codes["means"] / 65535)
    assert np.allclose(scene.positions, expected, rtol=2e-7, atol=0)
    if "rest" in codes:
        assert np.array_equal(scene.sh[:, 1:, :], codes["rest_book"][codes["rest"][codes["labels"]]].astype(np.float32))


# --- the shared sample ----------------------------------------------------------------------


def test_playcanvas_sample_loads_with_sane_statistics():
    if not SAMPLE.is_file():
        pytest.skip(f"shared test scene {SAMPLE.name} not found in {SAMPLE.parent} (the ../shared/scenes folder is absent)")
    scene = load_scene(SAMPLE)
    assert (scene.count, scene.sh_degree, scene.format, scene.dropped) == (83547, 0, "SOG v2", {})
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        array = getattr(scene, field)
        assert array.dtype == np.float32 and np.all(np.isfinite(array)), field
    means = json.loads(zipfile.ZipFile(SAMPLE).read("meta.json"))["means"]
    low, high = inverse_log(np.array(means["mins"])), inverse_log(np.array(means["maxs"]))
    # The writer maps each axis' lowest gaussian to code 0 exactly and (truncating) its
    # highest to 65535 or 65534: the bounds are the inverse log of mins and maxs.
    assert np.allclose(scene.positions.min(axis=0), low, rtol=1e-6, atol=0)
    top_step = (np.abs(high) + 1) * np.expm1((np.array(means["maxs"]) - np.array(means["mins"])) / 65535)
    assert np.all(np.abs(scene.positions.max(axis=0) - high) <= top_step * 1.01)
    # Morton order: neighbouring pixels are neighbours in space (not if the bytes were mixed up).
    extent = np.linalg.norm(high - low)
    steps = np.linalg.norm(np.diff(scene.positions, axis=0), axis=1)
    assert np.median(steps) < 0.01 * extent
    assert np.allclose(np.linalg.norm(scene.rotations, axis=1), 1.0, atol=1e-6)
    assert scene.opacities.min() == 0.0 and scene.opacities.max() == 1.0
    assert 0.2 < np.median(scene.opacities) < 0.6
    assert np.all(scene.scales > 0) and 1e-3 < np.median(scene.scales) < 1e-2
    # f_dc as colour (0.5 + C0 f_dc) lies within [0, 1] in this scene's codebook.
    colour = 0.5 + 0.28209479177387814 * scene.sh[:, 0, :]
    assert colour.min() >= -1e-6 and colour.max() <= 1 + 1e-6 and colour.std() > 0.05


def test_cli_info_names_the_format(capsys):
    if not SAMPLE.is_file():
        pytest.skip(f"shared test scene {SAMPLE.name} not found (the ../shared/scenes folder is absent)")
    code, out, err = run_cli(capsys, "info", str(SAMPLE))
    assert code == 0, err
    assert "SOG v2" in out and "83547" in out


# --- files written here ---------------------------------------------------------------------


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("layout", ["folder", "stored zip", "deflated zip"])
def test_encoded_scenes_decode_within_the_quantisation_error(tmp_path, degree, layout):
    raw = gaussians(n=300, degree=degree, seed=degree)
    meta, images, codes = encode_sog(*raw, width=23 if degree % 2 else None, fill="random")
    if layout == "folder":
        path = write_folder(tmp_path / "scene", meta, images)
    else:
        method = zipfile.ZIP_DEFLATED if layout == "deflated zip" else zipfile.ZIP_STORED
        path = write_bundle(tmp_path / "scene.sog", meta, images, method)
    scene = load_scene(path)
    assert (scene.count, scene.sh_degree, scene.format, scene.dropped) == (300, degree, "SOG v2", {})
    assert scene.source == str(path)
    assert_exact_dequantisation(scene, codes, meta)
    angles = assert_within_quantisation(scene, raw, meta)
    assert angles.max() > 0.05  # the bound is not vacuous: quantisation does move rotations


def test_a_folder_loads_as_its_meta_json(tmp_path):
    from raygs_viewer.scene.progress import Reporter
    from raygs_viewer.scene.sog_file import load_sog
    from raygs_viewer.scene.source import SceneSource

    meta, images, _ = encode_sog(*gaussians(n=20))
    path = write_folder(tmp_path / "scene", meta, images)
    by_file = load_scene(path)
    by_folder = load_sog(SceneSource(tmp_path / "scene"), Reporter(None, None), 1 << 20)
    assert np.array_equal(by_file.positions, by_folder.positions)
    assert np.array_equal(by_file.sh, by_folder.sh)
    with pytest.raises(UserError, match="folder has no meta.json"):
        load_sog(SceneSource(tmp_path), Reporter(None, None), 1 << 20)


def test_an_unbundled_scene_opens_from_its_folder_and_hashes_every_image(tmp_path):
    meta, images, _ = encode_sog(*gaussians(n=20))
    path = write_folder(tmp_path / "scene", meta, images)
    np.testing.assert_array_equal(load_scene(tmp_path / "scene").positions, load_scene(path).positions)
    digest = file_sha256(path)
    assert file_sha256(tmp_path / "scene") == digest
    assert digest != hashlib.sha256(Path(path).read_bytes()).hexdigest()   # more than meta.json
    # An image changed beside an unchanged meta.json: another scene, another digest.
    name = sorted(images)[0]
    (tmp_path / "scene" / name).write_bytes(webp_bytes(255 - np.asarray(images[name])))
    assert file_sha256(path) != digest


def test_a_json_named_bundle_and_images_in_a_subfolder(tmp_path):
    meta, images, _ = encode_sog(*gaussians(n=10))
    moved = {f"textures/{name}": rgba for name, rgba in images.items()}
    for section in ("means", "scales", "quats", "sh0"):
        meta[section]["files"] = [f"textures/{name}" for name in meta[section]["files"]]
    os.makedirs(tmp_path / "scene" / "textures")
    path = write_folder(tmp_path / "scene", meta, moved)
    assert load_scene(path).count == 10
    # A bundle is told by its zip signature whatever its name says (here .json).
    assert load_scene(write_bundle(tmp_path / "bundle.json", meta, moved)).count == 10


def test_pillow_decodes_lossless_rgba_exactly():
    """What the reader leans on: a lossless WebP's bytes come back as written, RGB under a
    zero alpha included (sh0's alpha is the opacity: 0 is common), and an all-opaque image
    (which the encoder stores without alpha) decodes to alpha 255."""
    rng = np.random.default_rng(3)
    rgba = rng.integers(0, 256, (37, 53, 4), dtype=np.uint8)
    rgba[::3, ::2, 3] = 0
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(webp_bytes(rgba))).convert("RGBA")), rgba)
    rgba[..., 3] = 255
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(webp_bytes(rgba))).convert("RGBA")), rgba)


def test_special_codes_decode_as_the_owners_readers_do(tmp_path):
    """A null first codebook entry is extrapolated (the engine), any other null drops its
    gaussians as NaN, a quats tag below 252 is the identity and a label at or past
    shN.count has zero SH (splat-transform)."""
    raw = gaussians(n=12, degree=1)
    meta, images, codes = encode_sog(*raw)
    images["scales.webp"][0, 0, :3] = 0
    meta["scales"]["codebook"][0] = None
    images["sh0.webp"][0, 1, 0] = 200
    meta["sh0"]["codebook"][200] = None
    images["quats.webp"][0, 2, 3] = 17
    images["shN_labels.webp"][0, 3, :2] = 255  # label 65535 >= count
    scene = load_scene(write_bundle(tmp_path / "s.sog", meta, images))
    assert scene.dropped == {"nan": 1} and scene.count == 11
    book = meta["scales"]["codebook"]
    assert np.allclose(scene.scales[0], np.exp(book[1] + (book[1] - book[255]) / 255), rtol=1e-6)
    # Gaussian 1 was dropped: 2 and 3 are now rows 1 and 2.
    assert np.array_equal(scene.rotations[1], [1, 0, 0, 0])
    assert np.array_equal(scene.sh[2, 1:], np.zeros((3, 3)))


def test_a_tiny_scene_with_one_gaussian(tmp_path):
    raw = gaussians(n=1, degree=3, palette=1)
    meta, images, codes = encode_sog(*raw)
    scene = load_scene(write_bundle(tmp_path / "one.sog", meta, images))
    assert scene.count == 1 and scene.sh_degree == 3
    assert_exact_dequantisation(scene, codes, meta)


def test_a_count_of_zero_is_an_empty_scene(tmp_path):
    meta, images, _ = encode_sog(*gaussians(n=4, degree=2))
    meta["count"] = 0
    scene = load_scene(write_bundle(tmp_path / "empty.sog", meta, images))
    assert scene.count == 0 and scene.sh_degree == 2 and scene.sh.shape == (0, 9, 3)


def test_progress_rises_to_done_and_cancel_stops_the_load(tmp_path):
    meta, images, _ = encode_sog(*gaussians(n=400, degree=2))
    path = write_bundle(tmp_path / "p.sog", meta, images, zipfile.ZIP_DEFLATED)
    calls = []
    load_scene(path, progress=lambda f, s: calls.append((f, s)), chunk_bytes=512)
    fractions = [f for f, _ in calls]
    assert fractions == sorted(fractions) and calls[-1] == (1.0, "done") and len(calls) > 20
    cancel = threading.Event()

    def progress(fraction, stage):
        if fraction > 0.3:
            cancel.set()

    with pytest.raises(UserError, match="^loading cancelled$"):
        load_scene(path, progress=progress, cancel=cancel, chunk_bytes=512)


# --- bad and hostile files ------------------------------------------------------------------


@pytest.fixture
def small():
    meta, images, _ = encode_sog(*gaussians(n=20, degree=1))
    return meta, images


def _mutated(meta, change):
    meta = json.loads(json.dumps(meta))
    change(meta)
    return meta


META_CASES = [
    ("no version, v1 layout", lambda m: (m.pop("version"), m["means"].update(shape=[20, 3])), "SOG version 1"),
    ("version 3", lambda m: m.update(version=3), "SOG version 3 is not supported"),
    ("version as text", lambda m: m.update(version="2"), 'SOG version "2" is not supported'),
    ("streamed index", lambda m: m.update(version=1, lodLevels=2), "streamed SOG"),
    ("count as text", lambda m: m.update(count="20"), "'count'"),
    ("negative count", lambda m: m.update(count=-1), "'count' is -1"),
    ("fractional count", lambda m: m.update(count=2.5), "whole number"),
    ("absurd count", lambda m: m.update(count=10 ** 12), "'count' is 1000000000000"),
    ("count as boolean", lambda m: m.update(count=True), "'count'"),
    ("means missing", lambda m: m.pop("means"), "'means' is missing"),
    ("means a list", lambda m: m.update(means=[1, 2]), "'means' is a list"),
    ("two mins", lambda m: m["means"].update(mins=[0, 1]), "'means.mins'"),
    ("text in maxs", lambda m: m["means"].update(maxs=[0, "1", 2]), "'means.maxs'"),
    ("huge maxs", lambda m: m["means"].update(maxs=[0, 1, 10 ** 400]), "'means.maxs'"),
    ("one means file", lambda m: m["means"].update(files=["means_l.webp"]), "'means.files'"),
    ("file name a number", lambda m: m["quats"].update(files=[7]), "'quats.files'"),
    ("short codebook", lambda m: m["scales"].update(codebook=[0.0] * 255), "255 entries"),
    ("codebook of text", lambda m: m["sh0"]["codebook"].__setitem__(9, "x"), "'sh0.codebook' holds something other than finite numbers"),
    ("codebook missing", lambda m: m["sh0"].pop("codebook"), "'sh0.codebook' is missing"),
    ("bands 4", lambda m: m["shN"].update(bands=4), "'shN.bands' is 4"),
    ("palette too big", lambda m: m["shN"].update(count=70000), "'shN.count' is 70000"),
    ("a list", lambda m: m.clear() or m.update(x=1), "no 'version' and no 'means'"),
]


@pytest.mark.parametrize("change,fragment", [c[1:] for c in META_CASES], ids=[c[0] for c in META_CASES])
def test_bad_meta_json_is_one_line(tmp_path, small, change, fragment):
    meta, images = small
    path = write_bundle(tmp_path / "bad.sog", _mutated(meta, change), images)
    assert_user_error(lambda: load_scene(path), path, fragment)
    folder_path = write_folder(tmp_path / "bad", _mutated(meta, change), images)
    assert_user_error(lambda: load_scene(folder_path), folder_path, fragment)


@pytest.mark.parametrize("text,fragment", [
    (b"[1, 2]", "expected a JSON object"),
    (b'{"version": 2, "count": NaN}', "not valid JSON"),
    (b"{" * 100000, "not valid JSON"),
    (b"\xff\xfe{}", "not valid JSON"),
    (b"", "not valid JSON"),
])
def test_unparsable_meta_json(tmp_path, text, fragment):
    path = tmp_path / "meta.json"
    path.write_bytes(text)
    assert_user_error(lambda: load_scene(path), path, fragment)


@pytest.mark.parametrize("name", ["../../etc/passwd", "/etc/passwd", "sub/../../means_l.webp", "..\\x.webp", ""])
def test_an_unbundled_meta_json_may_not_name_files_outside_its_folder(tmp_path, small, name):
    meta, images = small
    meta = _mutated(meta, lambda m: m["means"]["files"].__setitem__(1, name))
    path = write_folder(tmp_path / "scene", meta, images)
    assert_user_error(lambda: load_scene(path), path, "means.files" if not name else "outside the scene's folder")


def test_a_symlink_out_of_the_folder_is_refused(tmp_path, small):
    meta, images = small
    path = write_folder(tmp_path / "scene", meta, images)
    (tmp_path / "elsewhere.webp").write_bytes((tmp_path / "scene" / "quats.webp").read_bytes())
    os.remove(tmp_path / "scene" / "quats.webp")
    os.symlink(tmp_path / "elsewhere.webp", tmp_path / "scene" / "quats.webp")
    assert_user_error(lambda: load_scene(path), path, "quats.webp", "outside the scene's folder")


def test_missing_images_and_meta(tmp_path, small):
    meta, images = small
    images = dict(images)
    del images["sh0.webp"]
    path = write_bundle(tmp_path / "a.sog", meta, images)
    assert_user_error(lambda: load_scene(path), path, "sh0.webp: missing from the archive")
    path = write_folder(tmp_path / "b", meta, images)
    assert_user_error(lambda: load_scene(path), path, "sh0.webp: no such file")
    path = write_bundle(tmp_path / "c.sog", None, images)
    assert_user_error(lambda: load_scene(path), path, "no meta.json at the root")


def test_not_a_zip_and_truncated_zips(tmp_path, small):
    meta, images = small
    path = tmp_path / "x.sog"
    path.write_bytes(b"hello, not a zip at all")
    assert_user_error(lambda: load_scene(path), path, "not valid JSON")
    data = bundle_bytes(meta, images)
    for cut in (len(data) // 2, len(data) - 10, 10):
        path.write_bytes(data[:cut])
        assert_user_error(lambda: load_scene(path), path)


def test_wrong_image_sizes(tmp_path, small):
    meta, images = small
    too_small = dict(images, **{"scales.webp": images["scales.webp"][:2, :3]})
    path = write_bundle(tmp_path / "a.sog", meta, too_small)
    assert_user_error(lambda: load_scene(path), path, "scales.webp", "image is 3x2", "at least 20 pixels")
    # An honest but oversized image (a decompression bomb for a 20-gaussian scene).
    big = np.zeros((300, 300, 4), np.uint8)
    path = write_bundle(tmp_path / "b.sog", meta, dict(images, **{"quats.webp": big}))
    assert_user_error(lambda: load_scene(path), path, "quats.webp", "image is 300x300")
    narrow = np.zeros((1, 64, 4), np.uint8)
    path = write_bundle(tmp_path / "c.sog", meta, dict(images, **{"shN_centroids.webp": narrow}))
    assert_user_error(lambda: load_scene(path), path, "shN_centroids.webp", "192 pixels wide")


def test_a_webp_header_claiming_a_huge_image_is_refused_before_decoding(tmp_path, small):
    meta, images = small
    data = bytearray(webp_bytes(images["means_u.webp"]))
    assert data[12:16] == b"VP8L" and data[20] == 0x2F
    bits = int.from_bytes(data[21:25], "little")
    bits = (bits & ~((1 << 28) - 1)) | 0x3FFF | (0x3FFF << 14)  # 16384 x 16384
    data[21:25] = bits.to_bytes(4, "little")
    path = write_bundle(tmp_path / "bomb.sog", meta, dict(images, **{"means_u.webp": bytes(data)}))
    assert_user_error(lambda: load_scene(path), path, "means_u.webp", "image is 16384x16384")


def test_images_that_are_not_webp_or_corrupt(tmp_path, small):
    meta, images = small
    png = io.BytesIO()
    Image.fromarray(images["sh0.webp"], "RGBA").save(png, "PNG")
    path = write_bundle(tmp_path / "a.sog", meta, dict(images, **{"sh0.webp": png.getvalue()}))
    assert_user_error(lambda: load_scene(path), path, "sh0.webp", "not a WebP image")
    data = bytearray(webp_bytes(images["sh0.webp"]))
    data[40:] = bytes(len(data) - 40)
    path = write_bundle(tmp_path / "b.sog", meta, dict(images, **{"sh0.webp": bytes(data)}))
    assert_user_error(lambda: load_scene(path), path, "sh0.webp", "cannot decode the WebP image")


def _central_entry(data: bytes, name: str) -> int:
    at = data.index(b"PK\x01\x02")
    while True:
        length = struct.unpack("<H", data[at + 28: at + 30])[0]
        if data[at + 46: at + 46 + length] == name.encode():
            return at
        at = data.index(b"PK\x01\x02", at + 4)


def test_zip_bombs_and_lying_members_are_refused(tmp_path, small):
    meta, images = small
    # A meta.json that inflates to 5 MiB: refused by its declared size, never inflated.
    padded = json.dumps(meta).encode() + b" " * (5 << 20)
    path = write_bundle(tmp_path / "a.sog", padded, images, zipfile.ZIP_DEFLATED)
    assert_user_error(lambda: load_scene(path), path, "meta.json", "declares 5", "refused")
    # An image member of 64 MiB of zeros (64 KiB compressed) in a 20-gaussian scene.
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, rgba in images.items():
            archive.writestr(name, bytes(64 << 20) if name == "quats.webp" else webp_bytes(rgba))
        archive.writestr("meta.json", json.dumps(meta))
    path = tmp_path / "b.sog"
    path.write_bytes(out.getvalue())
    assert_user_error(lambda: load_scene(path), path, "quats.webp", "declares 67108864 bytes", "refused")
    # A member that declares fewer bytes than it inflates to: stopped one byte past them.
    data = bytearray(bundle_bytes(meta, images, zipfile.ZIP_DEFLATED))
    at = _central_entry(bytes(data), "scales.webp")
    size = struct.unpack("<I", data[at + 24: at + 28])[0]
    data[at + 24: at + 28] = struct.pack("<I", size - 100)
    path = tmp_path / "c.sog"
    path.write_bytes(bytes(data))
    assert_user_error(lambda: load_scene(path), path, "scales.webp", f"more than its declared {size - 100} bytes")
    data[at + 24: at + 28] = struct.pack("<I", size + 100)
    path.write_bytes(bytes(data))
    assert_user_error(lambda: load_scene(path), path, "scales.webp", f"declares {size + 100}")


def test_corrupt_members_and_odd_zip_features(tmp_path, small):
    meta, images = small
    data = bytearray(bundle_bytes(meta, images))
    at = _central_entry(bytes(data), "sh0.webp")
    offset = struct.unpack("<I", data[at + 42: at + 46])[0]
    data[offset + 30 + len("sh0.webp") + 50] ^= 0xFF
    path = tmp_path / "a.sog"
    path.write_bytes(bytes(data))
    assert_user_error(lambda: load_scene(path), path, "sh0.webp", "CRC mismatch")
    data = bytearray(bundle_bytes(meta, images))
    data[at + 8] |= 0x1
    path.write_bytes(bytes(data))
    assert_user_error(lambda: load_scene(path), path, "sh0.webp", "encrypted")
    path = write_bundle(tmp_path / "b.sog", meta, images, zipfile.ZIP_BZIP2)
    assert_user_error(lambda: load_scene(path), path, "compression method 12")


def test_a_central_directory_pointing_before_the_file(tmp_path, small):
    meta, images = small
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as archive:  # meta.json first: its offset becomes negative
        archive.writestr("meta.json", json.dumps(meta))
    data = bytearray(out.getvalue())
    end = data.rindex(b"PK\x05\x06")
    offset = struct.unpack("<I", data[end + 16: end + 20])[0]
    data[end + 16: end + 20] = struct.pack("<I", offset + 1000)
    path = tmp_path / "shifted.sog"
    path.write_bytes(bytes(data))
    assert_user_error(lambda: load_scene(path), path, "meta.json", "starts before the file")


def test_cli_reports_a_hostile_file_in_one_line(tmp_path, capsys, small):
    meta, images = small
    path = write_bundle(tmp_path / "bad.sog", _mutated(meta, lambda m: m.update(count=10 ** 9)), images)
    code, out, err = run_cli(capsys, "info", str(path))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("error:") and "bad.sog" in err and "Traceback" not in err
