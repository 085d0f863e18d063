"""Screenshot sidecars: building, the exact JSON round trip, strict loading, finding and
checking the scene, and ``raygs-viewer render --sidecar`` reproducing a screenshot."""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import os
import shutil
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest
from testkit import (
    DEMO_ARRAYS_SHA256,
    SETTINGS,
    assert_one_line_error,
    assert_user_error,
    delete_field,
    demo_sidecar,
    listing,
    run_cli,
    set_field,
    window_camera,
    write_case,
    write_inria_ply,
)

import raygs_viewer
import raygs_viewer.capture.sidecar as sidecar_module
from raygs_viewer.camera.lens_model import LensModel
from raygs_viewer.camera.pinhole import Camera, frame_points, look_at
from raygs_viewer.camera.stereo import PRESETS, Quantity, StereoRig, StereoView, rig_field
from raygs_viewer.capture.document_entries import load_settings_entry, load_stereo_entry
from raygs_viewer.capture.image_io import encode_image
from raygs_viewer.capture.screenshot import render_tiled, save_screenshot, scaled_camera
from raygs_viewer.capture.sidecar import (
    SIDECAR_FORMAT,
    SIDECAR_VERSION,
    Sidecar,
    build_sidecar,
    demo_sha256,
    load_sidecar,
    resolve_scene,
    scene_sha256,
    verify_scene_hash,
)
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import JsonFields
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.setting_info import Setting, setting
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.demo import demo_scene
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.depth import DepthSorter


def tiled(renderer, camera, settings):
    """render_tiled in the renderer's context: the CLI makes its own context current
    and releases it, after which GL calls on the session context would go nowhere."""
    with renderer.ctx, DepthSorter(renderer.scene) as sorter:
        return render_tiled(renderer, sorter, exact_order(sorter, camera, settings), camera, settings)








def write_json(path, data):
    path.write_text(json.dumps(data, indent=2))
    return path


def assert_bit_identical(a: Camera, b: Camera):
    assert (a.width, a.height) == (b.width, b.height)
    for name in ("fx", "fy", "cx", "cy"):
        assert getattr(a, name).hex() == float(getattr(b, name)).hex(), name
    assert a.R.dtype == b.R.dtype == np.float64 and a.t.dtype == b.t.dtype == np.float64
    assert a.R.tobytes() == b.R.tobytes() and a.t.tobytes() == b.t.tobytes()


# --------------------------------------------------------------------------- hashes


