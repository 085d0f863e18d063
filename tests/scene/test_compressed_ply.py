"""PlayCanvas compressed PLY (issue 18): the shared sample, files written here by a small
encoder built from the format's writer (splat-transform's compressed-chunk.ts), exact
words with answers worked by hand, and hostile headers and data.

The encoder below is the tests' own: per 256-gaussian chunk the min/max of each
attribute, unorms rounded with floor(t * (2^bits - 1) + 0.5), the quaternion's largest
component dropped (sign flipped to make it positive) and the other three stored as
a * sqrt(2) / 2 + 0.5, colours as f_dc * C0 + 0.5, SH bytes trunc((v / 8 + 0.5) * 256).
Decoding must give back the scene within half a quantisation step of each attribute.
"""

from __future__ import annotations

import base64
import math

import numpy as np
import pytest
import testkit

from raygs_viewer.scene.compressed_ply import CHUNK_GAUSSIANS, COMPRESSED_PLY_FORMAT
from raygs_viewer.scene.io import describe, load_scene

C0 = 0.28209479177387814
GUITAR = testkit.SHARED_SCENES / "formats" / "pc-guitar.compressed.ply"
EPS32 = float(np.finfo(np.float32).eps)

BOUNDS = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
          "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"]
COLOUR_BOUNDS = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
PACKED = ["packed_position", "packed_rotation", "packed_scale", "packed_color"]


# --------------------------------------------------------------------------- the tests' encoder


def known_scene(n=600, degree=0, seed=0, colour_in_unit=False):
    """Source values in the INRIA PLY's terms (float64): positions, log-scales, unit
    quaternions w x y z, f_dc, opacity logits, and f_rest (n, 3k) channel-major."""
    rng = np.random.default_rng(seed)
    k = (degree + 1) ** 2 - 1
    q = rng.normal(size=(n, 4))
    # Without colour bounds the stored colour is the unorm itself, so it must lie in [0, 1].
    dc_range = 0.45 / C0 if colour_in_unit else 1.5
    return {
        "positions": rng.uniform(-3, 3, (n, 3)),
        "log_scales": rng.uniform(-7, -1, (n, 3)),
        "quats": q / np.linalg.norm(q, axis=1, keepdims=True),
        "f_dc": rng.uniform(-dc_range, dc_range, (n, 3)),
        "logits": rng.uniform(-5, 5, n),
        "rest": rng.uniform(-3.9, 3.9, (n, 3 * k)),
    }


