"""Loading scenes: INRIA PLY and .splat (section 2 of the maths page)."""

from __future__ import annotations

import json
import os
import threading
import tracemalloc
import warnings

import numpy as np
import pytest
import testkit

from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import (
    DROP_REASONS,
    describe,
    dropped_summary,
    format_description,
    load_scene,
)

C0 = 0.28209479177387814
SHARED_SCENES = testkit.SHARED_SCENES

_STANDARD = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
from testkit import gaussian_columns, ply_bytes, splat_bytes, write_ply

# --------------------------------------------------------------------------- helpers








def sigmoid64(x):
    return 1.0 / (1.0 + np.exp(-np.asarray(x, np.float64)))


def assert_scene_error(path, *fragments):
    return testkit.assert_user_error(lambda: load_scene(path), path, *fragments)


@pytest.fixture
def strict_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


# --------------------------------------------------------------------------- PLY: good files


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_sh_degree_and_channel_major_layout(tmp_path, degree):
    n = 3
    cols = gaussian_columns(n, degree)
    scene = load_scene(write_ply(tmp_path / "sh.ply", cols))
    k = (degree + 1) ** 2 - 1
    assert scene.sh_degree == degree
    assert scene.sh.shape == (n, k + 1, 3) and scene.sh.dtype == np.float32
    for i in range(n):
        for c in range(3):
            assert scene.sh[i, 0, c] == np.float32(cols[f"f_dc_{c}"][i])
            for kk in range(k):
                # f_rest[c*K + k] is coefficient k+1 of channel c
                assert scene.sh[i, kk + 1, c] == 1000.0 * i + c * k + kk


def test_f_rest_order_in_file_does_not_matter(tmp_path):
    cols = gaussian_columns(3, 2)
    names = list(cols)
    shuffled = {name: cols[name] for name in reversed(names)}
    a = load_scene(write_ply(tmp_path / "a.ply", cols))
    b = load_scene(write_ply(tmp_path / "b.ply", shuffled))
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_activations(tmp_path, strict_warnings):
    cols = gaussian_columns(4)
    cols["rot_0"][:] = [2.0, 0.0, 0.0, -1.0]
    cols["rot_1"][:] = [0.0, 0.0, 0.0, 1.0]
    cols["rot_2"][:] = [0.0, 3.0, 0.0, 1.0]
    cols["rot_3"][:] = [0.0, 4.0, 1e-3, 1.0]
    path = write_ply(tmp_path / "act.ply", cols)
    scene = load_scene(path)
    for name in ("positions", "rotations", "scales", "opacities", "sh"):
        assert getattr(scene, name).dtype == np.float32
    assert scene.source == str(path)
    assert scene.dropped == {} and not scene.filter_fused
    f32 = lambda v: np.asarray(v, np.float32).astype(np.float64)  # the file stores float32
    np.testing.assert_array_equal(scene.positions, np.stack([cols["x"], cols["y"], cols["z"]], 1).astype(np.float32))
    np.testing.assert_allclose(scene.opacities, sigmoid64(f32(cols["opacity"])), rtol=1e-6)
    logs = np.stack([f32(cols[f"scale_{a}"]) for a in range(3)], 1)
    np.testing.assert_allclose(scene.scales, np.exp(logs), rtol=1e-6)
    # rot_0 is w; normalised
    np.testing.assert_allclose(scene.rotations, [[1, 0, 0, 0], [0, 0, 0.6, 0.8], [0, 0, 0, 1], [-0.5, 0.5, 0.5, 0.5]],
                               atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(scene.rotations, axis=1), 1, atol=1e-6)


def test_infinite_and_huge_opacity_logits(tmp_path, strict_warnings):
    cols = gaussian_columns(5)
    cols["opacity"][:] = [np.inf, -np.inf, 1e30, -1e30, 0.0]
    scene = load_scene(write_ply(tmp_path / "logits.ply", cols))
    assert scene.count == 5 and scene.dropped == {}
    assert scene.opacities[0] == 1.0 and scene.opacities[1] == 0.0
    assert scene.opacities[2] == 1.0 and scene.opacities[3] == 0.0
    assert scene.opacities[4] == 0.5