def test_scene_sha256_streams_the_file(tmp_path):
    path = tmp_path / "big.bin"
    data = np.random.default_rng(0).bytes((5 << 20) // 2 + 17)  # 2.5 MiB: several reads
    path.write_bytes(data)
    assert scene_sha256(path) == hashlib.sha256(data).hexdigest()
    assert_user_error(lambda: scene_sha256(tmp_path / "none.ply"), "none.ply", "no such file")
    assert_user_error(lambda: scene_sha256(tmp_path), tmp_path, "folder")


def test_demo_sha256_follows_the_generator():
    assert demo_sha256() == DEMO_ARRAYS_SHA256  # the digest test_demo pins
    scene = demo_scene()
    changed = dataclasses.replace(scene, opacities=scene.opacities * np.float32(0.5))
    demo_sha256.cache_clear()
    try:
        assert demo_sha256(lambda: changed) != DEMO_ARRAYS_SHA256
    finally:
        demo_sha256.cache_clear()


# --------------------------------------------------------------------------- building


def test_build_sidecar_fields(tmp_path, monkeypatch):
    scene_file = write_inria_ply(tmp_path / "s.ply")
    scene = load_scene(scene_file)
    monkeypatch.chdir(tmp_path)
    camera = look_at([0, 0, -3], [0, 0, 0], width=40, height=30)  # centred principal point
    data = build_sidecar(scene_path="s.ply", scene_sha256=scene_sha256("s.ply"), scene=scene, camera=camera,
                         settings=RenderSettings(), scale=1.5, window_camera=window_camera(),
                         extra={"up_axis": "-y", "navigation": "orbit"})
    # Mono sidecars keep version 1, so that older readers still read them.
    assert data["format"] == SIDECAR_FORMAT and data["version"] == 1 and SIDECAR_VERSION == 6
    assert data["program"] == {"name": "raygs-viewer", "version": raygs_viewer.__version__}
    created = datetime.fromisoformat(data["created"].replace("Z", "+00:00"))
    assert created.tzinfo is not None and created.utcoffset().total_seconds() == 0
    assert abs((datetime.now(timezone.utc) - created).total_seconds()) < 60
    assert data["image"] == {"width": 40, "height": 30, "scale": 1.5}
    assert data["scene"] == {"path": str(tmp_path / "s.ply"), "sha256": hashlib.sha256(scene_file.read_bytes()).hexdigest(),
                             "count": 5, "sh_degree": 0, "filter_fused": False}
    assert os.path.isabs(data["scene"]["path"])
    assert data["camera"]["cx"] == 20.0 and data["camera"]["cy"] == 15.0  # written even when centred
    assert data["world_to_camera"] == {"R": camera.R.tolist(), "t": camera.t.tolist()}
    # Every settings field, so one added later is recorded without touching the sidecar code.
    assert data["settings"] == dataclasses.asdict(RenderSettings())
    assert demo_sidecar()["settings"] == dataclasses.asdict(SETTINGS)
    assert demo_sidecar()["settings"]["p_min"] == 0.02 and demo_sidecar()["settings"]["background"] == (0.1, 0.2, 0.3)
    assert set(data["settings"]) == {f.name for f in dataclasses.fields(RenderSettings)}
    assert data["render_mode"] == "raygs" == data["settings"]["mode"]
    assert data["extra"] == {"up_axis": "-y", "navigation": "orbit"}
    assert data["window"]["world_to_camera"]["t"] == window_camera().t.tolist()
    assert data["window"]["camera"]["width"] == 64
    json.dumps(data, allow_nan=False)  # plain JSON types only
    assert demo_sidecar()["scene"]["path"] == "demo"


def test_settings_fields_flow_in_automatically():
    """A RenderSettings field added later is written and read back with no sidecar change."""
    @dataclasses.dataclass(frozen=True)
    class Extended(RenderSettings):
        exposure: float = setting(1.0, Setting("scale the image's brightness", "E", limits=(0.0, 8.0)))

    data = demo_sidecar(settings=Extended(exposure=2.5))
    assert data["settings"]["exposure"] == 2.5
    fields = JsonFields(Path("x.json"), json.loads(json.dumps(data)))
    loaded = load_settings_entry(fields, settings_type=Extended)
    assert loaded == Extended(exposure=2.5) and loaded != Extended()


# --------------------------------------------------------------------------- round trip


@pytest.mark.parametrize("scale", [1.0, 1.75])
def test_round_trip_is_bit_identical(tmp_path, scale):
    window = window_camera()
    camera = scaled_camera(window, scale)
    data = demo_sidecar(camera=camera, scale=scale, window_camera=window, extra={"gl": "llvmpipe"})
    path = write_json(tmp_path / "shot.json", data)
    loaded = load_sidecar(path)
    assert isinstance(loaded, Sidecar)
    assert_bit_identical(loaded.camera, camera)
    assert loaded.settings == SETTINGS
    assert loaded.scale == scale and loaded.render_mode == "raygs"
    assert loaded.scene_path == "demo" and loaded.scene_sha256 == demo_sha256()
    assert loaded.path == path and loaded.raw == json.loads(path.read_text())
    # The INRIA fields alone re-orthonormalise and recompute t: close, but not the
    # exact pose, which is why world_to_camera is stored.
    del data["world_to_camera"]
    inria = load_sidecar(write_json(tmp_path / "inria.json", data)).camera
    np.testing.assert_allclose(inria.R, camera.R, atol=1e-12)
    np.testing.assert_allclose(inria.t, camera.t, atol=1e-12)
    assert (inria.fx, inria.cx, inria.cy) == (camera.fx, camera.cx, camera.cy)


def test_round_trip_through_save_screenshot(tmp_path):
    data = demo_sidecar(settings=RenderSettings(sh_degree=None))
    _, js = save_screenshot(np.zeros((48, 64, 4), np.float32), data, folder=tmp_path)
    loaded = load_sidecar(js)
    assert_bit_identical(loaded.camera, window_camera())
    assert loaded.settings == RenderSettings()


#: A non-default value of every field after p_min, background, sh_degree: the accuracy
#: options and a streamed SOG's level of detail.
ACCURACY = dict(mode="raygs-exact-mip", mip=True, mip_sigma2=0.37, mip_modulation=False, gs_compensation=True,
                supersample=3, alpha_clamp=True, transmittance_cutoff=True, order="per-pixel", order_k=5,
                precision="float16", lod=2, lod_budget=123456, lod_distance=7.5)


def test_every_accuracy_setting_round_trips(tmp_path):
    defaults = RenderSettings()
    settings = RenderSettings(p_min=0.02, background=(0.1, 0.2, 0.3), sh_degree=1, **ACCURACY)
    fields = {f.name for f in dataclasses.fields(RenderSettings)}
    assert set(ACCURACY) == fields - {"p_min", "background", "sh_degree"}  # a new field needs a value here
    assert all(getattr(settings, name) != getattr(defaults, name) for name in fields)
    data = demo_sidecar(settings=settings)
    assert data["render_mode"] == "raygs-exact-mip"
    _, js = save_screenshot(np.zeros((48, 64, 4), np.float32), data, folder=tmp_path)
    loaded = load_sidecar(js)
    assert loaded.settings == settings and loaded.render_mode == "raygs-exact-mip"


@pytest.mark.parametrize("mode", ["raygs", "raygs-exact-mip", "gs"])
def test_render_mode_mirrors_the_settings_mode(tmp_path, mode):
    import raygs_viewer.render.settings as settings_module
    assert sidecar_module.RENDER_MODES == settings_module.RENDER_MODES
    data = demo_sidecar(settings=RenderSettings(mode=mode))
    assert data["render_mode"] == data["settings"]["mode"] == mode
    loaded = load_sidecar(write_json(tmp_path / "shot.json", data))
    assert loaded.render_mode == loaded.settings.mode == mode


@pytest.mark.parametrize("mode", ["raygs", "raygs-exact-mip", "gs"])
def test_an_older_sidecar_takes_the_mode_from_render_mode(tmp_path, mode):
    data = demo_sidecar(settings=RenderSettings(p_min=0.02, mip=True))
    del data["settings"]["mode"]  # written before settings had a mode
    data["render_mode"] = mode
    loaded = load_sidecar(write_json(tmp_path / "old.json", data))
    assert loaded.settings == RenderSettings(p_min=0.02, mip=True, mode=mode) and loaded.render_mode == mode


def test_settings_mode_and_render_mode_must_agree(tmp_path):
    data = demo_sidecar(settings=RenderSettings(mode="gs"))
    data["render_mode"] = "raygs"
    path = write_json(tmp_path / "shot.json", data)
    assert_user_error(lambda: load_sidecar(path), path, "'settings.mode' \"gs\"", "'render_mode' \"raygs\"",
                      "differs")
    # An unknown render_mode is reported as such, whatever settings.mode says.
    data["render_mode"] = "ewa"
    path = write_json(tmp_path / "unknown.json", data)
    assert_user_error(lambda: load_sidecar(path), path, "unknown 'render_mode' \"ewa\"")


# --------------------------------------------------------------------------- malformed sidecars


MALFORMED = {
    # case: (mutation of a valid sidecar dict, or raw file text, or None for no file; fragment of the message)
    "missing_file": (None, "no such file"),
    "not_json": ("{not json", "not valid JSON"),
    "not_utf8": (b"\xff\xfe{}", "cannot read"),
    "json_list": ("[]", "not a raygs-viewer screenshot sidecar"),
    "cameras_json": (json.dumps([{"width": 4}]), "not a raygs-viewer screenshot sidecar"),
    "no_format": (delete_field("format"), "'format'"),
    "wrong_format": (set_field("format", "something else"), "not a raygs-viewer screenshot sidecar"),
    "newer_version": (set_field("version", SIDECAR_VERSION + 1), "newer raygs-viewer"),
    "version_zero": (set_field("version", 0), "'version'"),
    "version_string": (set_field("version", "1"), "'version'"),
    "version_bool": (set_field("version", True), "'version'"),
    "no_version": (delete_field("version"), "missing 'version'"),
    "no_scene": (delete_field("scene"), "missing 'scene'"),
    "scene_not_object": (set_field("scene", "demo"), "'scene'"),
    "scene_path_missing": (delete_field("scene.path"), "'scene.path'"),
    "scene_path_number": (set_field("scene.path", 5), "'scene.path'"),
    "scene_path_empty": (set_field("scene.path", ""), "'scene.path'"),
    "sha256_short": (set_field("scene.sha256", "abc"), "'scene.sha256'"),
    "sha256_missing": (delete_field("scene.sha256"), "'scene.sha256'"),
    "relative_path_number": (set_field("scene.relative_path", 3), "'scene.relative_path'"),
    "no_camera": (delete_field("camera"), "missing 'camera'"),
    "camera_list": (set_field("camera", []), "'camera'"),
    "camera_no_fx": (delete_field("camera.fx"), "'fx'"),
    "camera_fx_negative": (set_field("camera.fx", -3.0), "fx"),
    "camera_width_zero": (set_field("camera.width", 0), "width"),
    "camera_width_fraction": (set_field("camera.width", 64.5), "width"),
    "camera_cx_string": (set_field("camera.cx", "32"), "'cx'"),
    "camera_cx_nan": (set_field("camera.cx", float("nan")), "'cx'"),
    "camera_fx_huge": ('__fx_1e400__', "'fx'"),
    "camera_rotation_bad": (set_field("camera.rotation", [[2, 0, 0], [0, 2, 0], [0, 0, 2]]), "rotation"),
    "w2c_not_object": (set_field("world_to_camera", [1, 2]), "'world_to_camera'"),
    "w2c_R_missing": (delete_field("world_to_camera.R"), "'world_to_camera.R'"),
    "w2c_R_2x3": (set_field("world_to_camera.R", [[1, 0, 0], [0, 1, 0]]), "'world_to_camera.R'"),
    "w2c_R_strings": (set_field("world_to_camera.R", [["1", 0, 0], [0, 1, 0], [0, 0, 1]]), "'world_to_camera.R'"),
    "w2c_R_scaled": (set_field("world_to_camera.R", [[2, 0, 0], [0, 2, 0], [0, 0, 2]]), "not a rotation"),
    "w2c_R_mirror": (set_field("world_to_camera.R", [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]), "not a rotation"),
    "w2c_t_nan": (set_field("world_to_camera.t", [0.0, float("nan"), 0.0]), "'world_to_camera.t'"),
    "w2c_t_inf": (set_field("world_to_camera.t", [0.0, float("inf"), 0.0]), "'world_to_camera.t'"),
    "w2c_t_two": (set_field("world_to_camera.t", [0.0, 1.0]), "'world_to_camera.t'"),
    "w2c_t_bool": (set_field("world_to_camera.t", [True, 0.0, 0.0]), "'world_to_camera.t'"),
    "pose_disagrees": (set_field("camera.position", [9.0, 9.0, 9.0]), "different poses"),
    "no_image": (delete_field("image"), "missing 'image'"),
    "image_scale_zero": (set_field("image.scale", 0), "'image.scale'"),
    "image_scale_huge": (set_field("image.scale", 9.0), "'image.scale'"),
    "image_scale_nan": (set_field("image.scale", float("nan")), "'image.scale'"),
    "image_scale_string": (set_field("image.scale", "2"), "'image.scale'"),
    "image_width_differs": (set_field("image.width", 65), "'image.width'"),
    "no_settings": (delete_field("settings"), "missing 'settings'"),
    "settings_list": (set_field("settings", [0.1]), "'settings'"),
    "unknown_setting": (set_field("settings.exposure", 2.0), "newer raygs-viewer"),
    "p_min_zero": (set_field("settings.p_min", 0.0), "p_min"),
    "p_min_string": (set_field("settings.p_min", "0.1"), "'settings.p_min'"),
    "p_min_nan": (set_field("settings.p_min", float("nan")), "'settings.p_min'"),
    "p_min_null": (set_field("settings.p_min", None), "'settings.p_min'"),
    "background_two": (set_field("settings.background", [0.1, 0.2]), "'settings.background'"),
    "background_string": (set_field("settings.background", "abc"), "'settings.background'"),
    "background_inf": (set_field("settings.background", [0.1, float("inf"), 0.3]), "'settings.background'"),
    "background_above_one": (set_field("settings.background", [2.0, 0.0, 0.0]),
                             "'settings': background must be three numbers in [0, 1]"),
    "background_negative": (set_field("settings.background", [0.0, 0.0, -0.5]), "in [0, 1]"),
    "sh_degree_four": (set_field("settings.sh_degree", 4), "sh_degree"),
    "sh_degree_fraction": (set_field("settings.sh_degree", 1.5), "'settings.sh_degree'"),
    "sh_degree_bool": (set_field("settings.sh_degree", True), "'settings.sh_degree'"),
    "render_mode_unknown": (set_field("render_mode", "ewa"), "'render_mode'"),
    "render_mode_differs": (set_field("render_mode", "gs"), "differs from 'render_mode'"),
    "render_mode_number": (set_field("render_mode", 1), "'render_mode'"),
    "mode_unknown": (set_field("settings.mode", "ewa"), "'settings.mode'"),
    "mode_number": (set_field("settings.mode", 2), "'settings.mode'"),
    "mip_string": (set_field("settings.mip", "yes"), "'settings.mip'"),
    "mip_number": (set_field("settings.mip", 1), "'settings.mip'"),
    "mip_modulation_null": (set_field("settings.mip_modulation", None), "'settings.mip_modulation'"),
    "mip_sigma2_negative": (set_field("settings.mip_sigma2", -0.1), "sigma^2"),
    "mip_sigma2_huge": (set_field("settings.mip_sigma2", 1000.0), "sigma^2"),
    "mip_sigma2_string": (set_field("settings.mip_sigma2", "0.1"), "'settings.mip_sigma2'"),
    "gs_compensation_string": (set_field("settings.gs_compensation", "true"), "'settings.gs_compensation'"),
    "supersample_zero": (set_field("settings.supersample", 0), "supersample"),
    "supersample_five": (set_field("settings.supersample", 5), "supersample"),
    "supersample_fraction": (set_field("settings.supersample", 1.5), "'settings.supersample'"),
    "supersample_bool": (set_field("settings.supersample", True), "'settings.supersample'"),
    "alpha_clamp_number": (set_field("settings.alpha_clamp", 0), "'settings.alpha_clamp'"),
    "transmittance_cutoff_list": (set_field("settings.transmittance_cutoff", []), "'settings.transmittance_cutoff'"),
    "render_mode_missing": (delete_field("render_mode"), "missing 'render_mode'"),
    "extra_list": (set_field("extra", []), "'extra'"),
}


def write_malformed(tmp_path, case):
    """The sidecar file of a MALFORMED case, next to a valid one's content."""
    change, _ = MALFORMED[case]
    if change == "__fx_1e400__":
        change = json.dumps(demo_sidecar(), indent=2).replace('"fx": ', '"fx": 1e400, "_fx": ')
    return write_case(tmp_path / "shot.json", change, demo_sidecar)


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_sidecar_is_one_line_user_error(tmp_path, case):
    path = write_malformed(tmp_path, case)
    assert_user_error(lambda: load_sidecar(path), path, MALFORMED[case][1])


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_sidecar_cli(capsys, tmp_path, case):
    path = write_malformed(tmp_path, case)
    before = listing(tmp_path)
    code, out, err = run_cli(capsys, "render", "--sidecar", path, "--out", tmp_path / "out.png")
    assert MALFORMED[case][1] in assert_one_line_error(code, err) and out == ""
    assert listing(tmp_path) == before


def test_newer_version_says_so(tmp_path):
    path = write_malformed(tmp_path, "newer_version")
    assert_user_error(lambda: load_sidecar(path), path, f"version {SIDECAR_VERSION + 1}", "newer raygs-viewer",
                      "update")


def test_the_valid_sidecar_behind_the_cases_loads(tmp_path):
    """The malformed cases differ from a valid sidecar only by their mutation."""
    assert load_sidecar(write_json(tmp_path / "ok.json", demo_sidecar())).settings == SETTINGS
    assert load_sidecar(write_json(tmp_path / "ok2.json", demo_sidecar() | {"extra": {}, "future_key": 1}))
    data = demo_sidecar()
    data["settings"].pop("sh_degree")  # written before the field existed: its default
    assert load_sidecar(write_json(tmp_path / "old.json", data)).settings == RenderSettings(
        p_min=0.02, background=(0.1, 0.2, 0.3))


# --------------------------------------------------------------------------- finding the scene


def ply_sidecar(tmp_path, scene_file, shots="shots", **kwargs):
    """A sidecar for ``scene_file`` saved with save_screenshot into ``tmp_path/shots``."""
    scene = load_scene(scene_file)
    camera = window_camera(40, 30)
    data = build_sidecar(scene_path=str(scene_file), scene_sha256=scene_sha256(scene_file), scene=scene,
                         camera=camera, settings=RenderSettings(), scale=1.0, **kwargs)
    _, js = save_screenshot(np.zeros((30, 40, 4), np.float32), data, folder=tmp_path / shots)
    return js


def test_resolve_scene_finds_a_scene_that_is_a_folder(tmp_path):
    """An unbundled SOG scene is a folder (its meta.json and images): a sidecar recorded
    on it finds it as it finds a file, and after the tree moved."""
    folder = tmp_path / "root" / "sog-scene"
    folder.mkdir(parents=True)
    scene = load_scene(write_inria_ply(tmp_path / "stand-in.ply"))
    data = build_sidecar(scene_path=str(folder), scene_sha256="0" * 64, scene=scene, camera=window_camera(40, 30),
                         settings=RenderSettings(), scale=1.0)
    _, js = save_screenshot(np.zeros((30, 40, 4), np.float32), data, folder=tmp_path / "root" / "shots")
    assert resolve_scene(load_sidecar(js)) == str(folder)
    shutil.move(tmp_path / "root", tmp_path / "moved")
    moved = resolve_scene(load_sidecar(tmp_path / "moved" / "shots" / js.name))
    assert Path(moved).resolve() == (tmp_path / "moved" / "sog-scene").resolve()


def test_resolve_scene(tmp_path):
    (tmp_path / "root").mkdir()
    scene_file = write_inria_ply(tmp_path / "root" / "scene.ply")
    js = ply_sidecar(tmp_path / "root", scene_file)
    shot = load_sidecar(js)
    assert resolve_scene(shot) == str(scene_file)
    assert resolve_scene(shot, "other.ply") == "other.ply"
    assert resolve_scene(shot, "demo") == "demo"
    verify_scene_hash(shot, str(scene_file))

    # The whole tree moved: the recorded absolute path is gone, the relative one works.
    moved = tmp_path / "moved"
    shutil.move(tmp_path / "root", moved)
    shot = load_sidecar(moved / "shots" / js.name)
    assert not Path(shot.scene_path).exists()
    assert Path(resolve_scene(shot)).resolve() == (moved / "scene.ply").resolve()

    # Screenshot and scene moved into one folder together: the same name beside the sidecar.
    together = tmp_path / "together"
    together.mkdir()
    shutil.copy(moved / "scene.ply", together / "scene.ply")
    shutil.copy(moved / "shots" / js.name, together / js.name)
    assert resolve_scene(load_sidecar(together / js.name)) == str(together / "scene.ply")

    # Nowhere: one line naming the recorded path.
    lonely = tmp_path / "lonely"
    lonely.mkdir()
    shutil.copy(moved / "shots" / js.name, lonely / js.name)
    message = assert_user_error(lambda: resolve_scene(load_sidecar(lonely / js.name)), js.name, "not found")
    assert str(tmp_path / "root" / "scene.ply") in message

    assert resolve_scene(load_sidecar(write_json(tmp_path / "d.json", demo_sidecar()))) == "demo"


def test_verify_scene_hash(tmp_path):
    scene_file = write_inria_ply(tmp_path / "scene.ply")
    js = ply_sidecar(tmp_path, scene_file)
    shot = load_sidecar(js)
    verify_scene_hash(shot, str(scene_file))
    old = shot.scene_sha256
    write_inria_ply(scene_file, seed=1)  # retrained: same name, other content
    new = scene_sha256(scene_file)
    message = assert_user_error(lambda: verify_scene_hash(shot, str(scene_file)), scene_file,
                                "scene file differs from the one the screenshot was taken with",
                                f"sha256 {new[:12]}… vs {old[:12]}…")
    assert js.name in message
    assert_user_error(lambda: verify_scene_hash(shot, "demo"), js, "demo")
    demo_shot = load_sidecar(write_json(tmp_path / "d.json", demo_sidecar()))
    verify_scene_hash(demo_shot, "demo")
    assert_user_error(lambda: verify_scene_hash(demo_shot, str(scene_file)), scene_file, "differs")


# --------------------------------------------------------------------------- render --sidecar


def test_render_sidecar_reproduces_the_screenshot_byte_for_byte(capsys, tmp_path, demo_renderer):
    """The window saves encode_image(render_tiled(...)); the CLI renders the sidecar
    through the same function: the PNGs are the same bytes."""
    window = window_camera(40, 30)
    camera = scaled_camera(window, 1.6)  # 64x48
    image = tiled(demo_renderer, camera, SETTINGS)
    assert np.all(np.isfinite(image)) and image[..., 3].max() > 0.5
    png, js = save_screenshot(image, demo_sidecar(camera=camera, scale=1.6, window_camera=window),
                              folder=tmp_path / "shots")
    out = tmp_path / "again.png"
    code, stdout, err = run_cli(capsys, "render", "--sidecar", js, "--out", out)
    assert code == 0 and err == "", err
    assert "64x48" in stdout
    assert out.read_bytes() == png.read_bytes() == encode_image(image, ".png")
    # The float image too, before rounding to 8 bits.
    npy = tmp_path / "again.npy"
    assert run_cli(capsys, "render", "--sidecar", js, "--out", npy)[0] == 0
    np.testing.assert_array_equal(np.load(npy), image)
    # Negative control: the same camera with default settings is another picture, so
    # the settings really come from the sidecar.
    default = tmp_path / "default.png"
    data = demo_sidecar(camera=camera, settings=RenderSettings())
    code, _, err = run_cli(capsys, "render", "--sidecar", write_json(tmp_path / "d.json", data), "--out", default)
    assert code == 0, err
    assert default.read_bytes() != out.read_bytes()
    assert default.read_bytes() == encode_image(tiled(demo_renderer, camera, RenderSettings()), ".png")
    for other in (RenderSettings(p_min=0.02, background=(0.1, 0.2, 0.3)),          # all SH bands
                  RenderSettings(p_min=0.02, sh_degree=1),                          # black background
                  RenderSettings(background=(0.1, 0.2, 0.3), sh_degree=1)):         # default p_min
        assert encode_image(tiled(demo_renderer, camera, other), ".png") != out.read_bytes(), other


def test_render_sidecar_reference(capsys, tmp_path, demo):
    camera = window_camera(32, 24)
    js = write_json(tmp_path / "shot.json", demo_sidecar(camera=camera))
    out = tmp_path / "ref.npy"
    code, stdout, err = run_cli(capsys, "render", "--sidecar", js, "--reference", "--out", out)
    assert code == 0 and "reference" in stdout, err
    expected = render_reference(demo, camera, SETTINGS)
    np.testing.assert_array_equal(np.load(out), expected.astype(np.float32))
    assert np.abs(expected - render_reference(demo, camera, RenderSettings())).max() > 0.05  # settings matter


def test_render_sidecar_scene_override_is_hash_checked(capsys, tmp_path):
    scene_file = write_inria_ply(tmp_path / "scene.ply", n=30, seed=2)
    js = ply_sidecar(tmp_path, scene_file)
    first = tmp_path / "first.npy"
    assert run_cli(capsys, "render", "--sidecar", js, "--out", first)[0] == 0
    # The same bytes elsewhere, given explicitly: accepted, same image.
    copy_file = tmp_path / "copy" / "renamed.ply"
    copy_file.parent.mkdir()
    shutil.copy(scene_file, copy_file)
    second = tmp_path / "second.npy"
    code, _, err = run_cli(capsys, "render", copy_file, "--sidecar", js, "--out", second)
    assert code == 0, err
    np.testing.assert_array_equal(np.load(first), np.load(second))
    # Another scene, or the demo, given explicitly: refused.
    other = write_inria_ply(tmp_path / "other.ply", n=30, seed=3)
    for override in (other, "demo"):
        code, _, err = run_cli(capsys, "render", override, "--sidecar", js, "--out", tmp_path / "x.png")
        assert "differs from the one the screenshot was taken with" in assert_one_line_error(code, err)
    # The recorded scene changed on disk: refused, naming the file.
    write_inria_ply(scene_file, n=30, seed=4)
    code, _, err = run_cli(capsys, "render", "--sidecar", js, "--out", tmp_path / "y.png")
    assert "scene.ply" in assert_one_line_error(code, err) and "sha256" in err
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "y.png").exists()