def _chunked(a):
    """(n, ...) -> (chunks, 256, ...), the last chunk padded with the last gaussian (as
    splat-transform's writer pads it)."""
    n = a.shape[0]
    chunks = -(-n // CHUNK_GAUSSIANS)
    pad = np.repeat(a[-1:], chunks * CHUNK_GAUSSIANS - n, axis=0)
    return np.concatenate([a, pad]).reshape((chunks, CHUNK_GAUSSIANS) + a.shape[1:])


def _quantise(t, bits):
    top = (1 << bits) - 1
    return np.clip(np.floor(t * top + 0.5), 0, top).astype(np.uint32)


def _normalised(v, low, high):
    """The writer's normalize(): 0 at or below min, 1 at or above max, 0 for a span < 1e-5."""
    span = high - low
    t = (v - low[:, None]) / np.where(span < 1e-5, 1.0, span)[:, None]
    return np.where(span[:, None] < 1e-5, 0.0, np.clip(t, 0.0, 1.0))


def _pack_111011(values):
    """values (chunks, 256, 3) -> (words (chunks, 256), low (chunks, 3), high (chunks, 3))."""
    low, high = values.min(axis=1), values.max(axis=1)
    t = _normalised(values, low, high)
    words = (_quantise(t[..., 0], 11) << np.uint32(21)) | (_quantise(t[..., 1], 10) << np.uint32(11)) \
        | _quantise(t[..., 2], 11)
    return words, low, high


def _pack_rotation(quats):
    q = quats / np.linalg.norm(quats, axis=-1, keepdims=True)
    largest = np.argmax(np.abs(q), axis=-1)
    q = q * np.where(np.take_along_axis(q, largest[..., None], -1) < 0, -1.0, 1.0)
    words = largest.astype(np.uint32)
    others = np.array([[s for s in range(4) if s != big] for big in range(4)])[largest]
    for j in range(3):
        component = np.take_along_axis(q, others[..., j:j + 1], -1)[..., 0]
        words = (words << np.uint32(10)) | _quantise(component * math.sqrt(2) * 0.5 + 0.5, 10)
    return words


def encode(src, *, colour_bounds=True, sh=None, elements_after=()):
    """The elements of a compressed PLY of ``src`` (see :func:`known_scene`): a list of
    (name, count, [(ply type, property)], data bytes), and the chunk bounds (chunks, 18)."""
    n = src["positions"].shape[0]
    chunks = -(-n // CHUNK_GAUSSIANS)
    position, p_low, p_high = _pack_111011(_chunked(src["positions"]))
    scale, s_low, s_high = _pack_111011(_chunked(src["log_scales"]))
    rotation = _pack_rotation(_chunked(src["quats"]))
    colour = _chunked(src["f_dc"]) * C0 + 0.5
    if colour_bounds:
        c_low, c_high = colour.min(axis=1), colour.max(axis=1)
        t = _normalised(colour, c_low, c_high)
    else:
        c_low, c_high = np.zeros((chunks, 3)), np.ones((chunks, 3))
        t = np.clip(colour, 0.0, 1.0)
    alpha = 1.0 / (1.0 + np.exp(-_chunked(src["logits"])))
    color = (_quantise(t[..., 0], 8) << np.uint32(24)) | (_quantise(t[..., 1], 8) << np.uint32(16)) \
        | (_quantise(t[..., 2], 8) << np.uint32(8)) | _quantise(alpha, 8)
    bounds = np.concatenate([p_low, p_high, s_low, s_high, c_low, c_high], axis=1).astype(np.float32)
    names = BOUNDS + (COLOUR_BOUNDS if colour_bounds else [])
    words = np.stack([position, rotation, scale, color], axis=-1).reshape(-1, 4)[:n]
    elements = [
        ("chunk", chunks, [("float", p) for p in names], bounds[:, :len(names)].tobytes()),
        ("vertex", n, [("uint", p) for p in PACKED], words.astype("<u4").tobytes()),
    ]
    rest = src["rest"] if sh is None else sh
    if rest.shape[1]:
        data = np.clip(np.trunc((rest / 8 + 0.5) * 256), 0, 255).astype(np.uint8)
        elements.append(("sh", n, [("uchar", f"f_rest_{j}") for j in range(rest.shape[1])], data.tobytes()))
    return elements + list(elements_after), bounds


def assemble(elements, header_extra=()) -> bytes:
    lines = ["ply", "format binary_little_endian 1.0", "comment written by test_compressed_ply"]
    lines += list(header_extra)
    for name, count, properties, _ in elements:
        lines.append(f"element {name} {count}")
        lines += [f"property {kind} {prop}" for kind, prop in properties]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii") + b"".join(data for *_, data in elements)


def write(path, elements, **kwargs):
    path.write_bytes(assemble(elements, **kwargs))
    return path


def chunk_of(n):
    return np.arange(n) // CHUNK_GAUSSIANS


# --------------------------------------------------------------------------- round trips


def assert_within_quantisation(scene, src, bounds, colour_bounds=True):
    n = src["positions"].shape[0]
    ci = chunk_of(n)
    b = bounds.astype(np.float64)[ci]
    half = np.array([0.5 / 2047, 0.5 / 1023, 0.5 / 2047])  # half a step of 11, 10, 11 bits

    def assert_close(name, got, want, tolerance):
        error = np.abs(got - want)
        if not error.size:
            return
        worst = int(np.unravel_index(np.argmax(error - tolerance), error.shape)[0])
        assert np.all(error <= tolerance), f"{name}: gaussian {worst} off by {error[worst]} > {tolerance[worst]}"

    # Position: half a step of the chunk's extent on each axis (+ float32 rounding).
    extent = b[:, 3:6] - b[:, 0:3]
    slack = 4 * EPS32 * np.maximum(np.abs(b[:, 0:3]), np.abs(b[:, 3:6]))
    assert_close("position", scene.positions.astype(np.float64), src["positions"], extent * half + slack)
    # Log-scale: half a step of the chunk's log-scale extent.
    extent = b[:, 9:12] - b[:, 6:9]
    assert_close("log-scale", np.log(scene.scales.astype(np.float64)), src["log_scales"],
                 extent * half + 8 * EPS32 * 7)
    # Colour: half an 8-bit step of the chunk's colour extent (of [0, 1] without bounds).
    extent = b[:, 15:18] - b[:, 12:15]
    assert_close("f_dc", scene.sh[:, 0, :].astype(np.float64), src["f_dc"], (extent / 510 + 1e-6) / C0)
    assert_close("opacity", scene.opacities.astype(np.float64), 1 / (1 + np.exp(-src["logits"])),
                 np.full(n, 1 / 510 + 1e-7))
    # Rotation: each stored component within half a 10-bit step of sqrt(2) (0.00069), the
    # largest from them; the angle between q and the decoded q (q ~ -q) stays below
    # 2 * |dq| with |dq| <= sqrt(3) * 0.00069 * (1 + sqrt(3)): about 0.37 degrees.
    dots = np.abs(np.sum(scene.rotations.astype(np.float64) * src["quats"], axis=1))
    angle = np.degrees(2 * np.arccos(np.clip(dots, 0, 1)))
    bound = np.degrees(2 * math.sqrt(3) * (math.sqrt(2) / 2046) * (1 + math.sqrt(3)))
    assert_close("rotation angle (degrees)", angle, np.zeros(n), np.full(n, bound))
    np.testing.assert_allclose(np.linalg.norm(scene.rotations.astype(np.float64), axis=1), 1, atol=1e-6)
    # SH rest: the centre of a 1/32-wide bin, for values inside (-4 + 1/32, 4 - 1/32).
    k = src["rest"].shape[1] // 3
    assert scene.sh_degree == {0: 0, 3: 1, 8: 2, 15: 3}[k]
    rest = scene.sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * k).astype(np.float64)
    assert_close("f_rest", rest, src["rest"], np.full(rest.shape, 1 / 64 + 1e-6))


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("colour_bounds", [True, False], ids=["colour-bounds", "no-colour-bounds"])
def test_round_trip_within_the_quantisation(tmp_path, degree, colour_bounds):
    # 600 = 2 full chunks and a partial one of 88.
    src = known_scene(600, degree, seed=degree, colour_in_unit=not colour_bounds)
    elements, bounds = encode(src, colour_bounds=colour_bounds)
    scene = load_scene(write(tmp_path / "scene.compressed.ply", elements))
    assert scene.count == 600 and scene.dropped == {}
    assert scene.format == COMPRESSED_PLY_FORMAT
    assert scene.sh.shape == (600, (degree + 1) ** 2, 3)
    assert_within_quantisation(scene, src, bounds, colour_bounds)


@pytest.mark.parametrize("n", [1, 255, 256, 257])
def test_chunk_boundaries(tmp_path, n):
    src = known_scene(n, 1, seed=n)
    elements, bounds = encode(src)
    scene = load_scene(write(tmp_path / "s.ply", elements))
    assert scene.count == n
    assert_within_quantisation(scene, src, bounds)


def test_chunked_reading_reports_progress_and_gives_the_same_scene(tmp_path):
    src = known_scene(700, 2, seed=5)
    path = write(tmp_path / "s.ply", encode(src)[0])
    whole = load_scene(path)
    calls = []
    pieces = load_scene(path, chunk_bytes=100, progress=lambda f, stage: calls.append((f, stage)))
    reading = [f for f, stage in calls if stage == "reading"]
    assert len(reading) > 20 and reading == sorted(reading)
    assert calls[-1] == (1.0, "done")
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(pieces, field), getattr(whole, field))