def test_tiny_scales_are_kept(tmp_path, strict_warnings):
    cols = gaussian_columns(2)
    cols["scale_0"][:] = [-23.0, -100.0]  # exp(-100) is a float32 subnormal: still positive
    scene = load_scene(write_ply(tmp_path / "tiny.ply", cols))
    assert scene.count == 2 and scene.dropped == {}
    np.testing.assert_allclose(scene.scales[0, 0], np.exp(-23.0), rtol=1e-6)
    assert scene.scales[1, 0] > 0


def test_filter_3d_fused_on_activated_values(tmp_path, strict_warnings):
    cols = gaussian_columns(4, degree=1, filter_3d=[0.01, 0.5, 0.0, 2.0])
    scene = load_scene(write_ply(tmp_path / "filter.ply", cols))
    assert scene.filter_fused and scene.count == 4
    f32 = lambda v: np.asarray(v, np.float32).astype(np.float64)
    s = np.exp(np.stack([f32(cols[f"scale_{a}"]) for a in range(3)], 1))
    f = f32(cols["filter_3D"])[:, None]
    o = sigmoid64(f32(cols["opacity"]))
    expected_o = o * np.sqrt(np.prod(s**2, axis=1) / np.prod(s**2 + f**2, axis=1))
    np.testing.assert_allclose(scene.scales, np.sqrt(s**2 + f**2), rtol=1e-6)
    np.testing.assert_allclose(scene.opacities, expected_o, rtol=1e-5)
    assert scene.opacities[2] == np.float32(o[2])  # f = 0: unchanged
    assert np.all(scene.opacities[[0, 1, 3]] < o[[0, 1, 3]])


def test_filter_3d_rescues_a_zero_scale(tmp_path, strict_warnings):
    cols = gaussian_columns(1, filter_3d=0.25)
    cols["scale_2"][:] = -np.inf
    cols["opacity"][:] = np.inf
    scene = load_scene(write_ply(tmp_path / "flat.ply", cols))
    assert scene.count == 1 and scene.dropped == {}
    assert scene.scales[0, 2] == np.float32(0.25)
    assert scene.opacities[0] == 0.0  # o' = 1 * 0 / 0.25 ...


def test_normals_present_or_absent_give_the_same_scene(tmp_path):
    a = load_scene(write_ply(tmp_path / "plain.ply", gaussian_columns(3, 3)))
    b = load_scene(write_ply(tmp_path / "normals.ply", gaussian_columns(3, 3, normals=True)))
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_unknown_properties_of_any_type_are_ignored(tmp_path):
    base = gaussian_columns(3, 1)
    cols = {"red": np.array([1, 2, 250])}  # a uchar first: misaligns every float after it
    cols.update(base)
    cols["transform"] = np.array([7.0, 8.0, 9.0])
    cols["weight"] = np.array([1e300, -1.0, 0.0])
    cols["label"] = np.array([-5, 6, 7])
    cols["nan_extra"] = np.array([np.nan, np.inf, -np.inf])  # unused: does not invalidate
    types = {"red": "uchar", "weight": "double", "label": "short"}
    a = load_scene(write_ply(tmp_path / "base.ply", base))
    b = load_scene(write_ply(tmp_path / "extra.ply", cols, types=types))
    assert b.count == 3 and b.dropped == {}
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_crlf_header(tmp_path):
    cols = gaussian_columns(2)
    a = load_scene(write_ply(tmp_path / "lf.ply", cols))
    b = load_scene(write_ply(tmp_path / "crlf.ply", cols, nl="\r\n"))
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.sh, b.sh)