def test_render_sidecar_after_the_folder_moved(capsys, tmp_path):
    root = tmp_path / "project"
    root.mkdir()
    scene_file = write_inria_ply(root / "scene.ply", n=30, seed=2)
    js = ply_sidecar(root, scene_file)
    before = tmp_path / "before.npy"
    assert run_cli(capsys, "render", "--sidecar", js, "--out", before)[0] == 0
    shutil.move(root, tmp_path / "elsewhere")
    after = tmp_path / "after.npy"
    code, _, err = run_cli(capsys, "render", "--sidecar", tmp_path / "elsewhere" / "shots" / js.name, "--out", after)
    assert code == 0, err
    np.testing.assert_array_equal(np.load(before), np.load(after))


@pytest.mark.parametrize("size, expected", [(["--width", "32"], (32, 24)),    # the height follows the aspect
                                           (["--height", "12"], (16, 12)),   # and the width
                                           (["--width", "40", "--height", "20"], (40, 20))])
def test_render_sidecar_at_another_size_scales_the_camera(capsys, tmp_path, demo_renderer, size, expected):
    """--width/--height with --sidecar: the screenshot's view, its settings, another size;
    fx and cx scale with the width, fy and cy with the height (as for --camera)."""
    camera = window_camera(64, 48)
    js = write_json(tmp_path / "shot.json", demo_sidecar(camera=camera))
    out = tmp_path / "resized.npy"
    code, stdout, err = run_cli(capsys, "render", "--sidecar", js, *size, "--out", out)
    assert code == 0, err
    width, height = expected
    assert f"{width}x{height}" in stdout and "view from" in stdout
    resized = camera.resized(width, height)
    assert resized.fx == pytest.approx(camera.fx * width / 64) and resized.cy == pytest.approx(camera.cy * height / 48)
    image = np.load(out)
    np.testing.assert_array_equal(image, tiled(demo_renderer, resized, SETTINGS))
    # Negative controls: the size alone (intrinsics unscaled), or the default settings,
    # make other pictures, so the camera is scaled and the settings are the sidecar's.
    unscaled = dataclasses.replace(camera, width=width, height=height)
    assert np.abs(image - tiled(demo_renderer, unscaled, SETTINGS)).max() > 0.05
    assert np.abs(image - tiled(demo_renderer, resized, RenderSettings())).max() > 0.05


