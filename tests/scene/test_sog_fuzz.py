"""Corrupt SOG files (issue 18): a mutated meta.json, a mutated zip, a mutated image or plain
random bytes either load as a valid scene or raise a one-line UserError naming the file:
never another exception, never a hang (each example has a deadline).

``RAYGS_FUZZ_EXAMPLES=5000`` runs each with that many examples (see test_fuzz.py).
"""

from __future__ import annotations

import functools
import json
import os
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from test_fuzz import json_paths
from test_sog import bundle_bytes, encode_sog, gaussians, webp_bytes

from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import load_scene

pytestmark = pytest.mark.filterwarnings("error")

_EXAMPLES = int(os.environ.get("RAYGS_FUZZ_EXAMPLES", "0"))


def fuzz(max_examples: int):
    return settings(max_examples=_EXAMPLES or max_examples, deadline=2000,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


@functools.cache
def base():
    """A valid 6-gaussian SH-1 scene: (meta, {name: WebP bytes})."""
    meta, images, _ = encode_sog(*gaussians(n=6, degree=1, palette=3))
    return meta, {name: webp_bytes(rgba) for name, rgba in images.items()}


@functools.cache
def base_bundle(method: int) -> bytes:
    meta, images = base()
    return bundle_bytes(meta, images, method)


def check_load(path):
    """Loads right or fails in one line naming the file."""
    try:
        scene = load_scene(path)
    except UserError as exc:
        message = str(exc)
        assert message and "\n" not in message and "\r" not in message, repr(message)
        assert Path(path).name in message, message
        event("UserError")
        return None
    event("loaded")
    for field in ("positions", "rotations", "scales", "opacities", "sh"):
        assert np.all(np.isfinite(getattr(scene, field))), field
    assert np.allclose(np.linalg.norm(scene.rotations, axis=1), 1.0, atol=1e-5)
    assert np.all((scene.opacities >= 0) & (scene.opacities <= 1)) and np.all(scene.scales > 0)
    assert scene.format == "SOG v2"
    return scene


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2 ** 70), 2 ** 70) | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=12) | st.sampled_from(["means_l.webp", "sh0.webp", "../meta.json", "/etc/passwd", ""]),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=12,
)


@st.composite
def mutated_meta(draw):
    meta = json.loads(json.dumps(base()[0]))
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in json_paths(meta) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = meta
        for key in path[:-1]:
            parent = parent[key]
        how = draw(st.sampled_from(["set", "delete", "nudge"]))
        if how == "delete":
            del parent[path[-1]]
        elif how == "nudge" and isinstance(parent[path[-1]], (int, float)) and not isinstance(parent[path[-1]], bool):
            parent[path[-1]] = parent[path[-1]] + draw(st.sampled_from([-1, 1, 0.5, 10 ** 6, -(10 ** 9)]))
        else:
            parent[path[-1]] = draw(json_values)
    return json.dumps(meta).encode()


@given(meta=mutated_meta(), bundled=st.booleans())
@fuzz(100)
def test_mutated_meta_json(tmp_path, meta, bundled):
    _, images = base()
    if bundled:
        path = tmp_path / "scene.sog"
        path.write_bytes(bundle_bytes(meta, images))
    else:
        folder = tmp_path / "scene"
        folder.mkdir(exist_ok=True)
        for name, data in images.items():
            (folder / name).write_bytes(data)
        path = folder / "meta.json"
        path.write_bytes(meta)
    check_load(path)


@st.composite
def mutated_bytes(draw, data: bytes):
    data = bytearray(data)
    for _ in range(draw(st.integers(1, 4))):
        how = draw(st.sampled_from(["flip", "truncate", "insert", "overwrite"]))
        at = draw(st.integers(0, max(0, len(data) - 1)))
        if how == "flip" and data:
            data[at] ^= draw(st.integers(1, 255))
        elif how == "truncate":
            del data[at:]
        elif how == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
        else:
            chunk = draw(st.binary(min_size=1, max_size=8))
            data[at: at + len(chunk)] = chunk
    return bytes(data)


@given(data=st.sampled_from([zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED]).flatmap(
    lambda method: mutated_bytes(base_bundle(method))))
@fuzz(150)
def test_mutated_bundles(tmp_path, data):
    path = tmp_path / "scene.sog"
    path.write_bytes(data)
    check_load(path)


@given(data=st.data(), name=st.sampled_from(sorted(base()[1])), bundled=st.booleans())
@fuzz(100)
def test_mutated_images(tmp_path, data, name, bundled):
    meta, images = base()
    images = dict(images, **{name: data.draw(mutated_bytes(images[name]))})
    if bundled:
        path = tmp_path / "scene.sog"
        path.write_bytes(bundle_bytes(meta, images, zipfile.ZIP_DEFLATED))
    else:
        folder = tmp_path / "scene"
        folder.mkdir(exist_ok=True)
        for file_name, raw in images.items():
            (folder / file_name).write_bytes(raw)
        path = folder / "meta.json"
        path.write_text(json.dumps(meta))
    check_load(path)


@given(data=st.binary(max_size=400) | st.binary(max_size=200).map(lambda b: b"PK\x03\x04" + b),
       suffix=st.sampled_from([".sog", ".json"]))
@fuzz(60)
def test_random_bytes(tmp_path, data, suffix):
    path = tmp_path / f"random{suffix}"
    path.write_bytes(data)
    check_load(path)