def test_a_constant_attribute_decodes_exactly(tmp_path):
    # A chunk whose values do not vary has min == max: the writer stores t = 0.
    src = known_scene(300, 0, seed=3)
    src["positions"][:, 2] = 1.25
    src["log_scales"][:, 0] = -3.5
    scene = load_scene(write(tmp_path / "s.ply", encode(src)[0]))
    assert np.all(scene.positions[:, 2] == np.float32(1.25))
    assert np.all(scene.scales[:, 0] == np.float32(math.exp(np.float32(-3.5))))


def test_an_empty_scene(tmp_path):
    elements = [("chunk", 0, [("float", p) for p in BOUNDS], b""),
                ("vertex", 0, [("uint", p) for p in PACKED], b"")]
    scene = load_scene(write(tmp_path / "empty.ply", elements))
    assert scene.count == 0 and scene.format == COMPRESSED_PLY_FORMAT


def test_extra_elements_and_property_order_are_found_by_name(tmp_path):
    src = known_scene(300, 1, seed=7)
    elements, bounds = encode(src, elements_after=[("extra", 2, [("double", "v")], bytes(16))])
    reference = load_scene(write(tmp_path / "a.ply", elements))
    # The vertex words in another order, an unknown uchar column in between.
    chunk, vertex, sh, extra = elements
    words = np.frombuffer(vertex[3], "<u4").reshape(-1, 4)
    rows = np.zeros(300, [("packed_color", "<u4"), ("pad", "u1"), ("packed_scale", "<u4"),
                          ("packed_position", "<u4"), ("packed_rotation", "<u4")])
    for j, name in enumerate(PACKED):
        rows[name] = words[:, j]
    shuffled = ("vertex", 300, [("uint", "packed_color"), ("uchar", "pad"), ("uint", "packed_scale"),
                                ("uint", "packed_position"), ("uint", "packed_rotation")], rows.tobytes())
    scene = load_scene(write(tmp_path / "b.ply", [extra, chunk, shuffled, sh]))
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        np.testing.assert_array_equal(getattr(scene, field), getattr(reference, field))