def test_render_camera_takes_a_sidecar_with_other_settings(capsys, tmp_path, demo_renderer):
    """--camera SHOT.json: the screenshot's camera alone; the settings and size are the
    command line's, so a screenshot renders again with other settings."""
    camera = window_camera(64, 48)
    js = write_json(tmp_path / "shot.json", demo_sidecar(camera=camera))
    out = tmp_path / "gs.npy"
    code, _, err = run_cli(capsys, "render", "--camera", js, "--mode", "gs", "--width", "32", "--out", out)
    assert code == 0, err
    image = np.load(out)
    np.testing.assert_array_equal(image, tiled(demo_renderer, camera.resized(32, 24), RenderSettings(mode="gs")))
    assert np.abs(image - tiled(demo_renderer, camera.resized(32, 24), RenderSettings())).max() > 0.05
    code, _, err = run_cli(capsys, "render", "--camera", js, "--camera-index", "1", "--out", tmp_path / "x.npy")
    assert "--camera-index must be 0..0" in assert_one_line_error(code, err)
    assert not (tmp_path / "x.npy").exists()


@pytest.mark.parametrize("option", [["--camera", "cams.json"], ["--camera-index", "0"],
                                    ["--p-min", "0.1"], ["--background", "1,1,1"],
                                    ["--sh-degree", "0"], ["--mode", "gs"], ["--mip"], ["--no-mip"],
                                    ["--mip-sigma2", "0.2"], ["--mip-modulation"], ["--no-mip-modulation"],
                                    ["--gs-compensation"], ["--supersample", "2"], ["--alpha-clamp"],
                                    ["--transmittance-cutoff"]])
