"""Camera path files: the exact JSON round trip, the file's fields, atomic saving that
never clobbers, strict loading (every problem one line naming the field) and the scene
hash warning."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from testkit import (
    SETTINGS,
    assert_user_error,
    delete_field,
    demo_sidecar,
    listing,
    random_rotation,
    set_field,
    write_case,
)

import raygs_viewer
from raygs_viewer.camera.lens_model import LensModel
from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.path import MAX_FRAMES, CameraPath, Interpolation, Keyframe
from raygs_viewer.camera.pinhole import camera_to_json
from raygs_viewer.camera.stereo import PRESETS, StereoRig, StereoView
from raygs_viewer.capture.nerfstudio import NerfstudioPath, nerfstudio_json
from raygs_viewer.capture.path_file import (
    PATH_FORMAT,
    PathDocument,
    load_path_document,
    path_document_json,
    save_path_document,
    scene_mismatch,
)
from raygs_viewer.capture.document_entries import stereo_entry
from raygs_viewer.capture.sidecar import demo_sha256
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import FileAxes

STEREO = StereoView(StereoRig(0.07, 3.5, 0.25), "sbs", LensModel(0.3, 0.1, 0.99, 1.02), PRESETS["index"])
SHA = hashlib.sha256(b"a scene").hexdigest()


def random_pose(rng) -> Pose:
    """A pose with yaw, pitch and roll, at awkward float positions."""
    return Pose(rng.normal(size=3) * 3.7, random_rotation(rng))


def make_path(loop=False, count=4, seed=7) -> CameraPath:
    rng = np.random.default_rng(seed)
    # Keyframes 0 and 2 have explicit times; 1 and 3 are placed by the pacing.
    times = {0: 0.0, 2: 1.7}
    keys = tuple(Keyframe(random_pose(rng), float(rng.uniform(20.0, 100.0)), times.get(k)) for k in range(count))
    return CameraPath(keys, duration=3.1, fps=24.0, interpolation=Interpolation(0.25, 0.4, loop, (0.0, 0.0, 1.0)))


def make_doc(**changes) -> PathDocument:
    doc = PathDocument(make_path(), 64, 48, SETTINGS, None, "demo", SHA, scene_count=1234, scene_sh_degree=3)
    return dataclasses.replace(doc, **changes)


def assert_same_path(a: CameraPath, b: CameraPath):
    """Bit for bit: every keyframe's position, rotation, fov and time, and the timing."""
    assert (a.duration, a.fps, a.interpolation) == (b.duration, b.fps, b.interpolation)
    assert len(a.keyframes) == len(b.keyframes)
    for ka, kb in zip(a.keyframes, b.keyframes):
        assert ka.pose.position.dtype == kb.pose.position.dtype == np.float64
        assert ka.pose.position.tobytes() == kb.pose.position.tobytes()
        assert ka.pose.R.tobytes() == kb.pose.R.tobytes()
        assert float(ka.fov_y_degrees).hex() == float(kb.fov_y_degrees).hex()
        assert ka.time == kb.time and type(ka.time) is type(kb.time)


def assert_same_document(a: PathDocument, b: PathDocument):
    assert_same_path(a.path, b.path)
    for name in ("width", "height", "settings", "stereo", "scene_path", "scene_sha256", "scene_count",
                 "scene_sh_degree", "scene_axes", "kind"):
        assert getattr(a, name) == getattr(b, name), name


# --------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("changes", [
    {},
    {"stereo": STEREO},
    {"stereo": StereoView(layout="anaglyph"), "settings": RenderSettings(mode="gs", supersample=2)},
    {"settings": None, "scene_path": None, "scene_sha256": None, "scene_count": None, "scene_sh_degree": None},
    {"path": make_path(loop=True)},
    {"path": make_path(count=1)},
    {"scene_sha256": None, "scene_count": None},
    {"scene_path": "/scenes/st.spz", "scene_axes": FileAxes("rdf")},
    {"scene_path": "/scenes/niantic.spz", "scene_axes": FileAxes("rub")},
], ids=["mono", "stereo", "anaglyph_gs", "no_scene_no_settings", "loop", "one_keyframe", "unknown_hash", "spz_rdf",
        "spz_rub"])