# --------------------------------------------------------------------------- exact words


def one_gaussian(tmp_path, words, bounds=None, sh_bytes=None):
    bounds = np.asarray(bounds if bounds is not None else
                        [-1, -2, -3, 1, 2, 3, -5, -4, -3, -1, 0, 1, 0.25, 0, -0.5, 0.75, 1, 1.5], np.float32)
    names = BOUNDS + COLOUR_BOUNDS[: len(bounds) - 12]
    elements = [("chunk", 1, [("float", p) for p in names], bounds.tobytes()),
                ("vertex", 1, [("uint", p) for p in PACKED], np.asarray(words, "<u4").tobytes())]
    if sh_bytes is not None:
        elements.append(("sh", 1, [("uchar", f"f_rest_{j}") for j in range(len(sh_bytes))],
                         bytes(sh_bytes)))
    return load_scene(write(tmp_path / "one.ply", elements))


def test_position_and_scale_bit_fields(tmp_path):
    # x = 2047 of 2047 (max), y = 0 of 1023 (min), z = 1023 of 2047.
    word = (2047 << 21) | (0 << 11) | 1023
    scene = one_gaussian(tmp_path, [word, 0, word, 0])
    t = 1023 / 2047
    assert scene.positions[0].tolist() == [1.0, -2.0, np.float32(-3 * (1 - t) + 3 * t)]
    np.testing.assert_allclose(scene.scales[0], np.exp([-1.0, -4.0, -3 * (1 - t) + 1 * t]), rtol=1e-7)
    # y alone: 1023 of 1023 (max) and 341 of 1023.
    scene = one_gaussian(tmp_path, [(341 << 11), 0, (1023 << 11), 0])
    np.testing.assert_allclose(scene.positions[0], [-1, -2 * (1 - 341 / 1023) + 2 * 341 / 1023, -3], rtol=1e-7)
    np.testing.assert_allclose(scene.scales[0], np.exp([-5.0, 0.0, -3.0]), rtol=1e-7)