def test_render_sidecar_rejects_view_options(capsys, tmp_path, option):
    js = write_json(tmp_path / "shot.json", demo_sidecar())
    before = listing(tmp_path)
    code, _, err = run_cli(capsys, "render", "--sidecar", js, *option, "--out", tmp_path / "out.png")
    assert option[0] in assert_one_line_error(code, err) and "--sidecar" in err
    assert listing(tmp_path) == before


def test_render_sidecar_checks_the_output_first(capsys, tmp_path, monkeypatch):
    import raygs_viewer.cli.commands as cli

    monkeypatch.setattr(cli, "load_scene_argument", lambda name: pytest.fail("scene loaded before the checks"))
    js = write_json(tmp_path / "shot.json", demo_sidecar())
    (tmp_path / "taken.png").write_bytes(b"precious")
    code, _, err = run_cli(capsys, "render", "--sidecar", js, "--out", tmp_path / "taken.png")
    assert "already exists" in assert_one_line_error(code, err)
    assert (tmp_path / "taken.png").read_bytes() == b"precious"


def test_load_sidecar_messages_are_user_errors_not_crashes(tmp_path):
    """Deeply nested or odd JSON values never escape as other exceptions."""
    for text in ("[" * 100000, '{"format": "raygs-viewer screenshot", "version": 1, "scene": []}', "null", "1e999"):
        path = tmp_path / "odd.json"
        path.write_text(text)
        with pytest.raises(UserError):
            load_sidecar(path)