def test_other_elements_before_and_after_vertex(tmp_path):
    cols = gaussian_columns(3)
    meta = ("element meta 2\nproperty int a\nproperty uchar b", np.zeros(2 * 5, np.uint8).tobytes())
    faces = ("element face 2\nproperty list uchar int vertex_indices",
             bytes([3]) + np.int32([0, 1, 2]).tobytes() + bytes([2]) + np.int32([1, 2]).tobytes())
    a = load_scene(write_ply(tmp_path / "plain.ply", cols))
    b = load_scene(write_ply(tmp_path / "elements.ply", cols, elements_before=[meta, faces]))
    c = load_scene(write_ply(tmp_path / "after.ply", cols, elements_after=[meta, faces]))
    for scene in (b, c):
        assert scene.count == 3
        np.testing.assert_array_equal(a.positions, scene.positions)
        np.testing.assert_array_equal(a.sh, scene.sh)


def test_ply_is_recognised_by_content_whatever_the_extension(tmp_path):
    scene = load_scene(write_ply(tmp_path / "scene.data", gaussian_columns(2)))
    assert scene.count == 2
    assert load_scene(write_ply(tmp_path / "SCENE.PLY", gaussian_columns(2))).count == 2


@pytest.mark.parametrize("degree", [0, 3])
def test_empty_scene_is_valid(tmp_path, degree):
    cols = {name: np.zeros(0) for name in gaussian_columns(1, degree)}
    scene = load_scene(write_ply(tmp_path / "empty.ply", cols))
    assert scene.count == 0 and scene.sh_degree == degree
    assert scene.sh.shape == (0, (degree + 1) ** 2, 3)
    info = describe(scene)
    json.dumps(info)
    assert info["count"] == 0 and info["bbox"] is None and info["opacity"] is None and info["scale"] is None
    assert "0" in format_description(info)


# --------------------------------------------------------------------------- PLY: invalid gaussians


def test_invalid_gaussians_are_dropped_and_counted(tmp_path, strict_warnings):
    n = 15
    cols = gaussian_columns(n, degree=1, filter_3d=0.0)
    cols["x"][:] = np.arange(n)  # tags to follow the survivors
    cols["y"][1] = np.nan                      # nan
    cols["f_rest_5"][2] = np.nan               # nan (in SH)
    cols["opacity"][3] = np.nan                # nan (opacity)
    cols["filter_3D"][4] = np.nan              # nan (filter)
    cols["z"][5] = -np.inf                     # infinite position
    cols["scale_1"][6] = np.inf                # infinite scale
    cols["scale_0"][7] = 100.0                 # exp overflows float32: infinite scale
    cols["scale_2"][8] = -np.inf               # zero scale
    cols["scale_2"][9] = -200.0                # exp underflows to 0: zero scale
    cols["rot_3"][10] = np.inf                 # infinite rotation
    for a in range(4):
        cols[f"rot_{a}"][11] = 0.0             # zero quaternion
    cols["f_dc_1"][12] = np.inf                # infinite colour
    cols["x"][13] = np.nan                     # nan wins over infinite scale
    cols["scale_0"][13] = np.inf
    cols["opacity"][14] = -np.inf              # valid
    scene = load_scene(write_ply(tmp_path / "invalid.ply", cols))
    assert scene.dropped == {"nan": 5, "infinite position": 1, "infinite scale": 2, "zero scale": 2,
                             "infinite rotation": 1, "zero quaternion": 1, "infinite colour": 1}
    assert set(scene.dropped) <= set(DROP_REASONS)
    np.testing.assert_array_equal(scene.positions[:, 0], [0, 14])
    assert scene.opacities[1] == 0.0
    for name in ("positions", "rotations", "scales", "opacities", "sh"):
        assert np.all(np.isfinite(getattr(scene, name)))
    assert np.all(scene.scales > 0)
    lines = dropped_summary(scene)
    assert "dropped 5 gaussians: nan" in lines
    assert "dropped 1 gaussian: zero quaternion" in lines
    assert len(lines) == 7
    info = describe(scene)
    assert info["dropped"]["total"] == 13 and info["dropped"]["by_reason"]["zero scale"] == 2