def test_rotation_smallest_three_component_order(tmp_path):
    s = math.sqrt(2)
    a, b, c = (1023 / 1023 - 0.5) * s, (0 / 1023 - 0.5) * s, (600 / 1023 - 0.5) * s
    for largest in range(4):
        word = (largest << 30) | (1023 << 20) | (0 << 10) | 600
        m = math.sqrt(max(0.0, 1 - (a * a + b * b + c * c)))
        stored = [a, b, c]
        expected = stored[:largest] + [m] + stored[largest:]  # slots w x y z, the largest one implied
        expected = np.array(expected) / np.linalg.norm(expected)
        scene = one_gaussian(tmp_path, [0, word, 0, 0])
        np.testing.assert_allclose(scene.rotations[0], expected, atol=1e-7, err_msg=f"largest = {largest}")
    # The identity: w largest, the other three at the middle of their range (512 of 1023).
    scene = one_gaussian(tmp_path, [0, (0 << 30) | (512 << 20) | (512 << 10) | 512, 0, 0])
    np.testing.assert_allclose(scene.rotations[0], [1, 0, 0, 0], atol=2e-3)
    assert scene.rotations[0, 0] > 0.999


def test_colour_and_opacity_bytes(tmp_path):
    word = (255 << 24) | (0 << 16) | (51 << 8) | 204
    scene = one_gaussian(tmp_path, [0, 0, 0, word])
    colour = [0.75, 0.0, -0.5 * (1 - 0.2) + 1.5 * 0.2]  # lerp between the colour bounds
    np.testing.assert_allclose(scene.sh[0, 0], (np.array(colour) - 0.5) / C0, rtol=1e-6)
    np.testing.assert_allclose(scene.opacities[0], 0.8, rtol=1e-7)
    # Without colour bounds the bytes are the colour itself.
    scene = one_gaussian(tmp_path, [0, 0, 0, word], bounds=[-1, -2, -3, 1, 2, 3, -5, -4, -3, -1, 0, 1])
    np.testing.assert_allclose(scene.sh[0, 0], (np.array([1.0, 0.0, 0.2]) - 0.5) / C0, rtol=1e-6)
    for alpha, opacity in ((0, 0.0), (255, 1.0)):
        scene = one_gaussian(tmp_path, [0, 0, 0, alpha])
        assert scene.count == 1 and scene.opacities[0] == opacity


def test_sh_bytes(tmp_path):
    values = [0, 1, 127, 128, 200, 254, 255, 64, 32]
    scene = one_gaussian(tmp_path, [0, 0, 0, 0], sh_bytes=values)
    expected = [-4.0, (1.5 / 256 - 0.5) * 8, (127.5 / 256 - 0.5) * 8, (128.5 / 256 - 0.5) * 8,
                (200.5 / 256 - 0.5) * 8, (254.5 / 256 - 0.5) * 8, 4.0, (64.5 / 256 - 0.5) * 8,
                (32.5 / 256 - 0.5) * 8]
    # f_rest_{c * 3 + j} is coefficient j + 1 of channel c.
    np.testing.assert_allclose(scene.sh[0, 1:, :].T.reshape(-1), expected, rtol=1e-7)


# --------------------------------------------------------------------------- a file splat-transform wrote

