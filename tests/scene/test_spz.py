"""Niantic's .spz (issue 18): reading versions 1-4, writing 2-4, axes, hostile files.

Files are written by the plain codec in spz_reference.py (from the owners' format
description, independent of the module); the axis conversion is checked against
constructions that do not use the module's flip tables: covariances F Sigma F and
SH colours seen from F d, with F = diag(1, -1, -1) (RUB <-> RDF).
"""

from __future__ import annotations

import base64
import gzip
import math
import struct
import threading
import zlib

import numpy as np
import pytest
import spz_reference as ref
import testkit
import zstandard

from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.scene.sh import sh_basis, sh_to_rgb
from raygs_viewer.scene.spz_file import spz_bytes
from raygs_viewer.scene.spz_stream import MAX_POINTS

F = np.array([1.0, -1.0, -1.0])
SHARED_SPZ = testkit.SHARED_SCENES / "formats" / "metalsplatter-train3.spz"
SHARED_PLY = testkit.SHARED_SCENES / "metalsplatter-train3.ply"

# What the owners' quantisation allows (12 fractional bits, 8-bit log-scale in steps of
# 1/16, alpha and colour bytes, SH buckets of 8 and 16 levels of 1/128), each a half
# step plus float32 slack. Rotations: a half step of sqrt(1/2)/511 on three components
# and the fourth rebuilt from the norm give at most about 0.24 degrees (version 3+).
POSITION_BOUND = 2.0 ** -13
LOG_SCALE_BOUND = 1 / 32
OPACITY_BOUND = 0.5 / 255
DC_BOUND = 0.5 / (0.15 * 255)
SH1_BOUND = 4.5 / 128
SH_REST_BOUND = 8.5 / 128
ROTATION_BOUND_DEG = 0.25
# Version 2 stores x, y, z in 8 bits (half step d = 0.5/127.5) and rebuilds w >= 0, whose
# error grows as w -> 0: about 2 sqrt(3) d sqrt(1 + 1/w^2) radians, 2.7 degrees for
# |w| >= 0.3 (measured: 2.5 there, 11.4 over all rotations, 0.20 for version 3).
ROTATION_BOUND_V2_DEG = 3.0


# --------------------------------------------------------------------------- helpers


def rub_gaussians(n=40, degree=3, seed=0, spread=3.0):
    """Random gaussians in the file's RUB axes, in the ranges .spz can hold."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return {
        "positions": rng.uniform(-spread, spread, (n, 3)).tolist(),
        "log_scales": rng.uniform(-7, 2, (n, 3)).tolist(),
        "rotations": q.tolist(),
        "alphas": rng.uniform(0, 1, n).tolist(),
        "colors": rng.uniform(-3, 3, (n, 3)).tolist(),
        "sh": rng.uniform(-0.9, 0.9, (n, ref.SH_DIM[degree], 3)).tolist(),
        "degree": degree,
    }


def rdf_scene(n=300, degree=3, seed=1, spread=3.0, w_min=0.0):
    """A Scene (RDF axes) whose values .spz can hold without clamping."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[:, 0] = np.sign(q[:, 0]) * np.maximum(np.abs(q[:, 0]), w_min)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    sh = np.empty((n, sh_coefficient_count(degree), 3), np.float32)
    sh[:, 0] = rng.uniform(-3, 3, (n, 3))
    sh[:, 1:] = rng.uniform(-0.95, 0.95, (n, sh.shape[1] - 1, 3))
    return Scene(rng.uniform(-spread, spread, (n, 3)).astype(np.float32), q.astype(np.float32),
                 np.exp(rng.uniform(-8, 3, (n, 3))).astype(np.float32), rng.uniform(0, 1, n).astype(np.float32),
                 sh, degree)


def covariances(rotations_wxyz, scales):
    q = np.asarray(rotations_wxyz, np.float64)
    r = quaternion_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True)) * np.asarray(scales, np.float64)[:, None, :]
    return r @ r.transpose(0, 2, 1)


def unit_directions(n, seed=7):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def full_sh(colors, rest):
    """(n, (d+1)^2, 3) from the DC colours and the rest."""
    return np.concatenate([np.asarray(colors, np.float64)[:, None, :],
                           np.asarray(rest, np.float64).reshape(len(colors), -1, 3)], axis=1)


