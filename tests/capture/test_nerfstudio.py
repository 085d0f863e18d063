"""nerfstudio camera_path files: axis conventions against nerfstudio's own camera model
(rebuilt here from its cameras.py), round trips in both directions, a file as the
nerfstudio viewer writes it, and one-line errors for bad files."""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
from testkit import assert_user_error, listing, random_rotation

import raygs_viewer.capture.nerfstudio as nerfstudio_module
from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.path import CameraPath, Interpolation, Keyframe
from raygs_viewer.capture.nerfstudio import (
    NerfstudioPath,
    is_nerfstudio,
    nerfstudio_json,
    read_nerfstudio,
    save_nerfstudio,
)
from raygs_viewer.capture.path_file import load_path_document
from raygs_viewer.errors import UserError

WIDTH, HEIGHT = 64, 48


# --------------------------------------------------------------------------- nerfstudio's camera model


def nerfstudio_rays(c2w16, fov_degrees, width, height):
    """Origins (3,) and unit directions (H, W, 3) of nerfstudio's perspective camera, as
    cameras.py builds them: focal = H / 2 / tan(fov / 2) (its three.js convention), cx, cy
    the image centre, pixel centres at +0.5, y flipped "from OpenCV to OpenGL", z = -1,
    then rotated by camera_to_world[:3, :3]."""
    c2w = np.array(c2w16, dtype=np.float64).reshape(4, 4)[:3]
    focal = height / 2.0 / np.tan(fov_degrees * (np.pi / 180.0) / 2.0)
    y, x = np.meshgrid(np.arange(height) + 0.5, np.arange(width) + 0.5, indexing="ij")
    coords = np.stack([(x - width / 2) / focal, -(y - height / 2) / focal, -np.ones_like(x)], axis=-1)
    directions = coords @ c2w[:, :3].T
    return c2w[:, 3], directions / np.linalg.norm(directions, axis=-1, keepdims=True)


def nerfstudio_pixel(c2w16, fov_degrees, width, height, point):
    """Where nerfstudio's camera model puts world ``point`` (continuous pixel coordinates,
    pixel centres at +0.5): the inverse of the ray above."""
    c2w = np.array(c2w16, dtype=np.float64).reshape(4, 4)[:3]
    focal = height / 2.0 / np.tan(fov_degrees * (np.pi / 180.0) / 2.0)
    d = c2w[:, :3].T @ (np.asarray(point) - c2w[:, 3])
    return np.array([width / 2 + focal * d[0] / -d[2], height / 2 - focal * d[1] / -d[2]])


def our_rays(camera):
    rays = camera.pixel_rays() @ camera.R  # camera space to world: R.T @ ray
    return camera.center, rays / np.linalg.norm(rays, axis=-1, keepdims=True)


def random_c2w(rng, scale=2.0) -> list[float]:
    matrix = np.eye(4)
    matrix[:3, :3] = random_rotation(rng)
    matrix[:3, 3] = rng.normal(size=3) * scale
    return matrix.reshape(-1).tolist()


def ns_file(count=5, seconds=2.0, seed=3, **top) -> dict:
    rng = np.random.default_rng(seed)
    entries = [{"camera_to_world": random_c2w(rng), "fov": float(rng.uniform(30, 80)), "aspect": WIDTH / HEIGHT}
               for _ in range(count)]
    return {"camera_type": "perspective", "render_width": WIDTH, "render_height": HEIGHT, "fps": count / seconds,
            "seconds": seconds, "camera_path": entries, **top}