# Written by splat-transform 3.7.0 (`splat-transform in.ply out.compressed.ply`) from an INRIA
# PLY of these five gaussians; it sorts them (Morton order), so they are matched by position.
_ST_SOURCE = {
    "positions": np.array([[0.0, 0.0, 0.0], [1.0, 0.5, -0.25], [-0.5, 2.0, 1.0], [0.25, -1.0, 0.75],
                           [2.0, 1.5, -1.0]]),
    "log_scales": np.array([[-3.0, -2.5, -4.0], [-1.0, -1.5, -2.0], [-5.0, -5.5, -6.0], [-2.0, -2.0, -2.0],
                            [-3.5, -1.25, -2.75]]),
    "quats": np.array([[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5], [0.0, 0.0, 0.6, -0.8],
                       [0.1, -0.7, 0.7, 0.1], [-0.3, 0.4, 0.5, 0.7071]]),
    "f_dc": np.array([[0.5, -0.5, 1.0], [-1.0, 0.25, 0.0], [1.5, 1.5, -1.5], [0.0, 0.0, 0.0], [-0.75, 0.8, 0.3]]),
    "logits": np.array([0.0, 2.0, -2.0, 4.0, -4.5]),
    "rest": np.array([[0.1 * (j - 4) * (i + 1) for j in range(9)] for i in range(5)]),
}
_ST_FILE = (
    "cGx5CmZvcm1hdCBiaW5hcnlfbGl0dGxlX2VuZGlhbiAxLjAKY29tbWVudCBHZW5lcmF0ZWQgYnkgc3BsYXQtdHJhbnNmb3Jt"
    "IDMuNy4wCmVsZW1lbnQgY2h1bmsgMQpwcm9wZXJ0eSBmbG9hdCBtaW5feApwcm9wZXJ0eSBmbG9hdCBtaW5feQpwcm9wZXJ0"
    "eSBmbG9hdCBtaW5fegpwcm9wZXJ0eSBmbG9hdCBtYXhfeApwcm9wZXJ0eSBmbG9hdCBtYXhfeQpwcm9wZXJ0eSBmbG9hdCBt"
    "YXhfegpwcm9wZXJ0eSBmbG9hdCBtaW5fc2NhbGVfeApwcm9wZXJ0eSBmbG9hdCBtaW5fc2NhbGVfeQpwcm9wZXJ0eSBmbG9h"
    "dCBtaW5fc2NhbGVfegpwcm9wZXJ0eSBmbG9hdCBtYXhfc2NhbGVfeApwcm9wZXJ0eSBmbG9hdCBtYXhfc2NhbGVfeQpwcm9w"
    "ZXJ0eSBmbG9hdCBtYXhfc2NhbGVfegpwcm9wZXJ0eSBmbG9hdCBtaW5fcgpwcm9wZXJ0eSBmbG9hdCBtaW5fZwpwcm9wZXJ0"
    "eSBmbG9hdCBtaW5fYgpwcm9wZXJ0eSBmbG9hdCBtYXhfcgpwcm9wZXJ0eSBmbG9hdCBtYXhfZwpwcm9wZXJ0eSBmbG9hdCBt"
    "YXhfYgplbGVtZW50IHZlcnRleCA1CnByb3BlcnR5IHVpbnQgcGFja2VkX3Bvc2l0aW9uCnByb3BlcnR5IHVpbnQgcGFja2Vk"
    "X3JvdGF0aW9uCnByb3BlcnR5IHVpbnQgcGFja2VkX3NjYWxlCnByb3BlcnR5IHVpbnQgcGFja2VkX2NvbG9yCmVsZW1lbnQg"
    "c2ggNQpwcm9wZXJ0eSB1Y2hhciBmX3Jlc3RfMApwcm9wZXJ0eSB1Y2hhciBmX3Jlc3RfMQpwcm9wZXJ0eSB1Y2hhciBmX3Jl"
    "c3RfMgpwcm9wZXJ0eSB1Y2hhciBmX3Jlc3RfMwpwcm9wZXJ0eSB1Y2hhciBmX3Jlc3RfNApwcm9wZXJ0eSB1Y2hhciBmX3Jl"
    "c3RfNQpwcm9wZXJ0eSB1Y2hhciBmX3Jlc3RfNgpwcm9wZXJ0eSB1Y2hhciBmX3Jlc3RfNwpwcm9wZXJ0eSB1Y2hhciBmX3Jl"
    "c3RfOAplbmRfaGVhZGVyCgAAAL8AAIC/AACAvwAAAEAAAABAAACAPwAAoMAAALDAAADAwAAAgL8AAKC/AAAAwIsiXz6jyLc+"
    "oWedPQxTbD8MU2w/XTdIPwCo+v9ph2zSf/4fYAO4phkAA5CZaaedNv8f/v/hmWAAAKwqMwACCCAAlBaAgP8Amf8GwEy3FXBb"
    "/1f6v/qZQGb//x8ATQAI4AAAAAAeAP//QFBgcICQoLDAZmxzeYCGjJOZc3Z5fICDhomMTFlmc4CMmaazWWNsdoCJk5ym"
)