def test_dropped_summary_empty_when_nothing_dropped(tmp_path):
    scene = load_scene(write_ply(tmp_path / "ok.ply", gaussian_columns(2)))
    assert dropped_summary(scene) == []


# --------------------------------------------------------------------------- PLY: bad input


def _header(*lines, fmt="binary_little_endian"):
    return "\n".join(["ply", f"format {fmt} 1.0", *lines, "end_header", ""]).encode()


def _standard_props(names=_STANDARD):
    return [f"property float {name}" for name in names]


def test_missing_file(tmp_path):
    assert_scene_error(tmp_path / "nothing.ply", "no such file")


def test_directory(tmp_path):
    d = tmp_path / "adir.ply"
    d.mkdir()
    assert_scene_error(d, "directory")


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root can read any file")
def test_unreadable_file(tmp_path):
    path = write_ply(tmp_path / "locked.ply", gaussian_columns(2))
    path.chmod(0)
    try:
        assert_scene_error(path, "permission denied")
    finally:
        path.chmod(0o644)


def test_read_error_is_a_user_error(tmp_path, monkeypatch):
    import errno

    import raygs_viewer.scene.ply_header as ply_header

    path = write_ply(tmp_path / "flaky.ply", gaussian_columns(2))

    def failing_open(*args, **kwargs):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(ply_header, "open", failing_open, raising=False)  # the first read of a .ply
    assert_scene_error(path, "cannot read", "Input/output error")