def rotation_angles_deg(a, b):
    """Angle of the rotation between unit quaternions a and b (q ~ -q), float64."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    b = b * np.sign(np.sum(a * b, axis=1))[:, None]
    return np.degrees(4 * np.arctan2(np.linalg.norm(a - b, axis=1), np.linalg.norm(a + b, axis=1)))


def write(tmp_path, data: bytes, name="scene.spz"):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def assert_matches_rub(scene: Scene, g: dict):
    """``scene`` (RDF) is the decoded RUB gaussians ``g`` by independent constructions."""
    n = len(g["positions"])
    assert scene.count == n
    np.testing.assert_array_equal(scene.positions, (np.asarray(g["positions"]) * F).astype(np.float32))
    q_rub = np.asarray(g["rotations"])[:, [3, 0, 1, 2]]
    sigma_rub = covariances(q_rub, g["scales"])
    sigma = covariances(scene.rotations, scene.scales)
    np.testing.assert_allclose(sigma, F[:, None] * sigma_rub * F[None, :],
                               rtol=2e-5, atol=2e-6 * np.max(g["scales"]) ** 2)
    np.testing.assert_allclose(np.linalg.norm(scene.rotations, axis=1), 1, atol=1e-6)
    np.testing.assert_allclose(scene.opacities, g["alphas"], atol=1e-7)
    degree = scene.sh_degree
    dirs = unit_directions(n)
    sh_rub = full_sh(g["colors"], np.asarray(g["sh"])[:, : sh_coefficient_count(degree) - 1])
    np.testing.assert_allclose(sh_to_rgb(scene.sh.astype(np.float64), degree, dirs),
                               sh_to_rgb(sh_rub, degree, dirs * F), atol=2e-6)


# --------------------------------------------------------------------------- the shared sample


@pytest.mark.skipif(not SHARED_SPZ.exists() or not SHARED_PLY.exists(), reason="shared scenes folder absent")
def test_shared_sample_matches_its_ply_within_the_quantisation():
    spz, ply = load_scene(SHARED_SPZ), load_scene(SHARED_PLY)
    assert (spz.format, spz.count, spz.sh_degree, spz.dropped) == ("spz v3", 3, 3, {})
    # The PLY's float32 positions (|x| < 3) add at most 2^-22 to the half step.
    assert np.abs(spz.positions - ply.positions).max() <= POSITION_BOUND + 2.0 ** -22
    assert np.abs(np.log(spz.scales / ply.scales)).max() <= LOG_SCALE_BOUND + 1e-5
    assert np.abs(spz.opacities - ply.opacities).max() <= OPACITY_BOUND + 1e-6
    assert np.abs(spz.sh[:, 0] - ply.sh[:, 0]).max() <= DC_BOUND + 1e-6
    assert np.abs(spz.sh[:, 1:4] - ply.sh[:, 1:4]).max() <= SH1_BOUND + 1e-6
    assert np.abs(spz.sh[:, 4:] - ply.sh[:, 4:]).max() <= SH_REST_BOUND + 1e-6
    assert rotation_angles_deg(spz.rotations, ply.rotations).max() <= ROTATION_BOUND_DEG
    # Without the axis conversion the file would be far off (y and z are not near 0).
    assert np.abs(spz.positions[:, 1:] * -1 - ply.positions[:, 1:]).max() > 0.1


# --------------------------------------------------------------------------- reading


@pytest.mark.parametrize("version,degree", [(1, 1), (2, 0), (2, 3), (3, 0), (3, 1), (3, 2), (3, 3), (4, 0), (4, 3)])
def test_reads_each_version_in_rdf_axes(tmp_path, version, degree):
    g = rub_gaussians(degree=degree, seed=version)
    path = write(tmp_path, ref.pack(g, version))
    scene = load_scene(path, chunk_bytes=97)  # many chunks, none aligned to a row
    assert scene.format == f"spz v{version}"
    assert scene.sh_degree == degree
    assert_matches_rub(scene, ref.unpack(path.read_bytes()))


def test_unnamed_files_are_recognised_by_their_first_bytes(tmp_path):
    g = rub_gaussians(n=5, degree=1)
    for version in (3, 4):
        scene = load_scene(write(tmp_path, ref.pack(g, version), f"scene{version}.bin"))
        assert scene.format == f"spz v{version}" and scene.count == 5


def test_sh_degree_4_is_read_as_its_degree_3_part(tmp_path):
    g = rub_gaussians(n=30, degree=4, seed=3)
    path = write(tmp_path, ref.pack(g, 4))
    scene = load_scene(path)
    assert scene.sh_degree == 3
    decoded = ref.unpack(path.read_bytes())
    decoded["sh"] = [rows[:15] for rows in decoded["sh"]]
    assert_matches_rub(scene, decoded)


def test_extension_records_and_the_coordinate_system_extension(tmp_path):
    g = rub_gaussians(n=8, degree=1)
    unknown = struct.pack("<II", 0x12340001, 5) + b"hello"
    # Legacy files append their records after the arrays.
    scene = load_scene(write(tmp_path, ref.pack(g, 3, flags=2, extensions=unknown)))
    assert_matches_rub(scene, g | ref.unpack(ref.pack(g, 3)))
    # Without the flag, bytes after the arrays are a corrupt file.
    testkit.assert_user_error(lambda: load_scene(write(tmp_path, ref.pack(g, 3, extensions=unknown), "x.spz")),
                              "x.spz", "runs past")
    # Stored in RDF already (SPZ_ADOBE_coordinate_system = 6): no conversion.
    rdf = struct.pack("<III", 0xADBE0003, 4, 6)
    scene = load_scene(write(tmp_path, ref.pack(g, 4, flags=2, extensions=unknown + rdf), "rdf.spz"))
    np.testing.assert_array_equal(scene.positions, np.float32(ref.unpack(ref.pack(g, 4))["positions"]))
    # A rotated-family system needs an SH rotation: refused in one line.
    lfd = struct.pack("<III", 0xADBE0003, 4, 9)
    testkit.assert_user_error(lambda: load_scene(write(tmp_path, ref.pack(g, 4, flags=2, extensions=lfd), "l.spz")),
                              "l.spz", "LFD")


def test_progress_and_cancel(tmp_path):
    path = write(tmp_path, ref.pack(rub_gaussians(n=200, degree=3), 3))
    seen = []
    load_scene(path, progress=lambda fraction, stage: seen.append((fraction, stage)), chunk_bytes=256)
    fractions = [f for f, _ in seen]
    assert fractions == sorted(fractions) and seen[-1] == (1.0, "done")
    assert sum(stage == "reading" for _, stage in seen) > 20
    cancel = threading.Event()
    cancel.set()
    with pytest.raises(UserError, match="cancelled"):
        load_scene(path, cancel=cancel, chunk_bytes=256)


# --------------------------------------------------------------------------- writing


def rub_of(scene: Scene) -> dict:
    """The scene's gaussians in RUB for the reference packer. Position and quaternion
    flips are the definitions checked by the covariance tests; the SH signs are derived
    here from the basis itself: sign_k = Y_k(F d) / Y_k(d) for a generic direction d."""
    d = np.array([[0.3, 0.5, 0.8]]) / np.linalg.norm([0.3, 0.5, 0.8])
    signs = np.sign(sh_basis(d * F, 3)[0] / sh_basis(d, 3)[0])
    k = sh_coefficient_count(scene.sh_degree)
    q = scene.rotations.astype(np.float64)[:, [1, 2, 3, 0]] * [1, -1, -1, 1]
    return {
        "positions": (scene.positions.astype(np.float64) * F).tolist(),
        "log_scales": np.log(scene.scales.astype(np.float64)).tolist(),
        "rotations": q.tolist(),
        "alphas": scene.opacities.astype(np.float64).tolist(),
        "colors": scene.sh[:, 0].astype(np.float64).tolist(),
        "sh": (scene.sh[:, 1:].astype(np.float64) * signs[None, 1:k, None]).tolist(),
        "degree": scene.sh_degree,
    }


@pytest.mark.parametrize("version", [2, 3, 4])
@pytest.mark.parametrize("degree", [0, 3])
def test_writer_matches_the_owners_quantisation(version, degree):
    scene = rdf_scene(n=120, degree=degree, seed=version + degree)
    head, arrays = ref.payload(spz_bytes(scene, version))
    assert head == {"version": version, "n": 120, "degree": degree, "fractional_bits": 12, "flags": 0}
    _, expected = ref.payload(ref.pack(rub_of(scene), version))
    names = ["positions", "alphas", "colours", "scales", "rotations", "sh"]
    for name, got, want in zip(names, arrays, expected):
        assert got == want, name


@pytest.mark.parametrize("version", [2, 3, 4])
def test_round_trip_within_the_quantisation(tmp_path, version):
    scene = rdf_scene(n=4000, degree=3, seed=version, w_min=0.3 if version == 2 else 0.0)
    back = load_scene(write(tmp_path, spz_bytes(scene, version)))
    assert back.format == f"spz v{version}" and back.count == scene.count and back.sh_degree == 3
    assert np.abs(back.positions - scene.positions).max() <= POSITION_BOUND + 2.0 ** -22
    assert np.abs(np.log(back.scales / scene.scales)).max() <= LOG_SCALE_BOUND + 1e-5
    assert np.abs(back.opacities - scene.opacities).max() <= OPACITY_BOUND + 1e-6
    assert np.abs(back.sh[:, 0] - scene.sh[:, 0]).max() <= DC_BOUND + 1e-6
    assert np.abs(back.sh[:, 1:4] - scene.sh[:, 1:4]).max() <= SH1_BOUND + 1e-6
    assert np.abs(back.sh[:, 4:] - scene.sh[:, 4:]).max() <= SH_REST_BOUND + 1e-6
    bound = ROTATION_BOUND_V2_DEG if version == 2 else ROTATION_BOUND_DEG
    assert rotation_angles_deg(back.rotations, scene.rotations).max() <= bound


def test_axes_of_a_written_file_by_construction():
    """A gaussian elongated along (1, 1, 0) in RDF, lit by the SH function -C1 y: in the
    file it is elongated along (1, -1, 0), sits at F p, and shows from F d the colour the
    scene shows from d."""
    angle = np.radians(45) / 2
    sh = np.zeros((1, 4, 3), np.float32)
    sh[0, 1, 0] = 0.8  # red rises towards -y in RDF
    scene = Scene(np.float32([[0.5, 1.0, 2.0]]), np.float32([[np.cos(angle), 0, 0, np.sin(angle)]]),
                  np.float32([[0.4, 0.05, 0.05]]), np.float32([0.7]), sh, 1)
    g = ref.unpack(spz_bytes(scene))
    np.testing.assert_allclose(g["positions"][0], [0.5, -1.0, -2.0], atol=POSITION_BOUND)
    sigma = covariances(np.asarray(g["rotations"])[:, [3, 0, 1, 2]], g["scales"])[0]
    major = np.linalg.eigh(sigma)[1][:, -1]
    assert abs(abs(major @ np.array([1, -1, 0]) / np.sqrt(2)) - 1) < 1e-4, major
    assert g["sh"][0][0][0] == pytest.approx(-0.8, abs=SH1_BOUND)  # red now rises towards +y
    d = np.array([[0.0, -1.0, 0.0]])
    seen_rdf = sh_to_rgb(scene.sh.astype(np.float64), 1, d)
    seen_rub = sh_to_rgb(full_sh(g["colors"], g["sh"]), 1, d * F)
    np.testing.assert_allclose(seen_rub, seen_rdf, atol=DC_BOUND * 0.3 + SH1_BOUND * 0.5)
    assert seen_rdf[0, 0] > 0.5 + 0.28 * sh[0, 0, 0] + 0.3  # the SH term matters in this check


def test_fractional_bits_shrink_for_large_scenes_and_huge_ones_are_refused(tmp_path):
    scene = rdf_scene(n=50, degree=0, spread=3000.0)
    data = spz_bytes(scene)
    assert ref.payload(data)[0]["fractional_bits"] == 11
    back = load_scene(write(tmp_path, data))
    assert np.abs(back.positions - scene.positions).max() <= 2.0 ** -12 + 3000 * 2.0 ** -23
    assert ref.payload(spz_bytes(rdf_scene(n=50, degree=0, spread=2047.0)))[0]["fractional_bits"] == 12
    with pytest.raises(UserError, match="does not fit") as info:
        spz_bytes(rdf_scene(n=5, degree=0, spread=2e7))
    assert "\n" not in str(info.value)
    with pytest.raises(UserError, match="version 1"):
        spz_bytes(scene, 1)


@pytest.mark.parametrize("version", [2, 3, 4])
def test_empty_scene_round_trip(tmp_path, version):
    empty = Scene(np.zeros((0, 3), np.float32), np.zeros((0, 4), np.float32), np.zeros((0, 3), np.float32),
                  np.zeros(0, np.float32), np.zeros((0, 16, 3), np.float32), 3)
    back = load_scene(write(tmp_path, spz_bytes(empty, version)))
    assert (back.count, back.sh_degree, back.format) == (0, 3, f"spz v{version}")


# --------------------------------------------------------------------------- bad input


def legacy(version=3, n=3, degree=0, bits=12, flags=0, body=None, extra=b""):
    """A gzip .spz whose header says what the arguments say (body: the arrays' bytes)."""
    header = struct.pack("<IIIBBBB", ref.MAGIC, version, n, degree, bits, flags, 0)
    if body is None:
        body = bytes(n * (9 + 1 + 3 + 3 + (4 if version >= 3 else 3) + 3 * ref.SH_DIM[degree]))
    return gzip.compress(header + body + extra)


def ngsp(n=3, degree=0, streams=None, toc=32, sizes=None, packed=None, version=4):
    """A version-4 file: header, TOC and the given zstd streams (default: valid zeros)."""
    sizes = [9 * n, n, 3 * n, 3 * n, 4 * n] + ([3 * n * ref.SH_DIM[degree]] if degree else []) \
        if sizes is None else sizes
    packed = [zstandard.ZstdCompressor().compress(bytes(s)) for s in sizes] if packed is None else packed
    count = len(packed) if streams is None else streams
    header = struct.pack("<IIIBBBBI", ref.MAGIC, version, n, degree, 12, 0, count, toc) + bytes(12)
    return header + b"".join(struct.pack("<QQ", len(p), s) for p, s in zip(packed, sizes)) + b"".join(packed)


def _corrupt_deflate():
    data = bytearray(legacy(n=50))
    data[10] ^= 0xFF  # the first deflate byte: an invalid block type
    data[11] ^= 0xFF
    return bytes(data)


def _bad_crc():
    data = bytearray(legacy(n=5))
    data[-8] ^= 1
    return bytes(data)


_ZSTD_BOMB = zstandard.ZstdCompressor().compress(bytes(50_000_000))

BAD_FILES = {
    "empty": (b"", "not a .spz file"),
    "neither gzip nor NGSP": (b"hello world, not a splat", "not a .spz file"),
    "gzip of something else": (gzip.compress(b"PK\x03\x04" + bytes(40)), "does not start with 'NGSP'"),
    "gzip of a short header": (gzip.compress(b"NGSP"), "ends inside its header"),
    "unsupported version in gzip": (legacy(version=5), "unsupported .spz version 5"),
    "version 0": (legacy(version=0), "unsupported .spz version 0"),
    "unsupported version NGSP": (ngsp(version=9), "unsupported .spz version 9"),
    "NGSP with a gzip version": (ngsp(version=3), "version 3 files are gzip-compressed"),
    "NGSP version 0": (ngsp(version=0), "unsupported .spz version 0"),
    "truncated gzip": (legacy(n=200, body=np.random.default_rng(0).bytes(200 * 20))[:-30],
                       "cut off inside the gaussians"),
    "gzip cut in its header": (legacy(n=200)[:12], "truncated .spz"),
    "gzip bomb": (legacy(n=3, extra=bytes(20_000_000)), "runs past"),
    "data too short": (legacy(n=1000, body=bytes(100)), "ends inside the gaussians"),
    "absurd count": (legacy(n=2**32 - 1, body=b""), f"at most {MAX_POINTS:,}"),
    "count beyond what gzip can hold": (legacy(n=MAX_POINTS, body=b""), "cannot come out of"),
    "SH degree 7": (legacy(degree=7, body=b""), "SH degree 7"),
    "fractional bits 40": (legacy(bits=40), "40 fractional bits"),
    "corrupt deflate": (_corrupt_deflate(), "damaged"),
    "bad checksum": (_bad_crc(), "damaged"),
    "NGSP short header": (ngsp()[:20], "32-byte"),
    "v4 absurd count": (ngsp(n=2**31, sizes=[9, 1, 3, 3, 4]), f"at most {MAX_POINTS:,}"),
    "v4 count beyond the owners' ratio": (ngsp(n=MAX_POINTS // 2, sizes=[9, 1, 3, 3, 4]), "cannot come out of"),
    "v4 TOC outside the file": (ngsp(toc=10**9), "table of contents"),
    "v4 TOC inside the header": (ngsp(toc=8), "table of contents"),
    "v4 wrong stream count": (ngsp(streams=9), "streams"),
    "v4 stream sizes past the end": (ngsp()[:-3], "accounts for"),
    "v4 trailing bytes": (ngsp() + b"x", "accounts for"),
    "v4 wrong uncompressed size": (ngsp(sizes=[27, 3, 9, 9, 13]), "declares 13 bytes"),
    "v4 zstd bomb": (ngsp(packed=[_ZSTD_BOMB] + [zstandard.ZstdCompressor().compress(bytes(s))
                                                 for s in (3, 9, 9, 12)]), "holds more than"),
    "v4 truncated stream": (ngsp(packed=[zstandard.ZstdCompressor().compress(bytes(range(27)))[:-4]]
                                 + [zstandard.ZstdCompressor().compress(bytes(s)) for s in (3, 9, 9, 12)]),
                            "stream 0"),
    "v4 garbage stream": (ngsp(packed=[b"\x28\xb5\x2f\xfd" + b"junk" * 4]
                               + [zstandard.ZstdCompressor().compress(bytes(s)) for s in (3, 9, 9, 12)]),
                          "stream 0"),
    "v4 bad coordinate system": (None, "coordinate system 99"),
}


def _bad_coordinate_system():
    g = rub_gaussians(n=2, degree=0)
    return ref.pack(g, 4, flags=2, extensions=struct.pack("<III", 0xADBE0003, 4, 99))


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_files_are_one_line_user_errors(tmp_path, case):
    data, fragment = BAD_FILES[case]
    if data is None:
        data = _bad_coordinate_system()
    path = write(tmp_path, data)
    message = testkit.assert_user_error(lambda: load_scene(path), path, fragment)
    assert "Traceback" not in message


def test_gzip_bomb_is_small_on_disk():
    data, _ = BAD_FILES["gzip bomb"]
    assert len(data) < 40_000 and len(zlib.decompress(data, 31)) > 20_000_000
    assert len(_ZSTD_BOMB) < 10_000


def test_valid_builders_behind_the_bad_files_load(tmp_path):
    """The bad files differ from valid ones only in what each case changes."""
    assert load_scene(write(tmp_path, legacy(n=3))).count == 3
    assert load_scene(write(tmp_path, ngsp(n=3), "v4.spz")).count == 3
    assert load_scene(write(tmp_path, ngsp(n=3, degree=2), "v4d2.spz")).sh_degree == 2
    assert math.isclose(load_scene(write(tmp_path, legacy(n=1), "one.spz")).scales[0, 0], math.exp(-10),
                        rel_tol=1e-6)


def test_rotation_words_a_writer_cannot_make_still_give_unit_quaternions(tmp_path):
    """Three stored components of -sqrt(1/2) square-sum to 1.5: the largest (w) becomes 0,
    and y, z flip sign into RDF."""
    header = struct.pack("<IIIBBBB", ref.MAGIC, 3, 2, 0, 12, 0, 0)
    body = bytes(2 * 16) + b"\xff" * 4 + bytes(4)
    scene = load_scene(write(tmp_path, gzip.compress(header + body)))
    np.testing.assert_allclose(scene.rotations[0], np.float32([0, -1, 1, 1]) / np.sqrt(3), atol=1e-6)
    np.testing.assert_allclose(scene.rotations[1], [0, 1, 0, 0])  # word 0: index 0 (x) is largest


# --------------------------------------------------------------------------- files the owners wrote

# Written by the owners' own writer (nianticlabs/spz 21715c3, ``loadSplatFromPly`` then
# ``saveSpz`` with PackOptions{from = RDF, version}) from the PLY of ``owners_columns()``:
# a check of the reader on their files, version 4's layout included, with no build here.
OWNERS_V2 = base64.b64decode(
    "H4sIAAAAAAAAAwFgAZ/+TkdTUAIAAAAMAAAAAQwAAOEQAOIlAIkbAJPk/7H5/6wVALXt/44vAIPi/8AcAFkDAD0WAJkvAFfS"
    "/0QWAKfd/0Hj/zIpAI/X/7T2/yYDAFzh/8QQAKMWAIfy/zEcAKna/0ng/4AFAIMUAIUIAE8VALjl/zcLAAHc/zkBAN4M7xII"
    "zIgSBibyRH1rhqNbeZ6PeF9zoWxzXWducp9sgYSFh3ZzXJl6bHRpXY2AWoqTTJ9ae46ViJ9GnG9VgJuOd1N2flKQZoNldJ1D"
    "a354dXd+fhnIk6u7Qp88K6x/KkGbNfWWetUie9krn4QVkpBqdHYpcZKZVai4GLhgOPAYsJiAKJBggJAYmDDY0Ng4ECBIiPCY"
    "QFDYMKBguFBA8ODAYECQ0IjAWLAgKGjgEGgwqMBw4EBA4NBooNjIwFAwmDhgwHiQIJgw2KAgcMiYyIAggJiAIEjY4BAwWHDQ"
    "OLBomOBAMEX348tgAQAA"
)

OWNERS_V4 = base64.b64decode(
    "TkdTUAQAAAAMAAAAAQwABiAAAAAAAAAAAAAAAAAAAAB1AAAAAAAAAGwAAAAAAAAAFQAAAAAAAAAMAAAAAAAAAC0AAAAAAAAA"
    "JAAAAAAAAAAtAAAAAAAAACQAAAAAAAAAOQAAAAAAAAAwAAAAAAAAAGcAAAAAAAAAbAAAAAAAAAAotS/9IGxhAwDhEADiJQCJ"
    "GwCT5P+x+f+sFQC17f+OLwCD4v/AHABZAwA9FgCZLwBX0v9EFgCn3f9B4/8yKQCP1/+09v8mAwBc4f/EEACjFgCH8v8xHACp"
    "2v9J4P+ABQCDFACFCABPFQC45f83CwAB3P85AQAotS/9IAxhAADeDO8SCMyIEgYm8kQotS/9ICQhAQB9a4ajW3mej3hfc6Fs"
    "c11nbnKfbIGEhYd2c1yZemx0aV2NgFootS/9ICQhAQCKk0yfWnuOlYifRpxvVYCbjndTdn5SkGaDZXSdQ2t+eHV3fn4otS/9"
    "IDCBAQBHssk5Wk9lz07/RavbC6CvqWsi9vN4GAgtbmB+C9ACPnybuWFA5gnGUbaP4+9KcsYotS/9IGz1AgDChhYZ0LUBFJ5n"
    "y6oqJ+Mxl7m4wp/M5THv8ji4BLrfhxWIBB3vQaZOmV4/lMu1Uw2OS6txz9eBv/vIFXrGHyCZ4Aiolt3HNY2XutmORJCjOHRt"
    "ohIrIDUjsXAjrQgA"
)


def owners_columns():
    rng = np.random.default_rng(2024)
    n, k = 12, 3
    cols = {a: rng.uniform(-3, 3, n) for a in "xyz"}
    cols.update({f"f_dc_{c}": rng.uniform(-1, 1, n) for c in range(3)})
    cols.update({f"f_rest_{j}": rng.uniform(-0.9, 0.9, n) for j in range(3 * k)})
    cols["opacity"] = rng.uniform(-4, 4, n)
    cols.update({f"scale_{a}": rng.uniform(-6, 0, n) for a in range(3)})
    cols.update({f"rot_{a}": rng.normal(size=n) for a in range(4)})
    return cols


@pytest.mark.parametrize("version,data", [(2, OWNERS_V2), (4, OWNERS_V4)])
def test_files_the_owners_wrote_match_their_ply(tmp_path, version, data):
    ply = load_scene(testkit.write_ply(tmp_path / "source.ply", owners_columns()))
    spz = load_scene(write(tmp_path, data))
    assert (spz.format, spz.count, spz.sh_degree) == (f"spz v{version}", 12, 1)
    assert np.abs(spz.positions - ply.positions).max() <= POSITION_BOUND + 2.0 ** -22
    assert np.abs(np.log(spz.scales / ply.scales)).max() <= LOG_SCALE_BOUND + 1e-5
    assert np.abs(spz.opacities - ply.opacities).max() <= OPACITY_BOUND + 1e-6
    assert np.abs(spz.sh[:, 0] - ply.sh[:, 0]).max() <= DC_BOUND + 1e-6
    assert np.abs(spz.sh[:, 1:] - ply.sh[:, 1:]).max() <= SH1_BOUND + 1e-6
    angles = rotation_angles_deg(spz.rotations, ply.rotations)
    w = np.abs(ply.rotations[:, 0])
    assert angles[w >= 0.3].max() <= (ROTATION_BOUND_V2_DEG if version == 2 else ROTATION_BOUND_DEG)