def test_identity_camera_looks_down_minus_z_with_y_up():
    """A nerfstudio camera with identity camera-to-world looks along world -z, image up
    along world +y: our camera's forward must be (0, 0, -1) and its down (0, -1, 0)."""
    identity = np.eye(4).reshape(-1).tolist()
    doc = read_nerfstudio(ns_file(count=1) | {"camera_path": [{"camera_to_world": identity, "fov": 50.0}]}, "x.json")
    pose = doc.path.keyframes[0].pose
    assert np.array_equal(pose.forward, [0.0, 0.0, -1.0])
    assert np.array_equal(pose.R[1], [0.0, -1.0, 0.0])  # camera +y (down) is world -y
    assert np.array_equal(pose.R[0], [1.0, 0.0, 0.0])
    assert np.array_equal(pose.position, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("seed", range(3))
def test_pixels_and_rays_match_nerfstudios_camera_model(seed):
    rng = np.random.default_rng(seed)
    data = ns_file(count=3, seed=seed)
    doc = read_nerfstudio(data, "x.json")
    cameras = doc.path.cameras(WIDTH, HEIGHT)
    assert len(cameras) == 3
    for entry, camera in zip(data["camera_path"], cameras):
        origin, directions = nerfstudio_rays(entry["camera_to_world"], entry["fov"], WIDTH, HEIGHT)
        center, ours = our_rays(camera)
        assert np.allclose(center, origin, rtol=0, atol=1e-12)
        assert np.abs(ours - directions).max() < 1e-12
        # A point in front of the camera lands on the same (continuous) pixel in both models.
        direction = directions[int(rng.integers(HEIGHT)), int(rng.integers(WIDTH))]
        point = origin + direction * rng.uniform(0.5, 5.0)
        mu = camera.R @ point + camera.t
        ours_uv = np.array([camera.fx * mu[0] / mu[2] + camera.cx, camera.fy * mu[1] / mu[2] + camera.cy])
        assert mu[2] > 0
        assert np.abs(ours_uv - nerfstudio_pixel(entry["camera_to_world"], entry["fov"], WIDTH, HEIGHT, point)).max() \
            < 1e-9


# --------------------------------------------------------------------------- round trips


def make_path(loop=False, count=4, seed=11) -> CameraPath:
    rng = np.random.default_rng(seed)
    keys = []
    for _ in range(count):
        keys.append(Keyframe(Pose(rng.normal(size=3) * 2, random_rotation(rng)), float(rng.uniform(30, 90))))
    return CameraPath(tuple(keys), duration=1.3, fps=10.0, interpolation=Interpolation(tension=0.3, loop=loop))


@pytest.mark.parametrize("loop", [False, True])
def test_export_then_import_gives_the_same_frames(loop):
    doc = NerfstudioPath(make_path(loop), WIDTH, HEIGHT)
    data = json.loads(json.dumps(nerfstudio_json(doc)))  # through JSON text, as a file would be
    assert len(data["camera_path"]) == doc.path.frame_count == 13
    imported = read_nerfstudio(data, "x.json")
    assert (imported.width, imported.height) == (WIDTH, HEIGHT) and imported.notes == ()
    assert imported.path.interpolation.loop == loop and imported.path.interpolation.tension == 0.3
    assert imported.path.frame_count == doc.path.frame_count
    assert imported.path.fps == pytest.approx(doc.path.fps, rel=1e-12)
    before, after = doc.path.cameras(WIDTH, HEIGHT), imported.path.cameras(WIDTH, HEIGHT)
    for a, b in zip(before, after):
        assert np.abs(a.R - b.R).max() < 1e-12 and np.abs(a.t - b.t).max() < 1e-12
        assert b.fy == pytest.approx(a.fy, rel=1e-12) and (a.cx, a.cy) == (b.cx, b.cy)


@pytest.mark.parametrize("loop", [False, True])
def test_import_then_export_reproduces_the_file(loop):
    data = ns_file(count=7, seconds=0.7, is_cycle=loop)
    doc = read_nerfstudio(data, "x.json")
    # The path's frames land exactly on the file's entries, at ns-render's rate.
    times = doc.path.frame_times()
    assert len(times) == 7
    key_times = [k.time for k in doc.path.keyframes]
    assert np.array_equal(times[:-1], key_times[:-1])
    assert times[-1] == pytest.approx(key_times[-1], rel=1e-15)  # the last: at most kept from rounding past the end
    exported = nerfstudio_json(doc)
    assert (exported["render_width"], exported["render_height"]) == (WIDTH, HEIGHT)
    assert exported["fps"] == pytest.approx(10.0, rel=1e-12) and exported["seconds"] == pytest.approx(0.7, rel=1e-12)
    assert exported["camera_type"] == "perspective" and exported["is_cycle"] == loop
    assert len(exported["camera_path"]) == 7
    for original, entry in zip(data["camera_path"], exported["camera_path"]):
        assert np.abs(np.subtract(entry["camera_to_world"], original["camera_to_world"])).max() < 1e-12
        assert entry["fov"] == pytest.approx(original["fov"], abs=1e-12)
        assert entry["aspect"] == WIDTH / HEIGHT


def test_exported_keyframes_load_in_nerfstudios_viewer_at_our_times():
    """The viewer's *Load path* (render_panel.py) turns "matrix" back into its camera with
    matrix[:3, :3] @ rot_x(pi) and places keyframe i at the sum of the transitions before it."""
    path = make_path(loop=False).with_keyframe_changed(2, time=1.0)
    doc = NerfstudioPath(path, WIDTH, HEIGHT)
    data = nerfstudio_json(doc)
    assert "default_fov" not in data  # every keyframe's fov is then its own in the viewer
    rot_x_pi = np.diag([1.0, -1.0, -1.0])
    for entry, key in zip(data["keyframes"], path.keyframes):
        matrix = np.array(entry["matrix"]).reshape(4, 4)
        assert np.array_equal(matrix[3], [0, 0, 0, 1])
        assert np.array_equal(matrix[:3, :3] @ rot_x_pi, key.pose.R.T)  # viser's (OpenCV) camera-to-world
        assert np.array_equal(matrix[:3, 3], key.pose.position)
        assert entry["fov"] == key.fov_y_degrees and entry["aspect"] == WIDTH / HEIGHT
    transitions = [k["override_transition_sec"] for k in data["keyframes"]]
    assert transitions[0] is None and not data["keyframes"][0]["override_transition_enabled"]
    assert np.allclose(np.cumsum([0.0] + transitions[1:]), path.keyframe_times(), rtol=0, atol=1e-12)
    assert sum(transitions[1:]) == pytest.approx(path.duration)
    # A loop: the first keyframe's transition closes the lap, and they sum to its duration.
    looped = nerfstudio_json(NerfstudioPath(make_path(loop=True), WIDTH, HEIGHT))
    assert sum(k["override_transition_sec"] for k in looped["keyframes"]) == pytest.approx(1.3)
    assert looped["default_transition_sec"] == pytest.approx(1.3 / 4)


def test_a_file_written_by_nerfstudios_viewer_imports(tmp_path):
    """A camera path as the viewer's Render tab writes it: keyframes of its own, default_*
    fields, a crop box, frames at i / num_frames of the duration."""
    def c2w(angle):  # a camera circling the origin at height 0.5 in a z-up world, looking at it (OpenGL axes)
        eye = np.array([2 * math.cos(angle), 2 * math.sin(angle), 0.5])
        back = eye / np.linalg.norm(eye)
        right = np.cross([0.0, 0.0, 1.0], back)
        right /= np.linalg.norm(right)
        matrix = np.eye(4)
        matrix[:3, :3] = np.stack([right, np.cross(back, right), back], axis=1)
        matrix[:3, 3] = eye
        return matrix.reshape(-1).tolist()

    fps, duration = 24.0, 2.0
    frames = int(fps * duration)
    data = {
        "default_fov": 75.0, "default_transition_sec": 1.0,
        "keyframes": [{"matrix": c2w(a), "fov": 75.0, "aspect": 1.7777777777777777,
                       "override_transition_enabled": False, "override_transition_sec": None} for a in (0, 1, 2)],
        "camera_type": "perspective", "render_height": 1080, "render_width": 1920,
        "fps": fps, "seconds": duration, "is_cycle": False, "smoothness_value": 0.5,
        "camera_path": [{"camera_to_world": c2w(2.0 * i / frames), "fov": 75.0, "aspect": 1.7777777777777777}
                        for i in range(frames)],
        "crop": {"crop_center": [0, 0, 0], "crop_scale": [1, 1, 1], "crop_rot": [0, 0, 0],
                 "crop_bg_color": {"r": 0, "g": 0, "b": 0}},
    }
    file = tmp_path / "2024-05-01-12-00-00.json"
    file.write_text(json.dumps(data))
    doc = load_path_document(file)
    assert doc.kind == "nerfstudio" and doc.source == file and (doc.width, doc.height) == (1920, 1080)
    assert doc.settings is None and doc.stereo is None and doc.scene_path is None and doc.scene_sha256 is None
    assert doc.path.frame_count == frames and doc.path.fps == pytest.approx(fps)
    assert doc.path.interpolation.up == (0.0, 0.0, 1.0) and doc.path.interpolation.tension == 0.5
    assert len(doc.notes) == 1 and "crop" in doc.notes[0] and file.name in doc.notes[0]
    for entry, camera in zip(data["camera_path"], doc.path.cameras(1920, 1080)):
        c2w_gl = np.array(entry["camera_to_world"]).reshape(4, 4)
        assert np.allclose(camera.R[2], -c2w_gl[:3, 2], rtol=0, atol=1e-12)  # looks at the origin
        assert np.allclose(camera.center, c2w_gl[:3, 3], rtol=0, atol=1e-12)
        assert camera.fy == pytest.approx(540 / math.tan(math.radians(37.5)))


def test_save_nerfstudio_never_clobbers(tmp_path):
    doc = NerfstudioPath(make_path(), WIDTH, HEIGHT)
    target = tmp_path / "camera_path.json"
    target.write_text("precious")
    with pytest.raises(UserError, match="already exists"):
        save_nerfstudio(doc, target)
    assert target.read_text() == "precious" and listing(tmp_path) == ["camera_path.json"]
    save_nerfstudio(doc, target, overwrite=True)
    assert load_path_document(target).kind == "nerfstudio" and listing(tmp_path) == ["camera_path.json"]
    with pytest.raises(UserError, match="no keyframes"):
        nerfstudio_json(NerfstudioPath(CameraPath(), WIDTH, HEIGHT))


def test_is_nerfstudio():
    assert is_nerfstudio(ns_file())
    assert not is_nerfstudio([ns_file()]) and not is_nerfstudio({"render_width": 4})
    assert not is_nerfstudio(ns_file() | {"format": "raygs-viewer camera path"})


def test_one_camera_is_a_one_frame_path():
    doc = read_nerfstudio(ns_file(count=1, seconds=5.0), "x.json")
    assert doc.path.frame_count == 1 and np.array_equal(doc.path.frame_times(), [0.0])


# --------------------------------------------------------------------------- bad files


def _set(key, value, entry=None):
    def mutate(data):
        (data if entry is None else data["camera_path"][entry])[key] = value
    return mutate


def _delete(key, entry=None):
    def mutate(data):
        del (data if entry is None else data["camera_path"][entry])[key]
    return mutate


def _matrix(entry, change):
    def mutate(data):
        matrix = np.array(data["camera_path"][entry]["camera_to_world"]).reshape(4, 4)
        data["camera_path"][entry]["camera_to_world"] = change(matrix).reshape(-1).tolist()
    return mutate


def _scaled(m):
    m[:3, :3] *= 2
    return m


def _mirrored(m):
    m[:3, 0] *= -1
    return m


MALFORMED = {
    "width_missing": (_delete("render_width"), "missing 'render_width'"),
    "height_missing": (_delete("render_height"), "missing 'render_height'"),
    "seconds_missing": (_delete("seconds"), "missing 'seconds'"),
    "width_zero": (_set("render_width", 0), "'render_width'"),
    "width_huge": (_set("render_width", 100000), "'render_width'"),
    "width_fraction": (_set("render_width", 64.5), "'render_width'"),
    "width_string": (_set("render_width", "64"), "'render_width'"),
    "height_nan": (_set("render_height", float("nan")), "'render_height'"),
    "seconds_zero": (_set("seconds", 0), "'seconds'"),
    "seconds_negative": (_set("seconds", -2.0), "'seconds'"),
    "seconds_inf": (_set("seconds", float("inf")), "'seconds'"),
    "seconds_string": (_set("seconds", "2"), "'seconds'"),
    "too_slow": (_set("seconds", 100.0), "frames per second"),
    "too_fast": (_set("seconds", 0.001), "frames per second"),
    "camera_type_fisheye": (_set("camera_type", "fisheye"), "'camera_type' \"fisheye\" is not supported"),
    "camera_type_equirect": (_set("camera_type", "equirectangular"), "'camera_type'"),
    "camera_type_number": (_set("camera_type", 1), "'camera_type'"),
    "is_cycle_string": (_set("is_cycle", "yes"), "'is_cycle'"),
    "smoothness_big": (_set("smoothness_value", 2.0), "'smoothness_value'"),
    "keyframes_object": (_set("keyframes", {}), "'keyframes'"),
    "camera_path_object": (_set("camera_path", {}), "'camera_path'"),
    "camera_path_empty": (_set("camera_path", []), "'camera_path' is empty"),
    "entry_number": (lambda d: d["camera_path"].__setitem__(2, 7), "'camera_path[2]' must be a JSON object"),
    "c2w_missing": (_delete("camera_to_world", 1), "missing 'camera_path[1].camera_to_world'"),
    "c2w_12": (lambda d: d["camera_path"][1].update(camera_to_world=d["camera_path"][1]["camera_to_world"][:12]),
               "'camera_path[1].camera_to_world' must be 16 numbers"),
    "c2w_nested": (_set("camera_to_world", np.eye(4).tolist(), 1), "'camera_path[1].camera_to_world'"),
    "c2w_nan": (_matrix(1, lambda m: m * np.where(np.eye(4) > 0, 1, np.nan)), "'camera_path[1].camera_to_world'"),
    "c2w_string": (lambda d: d["camera_path"][0]["camera_to_world"].__setitem__(3, "1"),
                   "'camera_path[0].camera_to_world'"),
    "c2w_scaled": (_matrix(3, _scaled), "'camera_path[3].camera_to_world' is not a rotation"),
    "c2w_mirrored": (_matrix(3, _mirrored), "'camera_path[3].camera_to_world' is not a rotation"),
    "c2w_transposed": (_matrix(4, lambda m: m.T.copy()), "row 0 0 0 1"),
    "fov_missing": (_delete("fov", 2), "missing 'camera_path[2].fov'"),
    "fov_zero": (_set("fov", 0.0, 2), "'camera_path[2].fov'"),
    "fov_180": (_set("fov", 180.0, 2), "'camera_path[2].fov'"),
    "fov_null": (_set("fov", None, 2), "'camera_path[2].fov'"),
    "aspect_negative": (_set("aspect", -1.0, 0), "'camera_path[0].aspect'"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_nerfstudio_file_is_one_line_user_error(tmp_path, case):
    change, fragment = MALFORMED[case]
    data = copy.deepcopy(ns_file(count=5, seconds=0.5))
    change(data)
    path = tmp_path / "camera_path.json"
    path.write_text(json.dumps(data))
    assert_user_error(lambda: load_path_document(path), path, fragment)


def test_the_entry_count_is_capped(tmp_path, monkeypatch):
    monkeypatch.setattr(nerfstudio_module, "MAX_KEYFRAMES", 4)
    path = tmp_path / "camera_path.json"
    path.write_text(json.dumps(ns_file(count=5, seconds=0.5)))
    assert_user_error(lambda: load_path_document(path), path, "'camera_path' has 5 entries (at most 4)")


def test_the_valid_file_behind_the_cases_loads():
    doc = read_nerfstudio(ns_file(count=5, seconds=0.5), "x.json")
    assert doc.path.frame_count == 5 and doc.path.fps == 10.0
    minimal = ns_file(count=5, seconds=0.5)
    for key in ("camera_type", "fps"):
        del minimal[key]
    for entry in minimal["camera_path"]:
        del entry["aspect"]
        entry["render_time"] = 0.5  # a dynamic scene's time: noted, not an error
    doc = read_nerfstudio(minimal | {"render_width": 64.0}, "x.json")
    assert doc.width == 64 and isinstance(doc.width, int) and "render_time" in doc.notes[0]