def test_round_trip_is_bit_identical(tmp_path, changes):
    doc = make_doc(**changes)
    file = save_path_document(doc, tmp_path / "fly.json")
    loaded = load_path_document(file)
    assert_same_document(loaded, doc)
    assert loaded.source == file and loaded.kind == "raygs" and loaded.notes == ()
    # And again: a loaded document saves to the same content (but for the time stamp).
    again = save_path_document(loaded, tmp_path / "again.json")
    first, second = (json.loads(p.read_text()) for p in (file, again))
    first.pop("created"), second.pop("created")
    assert first == second


def test_round_trip_of_a_scene_file_records_its_absolute_and_relative_path(tmp_path, monkeypatch):
    scene = tmp_path / "scenes" / "garden.ply"
    (tmp_path / "paths").mkdir()
    monkeypatch.chdir(tmp_path)
    doc = make_doc(scene_path=os.path.join("scenes", "garden.ply"))  # relative: recorded absolute
    file = save_path_document(doc, Path("paths") / "fly.json")
    data = json.loads(file.read_text())
    assert data["scene"]["path"] == str(scene)
    assert data["scene"]["relative_path"] == os.path.join("..", "scenes", "garden.ply")
    assert load_path_document(file).scene_path == str(scene)


def test_the_files_fields(tmp_path):
    doc = make_doc(stereo=STEREO, extra={"up": "+z", "navigation": "orbit"})
    file = save_path_document(doc, tmp_path / "fly.json", extra={"gl_renderer": "llvmpipe", "up": "-y"})
    data = json.loads(file.read_text())
    assert list(data) == ["format", "version", "program", "created", "scene", "image", "settings", "stereo",
                          "path", "keyframes", "extra"]
    assert data["format"] == PATH_FORMAT == "raygs-viewer camera path" and data["version"] == 1
    assert data["program"] == {"name": "raygs-viewer", "version": raygs_viewer.__version__}
    created = datetime.strptime(data["created"], "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=timezone.utc)
    assert abs((datetime.now(timezone.utc) - created).total_seconds()) < 3600  # UTC, not local time
    assert data["scene"] == {"path": "demo", "sha256": SHA, "count": 1234, "sh_degree": 3}  # no relative path
    # A .spz's axes only where they were recorded: older readers refuse the key (strict keys).
    assert path_document_json(make_doc(scene_axes=FileAxes("rdf")))["scene"]["spz_axes"] == "rdf"
    assert load_path_document(file).scene_axes is None
    assert data["image"] == {"width": 64, "height": 48}  # each eye's: the frames are composed
    assert data["settings"] == json.loads(json.dumps(dataclasses.asdict(SETTINGS)))
    assert data["stereo"] == stereo_entry(STEREO)
    assert data["path"] == {"duration": 3.1, "fps": 24.0, "loop": False, "alpha": 0.25, "tension": 0.4,
                            "up": [0.0, 0.0, 1.0]}
    assert data["extra"] == {"up": "-y", "navigation": "orbit", "gl_renderer": "llvmpipe"}  # the argument wins
    assert len(data["keyframes"]) == 4
    for entry, key in zip(data["keyframes"], doc.path.keyframes):
        assert list(entry) == ["position", "rotation", "fov", "time"]
        assert entry["position"] == key.pose.position.tolist()
        # camera-to-world like INRIA cameras.json: its columns are the camera's right, down, forward axes.
        assert np.array_equal(np.array(entry["rotation"])[:, 2], key.pose.forward)
        assert entry["fov"] == key.fov_y_degrees and entry["time"] == key.time
    assert [e["time"] for e in data["keyframes"]] == [0.0, None, 1.7, None]
    # One list of numbers per line: a keyframe stays readable.
    assert '"up": [0.0, 0.0, 1.0]' in file.read_text()
    assert file.read_text().endswith("}\n")


def test_an_inria_style_rotation_matches_camera_to_json(tmp_path):
    """"rotation" is exactly what INRIA's cameras.json holds for the keyframe's camera."""
    doc = make_doc()
    data = path_document_json(doc)
    for entry, key in zip(data["keyframes"], doc.path.keyframes):
        inria = camera_to_json(key.pose.camera(64, 48, fx=50.0, fy=50.0, cx=32.0, cy=24.0))
        assert entry["rotation"] == inria["rotation"]
        assert np.allclose(entry["position"], inria["position"], rtol=0, atol=1e-14)


# --------------------------------------------------------------------------- saving


def test_save_never_clobbers_and_is_atomic(tmp_path):
    target = tmp_path / "fly.json"
    target.write_text("precious")
    with pytest.raises(UserError, match="already exists"):
        save_path_document(make_doc(), target)
    assert target.read_text() == "precious" and listing(tmp_path) == ["fly.json"]  # no temporary left
    save_path_document(make_doc(), target, overwrite=True)
    assert load_path_document(target).width == 64 and listing(tmp_path) == ["fly.json"]


@pytest.mark.parametrize("name, fragment", [
    ("fly.txt", "must end in .json"),
    ("missing/fly.json", "does not exist"),
    ("folder.json", "is a folder"),
])
def test_save_checks_the_output(tmp_path, name, fragment):
    (tmp_path / "folder.json").mkdir()
    before = listing(tmp_path)
    with pytest.raises(UserError, match=fragment):
        save_path_document(make_doc(), tmp_path / name)
    assert listing(tmp_path) == before and listing(tmp_path / "folder.json") == []


@pytest.mark.parametrize("changes, fragment", [
    ({"width": 0}, "'image.width'"),
    ({"height": 20000}, "'image.height'"),
    ({"path": CameraPath()}, "'keyframes' is empty"),
])
def test_save_refuses_what_load_would_refuse(tmp_path, changes, fragment):
    with pytest.raises(UserError, match=fragment.replace("[", r"\[").replace("]", r"\]")) as info:
        save_path_document(make_doc(**changes), tmp_path / "fly.json")
    assert "\n" not in str(info.value)
    assert listing(tmp_path) == []


# --------------------------------------------------------------------------- malformed files


ROTATION = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
MALFORMED = {
    # case: (mutation of a valid file's dict, or raw file text, or None for no file; fragment of the message)
    "missing_file": (None, "no such file"),
    "not_json": ("{not json", "not valid JSON"),
    "not_utf8": (b"\xff\xfe{}", "cannot read"),
    "json_list": ("[]", "not a camera path file"),
    "cameras_json": (json.dumps([{"width": 4}]), "not a camera path file"),
    "sidecar": (json.dumps(demo_sidecar()), "'format' is \"raygs-viewer screenshot\""),
    "no_format": (delete_field("format"), "neither 'format' nor 'camera_path'"),
    "format_number": (set_field("format", 1), "'format' is 1"),
    "newer_version": (set_field("version", 3), "newer raygs-viewer"),
    "edits_in_version_1": (set_field("edits", {}), "'edits' needs camera path version 2"),
    "version_zero": (set_field("version", 0), "'version'"),
    "version_string": (set_field("version", "1"), "'version'"),
    "version_missing": (delete_field("version"), "missing 'version'"),
    "unknown_top": (set_field("camera", {}), "unknown field 'camera'"),
    "unknown_top_newline": (set_field("a\nb", 1), "unknown field 'a\\nb'"),
    "program_list": (set_field("program", []), "'program'"),
    "program_unknown": (set_field("program.build", "x"), "'program.build'"),
    "program_version_number": (set_field("program.version", 1), "'program.version'"),
    "created_number": (set_field("created", 5), "'created'"),
    "scene_string": (set_field("scene", "demo"), "'scene'"),
    "scene_unknown": (set_field("scene.filter_fused", False), "unknown field 'scene.filter_fused'"),
    "scene_path_missing": (delete_field("scene.path"), "missing 'scene.path'"),
    "scene_path_relative": (set_field("scene.path", "scene.ply"), "'scene.path'"),
    "scene_path_number": (set_field("scene.path", 3), "'scene.path'"),
    "scene_sha_short": (set_field("scene.sha256", "abc"), "'scene.sha256'"),
    "scene_sha_missing": (delete_field("scene.sha256"), "missing 'scene.sha256'"),
    "scene_count_negative": (set_field("scene.count", -1), "'scene.count'"),
    "scene_count_float": (set_field("scene.count", 1.5), "'scene.count'"),
    "scene_sh_degree_four": (set_field("scene.sh_degree", 4), "'scene.sh_degree'"),
    "scene_relative_number": (set_field("scene.relative_path", 2), "'scene.relative_path'"),
    "scene_spz_axes_unknown": (set_field("scene.spz_axes", "luf"), "'scene.spz_axes' must be \"rub\" or \"rdf\""),
    "scene_spz_axes_number": (set_field("scene.spz_axes", 1), "'scene.spz_axes'"),
    "image_missing": (delete_field("image"), "missing 'image'"),
    "image_list": (set_field("image", [64, 48]), "'image'"),
    "image_width_missing": (delete_field("image.width"), "missing 'image.width'"),
    "image_width_zero": (set_field("image.width", 0), "'image.width'"),
    "image_width_huge": (set_field("image.width", 16385), "'image.width'"),
    "image_width_float": (set_field("image.width", 64.0), "'image.width'"),
    "image_height_bool": (set_field("image.height", True), "'image.height'"),
    "image_unknown": (set_field("image.scale", 2), "unknown field 'image.scale'"),
    "settings_list": (set_field("settings", [1]), "'settings'"),
    "settings_unknown": (set_field("settings.exposure", 2.0), "'settings.exposure'"),
    "settings_p_min_string": (set_field("settings.p_min", "0.1"), "'settings.p_min'"),
    "settings_mode_unknown": (set_field("settings.mode", "ewa"), "'settings'"),
    "settings_background_above_one": (set_field("settings.background", [2.0, 0.0, 0.0]),
                                      "'settings': background must be three numbers in [0, 1]"),
    "settings_background_negative": (set_field("settings.background", [0.0, -0.1, 0.0]), "in [0, 1]"),
    "stereo_list": (set_field("stereo", []), "'stereo'"),
    "stereo_ipd_string": (set_field("stereo.ipd", "63"), "'stereo.ipd'"),
    "stereo_layout_unknown": (set_field("stereo.layout", "top-bottom"), "'stereo.layout'"),
    "stereo_unknown": (set_field("stereo.eye_relief", 1), "'stereo.eye_relief'"),
    "path_missing": (delete_field("path"), "missing 'path'"),
    "path_list": (set_field("path", []), "'path'"),
    "path_unknown": (set_field("path.speed", 1), "unknown field 'path.speed'"),
    "duration_missing": (delete_field("path.duration"), "missing 'path.duration'"),
    "duration_zero": (set_field("path.duration", 0), "'path.duration'"),
    "duration_negative": (set_field("path.duration", -1.0), "'path.duration'"),
    "duration_nan": (set_field("path.duration", float("nan")), "'path.duration'"),
    "duration_huge": (set_field("path.duration", 1e9), "'path.duration'"),
    "duration_string": (set_field("path.duration", "10"), "'path.duration'"),
    "fps_missing": (delete_field("path.fps"), "missing 'path.fps'"),
    "fps_zero": (set_field("path.fps", 0), "'path.fps'"),
    "fps_huge": (set_field("path.fps", 1000.0), "'path.fps'"),
    "fps_inf": (set_field("path.fps", float("inf")), "'path.fps'"),
    "too_many_frames": (lambda d: d["path"].update(duration=80000.0, fps=240.0), f"at most {MAX_FRAMES}"),
    "loop_number": (set_field("path.loop", 1), "'path.loop'"),
    "alpha_big": (set_field("path.alpha", 1.5), "'path.alpha'"),
    "tension_negative": (set_field("path.tension", -0.1), "'path.tension'"),
    "up_two": (set_field("path.up", [0.0, 1.0]), "'path.up'"),
    "up_long": (set_field("path.up", [0.0, 2.0, 0.0]), "'path.up' must be a unit vector"),
    "up_zero": (set_field("path.up", [0.0, 0.0, 0.0]), "'path.up' must be a unit vector"),
    "up_string": (set_field("path.up", "-y"), "'path.up'"),
    "keyframes_missing": (delete_field("keyframes"), "missing 'keyframes'"),
    "keyframes_object": (set_field("keyframes", {}), "'keyframes'"),
    "keyframes_empty": (set_field("keyframes", []), "'keyframes' is empty"),
    "keyframe_number": (set_field("keyframes.1", 5), "'keyframes[1]' must be a JSON object"),
    "keyframe_unknown": (set_field("keyframes.2.roll", 0.0), "unknown field 'keyframes[2].roll'"),
    "keyframe_position_missing": (delete_field("keyframes.0.position"), "missing 'keyframes[0].position'"),
    "keyframe_position_two": (set_field("keyframes.0.position", [1.0, 2.0]), "'keyframes[0].position'"),
    "keyframe_position_nan": (set_field("keyframes.3.position", [1.0, float("nan"), 2.0]), "'keyframes[3].position'"),
    "keyframe_position_bool": (set_field("keyframes.3.position", [1.0, True, 2.0]), "'keyframes[3].position'"),
    "keyframe_position_huge": ("__1e400__", "'keyframes[0].position'"),
    "keyframe_rotation_missing": (delete_field("keyframes.1.rotation"), "missing 'keyframes[1].rotation'"),
    "keyframe_rotation_2x3": (set_field("keyframes.1.rotation", ROTATION[:2]), "'keyframes[1].rotation'"),
    "keyframe_rotation_scaled": (set_field("keyframes.1.rotation", (2 * np.eye(3)).tolist()), "not a rotation"),
    "keyframe_rotation_mirror": (set_field("keyframes.1.rotation", np.diag([1.0, 1.0, -1.0]).tolist()),
                                 "not a rotation"),
    "keyframe_rotation_sheared": (set_field("keyframes.1.rotation", [[1, 0.01, 0], [0, 1, 0], [0, 0, 1]]),
                                  "'keyframes[1].rotation' is not a rotation"),
    "keyframe_rotation_huge": (set_field("keyframes.1.rotation", (1e300 * np.eye(3)).tolist()), "not a rotation"),
    "keyframe_fov_missing": (delete_field("keyframes.2.fov"), "missing 'keyframes[2].fov'"),
    "keyframe_fov_small": (set_field("keyframes.2.fov", 0.5), "'keyframes[2].fov'"),
    "keyframe_fov_180": (set_field("keyframes.2.fov", 180), "'keyframes[2].fov'"),
    "keyframe_fov_string": (set_field("keyframes.2.fov", "60"), "'keyframes[2].fov'"),
    "keyframe_time_negative": (set_field("keyframes.0.time", -0.1), "'keyframes[0].time'"),
    "keyframe_time_past_end": (set_field("keyframes.2.time", 3.2), "'keyframes[2].time'"),
    "keyframe_time_string": (set_field("keyframes.2.time", "1"), "'keyframes[2].time'"),
    "keyframe_times_backwards": (set_field("keyframes.3.time", 1.0), "'keyframes[3].time' 1 is not after"),
    "keyframe_times_equal": (set_field("keyframes.3.time", 1.7), "'keyframes[3].time'"),
    "loop_time_at_end": (lambda d: d["path"].update(loop=True) or d["keyframes"][3].update(time=3.1),
                         "'keyframes[3].time'"),
    "extra_list": (set_field("extra", []), "'extra'"),
}


def valid_data() -> dict:
    return json.loads(json.dumps(path_document_json(make_doc(stereo=STEREO))))


def write_malformed(tmp_path, case):
    change, _ = MALFORMED[case]
    if change == "__1e400__":
        change = json.dumps(valid_data()).replace('"position": [', '"position": [1e400, ', 1)
    return write_case(tmp_path / "fly.json", change, valid_data)


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_path_file_is_one_line_user_error(tmp_path, case):
    path = write_malformed(tmp_path, case)
    assert_user_error(lambda: load_path_document(path), path, MALFORMED[case][1])


def test_the_valid_file_behind_the_cases_loads(tmp_path):
    """The malformed cases differ from a valid file only by their mutation; the optional
    fields may be null or left out."""
    path = tmp_path / "fly.json"
    path.write_text(json.dumps(valid_data()))
    assert load_path_document(path).stereo == STEREO
    data = valid_data()
    for key in ("program", "created", "scene", "settings", "stereo", "extra"):
        del data[key]
    for key in ("loop", "alpha", "tension", "up"):
        del data["path"][key]
    for entry in data["keyframes"]:
        del entry["time"]
    data["settings"] = {"p_min": 0.02}  # missing settings take their defaults, like a sidecar's
    path.write_text(json.dumps(data))
    doc = load_path_document(path)
    assert doc.settings == RenderSettings(p_min=0.02) and doc.stereo is None and doc.scene_path is None
    assert doc.path.interpolation == Interpolation() and all(k.time is None for k in doc.path.keyframes)
    data["scene"], data["extra"] = None, None
    path.write_text(json.dumps(data))
    assert load_path_document(path).extra == {}


def test_newer_version_says_so(tmp_path):
    path = write_malformed(tmp_path, "newer_version")
    assert_user_error(lambda: load_path_document(path), path, "version 3", "newer raygs-viewer", "update")


def _edits():
    """Random edits of a valid file: a value replaced by random JSON, or a key deleted,
    anywhere in the tree."""
    leaves = st.none() | st.booleans() | st.integers(-10**30, 10**30) | st.floats() | st.text(max_size=5)
    values = st.recursive(leaves, lambda inner: st.lists(inner, max_size=4)
                          | st.dictionaries(st.text(max_size=4), inner, max_size=3), max_leaves=8)
    return st.lists(st.tuples(st.integers(0, 10**6), st.booleans(), values), min_size=1, max_size=3)


def _containers(node, found):
    if isinstance(node, dict):
        found.append(node)
        for value in node.values():
            _containers(value, found)
    elif isinstance(node, list):
        found.append(node)
        for value in node:
            _containers(value, found)
    return found


def apply_edits(data, edits):
    for pick, delete, value in edits:
        containers = [c for c in _containers(data, []) if c]
        target = containers[pick % len(containers)]
        keys = list(target) if isinstance(target, dict) else list(range(len(target)))
        key = keys[(pick // len(containers)) % len(keys)]
        if delete:
            del target[key]
        else:
            target[key] = value
    return data


@functools.cache
def _nerfstudio_text() -> str:
    path = make_path(count=3)
    path = dataclasses.replace(path, keyframes=tuple(dataclasses.replace(k, time=None) for k in path.keyframes),
                               duration=0.5, fps=20.0)
    return json.dumps(nerfstudio_json(NerfstudioPath(path, 64, 48)))


def valid_nerfstudio_data() -> dict:
    return json.loads(_nerfstudio_text())


@pytest.mark.parametrize("valid", [valid_data, valid_nerfstudio_data], ids=["raygs", "nerfstudio"])
@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(edits=_edits())
def test_random_edits_only_ever_raise_user_error(tmp_path_factory, valid, edits):
    """Of either format: a file read back is valid, anything else one line naming the file."""
    file = tmp_path_factory.mktemp("fuzz") / "fuzz.json"
    file.write_text(json.dumps(apply_edits(valid(), edits)))
    try:
        doc = load_path_document(file)
    except UserError as exc:
        message = str(exc)
        assert "\n" not in message and "fuzz.json" in message, message
    else:
        assert len(doc.path.keyframes) >= 1 and 1 <= doc.width <= 16384 and doc.path.frame_count >= 1


# --------------------------------------------------------------------------- the scene


def test_scene_mismatch_warns_only_when_the_hash_differs(tmp_path):
    demo = make_doc(scene_sha256=demo_sha256())
    assert scene_mismatch(demo, "demo") is None
    assert scene_mismatch(make_doc(scene_sha256=None), "demo") is None  # unknown: nothing to check
    scene = tmp_path / "garden.ply"
    scene.write_bytes(b"a scene")
    recorded = make_doc(scene_path=str(scene), source=tmp_path / "fly.json")
    assert scene_mismatch(recorded, str(scene)) is None  # SHA is the digest of those bytes
    scene.write_bytes(b"another training run")
    warning = scene_mismatch(recorded, str(scene))
    assert warning is not None and "\n" not in warning
    assert "fly.json" in warning and str(scene) in warning and SHA[:12] in warning
    assert hashlib.sha256(b"another training run").hexdigest()[:12] in warning
    warning = scene_mismatch(demo, str(scene))
    assert "demo scene" in warning and str(scene) in warning
    assert "demo scene" in scene_mismatch(make_doc(), "demo")
    # A digest the caller already has is used as given (no second pass over a large file).
    assert scene_mismatch(recorded, str(tmp_path / "absent.ply"), actual_sha256=SHA) is None


def test_a_mismatch_is_a_warning_the_document_still_loads(tmp_path):
    file = save_path_document(make_doc(), tmp_path / "fly.json")
    doc = load_path_document(file)
    assert doc.scene_sha256 == SHA and scene_mismatch(doc, "demo") is not None