# --------------------------------------------------------------------------- stereo

STEREO = StereoView(StereoRig(0.07, 3.5, 0.25), "sbs", LensModel(0.3, 0.1, 0.99, 1.02), PRESETS["index"])


def stereo_sidecar(view=STEREO, **kwargs):
    return demo_sidecar(stereo=view, **kwargs)


@pytest.mark.parametrize("layout, width", [("sbs", 128), ("cross", 128), ("anaglyph", 64), ("left", 64),
                                           ("right", 64)])
def test_stereo_sidecar_round_trip(tmp_path, layout, width):
    view = dataclasses.replace(STEREO, layout=layout)
    data = stereo_sidecar(view)
    assert data["version"] == 2
    assert data["image"]["width"] == width and data["image"]["height"] == 48  # the composed image
    assert data["camera"]["width"] == 64  # the midpoint camera: each eye's size
    assert data["stereo"] == {"ipd": 0.07, "convergence": 3.5, "scene_scale": 0.25, "layout": layout,
                              "lens": {"k1": 0.3, "k2": 0.1, "chroma_red": 0.99, "chroma_blue": 1.02},
                              "headset": {"name": "index", "label": PRESETS["index"].label, "width": 1440,
                                          "height": 1600, "fov_x": 108.0, "fov_y": 104.0}}
    loaded = load_sidecar(write_json(tmp_path / "pair.json", data))
    assert loaded.stereo == view
    assert_bit_identical(loaded.camera, window_camera())
    no_lens = dataclasses.replace(view, lens=None, headset=None)
    assert load_sidecar(write_json(tmp_path / "plain.json", stereo_sidecar(no_lens))).stereo == no_lens
    assert load_sidecar(write_json(tmp_path / "mono.json", demo_sidecar())).stereo is None


MALFORMED_STEREO = {
    "old_version": (set_field("version", 1), "needs sidecar version 2"),
    "stereo_list": (set_field("stereo", []), "'stereo'"),
    "ipd_string": (set_field("stereo.ipd", "63"), "'stereo.ipd'"),
    "ipd_negative": (set_field("stereo.ipd", -0.01), "ipd"),
    "convergence_zero": (set_field("stereo.convergence", 0.0), "convergence"),
    "scale_nan": (set_field("stereo.scene_scale", float("nan")), "'stereo.scene_scale'"),
    "layout_unknown": (set_field("stereo.layout", "top-bottom"), "'stereo.layout'"),
    "layout_number": (set_field("stereo.layout", 1), "'stereo.layout'"),
    "unknown_field": (set_field("stereo.eye_relief", 0.01), "'stereo.eye_relief'"),
    "lens_list": (set_field("stereo.lens", [0.2]), "'stereo.lens'"),
    "lens_k1_string": (set_field("stereo.lens.k1", "0.2"), "'stereo.lens.k1'"),
    "lens_k1_null": (set_field("stereo.lens.k1", None), "'stereo.lens.k1'"),
    "lens_k1_huge": (set_field("stereo.lens.k1", 1e6), "k1"),
    "lens_extra": (set_field("stereo.lens.k3", 0.1), "'stereo.lens.k3'"),
    "headset_width_zero": (set_field("stereo.headset.width", 0), "headset resolution"),
    "headset_width_fraction": (set_field("stereo.headset.width", 1440.5), "'stereo.headset.width'"),
    "headset_fov_huge": (set_field("stereo.headset.fov_x", 400.0), "field of view"),
    "headset_name_missing": (delete_field("stereo.headset.name"), "'stereo.headset.name'"),
    "image_mono_width": (set_field("image.width", 64), "'image.width' 64 differs"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED_STEREO))