def test_a_file_splat_transform_wrote(tmp_path):
    path = tmp_path / "st.compressed.ply"
    path.write_bytes(base64.b64decode(_ST_FILE))
    scene = load_scene(path)
    assert scene.count == 5 and scene.sh_degree == 1 and scene.format == COMPRESSED_PLY_FORMAT
    order = np.argmin(np.linalg.norm(scene.positions[:, None, :] - _ST_SOURCE["positions"][None], axis=2), axis=1)
    assert sorted(order) == list(range(5))
    src = {name: values[order] for name, values in _ST_SOURCE.items()}
    src["quats"] = src["quats"] / np.linalg.norm(src["quats"], axis=1, keepdims=True)
    header_end = path.read_bytes().index(b"end_header\n") + len(b"end_header\n")
    bounds = np.frombuffer(path.read_bytes(), "<f4", 18, header_end).reshape(1, 18)
    assert_within_quantisation(scene, src, bounds)


# --------------------------------------------------------------------------- the shared sample


@pytest.mark.skipif(not GUITAR.is_file(), reason=f"shared sample {GUITAR} not present")
def test_the_shared_sample_loads():
    scene = load_scene(GUITAR)
    assert scene.count == 90_854 and scene.sh_degree == 0 and scene.dropped == {}
    assert scene.format == COMPRESSED_PLY_FORMAT and describe(scene)["format"] == COMPRESSED_PLY_FORMAT
    data = GUITAR.read_bytes()
    start = data.index(b"\nend_header\n") + len(b"\nend_header\n")
    bounds = np.frombuffer(data, "<f4", 355 * 18, start).reshape(355, 18).astype(np.float64)[chunk_of(90_854)]
    p = scene.positions.astype(np.float64)
    slack = 1e-6 * (1 + np.abs(bounds[:, 0:6]).max(axis=1, keepdims=True))
    assert np.all(p >= bounds[:, 0:3] - slack) and np.all(p <= bounds[:, 3:6] + slack)
    log_s = np.log(scene.scales.astype(np.float64))
    assert np.all(log_s >= bounds[:, 6:9] - 1e-5) and np.all(log_s <= bounds[:, 9:12] + 1e-5)
    colour = scene.sh[:, 0, :].astype(np.float64) * C0 + 0.5
    assert np.all(colour >= bounds[:, 12:15] - 1e-5) and np.all(colour <= bounds[:, 15:18] + 1e-5)
    np.testing.assert_allclose(np.linalg.norm(scene.rotations.astype(np.float64), axis=1), 1, atol=1e-6)
    assert np.all((scene.opacities >= 0) & (scene.opacities <= 1))
    # A real, object-sized scene: splats of about a millimetre to a few centimetres.
    assert 1e-3 < np.median(scene.scales) < 2e-2 and scene.scales.max() < 1.0
    extent = p.max(axis=0) - p.min(axis=0)
    assert np.all((extent > 0.5) & (extent < 10))


# --------------------------------------------------------------------------- bad input


def base_elements(n=300, degree=1):
    return encode(known_scene(n, degree, seed=11))[0]


def _drop_property(element_name, prop):
    def change(elements):
        out = []
        for name, count, props, data in elements:
            if name == element_name:
                index = [p for _, p in props].index(prop)
                size = {"float": 4, "uint": 4, "uchar": 1}[props[index][0]]
                row = sum({"float": 4, "uint": 4, "uchar": 1}[k] for k, _ in props)
                raw = np.frombuffer(data, "u1").reshape(count, row)
                at = sum({"float": 4, "uint": 4, "uchar": 1}[k] for k, _ in props[:index])
                data = np.delete(raw, np.s_[at: at + size], axis=1).tobytes()
                props = props[:index] + props[index + 1:]
            out.append((name, count, props, data))
        return out
    return change


def _retype(element_name, prop, kind):
    def change(elements):
        return [(name, count, [(kind if p == prop and name == element_name else k, p) for k, p in props], data)
                for name, count, props, data in elements]
    return change


def _recount(element_name, count_of):
    def change(elements):
        return [(name, count_of(count) if name == element_name else count, props, data)
                for name, count, props, data in elements]
    return change


def _rename(element_name, old, new):
    def change(elements):
        return [(name, count, [(k, new if p == old and name == element_name else p) for k, p in props], data)
                for name, count, props, data in elements]
    return change


def _without(element_name):
    return lambda elements: [e for e in elements if e[0] != element_name]