BAD_FILES = {
    "bad_magic": (b"PK\x03\x04 this is a zip", "not a PLY"),
    "empty": (b"", "not a PLY"),
    "ascii": (_header("element vertex 1", *_standard_props(), fmt="ascii") + b"0 " * 14 + b"\n", "ASCII"),
    "big_endian": (ply_bytes(gaussian_columns(2), fmt="binary_big_endian"), "big-endian"),
    "no_end_header": (b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n", "end_header"),
    "garbage_header": (_header("element vertex 0", "bogus line here", *_standard_props()), "garbage"),
    "binary_garbage_header": (b"ply\n\xff\xfe\x00\x01garbage\nend_header\n", "ASCII"),
    "no_format": (b"ply\nelement vertex 0\nend_header\n", "format"),
    "bad_version": (b"ply\nformat binary_little_endian 2.0\nelement vertex 0\nend_header\n", "version"),
    "unknown_type": (_header("element vertex 0", "property float128 x", *_standard_props()[1:]), "type"),
    "negative_count": (_header("element vertex -3", *_standard_props()), "count"),
    "text_count": (_header("element vertex many", *_standard_props()), "count"),
    "property_before_element": (_header("property float x", "element vertex 0", *_standard_props()), "property"),
    "no_vertex": (_header("element point 0", *_standard_props()), "vertex"),
    "duplicate_element": (_header("element vertex 0", *_standard_props(), "element vertex 0"), "duplicate"),
    "list_in_vertex": (_header("element vertex 0", *_standard_props(), "property list uchar int idx"), "list"),
    "duplicate_property": (_header("element vertex 0", *_standard_props(), "property float scale_1"), "duplicate"),
    "truncated_data": (ply_bytes(gaussian_columns(5, 1))[:-10], "truncated"),
    "count_too_large": (ply_bytes(gaussian_columns(5), count=6), "truncated"),
    "truncated_before_vertex": (ply_bytes(gaussian_columns(2), elements_before=[
        ("element meta 1000\nproperty double a", b"")]), "truncated"),
    "huge_list_element": (ply_bytes(gaussian_columns(2), elements_before=[
        ("element face 1000000000000\nproperty list uchar int idx", b"")]), "truncated"),
    "truncated_list_data": (ply_bytes(gaussian_columns(2), elements_after=[
        ("element face 2\nproperty list uchar int idx", bytes([3, 3]))]), "cannot read"),
    "missing_x": (_header("element vertex 0", *_standard_props(_STANDARD[1:])), "'x'"),
    "missing_opacity": (_header("element vertex 0", *_standard_props([n for n in _STANDARD if n != "opacity"])),
                        "'opacity'"),
    "missing_rot_3": (_header("element vertex 0", *_standard_props(_STANDARD[:-1])), "'rot_3'"),
    "f_rest_8": (_header("element vertex 0", *_standard_props(), *(f"property float f_rest_{i}" for i in range(8))),
                 "8 f_rest"),
    "f_rest_10": (_header("element vertex 0", *_standard_props(),
                          *(f"property float f_rest_{i}" for i in range(10))), "10 f_rest"),
    "f_rest_gap": (_header("element vertex 0", *_standard_props(),
                           *(f"property float f_rest_{i}" for i in (*range(8), 9))), "f_rest_8"),
    "f_rest_bad_name": (_header("element vertex 0", *_standard_props(),
                                *(f"property float f_rest_{i}" for i in (*range(8), "08"))), "f_rest_08"),
    "scale_double": (ply_bytes(gaussian_columns(2), types={"scale_0": "double"}),
                     "property 'scale_0' is double, expected float"),
    "x_uchar": (ply_bytes(gaussian_columns(2), types={"x": "uchar"}), "'x' is uchar"),
    "f_rest_double": (ply_bytes(gaussian_columns(2, 1), types={"f_rest_4": "double"}), "'f_rest_4' is double"),
    "filter_double": (ply_bytes(gaussian_columns(2, filter_3d=0.1), types={"filter_3D": "double"}),
                      "'filter_3D' is double"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_ply_input_is_a_one_line_user_error(tmp_path, case):
    content, fragment = BAD_FILES[case]
    path = tmp_path / f"{case}.ply"
    path.write_bytes(content)
    assert_scene_error(path, fragment)


def test_unrecognised_format(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("hello\n")
    assert_scene_error(path, "unrecognised")


def test_declared_count_far_too_large_fails_without_allocating(tmp_path):
    path = write_ply(tmp_path / "huge.ply", gaussian_columns(3, 3), count=10**12)
    tracemalloc.start()
    try:
        assert_scene_error(path, "truncated", str(10**12))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 8 * 2**20, peak  # the header buffer (1 MiB) and change


# --------------------------------------------------------------------------- .splat




def test_splat_loading(tmp_path):
    positions = [[1, 2, 3], [-1, 0.5, 4]]
    scales = [[0.1, 0.2, 0.3], [1, 1, 2]]
    rgba = [[255, 0, 128, 255], [10, 20, 30, 0]]
    quats = [[255, 128, 128, 128], [128, 128, 128, 0]]  # (w=~1), (z=-1)
    path = tmp_path / "tiny.splat"
    path.write_bytes(splat_bytes(positions, scales, rgba, quats))
    scene = load_scene(path)
    assert scene.count == 2 and scene.sh_degree == 0 and not scene.filter_fused
    assert scene.source == str(path)
    np.testing.assert_array_equal(scene.positions, np.float32(positions))
    np.testing.assert_array_equal(scene.scales, np.float32(scales))  # linear, not log
    np.testing.assert_allclose(scene.opacities, [1.0, 0.0])
    np.testing.assert_allclose(scene.sh[:, 0, :], (np.float64(rgba)[:, :3] / 255 - 0.5) / C0, rtol=1e-6)
    np.testing.assert_allclose(scene.rotations, [[1, 0, 0, 0], [0, 0, 0, -1]], atol=1e-7)


def test_splat_invalid_rows_dropped(tmp_path):
    positions = [[0, 0, 0], [np.nan, 0, 0], [0, np.inf, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0], [5, 5, 5]]
    scales = [[1, 1, 1]] * 3 + [[0, 1, 1], [-1, 1, 1], [1, 1, 1], [1, np.inf, 1]]
    quats = [[200, 128, 128, 128]] * 5 + [[128, 128, 128, 128], [200, 128, 128, 128]]
    path = tmp_path / "bad.splat"
    path.write_bytes(splat_bytes(positions, scales, [[1, 2, 3, 4]] * 7, quats))
    scene = load_scene(path)
    assert scene.count == 1
    assert scene.dropped == {"nan": 1, "infinite position": 1, "zero scale": 1, "negative scale": 1,
                             "zero quaternion": 1, "infinite scale": 1}


def test_splat_size_not_multiple_of_32(tmp_path):
    path = tmp_path / "odd.splat"
    path.write_bytes(bytes(70))
    assert_scene_error(path, "multiple of 32")


def test_empty_splat_is_an_empty_scene(tmp_path):
    path = tmp_path / "empty.splat"
    path.write_bytes(b"")
    scene = load_scene(path)
    assert scene.count == 0 and scene.sh.shape == (0, 1, 3)


# --------------------------------------------------------------------------- describe


def test_describe_small_scene(tmp_path):
    cols = gaussian_columns(3)
    cols["x"][:], cols["y"][:], cols["z"][:] = [0, 1, 2], [-1, 5, 3], [4, 4, -4]
    cols["opacity"][:] = [0.0, np.inf, -np.inf]
    for a, v in enumerate([[0, 0, 0], [np.log(2)] * 3, [np.log(0.5), 0, np.log(4)]]):
        for i in range(3):
            cols[f"scale_{i}"][a] = v[i]
    cols["rot_0"][1] = np.nan  # one dropped
    cols["x"][2] = 7
    path = write_ply(tmp_path / "stats.ply", cols)
    info = describe(load_scene(path))
    assert json.loads(json.dumps(info)) == info
    assert info["count"] == 2 and info["sh_degree"] == 0 and info["filter_fused"] is False
    assert info["source"] == str(path)
    assert info["bbox"] == {"min": [0.0, -1.0, -4.0], "max": [7.0, 3.0, 4.0]}
    assert info["opacity"] == {"min": 0.0, "median": 0.25, "mean": 0.25, "max": 0.5}
    assert info["scale"]["min"] == 0.5 and info["scale"]["max"] == 4.0
    assert info["scale"]["median"] == pytest.approx(1.0, rel=1e-6)
    assert info["scale"]["median_anisotropy"] == pytest.approx((1 + 8) / 2, rel=1e-6)
    assert info["dropped"] == {"total": 1, "by_reason": {"nan": 1}}
    text = format_description(info)
    assert len(text.splitlines()) >= 6
    for fragment in ("stats.ply", "gaussians:    2", "nan: 1", "SH degree:    0"):
        assert fragment in text, text


# --------------------------------------------------------------------------- real scenes

REAL_SCENES = [
    ("ss-fruit_drops_minimal.ply", 4721, 3),
    ("donut-mip-fused.ply", 45624, 0),
    ("metalsplatter-train3.ply", 3, 3),
    ("gs3d-pr477-lod3_tile_0.ply", 1971, 3),
    ("schwa-centered_lastchance.splat", 14007, 0),
]


@pytest.mark.parametrize("name,count,degree", REAL_SCENES)
def test_real_scenes(name, count, degree, strict_warnings):
    path = SHARED_SCENES / name
    if not path.is_file():
        pytest.skip(f"shared test scene {name} not found in {SHARED_SCENES} (the ../shared/scenes folder is absent)")
    scene = load_scene(path)
    assert scene.count == count
    assert scene.sh_degree == degree
    assert scene.filter_fused is False
    assert scene.dropped == {}
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        array = getattr(scene, field)
        assert array.dtype == np.float32 and np.all(np.isfinite(array)), field
    np.testing.assert_allclose(np.linalg.norm(scene.rotations.astype(np.float64), axis=1), 1.0, atol=1e-6)
    assert np.all(scene.scales > 0)
    assert np.all((scene.opacities >= 0) & (scene.opacities <= 1))
    info = describe(scene)
    json.dumps(info)
    assert info["count"] == count


# --------------------------------------------------------------------------- progress and cancel


def _recorded_load(path, **kwargs):
    calls = []
    scene = load_scene(path, progress=lambda fraction, stage: calls.append((fraction, stage)), **kwargs)
    return scene, calls


def _assert_progress_shape(calls):
    fractions = [f for f, _ in calls]
    assert fractions == sorted(fractions), calls
    assert all(0.0 <= f <= 1.0 for f in fractions), calls
    assert calls[0] == (0.0, "reading") and calls[-1] == (1.0, "done"), calls
    assert [s for _, s in calls].count("done") == 1
    assert {s for _, s in calls} <= {"reading", "activating", "validating", "done"}, calls


@pytest.mark.parametrize("chunk", [1, 200, 1000, 1 << 22])
def test_chunked_ply_reading_reports_progress_and_gives_the_same_scene(tmp_path, chunk):
    base = gaussian_columns(23, degree=2, filter_3d=0.01)
    cols = {"red": np.arange(23) % 250}  # a uchar first misaligns the floats: every gather path
    cols.update(base)
    path = write_ply(tmp_path / "chunks.ply", cols, types={"red": "uchar"})
    whole = load_scene(path)
    scene, calls = _recorded_load(path, chunk_bytes=chunk)
    _assert_progress_shape(calls)
    row = 1 + 4 * (len(cols) - 1)
    rows_per_chunk = max(1, chunk // row)
    assert [s for _, s in calls].count("reading") == 1 + -(-23 // rows_per_chunk)
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(scene, field), getattr(whole, field))


@pytest.mark.parametrize("chunk", [1, 50, 64, 1 << 22])
def test_chunked_splat_reading_reports_progress_and_gives_the_same_scene(tmp_path, chunk):
    rng = np.random.default_rng(3)
    n = 9
    path = tmp_path / "chunks.splat"
    path.write_bytes(splat_bytes(rng.normal(size=(n, 3)), rng.uniform(0.1, 1, (n, 3)),
                                 rng.integers(0, 256, (n, 4)), rng.integers(0, 256, (n, 4))))
    whole = load_scene(path)
    scene, calls = _recorded_load(path, chunk_bytes=chunk)
    _assert_progress_shape(calls)
    assert [s for _, s in calls].count("reading") == 1 + -(-32 * n // chunk)
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(scene, field), getattr(whole, field))


def test_progress_on_an_empty_scene(tmp_path):
    cols = {name: np.zeros(0) for name in gaussian_columns(1)}
    scene, calls = _recorded_load(write_ply(tmp_path / "empty.ply", cols))
    assert scene.count == 0
    _assert_progress_shape(calls)


def test_a_failed_load_reports_no_done(tmp_path):
    calls = []
    with pytest.raises(UserError, match="no such file"):
        load_scene(tmp_path / "nothing.ply", progress=lambda f, s: calls.append((f, s)))
    assert calls == [(0.0, "reading")]


def test_cancel_before_loading(tmp_path):
    cancel = threading.Event()
    cancel.set()
    path = write_ply(tmp_path / "ok.ply", gaussian_columns(3))
    with pytest.raises(UserError) as info:
        load_scene(path, cancel=cancel)
    assert str(info.value) == "loading cancelled"


@pytest.mark.parametrize("suffix", [".ply", ".splat"])
def test_cancel_stops_at_the_next_progress_point(tmp_path, suffix):
    path = tmp_path / f"cancel{suffix}"
    if suffix == ".ply":
        write_ply(path, gaussian_columns(20))
    else:
        path.write_bytes(splat_bytes([[0, 0, 0]] * 20, [[1, 1, 1]] * 20, [[1, 2, 3, 4]] * 20,
                                     [[200, 128, 128, 128]] * 20))
    cancel = threading.Event()
    calls = []

    def progress(fraction, stage):
        calls.append((fraction, stage))
        if len(calls) == 3:  # the second chunk of gaussian data
            cancel.set()

    with pytest.raises(UserError) as info:
        load_scene(path, progress=progress, cancel=cancel, chunk_bytes=64)
    assert str(info.value) == "loading cancelled"
    assert len(calls) == 3 and [s for _, s in calls] == ["reading"] * 3