def test_malformed_stereo_sidecar_is_one_line_user_error(tmp_path, case):
    change, fragment = MALFORMED_STEREO[case]
    data = copy.deepcopy(stereo_sidecar())
    change(data)
    path = tmp_path / "pair.json"
    path.write_text(json.dumps(data))
    assert_user_error(lambda: load_sidecar(path), path, fragment)


@pytest.mark.parametrize("missing, expected", [
    ("stereo.ipd", dataclasses.replace(STEREO, rig=StereoRig(convergence=3.5, scene_scale=0.25))),
    ("stereo.scene_scale", dataclasses.replace(STEREO, rig=StereoRig(0.07, 3.5))),
    ("stereo.layout", STEREO),  # "sbs", the default
    ("stereo.lens", dataclasses.replace(STEREO, lens=None)),
    ("stereo.lens.k1", dataclasses.replace(STEREO, lens=LensModel(k2=0.1, chroma_red=0.99, chroma_blue=1.02))),
    ("stereo.headset", dataclasses.replace(STEREO, headset=None)),
])
def test_a_stereo_key_the_file_lacks_takes_its_default(tmp_path, missing, expected):
    """A file written before a stereo field existed still loads (the issue's trap: one
    rig field added would otherwise have broken every stereo screenshot)."""
    data = stereo_sidecar()
    delete_field(missing)(data)
    assert load_sidecar(write_json(tmp_path / "old.json", data)).stereo == expected


@dataclasses.dataclass(frozen=True)
class EyeReliefRig(StereoRig):
    """The rig with one more field, as a later version might add it."""

    eye_relief: float = rig_field(0.012, Quantity(0.0, 0.1, "metres", "distance from the eye to the lens", "METRES"))


def test_a_rig_field_added_later_reads_the_files_written_before_it(tmp_path):
    from raygs_viewer.camera.path import path_through_cameras
    from raygs_viewer.capture.path_file import PathDocument, path_document_json

    old_sidecar = json.loads(json.dumps(stereo_sidecar()))  # today's files, without the field
    path = path_through_cameras([window_camera(), look_at([0, 0, -3], [0, 0, 0], width=64, height=48)])
    old_path_file = json.loads(json.dumps(path_document_json(PathDocument(path, 64, 48, SETTINGS, STEREO, "demo",
                                                                          demo_sha256()))))
    for name, data in (("shot.json", old_sidecar), ("fly.json", old_path_file)):
        view = load_stereo_entry(JsonFields(Path(name), data), EyeReliefRig)
        assert view == dataclasses.replace(STEREO, rig=EyeReliefRig(0.07, 3.5, 0.25))
        assert view.rig.eye_relief == 0.012

    # The later version writes the field and reads it back, checked against its limits...
    data = json.loads(json.dumps(stereo_sidecar(dataclasses.replace(STEREO, rig=EyeReliefRig(0.07, 3.5, 0.25, 0.02)))))
    assert data["stereo"]["eye_relief"] == 0.02
    assert load_stereo_entry(JsonFields(Path("new.json"), data), EyeReliefRig).rig == EyeReliefRig(0.07, 3.5, 0.25, 0.02)
    for value, fragment in ((0.5, "stereo eye relief must be a number in [0, 0.1]"),
                            ("12", "'stereo.eye_relief' must be a number")):
        data["stereo"]["eye_relief"] = value
        assert_user_error(lambda: load_stereo_entry(JsonFields(Path("new.json"), data), EyeReliefRig), "new.json",
                          fragment)
    # ... and today's program refuses it: it cannot honour an option it does not know.
    data["stereo"]["eye_relief"] = 0.02
    path = write_json(tmp_path / "new.json", data)
    assert_user_error(lambda: load_sidecar(path), path, "unknown field 'stereo.eye_relief'", "newer raygs-viewer")


# --------------------------------------------------------------------------- channel pictures (version 3)


@pytest.mark.parametrize("view", [ChannelView("depth", (0.5, 7.25)), ChannelView("median_depth"),
                                  ChannelView("normal", None, "world"), ChannelView("alpha"),
                                  ChannelView("depth", alpha_threshold=0.3), ChannelView("normal", alpha_threshold=0)])
def test_channel_view_sidecar_round_trip(tmp_path, view):
    data = demo_sidecar(channel_view=view)
    assert data["version"] == 3
    assert data["channel_view"] == {"channel": view.channel,
                                    "depth_range": None if view.depth_range is None else list(view.depth_range),
                                    "normal_space": view.normal_space, "alpha_threshold": view.alpha_threshold}
    loaded = load_sidecar(write_json(tmp_path / "shot.json", data))
    assert loaded.channel_view == view
    assert loaded.settings == SETTINGS
    assert_bit_identical(loaded.camera, window_camera())
    both = load_sidecar(write_json(tmp_path / "pair.json", stereo_sidecar(channel_view=view)))
    assert both.channel_view == view and both.stereo == STEREO and both.raw["version"] == 3


@pytest.mark.parametrize("view", [None, ChannelView("rgb"), ChannelView("rgb", normal_space="world")])
def test_colour_sidecars_record_no_channel_view_and_keep_their_version(tmp_path, view):
    """Older readers keep reading colour screenshots; a picture of another channel they
    would render as colour, so it takes version 3, which they refuse."""
    data = demo_sidecar(channel_view=view)
    assert "channel_view" not in data and data["version"] == 1
    assert stereo_sidecar(channel_view=view)["version"] == 2
    assert load_sidecar(write_json(tmp_path / "shot.json", data)).channel_view is None


@pytest.mark.parametrize("missing, expected", [("channel_view.depth_range", ChannelView("normal", None, "world")),
                                               ("channel_view.normal_space", ChannelView("normal")),
                                               # written before the threshold: drawn unmasked
                                               ("channel_view.alpha_threshold",
                                                ChannelView("normal", None, "world", alpha_threshold=0.0))])
def test_a_channel_view_key_the_file_lacks_takes_its_default(tmp_path, missing, expected):
    data = demo_sidecar(channel_view=ChannelView("normal", None, "world"))
    delete_field(missing)(data)
    assert load_sidecar(write_json(tmp_path / "old.json", data)).channel_view == expected


