"""Corrupt files (issue 6, part 3): fuzzing every reader of user files.

A PLY, .splat, cameras.json or screenshot sidecar, however corrupt, either loads
correctly or raises a one-line UserError naming the file: never another exception,
never a hang (every example has a deadline), never an allocation that follows a count
the file cannot hold. Mutations start from valid files; a load that succeeds is checked
against a plain, independent reading of the same bytes, so "loads" means "loads right".

``RAYGS_FUZZ_EXAMPLES=5000`` runs every fuzz test with that many examples instead of the
modest default (hypothesis' "ci" profile, see conftest.py, makes them reproducible).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import os
import tracemalloc
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from ply_reference import reference_load_ply
from testkit import (
    demo_sidecar,
    gaussian_columns,
    ply_bytes,
    random_rotation,
    splat_bytes,
    window_camera,
    write_ply,
)

from raygs_viewer.camera.lens_model import LensModel
from raygs_viewer.camera.pinhole import Camera, load_camera, load_cameras
from raygs_viewer.camera.stereo import (
    LAYOUTS,
    PRESETS,
    StereoRig,
    StereoView,
    composed_size,
)
from raygs_viewer.capture.sidecar import Sidecar, load_sidecar
from raygs_viewer.cli import main as cli
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import RENDER_MODES, RenderSettings
from raygs_viewer.scene import io as scene_io
from raygs_viewer.scene.io import DROP_REASONS, load_scene

# A RuntimeWarning is a second line on the user's terminal (and an exception under -W error).
pytestmark = pytest.mark.filterwarnings("error")

C0 = 0.28209479177387814
_EXAMPLES = int(os.environ.get("RAYGS_FUZZ_EXAMPLES", "0"))


def fuzz(max_examples: int):
    """Hypothesis settings of one fuzz test: a 2 s deadline per example catches hangs."""
    return settings(max_examples=_EXAMPLES or max_examples, deadline=2000,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


def assert_one_line(exc: UserError, path) -> str:
    message = str(exc)
    assert message and len(message.splitlines()) == 1, repr(message)
    assert "\n" not in message and "\r" not in message, repr(message)
    assert "Traceback" not in message, message
    assert Path(path).name in message, message
    return message


def outcome(load, path):
    """load(path), or None after checking that its UserError is one line naming the file.
    Any other exception fails the test (hypothesis then shrinks the file)."""
    try:
        result = load(path)
    except UserError as exc:
        event("UserError")
        assert_one_line(exc, path)
        return None
    event("loaded")
    return result


# =========================================================================== PLY

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "<i2", "int16": "<i2",
              "ushort": "<u2", "uint16": "<u2", "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4",
              "float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8"}
_REST_DEGREE = {0: 0, 9: 1, 24: 2, 45: 3}


def reference_vertices(data: bytes):
    """(vertex rows, whether every element's data is there) by a plain reading of the
    binary little-endian PLY spec, independent of the loader; None where it fails."""
    nl = next((nl for nl in (b"\r\n", b"\n", b"\r") if data.startswith(b"ply" + nl)), None)
    if nl is None:
        return None
    marker = nl + b"end_header" + nl
    end = data.find(marker)
    if end < 0:
        return None
    try:
        text = data[:end].decode("ascii")
    except UnicodeDecodeError:
        return None
    elements, fmt = [], False
    for line in text.split(nl.decode())[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words == ["format", "binary_little_endian", "1.0"] and not fmt:
            fmt = True
        elif fmt and words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif fmt and elements and words[0] == "property" and len(words) == 3 and words[1] in _PLY_TYPES:
            elements[-1][2].append((words[2], np.dtype(_PLY_TYPES[words[1]]), None))
        elif (fmt and elements and words[0] == "property" and len(words) == 5 and words[1] == "list"
              and words[2] in _PLY_TYPES and words[3] in _PLY_TYPES):
            elements[-1][2].append((words[4], np.dtype(_PLY_TYPES[words[3]]), np.dtype(_PLY_TYPES[words[2]])))
        else:
            return None
    body = data[end + len(marker):]
    pos, vertex, complete = 0, None, True
    for name, count, props in elements:
        if any(length is not None for _, _, length in props):
            if name == "vertex" and vertex is None:
                return None
            row = 0
            while row < count and complete:  # every row holds >= 1 byte, so this ends
                for _, value, length in props:
                    if length is None:
                        pos += value.itemsize
                        continue
                    if pos + length.itemsize > len(body):
                        complete = False
                        break
                    n = int(np.frombuffer(body, length, 1, pos)[0])
                    pos += length.itemsize + n * value.itemsize
                    if n < 0:
                        complete = False
                        break
                complete = complete and pos <= len(body)
                row += 1
            continue
        try:
            dtype = np.dtype([(p, value) for p, value, _ in props])
        except ValueError:  # duplicate property names
            return None
        if dtype.itemsize == 0:
            continue
        if name == "vertex" and vertex is None and count == 0:
            vertex = np.zeros(0, dtype)  # an empty scene, whatever the other elements hold
        if pos + count * dtype.itemsize > len(body):
            complete = False
            break
        if name == "vertex" and vertex is None:
            vertex = np.frombuffer(body, dtype, count, pos)
        pos += count * dtype.itemsize
    return None if vertex is None else (vertex, complete)


def expected_gaussians(rows: np.ndarray) -> dict:
    """What section 2 of the maths page and the loader's docstring make of these vertex
    rows: the kept gaussians, activated, in float64."""
    names = rows.dtype.names

    def col(name):
        with np.errstate(invalid="ignore"):  # signalling NaNs
            return rows[name].astype(np.float64)

    n_rest = sum(name.startswith("f_rest_") for name in names)
    k = n_rest // 3
    n = rows.shape[0]
    positions = np.stack([col(c) for c in "xyz"], 1)
    dc = np.stack([col(f"f_dc_{c}") for c in range(3)], 1)
    rest = np.stack([col(f"f_rest_{j}") for j in range(n_rest)], 1) if n_rest else np.zeros((n, 0))
    logit = col("opacity")
    log_scale = np.stack([col(f"scale_{a}") for a in range(3)], 1)
    rot = np.stack([col(f"rot_{a}") for a in range(4)], 1)
    filt = col("filter_3D") if "filter_3D" in names else None
    used = np.concatenate([positions, dc, rest, logit[:, None], log_scale, rot]
                          + ([filt[:, None]] if filt is not None else []), axis=1)
    with np.errstate(all="ignore"):
        scale = np.exp(log_scale)
        opacity = 1.0 / (1.0 + np.exp(-logit))
        if filt is not None:
            fused = np.sqrt(scale * scale + np.square(filt)[:, None])
            opacity = opacity * np.prod(scale / fused, axis=1)
            scale = fused
        scale32 = scale.astype(np.float32)
        norm = np.sqrt(np.sum(rot * rot, axis=1))
        keep = ~(np.isnan(used).any(1) | np.isinf(positions).any(1) | np.isinf(scale32).any(1)
                 | (scale32 == 0).any(1) | np.isinf(rot).any(1) | (norm == 0)
                 | np.isinf(dc).any(1) | np.isinf(rest).any(1))
        quat = rot / norm[:, None]
    sh = np.concatenate([dc[:, None, :], rest.reshape(n, 3, k).transpose(0, 2, 1)], axis=1)
    return {"keep": keep, "degree": _REST_DEGREE[n_rest], "filter": filt is not None,
            "positions": positions[keep], "scales": scale32[keep], "opacities": opacity[keep],
            "rotations": quat[keep], "sh": sh[keep]}


def assert_valid_scene(scene) -> None:
    for name in ("positions", "rotations", "scales", "opacities", "sh"):
        array = getattr(scene, name)
        assert array.dtype == np.float32 and np.all(np.isfinite(array)), name
    assert np.all(scene.scales > 0)
    assert np.all((scene.opacities >= 0) & (scene.opacities <= 1))
    if scene.count:
        np.testing.assert_allclose(np.linalg.norm(scene.rotations.astype(np.float64), axis=1), 1, atol=1e-6)
    assert set(scene.dropped) <= set(DROP_REASONS) and all(v > 0 for v in scene.dropped.values())


def assert_scene_is_the_file(scene, data: bytes) -> dict:
    """A loaded PLY holds exactly what a plain reading of its bytes gives."""
    assert_valid_scene(scene)
    reference = reference_vertices(data)
    assert reference is not None, "the loader accepted a file that a plain reading of PLY rejects"
    rows, complete = reference
    assert complete or rows.shape[0] == 0, "the loader accepted a file whose elements do not fit in it"
    expected = expected_gaussians(rows)
    assert scene.count == int(expected["keep"].sum())
    assert sum(scene.dropped.values()) == rows.shape[0] - scene.count
    assert scene.sh_degree == expected["degree"] and scene.filter_fused == expected["filter"]
    np.testing.assert_array_equal(scene.positions, expected["positions"].astype(np.float32))
    np.testing.assert_array_equal(scene.sh, expected["sh"].astype(np.float32))
    np.testing.assert_allclose(scene.scales, expected["scales"], rtol=1e-6, atol=3e-45)
    np.testing.assert_allclose(scene.opacities, expected["opacities"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(scene.rotations, expected["rotations"], rtol=1e-6, atol=1e-7)
    return expected


# --------------------------------------------------------------------------- strategies

_TYPE_NAMES = list(_PLY_TYPES)
_CANONICAL_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double"]
_BAD_TYPES = ["float128", "float16", "half", "Float", "f4", "list", "string", ""]
_ABSURD_COUNTS = ["1000000000000", str(2**31), str(2**32 + 1), str(2**63 - 1), str(2**63), str(2**64),
                  str(2**64 + 1), "9" * 40, "-1", "-5", "1e12", "many", "0x10", "3.5", "+3", "", "0"]
_HEADER_WORDS = ["ply", "format", "binary_little_endian", "binary_big_endian", "ascii", "1.0", "element",
                 "vertex", "face", "property", "list", "float", "double", "uchar", "int", "uint", "char",
                 "comment", "obj_info", "end_header", "x", "y", "z", "opacity", "scale_0", "rot_0", "f_dc_0",
                 "f_rest_0", "f_rest_44", "filter_3D", "0", "1", "3", "-1", "1e12", str(2**64), "nan"]
_SPECIAL_FLOATS = [np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-45, -1e-45, 1e-38, 3.4e38, -3.4e38,
                   88.8, 89.0, -103.0, -104.0, -200.0, 1e30, -1e30]

counts = st.one_of(st.sampled_from(_ABSURD_COUNTS), st.integers(0, 12).map(str),
                   st.integers(0, 2**70).map(str))
header_lines = st.one_of(
    st.lists(st.sampled_from(_HEADER_WORDS), max_size=6).map(" ".join),
    st.text(st.characters(max_codepoint=255), max_size=40),
)


@st.composite
def gaussian_files(draw, max_n=6):
    """Columns of a valid INRIA PLY: any SH degree, with or without normals and filter_3D."""
    n = draw(st.integers(0, max_n))
    degree = draw(st.sampled_from([0, 1, 2, 3]))
    filter_3d = draw(st.sampled_from([None, None, 0.0, 0.05]))
    return gaussian_columns(n, degree, seed=draw(st.integers(0, 2**16)), normals=draw(st.booleans()),
                            filter_3d=filter_3d)


def split_ply(data: bytes) -> tuple[list[str], bytes]:
    """A file of ply_bytes (LF) -> (header lines between 'ply' and 'end_header' inclusive, body)."""
    end = data.index(b"\nend_header\n") + len(b"\nend_header\n")
    return data[:end].decode("ascii").split("\n")[1:-1], data[end:]


def join_ply(lines: list[str], body: bytes, nl: str = "\n") -> bytes:
    return nl.join(["ply", *lines, ""]).encode("latin-1") + body


@st.composite
def extra_element(draw, absurd: bool):
    """(header lines, data) of another element: fixed, list or no properties; its data
    right, short or long; with ``absurd``, a count or list length the file cannot hold."""
    name = draw(st.sampled_from(["face", "meta", "edge", "junk", "camera"]))
    props = draw(st.lists(st.tuples(st.sampled_from(_TYPE_NAMES), st.sampled_from([None, None, "uchar", "uint",
                                                                                    "int", "char"])),
                          max_size=3))
    count = draw(st.integers(0, 4))
    rows = []
    for _ in range(count):
        row = b""
        for value, length in props:
            size = np.dtype(_PLY_TYPES[value]).itemsize
            if length is None:
                row += draw(st.binary(min_size=size, max_size=size))
                continue
            items = draw(st.integers(0, 3))
            if absurd and draw(st.booleans()):
                items = draw(st.sampled_from([2**31 - 1, 2**32 - 1, 255, 127, -1, 2**16 - 1]))
            dtype = np.dtype(_PLY_TYPES[length])
            info = np.iinfo(dtype)
            row += np.array([min(max(items, info.min), info.max)], dtype).tobytes()
            shown = size * max(0, min(items, 3))
            row += draw(st.binary(min_size=shown, max_size=shown))
        rows.append(row)
    data = b"".join(rows)
    shown = str(count)
    if absurd:
        shown = draw(st.sampled_from([str(count), "1000000000000", str(2**62), str(2**63 - 1), str(2**63),
                                      str(2**64), "9" * 30]))
    if draw(st.integers(0, 4)) == 0:
        data = data[:draw(st.integers(0, len(data)))] + draw(st.binary(max_size=8))
    lines = [f"element {name} {shown}"]
    for i, (value, length) in enumerate(props):
        lines.append(f"property {value} p{i}" if length is None else f"property list {length} {value} p{i}")
    return lines, data


def _property_lines(lines):
    return [i for i, line in enumerate(lines) if line.startswith("property ")]


@st.composite
def line_mutation(draw, lines: list[str], body: bytes) -> tuple[list[str], bytes]:
    lines = list(lines)
    kind = draw(st.sampled_from(["replace", "insert", "delete", "duplicate", "swap", "type", "count", "format",
                                 "element", "list", "rename"]))
    index = draw(st.integers(0, len(lines) - 1)) if lines else 0
    props = _property_lines(lines)
    vertex = next((i for i, line in enumerate(lines) if line.startswith("element vertex")), None)
    if kind == "replace" and lines:
        lines[index] = draw(header_lines)
    elif kind == "insert":
        lines.insert(draw(st.integers(0, len(lines))), draw(header_lines))
    elif kind == "delete" and lines:
        del lines[index]
    elif kind == "duplicate" and lines:
        lines.insert(draw(st.integers(0, len(lines))), lines[index])
    elif kind == "swap" and len(lines) > 1:
        j = draw(st.integers(0, len(lines) - 1))
        lines[index], lines[j] = lines[j], lines[index]
    elif kind == "type" and props:
        i = draw(st.sampled_from(props))
        words = lines[i].split()
        words[-2] = draw(st.sampled_from(_TYPE_NAMES + _BAD_TYPES))
        lines[i] = " ".join(words)
    elif kind == "count" and vertex is not None:
        lines[vertex] = f"element vertex {draw(counts)}"
    elif kind == "format" and lines:
        lines[0] = draw(st.sampled_from(["format ascii 1.0", "format binary_big_endian 1.0",
                                         "format binary_little_endian 2.0", "format binary_little_endian",
                                         "format binary_little_endian 1.0 extra", "format pcd 1.0",
                                         "format binary_little_endian 1.0"]))
    elif kind == "element" and vertex is not None:
        element, data = draw(extra_element(absurd=draw(st.booleans())))
        if draw(st.booleans()):
            lines[vertex:vertex] = element
            body = data + body
        else:
            lines[-1:-1] = element
            body = body + data
    elif kind == "list" and props:
        lines.insert(draw(st.sampled_from(props)), f"property list {draw(st.sampled_from(_TYPE_NAMES))} float idx")
    elif kind == "rename" and props:
        i = draw(st.sampled_from(props))
        words = lines[i].split()
        words[-1] = draw(st.sampled_from(["f_rest_99", "f_rest_08", "f_rest_", "scale_0", "x", "X", "rot_4",
                                          "filter_3D", "nx", "f_rest_9"]))
        lines[i] = " ".join(words)
    return lines, body


@st.composite
def byte_mutation(draw, data: bytes) -> bytes:
    kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete", "append", "float"]))
    at = draw(st.integers(0, len(data)))
    if kind == "truncate":
        return data[:at]
    if kind == "flip" and data:
        out = bytearray(data)
        for i in draw(st.lists(st.integers(0, len(data) - 1), min_size=1, max_size=8)):
            out[i] ^= draw(st.integers(1, 255))
        return bytes(out)
    if kind == "insert":
        return data[:at] + draw(st.binary(min_size=1, max_size=16)) + data[at:]
    if kind == "delete":
        return data[:at] + data[at + draw(st.integers(1, 16)):]
    if kind == "append":
        return data + draw(st.binary(min_size=1, max_size=64))
    if kind == "float":
        end = data.find(b"end_header")
        slots = (len(data) - end - 11) // 4 if end >= 0 else 0
        if slots > 0:
            at = len(data) - 4 * draw(st.integers(1, slots))
            value = np.float32(draw(st.sampled_from(_SPECIAL_FLOATS))).tobytes()
            return data[:at] + value + data[at + 4:]
    return data


@st.composite
def corrupt_plys(draw) -> bytes:
    """A valid PLY, then 1-3 mutations of its header lines or bytes."""
    lines, body = split_ply(ply_bytes(draw(gaussian_files())))
    nl = draw(st.sampled_from(["\n", "\n", "\r\n", "\r"]))
    data = None
    for _ in range(draw(st.integers(1, 3))):
        if data is None and draw(st.booleans()):
            lines, body = draw(line_mutation(lines, body))
        else:
            data = draw(byte_mutation(join_ply(lines, body, nl) if data is None else data))
    return join_ply(lines, body, nl) if data is None else data


# --------------------------------------------------------------------------- PLY tests


@fuzz(300)
@given(data=corrupt_plys())
def test_corrupt_ply_loads_correctly_or_is_a_one_line_user_error(tmp_path, data):
    path = tmp_path / "fuzz.ply"
    path.write_bytes(data)
    scene = outcome(load_scene, path)
    if scene is not None:
        assert_scene_is_the_file(scene, data)


@fuzz(150)
@given(data=st.one_of(
    st.binary(max_size=600),
    st.builds(lambda head, text, body: head + text.encode("latin-1") + body,
              st.sampled_from([b"ply\n", b"ply\r\n", b"ply\r", b"ply\nformat binary_little_endian 1.0\n", b"PLY\n",
                               b"ply", b""]),
              st.lists(header_lines, max_size=8).map(lambda lines: "\n".join(lines + ["end_header", ""])),
              st.binary(max_size=300)),
), suffix=st.sampled_from([".ply", ".PLY", ".bin", ""]))
def test_random_bytes_and_header_text(tmp_path, data, suffix):
    path = tmp_path / f"random{suffix}"
    path.write_bytes(data)
    scene = outcome(load_scene, path)
    if scene is not None:
        assert_scene_is_the_file(scene, data)


def assert_same_scene(scene, reference) -> None:
    """Bit for bit: every array's bytes (NaN payloads and signed zeros included), dtype,
    shape, and the metadata."""
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        ours, theirs = getattr(scene, field), getattr(reference, field)
        assert (ours.dtype, ours.shape) == (theirs.dtype, theirs.shape), field
        assert ours.tobytes() == theirs.tobytes(), field
    assert (scene.count, scene.sh_degree, scene.filter_fused, scene.source, scene.dropped) == \
        (reference.count, reference.sh_degree, reference.filter_fused, reference.source, reference.dropped)


@fuzz(300)
@given(data=st.one_of(corrupt_plys(), st.deferred(lambda: valid_variants()).map(lambda case: case[1]),
                      st.deferred(lambda: special_value_plys())),
       chunk=st.sampled_from([1, 100, 4 << 20]))
def test_ply_loads_as_the_reader_before_issue_16_did(tmp_path, data, chunk):
    """The chunked reader against a frozen copy of the one it replaced (ply_reference.py):
    a file loads now exactly when it loaded then, into the same Scene to the bit."""
    path = tmp_path / "fuzz.ply"
    path.write_bytes(data)
    scene = outcome(lambda p: load_scene(p, chunk_bytes=chunk), path)
    with mock.patch.object(scene_io, "load_ply", reference_load_ply):
        reference = outcome(lambda p: load_scene(p, chunk_bytes=chunk), path)
    assert (scene is None) == (reference is None), (scene, reference)
    if scene is not None:
        assert_same_scene(scene, reference)


@st.composite
def special_value_plys(draw) -> bytes:
    """A valid PLY whose values are drawn from NaN, infinities, zeros, subnormals and
    overflowing log-scales: every drop reason and activation edge."""
    cols = draw(gaussian_files())
    n = len(cols["x"])
    for name in cols:
        picks = draw(st.lists(st.booleans(), min_size=n, max_size=n))
        values = draw(st.lists(st.sampled_from(_SPECIAL_FLOATS), min_size=n, max_size=n))
        cols[name] = np.where(picks, values, cols[name])
    return ply_bytes(cols)


@st.composite
def valid_variants(draw):
    """(columns, the bytes of an equivalent valid PLY): comments anywhere, obj_info
    before the elements,
    blank lines (a space), CRLF or CR line ends, unknown properties of every type at any position,
    any property order, other elements (lists, no properties, large counts) before and
    after ``vertex``."""
    cols = draw(gaussian_files())
    n = len(cols["x"])
    out, types = dict(cols), {}
    for i in range(draw(st.integers(0, 3))):
        name, kind = f"extra_{i}", draw(st.sampled_from(_CANONICAL_TYPES))
        info = np.finfo if kind in ("float", "float32", "double", "float64") else np.iinfo
        limits = info(np.dtype(_PLY_TYPES[kind]))
        out[name] = np.array(draw(st.lists(st.floats(float(limits.min), float(limits.max)) if info is np.finfo
                                           else st.integers(int(limits.min), int(limits.max)),
                                           min_size=n, max_size=n)))
        types[name] = kind
    names = draw(st.permutations(list(out)))
    out = {name: out[name] for name in names}
    before = draw(st.lists(valid_element(), max_size=2))
    after = draw(st.lists(valid_element(), max_size=2))
    names_used = set()
    before = [e for e in before if not (e[2] in names_used or names_used.add(e[2]))]
    after = [e for e in after if not (e[2] in names_used or names_used.add(e[2]))]
    data = ply_bytes(out, types=types, elements_before=[e[:2] for e in before],
                     elements_after=[e[:2] for e in after])
    lines, body = split_ply(data)
    for _ in range(draw(st.integers(0, 4))):
        text = draw(st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=30))
        # (A truly empty line is not PLY: plyfile takes it for the end of the file.)
        line = draw(st.sampled_from(["comment " + text, "obj_info " + text, "comment", " "]))
        first_element = next(i for i, line in enumerate(lines) if line.startswith("element"))
        lines.insert(draw(st.integers(0, first_element if line.startswith("obj_info") else len(lines) - 1)), line)
    return cols, join_ply(lines, body, draw(st.sampled_from(["\n", "\r\n", "\r"])))


@st.composite
def valid_element(draw):
    """(header, data, name) of a well-formed non-vertex element."""
    name = draw(st.sampled_from(["face", "meta", "edge", "camera"]))
    if draw(st.integers(0, 3)) == 0:  # no properties: any count fits in no bytes
        return f"element {name} {draw(st.sampled_from([0, 5, 10**12, 2**62]))}", b"", name
    kinds = draw(st.lists(st.sampled_from(_TYPE_NAMES + ["list"]), min_size=1, max_size=3))
    count = draw(st.integers(0, 3))
    header = [f"element {name} {count}"]
    for i, kind in enumerate(kinds):
        header.append(f"property list uchar int p{i}" if kind == "list" else f"property {kind} p{i}")
    data = b""
    for _ in range(count):
        for kind in kinds:
            if kind == "list":
                items = draw(st.integers(0, 4))
                data += bytes([items]) + draw(st.binary(min_size=4 * items, max_size=4 * items))
            else:
                size = np.dtype(_PLY_TYPES[kind]).itemsize
                data += draw(st.binary(min_size=size, max_size=size))
    return "\n".join(header), data, name


@fuzz(150)
@given(case=valid_variants())
def test_valid_variants_load_the_same_scene(tmp_path, case):
    cols, data = case
    plain = load_scene(write_ply(tmp_path / "plain.ply", cols))
    path = tmp_path / "variant.ply"
    path.write_bytes(data)
    scene = load_scene(path)  # valid: must load
    assert_scene_is_the_file(scene, data)
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(scene, field), getattr(plain, field))
    assert (scene.count, scene.sh_degree, scene.filter_fused, scene.dropped) == \
        (plain.count, plain.sh_degree, plain.filter_fused, plain.dropped)


@fuzz(150)
@given(cols=gaussian_files(max_n=8), data=st.data())
def test_nan_and_inf_values_drop_exactly_those_gaussians(tmp_path, cols, data):
    n = len(cols["x"])
    names = [name for name in cols if name not in ("nx", "ny", "nz")]
    hits = data.draw(st.lists(st.tuples(st.integers(0, max(0, n - 1)), st.sampled_from(names),
                                        st.sampled_from(_SPECIAL_FLOATS)), max_size=6)) if n else []
    for row, name, value in hits:
        cols[name][row] = value
    path = write_ply(tmp_path / "values.ply", cols)
    scene = load_scene(path)
    expected = assert_scene_is_the_file(scene, path.read_bytes())
    untouched = np.ones(n, bool)
    untouched[[row for row, _, _ in hits]] = False
    assert np.all(expected["keep"][untouched])  # a valid gaussian is never dropped


_ABSURD_FILES = st.one_of(
    # the vertex count
    st.builds(lambda cols, count: ply_bytes(cols, count=count), gaussian_files(),
              st.sampled_from([10**6, 10**12, 2**31, 2**32, 2**62, 2**63 - 1, 2**63, 2**64, 10**40])),
    # another element's count or list lengths (before or after vertex)
    st.builds(lambda cols, element, first: ply_bytes(cols, **{"elements_before" if first else "elements_after":
                                                               [element]}),
              gaussian_files(), extra_element(absurd=True).map(lambda e: ("\n".join(e[0]), e[1])), st.booleans()),
)


@fuzz(120)
@given(data=_ABSURD_FILES)
def test_absurd_counts_allocate_nothing_proportional_to_them(tmp_path, data):
    path = tmp_path / "absurd.ply"
    path.write_bytes(data)
    tracemalloc.start()
    try:
        scene = outcome(load_scene, path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 * len(data) + (16 << 20), peak
    if scene is not None:
        assert_scene_is_the_file(scene, data)


@fuzz(40)
@given(data=corrupt_plys())
def test_cli_info_on_corrupt_files_prints_one_error_line(tmp_path, capsys, data):
    path = tmp_path / "cli.ply"
    path.write_bytes(data)
    try:
        load_scene(path)
        failed = False
    except UserError:
        failed = True
    capsys.readouterr()
    code = cli.main(["info", str(path)])
    out, err = capsys.readouterr()
    if failed:
        assert code == 2 and out == "", (code, out)
        assert err.startswith("error: ") and err.count("\n") == 1 and err.endswith("\n"), repr(err)
        assert "Traceback" not in err and path.name in err
    else:
        assert code == 0 and "error" not in err


# =========================================================================== .splat

_SPLAT = np.dtype([("position", "<f4", (3,)), ("scale", "<f4", (3,)), ("rgba", "u1", (4,)), ("rotation", "u1", (4,))])


def assert_splat_is_the_file(scene, data: bytes) -> None:
    assert_valid_scene(scene)
    assert len(data) % 32 == 0
    rows = np.frombuffer(data, _SPLAT)
    positions, scales = rows["position"], rows["scale"]
    q = (rows["rotation"].astype(np.float64) - 128) / 128
    norm = np.linalg.norm(q, axis=1)
    with np.errstate(invalid="ignore"):
        keep = ~(np.isnan(positions).any(1) | np.isnan(scales).any(1) | np.isinf(positions).any(1)
                 | np.isinf(scales).any(1) | (scales <= 0).any(1) | (norm == 0))
    assert scene.count == keep.sum() and sum(scene.dropped.values()) == len(rows) - keep.sum()
    assert scene.sh_degree == 0 and not scene.filter_fused
    np.testing.assert_array_equal(scene.positions, positions[keep])
    np.testing.assert_array_equal(scene.scales, scales[keep])
    rgba = rows["rgba"][keep].astype(np.float64)
    np.testing.assert_allclose(scene.opacities, rgba[:, 3] / 255, atol=1e-7)
    np.testing.assert_allclose(scene.sh[:, 0, :], (rgba[:, :3] / 255 - 0.5) / C0, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(scene.rotations, q[keep] / norm[keep, None], atol=1e-6)


splat_floats = st.one_of(st.floats(width=32), st.sampled_from(_SPECIAL_FLOATS))


@st.composite
def splat_files(draw) -> bytes:
    n = draw(st.integers(0, 6))
    three = st.lists(splat_floats, min_size=3, max_size=3)
    bytes4 = st.lists(st.integers(0, 255), min_size=4, max_size=4)
    data = splat_bytes(np.reshape(draw(st.lists(three, min_size=n, max_size=n)), (n, 3)),
                       np.reshape(draw(st.lists(three, min_size=n, max_size=n)), (n, 3)),
                       np.reshape(draw(st.lists(bytes4, min_size=n, max_size=n)), (n, 4)),
                       np.reshape(draw(st.lists(bytes4, min_size=n, max_size=n)), (n, 4))) if n else b""
    for _ in range(draw(st.integers(0, 2))):
        data = draw(byte_mutation(data))
    return data


@fuzz(200)
@given(data=st.one_of(splat_files(), st.binary(max_size=300)))
def test_corrupt_splat_loads_correctly_or_is_a_one_line_user_error(tmp_path, data):
    path = tmp_path / "fuzz.splat"
    path.write_bytes(data)
    scene = outcome(load_scene, path)
    if scene is not None:
        assert_splat_is_the_file(scene, data)
    else:
        assert len(data) % 32  # every whole number of rows is a scene


# =========================================================================== JSON


_BIGINT = "@@bigint@@"   # written as a 5000-digit integer: beyond Python's int parsing limit
_DEEP = "@@deep@@"       # written as 3000 nested lists
_SPECIAL_JSON = [float("nan"), float("inf"), float("-inf"), 0, -0.0, 1, -1, 0.5, 1e308, -1e308, 1e-320,
                 10**400, -10**400, 2**63, 2**64, True, False, None, "", "1", "NaN", [], {}, [0, 0, 0],
                 [[1, 0, 0], [0, 1, 0], [0, 0, 1]], [[[1.0]]], _BIGINT, _DEEP]
_FACTORS = [-1.0, 0.0, 0.5, 1 + 1e-9, 1 + 1e-4, 2.0, 1e200, -1e200, 1e-200, 1e308, 10**400]
_KEYS = ["a\nb", "x\x1cy", "\u2028", "\r", "", "mode", "exposure", "k3", "eye_relief", "é"]

special_json = st.sampled_from(_SPECIAL_JSON).map(copy.deepcopy)  # mutations must not touch the list
json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=8), special_json),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4),
    max_leaves=10,
)


def json_paths(value, prefix=()):
    """Every path (keys and indices) into a parsed JSON value, the root first."""
    yield prefix
    if isinstance(value, dict):
        for key, child in value.items():
            yield from json_paths(child, prefix + (key,))
    elif isinstance(value, list):
        for i, child in enumerate(value):
            yield from json_paths(child, prefix + (i,))


def _at(value, path):
    for key in path:
        value = value[key]
    return value


def _scaled(value, factor):
    if isinstance(value, list):
        return [_scaled(v, factor) for v in value]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        try:
            return value * factor
        except OverflowError:
            return value
    return value


@st.composite
def mutated_json(draw, base) -> bytes:
    """``base`` after 1-3 changes at any depth (delete, replace by any JSON value or an
    awkward one, scale numbers, add an odd key, wrap in a list), then maybe its text
    truncated or a few bytes flipped."""
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["delete", "replace", "special", "scale", "add_key", "wrap"]))
        paths = list(json_paths(data))
        if kind == "add_key":
            paths = [path for path in paths if isinstance(_at(data, path), dict)] or paths
        path = draw(st.sampled_from(paths))
        parent = _at(data, path[:-1])
        old = _at(data, path)
        if kind == "delete" and path:
            del parent[path[-1]]
            continue
        if kind == "add_key" and isinstance(old, dict):
            old[draw(st.one_of(st.sampled_from(_KEYS), st.text(max_size=4)))] = draw(json_values)
            continue
        new = {"special": lambda: draw(special_json),
               "scale": lambda: _scaled(old, draw(st.sampled_from(_FACTORS))),
               "wrap": lambda: [old]}.get(kind, lambda: draw(json_values))()
        if path:
            parent[path[-1]] = new
        else:
            data = new
    text = json.dumps(data).replace(f'"{_BIGINT}"', "9" * 5000).replace(f'"{_DEEP}"', "[" * 3000 + "]" * 3000)
    raw = text.encode("utf-8", "surrogatepass")
    if draw(st.integers(0, 5)) == 0:
        raw = draw(byte_mutation(raw))
    return raw


def _rotation_ok(rotation, tolerance) -> bool:
    """An independent, NaN-safe check that a JSON 3x3 is a proper rotation."""
    r = np.array(rotation, dtype=np.float64)
    with np.errstate(all="ignore"):
        return bool(np.all(np.isfinite(r)) and np.all(np.abs(r.T @ r - np.eye(3)) <= tolerance)
                    and np.linalg.det(r) > 0)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def assert_camera_is_the_entry(camera: Camera, entry: dict) -> None:
    assert isinstance(entry, dict)
    for key in ("width", "height", "fx", "fy"):
        assert _is_number(entry[key]) and getattr(camera, key) == entry[key], key
    assert isinstance(camera.width, int) and 1 <= camera.width <= 65536 and 1 <= camera.height <= 65536
    assert camera.fx > 0 and camera.fy > 0
    for key, default in (("cx", entry["width"] / 2), ("cy", entry["height"] / 2)):
        assert getattr(camera, key) == entry.get(key, default) and math.isfinite(getattr(camera, key))
    assert _rotation_ok(entry["rotation"], 1e-3), entry["rotation"]
    position = np.array(entry["position"], dtype=np.float64)
    assert position.shape == (3,) and np.all(np.isfinite(position))
    np.testing.assert_allclose(camera.R @ camera.R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(camera.R) > 0
    np.testing.assert_allclose(camera.R.T, np.array(entry["rotation"], dtype=np.float64), atol=2e-3)
    np.testing.assert_allclose(camera.center, position, rtol=1e-9, atol=1e-9 * (1 + np.abs(position).max()))


# --------------------------------------------------------------------------- cameras.json


@st.composite
def camera_files(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    entries = []
    for i in range(draw(st.integers(1, 3))):
        entry = {"id": i, "img_name": f"img_{i}", "width": int(rng.integers(1, 200)),
                 "height": int(rng.integers(1, 200)), "position": rng.normal(size=3).tolist(),
                 "rotation": random_rotation(rng).T.tolist(), "fx": float(rng.uniform(10, 300)),
                 "fy": float(rng.uniform(10, 300))}
        if draw(st.booleans()):
            entry["cx"], entry["cy"] = float(rng.uniform(0, 200)), float(rng.uniform(0, 200))
        entries.append(entry)
    return entries if len(entries) > 1 or draw(st.booleans()) else entries[0]


@fuzz(300)
@given(case=camera_files().flatmap(lambda base: st.tuples(mutated_json(base), st.integers(-4, 4))))
def test_corrupt_cameras_json_loads_correctly_or_is_a_one_line_user_error(tmp_path, case):
    raw, index = case
    path = tmp_path / "cameras.json"
    path.write_bytes(raw)
    camera = outcome(lambda p: load_camera(p, index), path)
    if camera is None:
        return
    data = json.loads(raw.decode("utf-8"))
    entries = data if isinstance(data, list) else [data]
    assert_camera_is_the_entry(camera, entries[index])
    assert len(load_cameras(path)) == len(entries)


@fuzz(100)
@given(data=st.one_of(json_values.map(lambda v: json.dumps(v).encode()), st.binary(max_size=200)),
       index=st.integers(-2, 2))
def test_random_json_as_cameras(tmp_path, data, index):
    path = tmp_path / "random.json"
    path.write_bytes(data)
    camera = outcome(lambda p: load_camera(p, index), path)
    if camera is not None:
        value = json.loads(data)
        assert_camera_is_the_entry(camera, (value if isinstance(value, list) else [value])[index])


# --------------------------------------------------------------------------- sidecars

_STEREO = StereoView(StereoRig(0.07, 3.5, 0.25), "sbs", LensModel(0.3, 0.1, 0.99, 1.02), PRESETS["index"])


@pytest.fixture(scope="module")
def sidecars():
    """Valid sidecars to mutate: mono (with and without a window camera), and stereo in
    every layout, with and without lens and headset."""
    bases = [demo_sidecar(), demo_sidecar(window_camera=window_camera(32, 24), extra={"up_axis": "-y"},
                                          settings=RenderSettings(mode="gs", supersample=2))]
    for layout in LAYOUTS:
        bases.append(demo_sidecar(stereo=dataclasses.replace(_STEREO, layout=layout)))
    bases.append(demo_sidecar(stereo=StereoView(StereoRig(), "anaglyph", None, None)))
    bases = [json.loads(json.dumps(b)) for b in bases]
    return bases


def assert_sidecar_is_the_data(sidecar: Sidecar, data: dict) -> None:
    assert isinstance(sidecar, Sidecar)
    assert 1 <= data["version"] <= 2 and (sidecar.stereo is not None) == ("stereo" in data)
    assert sidecar.render_mode in RENDER_MODES and sidecar.settings.mode == sidecar.render_mode == data["render_mode"]
    assert 0 < sidecar.scale <= 8 and sidecar.scale == data["image"]["scale"]
    assert sidecar.scene_path == data["scene"]["path"] != ""
    camera = sidecar.camera
    entry = data["camera"]
    assert (camera.width, camera.height, camera.fx, camera.fy) == \
        (entry["width"], entry["height"], entry["fx"], entry["fy"])
    if "world_to_camera" in data:
        pose = data["world_to_camera"]
        assert _rotation_ok(np.array(pose["R"], dtype=np.float64).T, 1e-5)
        assert camera.R.tolist() == pose["R"] and camera.t.tolist() == pose["t"]
    else:
        assert_camera_is_the_entry(camera, entry)
    size = (camera.width, camera.height) if sidecar.stereo is None else \
        composed_size(camera.width, camera.height, sidecar.stereo.layout)
    assert (data["image"]["width"], data["image"]["height"]) == size


@fuzz(300)
@given(data=st.data())
def test_corrupt_sidecar_loads_correctly_or_is_a_one_line_user_error(tmp_path, sidecars, data):
    raw = data.draw(st.sampled_from(sidecars).flatmap(mutated_json))
    path = tmp_path / "shot.json"
    path.write_bytes(raw)
    sidecar = outcome(load_sidecar, path)
    if sidecar is not None:
        assert_sidecar_is_the_data(sidecar, sidecar.raw)
        assert sidecar.raw == json.loads(raw.decode("utf-8")) or "NaN" in raw.decode("utf-8")


@fuzz(100)
@given(data=st.one_of(json_values.map(lambda v: json.dumps(v).encode()), st.binary(max_size=200)))
def test_random_json_as_sidecar(tmp_path, data):
    path = tmp_path / "random.json"
    path.write_bytes(data)
    sidecar = outcome(load_sidecar, path)
    assert sidecar is None  # random JSON is never a sidecar


_FREE_FORM = [("extra",), ("program",), ("created",), ("window",), ("scene", "count"), ("scene", "sh_degree")]


@fuzz(60)
@given(data=st.data())
def test_free_form_fields_do_not_change_the_load(tmp_path, sidecars, data):
    """Fields the loader does not read (and unknown top-level keys) may hold anything."""
    base = data.draw(st.sampled_from(sidecars))
    plain = load_sidecar(_write(tmp_path / "plain.json", base))
    changed = copy.deepcopy(base)
    for path in data.draw(st.lists(st.sampled_from(_FREE_FORM + [("future_key",)]), min_size=1, max_size=3)):
        target = changed
        for key in path[:-1]:
            target = target[key]
        value = data.draw(json_values.filter(lambda v: not isinstance(v, str) or v not in (_BIGINT, _DEEP)))
        if path[-1] == "extra":
            value = value if isinstance(value, dict) else {"value": value}
        target[path[-1]] = value
    sidecar = load_sidecar(_write(tmp_path / "changed.json", changed))
    assert sidecar.camera.R.tobytes() == plain.camera.R.tobytes() and sidecar.camera.t.tobytes() == \
        plain.camera.t.tobytes()
    assert (sidecar.settings, sidecar.stereo, sidecar.scale, sidecar.scene_sha256) == \
        (plain.settings, plain.stereo, plain.scale, plain.scene_sha256)


def _write(path: Path, data) -> Path:
    path.write_text(json.dumps(data))
    return path


# =========================================================================== regressions
# Plain tests for what the fuzzing above found.


@pytest.mark.parametrize("count", [2**63, 2**64, 10**30])
@pytest.mark.parametrize("where", ["elements_before", "elements_after"])
def test_an_element_count_beyond_int64_is_a_user_error(tmp_path, count, where):
    """An element without properties needs no bytes, so no size check bounds its count;
    plyfile's numpy shape overflowed (OverflowError) past 2**63 - 1."""
    path = write_ply(tmp_path / "count.ply", gaussian_columns(2), **{where: [(f"element junk {count}", b"")]})
    with pytest.raises(UserError) as info:
        load_scene(path)
    assert "too large" in assert_one_line(info.value, path)
    fine = write_ply(tmp_path / "fine.ply", gaussian_columns(2), **{where: [(f"element junk {2**62}", b"")]})
    assert load_scene(fine).count == 2


@pytest.mark.parametrize("length_type, value_type, length", [("uint", "int", 2**32 - 1), ("int", "double", 2**31 - 1),
                                                             ("ushort", "float", 2**16 - 1), ("char", "int", -1)])
@pytest.mark.parametrize("where", ["elements_before", "elements_after"])
def test_a_list_length_beyond_the_file_allocates_nothing(tmp_path, length_type, value_type, length, where):
    """plyfile read a list with stream.read(length * itemsize), which allocated the whole
    bogus length (16 GiB for a uint) before finding the file short."""
    length_bytes = np.array([length], np.dtype(_PLY_TYPES[length_type])).tobytes()
    element = (f"element face 1\nproperty list {length_type} {value_type} idx", length_bytes + bytes(8))
    path = write_ply(tmp_path / "list.ply", gaussian_columns(3), **{where: [element]})
    tracemalloc.start()
    try:
        with pytest.raises(UserError) as info:
            load_scene(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert "early end-of-file" in assert_one_line(info.value, path)
    assert peak < 8 << 20, peak


def _camera_text(**changes):
    entry = {"width": 64, "height": 48, "position": [0.0, 0.0, 0.0], "rotation": np.eye(3).tolist(),
             "fx": 50.0, "fy": 50.0}
    entry.update(changes)
    return json.dumps([entry])


BAD_CAMERA_FILES = {
    # an integer beyond float range: OverflowError from math.isfinite / numpy
    "huge_int_width": (_camera_text(width=10**400), "'width' must be finite"),
    "huge_int_fx": (_camera_text(fx=-10**400), "'fx' must be finite"),
    "huge_int_cx": (_camera_text(cx=10**400), "'cx' must be finite"),
    "huge_int_position": (_camera_text(position=[10**400, 0, 0]), "must be finite"),
    "huge_int_rotation": (_camera_text(rotation=[[1, 0, 0], [0, 1, 0], [0, 0, 2**1024]]), "must be finite"),
    # over 4300 digits: json.loads raised a ValueError that is no JSONDecodeError
    "5000_digits": (_camera_text(fx=1.5).replace("1.5", "9" * 5000), "too many digits"),
    # nested deeper than the stack allows the recursive check (RecursionError)
    "deep_position": (_camera_text(position=0).replace('"position": 0', '"position": ' + "[" * 700 + "]" * 700),
                      "arrays of numbers"),
    "deep_rotation": (_camera_text(rotation=0).replace('"rotation": 0', '"rotation": ' + "[" * 900 + "1"
                                                       + "]" * 900), "arrays of numbers"),
}


@pytest.mark.parametrize("case", sorted(BAD_CAMERA_FILES))
def test_camera_files_that_raised_other_exceptions(tmp_path, case):
    text, fragment = BAD_CAMERA_FILES[case]
    path = tmp_path / "cameras.json"
    path.write_text(text)
    with pytest.raises(UserError) as info:
        load_camera(path)
    assert fragment in assert_one_line(info.value, path)


def _sidecar_change(dotted, value):
    def change(data):
        *parents, last = dotted.split(".")
        _at(data, parents)[last] = value
    return change


BAD_SIDECARS = {
    # an integer beyond float range: OverflowError from math.isfinite / numpy
    "huge_int_scale": (False, _sidecar_change("image.scale", 10**400), "'image.scale' must be finite"),
    "huge_int_p_min": (False, _sidecar_change("settings.p_min", 10**400), "'settings.p_min' must be finite"),
    "huge_int_background": (False, _sidecar_change("settings.background", [0, -10**400, 0]),
                            "'settings.background' must be finite"),
    "huge_int_t": (False, _sidecar_change("world_to_camera.t", [10**400, 0, 0]), "'world_to_camera.t' must be finite"),
    "huge_int_R": (False, _sidecar_change("world_to_camera.R", [[10**400, 0, 0], [0, 1, 0], [0, 0, 1]]),
                   "'world_to_camera.R' must be finite"),
    "huge_int_ipd": (True, _sidecar_change("stereo.ipd", 10**400), "'stereo.ipd' must be finite"),
    "huge_int_fov": (True, _sidecar_change("stereo.headset.fov_x", 10**400), "'stereo.headset.fov_x' must be finite"),
    # a newline in an unknown key split the message in two
    "newline_setting": (False, _sidecar_change("settings.a\nb", 1), "unknown setting 'settings.a\\nb'"),
    "newline_stereo_field": (True, _sidecar_change("stereo.x\ry", 1), "unknown field 'stereo.x\\ry'"),
    "separator_lens_field": (True, _sidecar_change("stereo.lens.k\x1c3", 1), "unknown field 'stereo.lens.k\\x1c3'"),
}


@pytest.mark.parametrize("case", sorted(BAD_SIDECARS))
def test_sidecars_that_raised_other_exceptions_or_split_lines(tmp_path, sidecars, case):
    stereo, change, fragment = BAD_SIDECARS[case]
    data = copy.deepcopy(sidecars[2] if stereo else sidecars[0])
    change(data)
    path = _write(tmp_path / "shot.json", data)
    with pytest.raises(UserError) as info:
        load_sidecar(path)
    assert fragment in assert_one_line(info.value, path)


@pytest.mark.parametrize("case", ["huge_int_width", "newline_setting", "element_count", "list_length"])
def test_cli_reports_the_regressions_in_one_line(tmp_path, capsys, sidecars, case):
    if case in BAD_SIDECARS:
        data = copy.deepcopy(sidecars[0])
        BAD_SIDECARS[case][1](data)
        path = _write(tmp_path / "shot.json", data)
        args = ["render", "--sidecar", str(path), "--out", str(tmp_path / "out.png")]
    elif case == "element_count":
        path = write_ply(tmp_path / "count.ply", gaussian_columns(2), elements_after=[(f"element junk {2**64}", b"")])
        args = ["info", str(path)]
    elif case == "list_length":
        element = ("element face 1\nproperty list uint int idx", np.uint32([2**32 - 1]).tobytes())
        path = write_ply(tmp_path / "list.ply", gaussian_columns(2), elements_before=[element])
        args = ["info", str(path)]
    else:
        path = tmp_path / "cameras.json"
        path.write_text(BAD_CAMERA_FILES[case][0])
        args = ["render", "demo", "--camera", str(path), "--out", str(tmp_path / "out.png")]
    assert cli.main(args) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("error: ") and err.count("\n") == 1 and path.name in err, err


def test_a_signalling_nan_is_dropped_without_a_warning(tmp_path):
    """A flipped bit turns +-inf into a signalling NaN, whose float32 -> float64 cast
    raised "invalid value encountered in cast" (a RuntimeWarning on the terminal)."""
    cols = gaussian_columns(5)
    data = bytearray(ply_bytes(cols))
    body = data.index(b"end_header\n") + len(b"end_header\n")
    row = 14 * 4
    for i, name in enumerate(("x", "opacity", "scale_1", "rot_3")):
        offset = body + (i + 1) * row + 4 * list(cols).index(name)
        data[offset:offset + 4] = np.uint32([0x7F800001]).tobytes()
    path = tmp_path / "snan.ply"
    path.write_bytes(bytes(data))
    scene = load_scene(path)  # the module's filterwarnings("error") turns a warning into a failure
    assert scene.count == 1 and scene.dropped == {"nan": 4}


def test_an_absurd_rotation_is_rejected_without_a_warning(tmp_path, sidecars):
    """R^T R overflowed ("overflow encountered in matmul") before the check rejected it."""
    path = tmp_path / "cameras.json"
    path.write_text(_camera_text(rotation=[[1e200, 0, 0], [0, 1e200, 0], [0, 0, 1]]))
    with pytest.raises(UserError, match="not a rotation matrix"):
        load_camera(path)
    data = copy.deepcopy(sidecars[0])
    data["world_to_camera"]["R"] = [[1e200, 0, 0], [0, 1e200, 0], [0, 0, 1]]
    with pytest.raises(UserError, match="not a rotation matrix"):
        load_sidecar(_write(tmp_path / "shot.json", data))
