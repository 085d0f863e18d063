"""Corrupt .spz files (issue 18, part 5): mutated files of every version either load right
or raise a one-line UserError naming the file; never another exception, never a hang
(each example has a deadline). A file that loads is checked against the plain reading of
spz_reference.py, so "loads" means "loads right".

``RAYGS_FUZZ_EXAMPLES=5000`` runs with that many examples (see test_fuzz.py).
"""

from __future__ import annotations

import gzip
import os
import struct
from pathlib import Path

import numpy as np
import pytest
import spz_reference as ref
import zstandard
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import load_scene

pytestmark = pytest.mark.filterwarnings("error")

_EXAMPLES = int(os.environ.get("RAYGS_FUZZ_EXAMPLES", "0"))
F = np.array([1.0, -1.0, -1.0])


def fuzz(max_examples: int):
    return settings(max_examples=_EXAMPLES or max_examples, deadline=2000,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


@st.composite
def gaussians(draw):
    n = draw(st.integers(0, 6))
    degree = draw(st.integers(0, 2))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    q = rng.normal(size=(n, 4)) + 1e-3
    return {
        "positions": rng.uniform(-100, 100, (n, 3)).tolist(),
        "log_scales": rng.uniform(-9, 5, (n, 3)).tolist(),
        "rotations": (q / np.linalg.norm(q, axis=1, keepdims=True)).tolist(),
        "alphas": rng.uniform(0, 1, n).tolist(),
        "colors": rng.uniform(-3, 3, (n, 3)).tolist(),
        "sh": rng.uniform(-1, 1, (n, ref.SH_DIM[degree], 3)).tolist(),
        "degree": degree,
    }


@st.composite
def mutated(draw, data: bytes, start: int = 0, same_length: bool = False) -> bytes:
    """Byte flips, overwrites, runs of one byte, a cut or an append, a few at a time, at
    ``start`` or later; ``same_length``: no cut or append (arrays behind a valid header)."""
    data = bytearray(data)
    kinds = ["flip", "set", "run", "u32"] + ([] if same_length else ["cut", "append"])
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(kinds))
        if kind == "cut":
            data = data[: draw(st.integers(0, len(data)))]
        elif kind == "append":
            data += draw(st.binary(min_size=1, max_size=40))
        elif len(data) <= start:
            continue
        elif kind == "u32" and len(data) - 4 >= start:
            at = draw(st.integers(start, len(data) - 4))
            data[at: at + 4] = struct.pack("<I", draw(st.sampled_from([0, 1, 3, 4, 5, 255, 2**31, 2**32 - 1])))
        elif kind == "run":
            at = draw(st.integers(start, len(data) - 1))
            length = min(draw(st.integers(1, 24)), len(data) - at)
            data[at: at + length] = bytes([draw(st.sampled_from([0, 0x7F, 0x80, 0xFF]))]) * length
        else:
            at = draw(st.integers(start, len(data) - 1))
            data[at] = (data[at] ^ (1 << draw(st.integers(0, 7)))) if kind == "flip" else draw(st.integers(0, 255))
    return bytes(data)


@st.composite
def spz_files(draw) -> bytes:
    g = draw(gaussians())
    version = draw(st.sampled_from([1, 2, 3, 4]))
    data = ref.pack(g, version)
    where = draw(st.sampled_from(["file", "payload", "arrays"]))
    if where != "file" and data[:2] == b"\x1f\x8b":
        # Mutations inside the gzip stream reach the header and the arrays, re-gzipped.
        arrays = where == "arrays"
        return gzip.compress(draw(mutated(gzip.decompress(data), 16 if arrays else 0, arrays)))
    if where == "arrays" and data[:4] == b"NGSP":
        # The same for version 4: mutated arrays, recompressed behind the same header.
        _, arrays = ref.payload(data)
        arrays = [draw(mutated(a, same_length=True)) for a in arrays if a]
        streams = [zstandard.ZstdCompressor().compress(a) for a in arrays]
        toc = b"".join(struct.pack("<QQ", len(z), len(a)) for z, a in zip(streams, arrays))
        return data[:32] + toc + b"".join(streams)
    return draw(mutated(data))


def check_against_reference(scene, data: bytes) -> None:
    """A scene that loaded is what the plain reading of the same bytes says."""
    assert np.isfinite(scene.positions).all() and np.isfinite(scene.sh).all()
    assert (scene.scales > 0).all() and np.isfinite(scene.scales).all()
    assert ((scene.opacities >= 0) & (scene.opacities <= 1)).all()
    np.testing.assert_allclose(np.linalg.norm(scene.rotations, axis=1), 1, atol=1e-5)
    try:
        g = ref.unpack(data)
    except Exception:  # the plain reading is not a validator (e.g. data after the gzip stream)
        event("reference could not read it")
        return
    if g["version"] == 1 and not np.isfinite(g["positions"]).all():
        return  # dropped gaussians: counted, not compared row by row
    assert scene.count == g["n"]
    np.testing.assert_array_equal(scene.positions, (np.asarray(g["positions"]).reshape(-1, 3) * F).astype(np.float32))
    np.testing.assert_allclose(scene.opacities, g["alphas"], atol=1e-7)


@fuzz(300)
@given(data=st.one_of(spz_files(), st.binary(max_size=200)))
def test_corrupt_spz_loads_correctly_or_is_a_one_line_user_error(tmp_path, data):
    path = tmp_path / "fuzz.spz"
    path.write_bytes(data)
    try:
        scene = load_scene(path, chunk_bytes=int.from_bytes(data[-1:] or b"\x40", "little") + 1)
    except UserError as exc:
        event("UserError")
        message = str(exc)
        assert message and "\n" not in message and "\r" not in message, repr(message)
        assert Path(path).name in message, message
        return
    event("loaded")
    check_against_reference(scene, data)