MALFORMED_CHANNEL_VIEW = {
    "old_version": (set_field("version", 2), "needs sidecar version 3"),
    "not_object": (set_field("channel_view", "depth"), "'channel_view'"),
    "channel_missing": (delete_field("channel_view.channel"), "missing 'channel_view.channel'"),
    "channel_unknown": (set_field("channel_view.channel", "disparity"), "unknown view channel"),
    "channel_number": (set_field("channel_view.channel", 3), "'channel_view.channel'"),
    "range_reversed": (set_field("channel_view.depth_range", [5.0, 1.0]), "near < far"),
    "range_three": (set_field("channel_view.depth_range", [1.0, 2.0, 3.0]), "'channel_view.depth_range'"),
    "range_words": (set_field("channel_view.depth_range", "1,2"), "'channel_view.depth_range'"),
    "space_unknown": (set_field("channel_view.normal_space", "object"), "normal space"),
    "threshold_above_1": (set_field("channel_view.alpha_threshold", 1.5), "alpha threshold must be"),
    "threshold_words": (set_field("channel_view.alpha_threshold", "half"), "'channel_view.alpha_threshold'"),
    "unknown_field": (set_field("channel_view.gamma", 2.2), "'channel_view.gamma'"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED_CHANNEL_VIEW))
def test_malformed_channel_view_is_one_line_user_error(tmp_path, case):
    change, fragment = MALFORMED_CHANNEL_VIEW[case]
    data = copy.deepcopy(demo_sidecar(channel_view=ChannelView("depth", (1.0, 4.0))))
    change(data)
    path = write_json(tmp_path / "shot.json", data)
    assert_user_error(lambda: load_sidecar(path), path, fragment)


# --------------------------------------------------------------------------- a .spz's axes


def spz_scene_file(tmp_path, spz_axes="rdf"):
    """A .spz of 40 gaussians written in ``spz_axes``, as splat-transform writes "rdf"."""
    from raygs_viewer.scene.spz_format import SpzEncoding
    from raygs_viewer.scene.writing import write_scene
    scene = load_scene(write_inria_ply(tmp_path / "source.ply", n=40, seed=5))
    return write_scene(scene, tmp_path / f"scene-{spz_axes}.spz", spz=SpzEncoding(axes=spz_axes))


def test_a_spz_scene_records_the_axes_it_was_read_in(tmp_path):
    spz = spz_scene_file(tmp_path)
    for axes, version in (("rub", 1), ("rdf", 4)):
        scene = load_scene(SceneSource(spz, spz_axes=axes))
        data = build_sidecar(scene_path=str(spz), scene_sha256=scene_sha256(spz), scene=scene,
                             camera=window_camera(40, 30), settings=RenderSettings(), scale=1.0)
        # "rdf" needs version 4: a reader without the key would show the scene upside down.
        assert data["scene"]["spz_axes"] == axes and data["version"] == version
        assert load_sidecar(write_json(tmp_path / f"{axes}.json", data)).axes == FileAxes(axes)
    ply = load_scene(tmp_path / "source.ply")
    data = build_sidecar(scene_path=str(tmp_path / "source.ply"), scene_sha256="0" * 64, scene=ply,
                         camera=window_camera(40, 30), settings=RenderSettings(), scale=1.0)
    assert "spz_axes" not in data["scene"]
    # Older sidecars, and other scenes, read as the specification's axes.
    for older in (write_json(tmp_path / "ply.json", data), write_json(tmp_path / "d.json", demo_sidecar())):
        shot = load_sidecar(older)
        assert shot.axes is None and shot.source(shot.scene_path).spz_axes == "rub"


@pytest.mark.parametrize("change,fragment", [
    ({"spz_axes": "up"}, "'scene.spz_axes' must be \"rub\" or \"rdf\", got \"up\""),
    ({"spz_axes": 6}, "'scene.spz_axes'"),
    ({"spz_axes": "rdf", "version": 3}, "'scene.spz_axes' rdf needs sidecar version 4"),
])
def test_a_bad_spz_axes_entry_is_one_line(tmp_path, change, fragment):
    data = demo_sidecar()
    data["scene"]["spz_axes"] = change["spz_axes"]
    data["version"] = change.get("version", SIDECAR_VERSION)
    path = write_json(tmp_path / "bad.json", data)
    assert_user_error(lambda: load_sidecar(path), path, fragment)


def test_render_sidecar_reads_the_spz_in_its_recorded_axes(capsys, tmp_path):
    spz = spz_scene_file(tmp_path)
    rdf, rub = load_scene(SceneSource(spz, spz_axes="rdf")), load_scene(spz)
    camera = frame_points(rdf.positions, 48, 36)
    data = build_sidecar(scene_path=str(spz), scene_sha256=scene_sha256(spz), scene=rdf, camera=camera,
                         settings=RenderSettings(), scale=1.0)
    js = write_json(tmp_path / "shot.json", data)
    out = tmp_path / "again.npy"
    code, _, err = run_cli(capsys, "render", "--sidecar", js, "--reference", "--out", out)
    assert code == 0, err
    expected = render_reference(rdf, camera, RenderSettings())
    np.testing.assert_array_equal(np.load(out), expected.astype(np.float32))
    assert np.abs(expected - render_reference(rub, camera, RenderSettings())).max() > 0.1  # the axes matter
    # The sidecar says how: an explicit --spz-axes is refused, whatever it says.
    for axes in ("rdf", "rub"):
        code, _, err = run_cli(capsys, "render", "--sidecar", js, "--spz-axes", axes, "--out", tmp_path / "x.png")
        assert "drop --spz-axes" in assert_one_line_error(code, err)
    assert not (tmp_path / "x.png").exists()


def test_edits_take_version_5_which_older_readers_refuse(tmp_path):
    """A screenshot of an edited scene shows the scene less its deleted gaussians: a reader
    that ignored "edits" would render another picture, so the field needs version 5."""
    edits = {"format": "raygs-viewer edits", "version": 1, "scene": {}, "operations": [{"op": "delete"}]}
    data = demo_sidecar(edits=edits)
    assert data["version"] == 5 and data["edits"] == edits
    assert load_sidecar(write_json(tmp_path / "shot.json", data)).edits == edits
    assert demo_sidecar()["version"] == 1 and load_sidecar(write_json(tmp_path / "plain.json", demo_sidecar())).edits is None
    data["version"] = 4
    with pytest.raises(UserError, match="'edits' needs sidecar version 5"):
        load_sidecar(write_json(tmp_path / "old.json", data))
