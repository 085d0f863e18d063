"""Fuzzing the compressed PLY reader (issue 18, part 5): mutated compressed PLY files
either load right or raise a one-line UserError naming the file; never another
exception, a hang (every example has a deadline) or an allocation that follows a count
the file cannot hold.

"Loads right" is checked against a plain per-gaussian decode written here from
splat-transform's decompress-ply.ts, independent of the reader's vectorised one.
``RAYGS_FUZZ_EXAMPLES=5000`` runs more examples (see test_fuzz.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_compressed_ply import assemble, encode, known_scene
from test_fuzz import assert_valid_scene, fuzz, outcome

from raygs_viewer.scene.io import load_scene

pytestmark = pytest.mark.filterwarnings("error")

C0 = 0.28209479177387814
_N = 300  # two chunks, the second partial


def _base(degree: int, colour_bounds: bool) -> bytes:
    src = known_scene(_N, degree, seed=degree, colour_in_unit=not colour_bounds)
    return assemble(encode(src, colour_bounds=colour_bounds)[0])


BASES = {(d, c): _base(d, c) for d in (0, 1, 3) for c in (True, False)}


# --------------------------------------------------------------------------- the plain decode


def _unorm(value: int, bits: int) -> float:
    top = (1 << bits) - 1
    return (value & top) / top


def _lerp(a, b, t):
    return a * (1 - t) + b * t


def plain_decode(data: bytes, degree: int, colour_bounds: bool):
    """Gaussian by gaussian, as splat-transform's decompressPly does, for a file laid out as
    :func:`_base` writes it (header unchanged): (kept values, drop count)."""
    start = data.index(b"\nend_header\n") + len(b"\nend_header\n")
    columns = 18 if colour_bounds else 12
    chunks = -(-_N // 256)
    bounds = np.frombuffer(data, "<f4", chunks * columns, start).reshape(chunks, columns).astype(np.float64)
    start += chunks * columns * 4
    words = np.frombuffer(data, "<u4", _N * 4, start).reshape(_N, 4)
    k = (degree + 1) ** 2 - 1
    sh_bytes = np.frombuffer(data, "u1", _N * 3 * k, start + _N * 16).reshape(_N, 3 * k)
    out = {"positions": [], "rotations": [], "scales": [], "opacities": [], "sh": []}
    dropped = 0
    with np.errstate(all="ignore"):
        for i in range(_N):
            b = bounds[i // 256]
            pp, pr, ps, pc = (int(w) for w in words[i])
            position = np.array([_lerp(b[0], b[3], _unorm(pp >> 21, 11)), _lerp(b[1], b[4], _unorm(pp >> 11, 10)),
                                 _lerp(b[2], b[5], _unorm(pp, 11))])
            log_scale = np.array([_lerp(b[6], b[9], _unorm(ps >> 21, 11)), _lerp(b[7], b[10], _unorm(ps >> 11, 10)),
                                  _lerp(b[8], b[11], _unorm(ps, 11))])
            t = [_unorm(pc >> 24, 8), _unorm(pc >> 16, 8), _unorm(pc >> 8, 8)]
            colour = np.array([_lerp(b[12 + c], b[15 + c], t[c]) for c in range(3)] if colour_bounds else t)
            dc = (colour - 0.5) / C0
            abc = [(_unorm(pr >> shift, 10) - 0.5) * math.sqrt(2) for shift in (20, 10, 0)]
            m = math.sqrt(max(0.0, 1 - sum(v * v for v in abc)))
            which = pr >> 30
            q = np.array(abc[:which] + [m] + abc[which:])
            # Judged as the scene holds them, in float32: a finite colour past 3.4e38 is infinite there.
            position, dc = position.astype(np.float32), dc.astype(np.float32)
            scale = np.exp(log_scale).astype(np.float32)
            if (np.isnan(position).any() or np.isnan(log_scale).any() or np.isnan(dc).any()
                    or np.isinf(position).any() or np.isinf(scale).any() or (scale == 0).any()
                    or np.isinf(dc).any()):
                dropped += 1
                continue
            rest = [((0.0 if v == 0 else 1.0 if v == 255 else (v + 0.5) / 256) - 0.5) * 8 for v in sh_bytes[i]]
            out["positions"].append(position)
            out["rotations"].append(q / np.linalg.norm(q))
            out["scales"].append(scale)
            out["opacities"].append(_unorm(pc, 8))
            out["sh"].append(np.concatenate([dc[None, :], np.reshape(rest, (3, k)).T]))
    return out, dropped


def assert_decodes_plainly(scene, data: bytes, degree: int, colour_bounds: bool) -> None:
    expected, dropped = plain_decode(data, degree, colour_bounds)
    assert sum(scene.dropped.values()) == dropped and scene.count == _N - dropped
    if not scene.count:
        return
    np.testing.assert_array_equal(scene.positions, np.array(expected["positions"], np.float32))
    np.testing.assert_allclose(scene.rotations, np.array(expected["rotations"]), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(scene.scales, np.array(expected["scales"]), rtol=1e-6)
    np.testing.assert_array_equal(scene.opacities, np.array(expected["opacities"], np.float32))
    np.testing.assert_allclose(scene.sh, np.array(expected["sh"]), rtol=1e-6, atol=1e-7)


# --------------------------------------------------------------------------- strategies

bases = st.sampled_from(sorted(BASES))
_SPECIAL = [np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-45, 3.4e38, -3.4e38, 1e30, -1e30, 88.8, -104.0, 1e5]


@fuzz(60)
@given(base=bases, flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(0, 255)),
                                  min_size=1, max_size=12))
def test_flipped_data_bytes_decode_plainly(tmp_path, base, flips):
    data = bytearray(BASES[base])
    start = data.index(b"\nend_header\n") + len(b"\nend_header\n")
    for where, value in flips:
        data[start + int(where * (len(data) - start))] = value
    path = tmp_path / "flipped.compressed.ply"
    path.write_bytes(bytes(data))
    scene = load_scene(path)  # the header is intact: every word decodes to something
    assert_valid_scene(scene)
    assert_decodes_plainly(scene, bytes(data), *base)


@fuzz(60)
@given(base=bases, values=st.lists(st.tuples(st.integers(0, 35), st.sampled_from(_SPECIAL)),
                                   min_size=1, max_size=6))
def test_extreme_chunk_bounds_drop_or_decode_plainly(tmp_path, base, values):
    data = bytearray(BASES[base])
    start = data.index(b"\nend_header\n") + len(b"\nend_header\n")
    columns = 18 if base[1] else 12
    bounds = np.frombuffer(data, "<f4", 2 * columns, start).copy()
    for index, value in values:
        bounds[index % bounds.size] = value
    data[start: start + bounds.nbytes] = bounds.tobytes()
    path = tmp_path / "bounds.compressed.ply"
    path.write_bytes(bytes(data))
    scene = load_scene(path)
    assert_valid_scene(scene)
    assert_decodes_plainly(scene, bytes(data), *base)


@fuzz(60)
@given(base=bases, cut=st.floats(0, 1, exclude_max=True))
def test_truncated_anywhere(tmp_path, base, cut):
    data = BASES[base]
    path = tmp_path / "cut.compressed.ply"
    path.write_bytes(data[: int(cut * len(data))])
    assert outcome(load_scene, path) is None


_WORDS = ["element", "chunk", "vertex", "sh", "property", "float", "uint", "uchar", "double", "int", "list",
          "packed_position", "packed_rotation", "packed_scale", "packed_color", "min_x", "max_scale_z",
          "min_r", "max_b", "f_rest_0", "f_rest_8", "f_rest_44", "0", "1", "2", "255", "256", "300", "301",
          "-1", str(2**32), str(2**40), str(2**63 - 1), str(2**64), "comment", "end_header"]
header_lines = st.one_of(st.lists(st.sampled_from(_WORDS), min_size=1, max_size=5).map(" ".join),
                         st.text(st.characters(max_codepoint=127), max_size=30))


@fuzz(150)
@given(base=bases, edits=st.lists(st.tuples(st.sampled_from(["replace", "insert", "delete"]),
                                            st.floats(0, 1, exclude_max=True), header_lines),
                                  min_size=1, max_size=3))
def test_mutated_headers(tmp_path, base, edits):
    data = BASES[base]
    end = data.index(b"\nend_header\n")
    lines = data[:end].decode("ascii").split("\n")
    for action, where, line in edits:
        at = 2 + int(where * (len(lines) - 2))  # after "ply" and "format"
        if action == "replace" and at < len(lines):
            lines[at] = line
        elif action == "insert":
            lines.insert(at, line)
        elif action == "delete" and at < len(lines):
            del lines[at]
    path = tmp_path / "header.compressed.ply"
    path.write_bytes("\n".join(lines).encode("ascii", "replace") + data[end:])
    scene = outcome(load_scene, path)
    if scene is not None:
        assert_valid_scene(scene)