HOSTILE = {
    "missing packed_color": (_drop_property("vertex", "packed_color"), "no property 'packed_color'"),
    "packed_position as float": (_retype("vertex", "packed_position", "float"), "'packed_position' is float"),
    "missing min_x": (_drop_property("chunk", "min_x"), "no property 'min_x'"),
    "max_scale_z as double": (_retype("chunk", "max_scale_z", "double"), "'max_scale_z' is double"),
    "half the colour bounds": (_drop_property("chunk", "max_g"), "no property 'max_g'"),
    "too few chunks": (_recount("chunk", lambda c: c - 1), "need ceil(300 / 256) = 2 'chunk' rows"),
    "too many chunks": (_recount("chunk", lambda c: c + 1), "the header declares 3"),
    "sh rows differ": (_recount("sh", lambda c: c - 1), "'sh' element has 299 rows but 'vertex' has 300"),
    "sh of 8 coefficients": (_drop_property("sh", "f_rest_8"), "8 f_rest_* properties; expected 9, 24 or 45"),
    "sh as float": (_retype("sh", "f_rest_3", "float"), "'f_rest_3' is float, expected uchar"),
    "sh index gap": (_rename("sh", "f_rest_0", "f_rest_9"), "missing f_rest_0"),
    "sh unknown property": (_rename("sh", "f_rest_2", "red"), "property 'red'"),
    "no vertex element": (_without("vertex"), "no 'vertex' element"),
    "absurd count": (lambda e: _recount("chunk", lambda c: 2**40 // 256)(_recount("vertex", lambda c: 2**40)(
        _recount("sh", lambda c: 2**40)(e))), "truncated: the header declares 1099511627776 gaussians"),
    "list property": (lambda e: [e[0], e[1], ("faces", 1, [("list uchar int", "idx")], b"\x00")] + e[2:],
                      "list property 'idx'"),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_hostile_headers_are_one_line_errors(tmp_path, case):
    change, fragment = HOSTILE[case]
    path = write(tmp_path / "bad.compressed.ply", change(base_elements()))
    testkit.assert_user_error(lambda: load_scene(path), path, fragment)


@pytest.mark.parametrize("cut", [1, 100, 300 * 9 + 1, 300 * 9 + 16 * 300, 300 * 9 + 16 * 300 + 2 * 72 - 4])
def test_truncated_files(tmp_path, cut):
    data = assemble(base_elements())
    path = tmp_path / "cut.ply"
    path.write_bytes(data[:-cut])
    testkit.assert_user_error(lambda: load_scene(path), path, "truncated")


def test_a_header_plyfile_refuses_is_refused_with_data(tmp_path):
    data = assemble(base_elements(), header_extra=[""])  # an empty header line
    path = tmp_path / "empty-line.ply"
    path.write_bytes(data)
    testkit.assert_user_error(lambda: load_scene(path), path, "cannot read PLY data", "empty line")


def test_non_finite_bounds_drop_their_chunk(tmp_path):
    src = known_scene(768, 0, seed=2)
    elements, bounds = encode(src)
    bounds = bounds.copy()
    bounds[0, 0] = np.nan  # min_x of chunk 0
    bounds[1, 9] = 1e30  # max_scale_x of chunk 1: exp overflows unless t = 0
    bounds[2, 15] = np.inf  # max_r of chunk 2
    name, count, props, _ = elements[0]
    scene = load_scene(write(tmp_path / "s.ply", [(name, count, props, bounds.tobytes())] + elements[1:]))
    words = np.frombuffer(elements[1][3], "<u4").reshape(-1, 4)
    t_scale = (words[256:512, 2] >> 21) & 2047
    t_red = (words[512:, 3] >> 24) & 255
    # lerp(min, inf, t): inf for t > 0, inf * 0 = nan for t = 0.
    expected = {"nan": 256 + int(np.sum(t_red == 0)), "infinite scale": int(np.sum(t_scale > 0)),
                "infinite colour": int(np.sum(t_red > 0))}
    assert scene.dropped == {k: v for k, v in expected.items() if v}
    assert scene.count == 768 - sum(expected.values())
    assert np.all(np.isfinite(scene.positions)) and np.all(np.isfinite(scene.sh)) and np.all(scene.scales > 0)
