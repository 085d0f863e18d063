"""Loading a scene with its cameras, hash and warnings, in the foreground and in the
background (raygs_viewer.scene.loader).

Background tests steer the loader's ``read_scene`` with events; none measures
time. DEADLOCK only bounds a wait that a broken implementation would never end.
"""

from __future__ import annotations

import functools
import hashlib
import json
import threading
from pathlib import Path

import numpy as np
import pytest
import testkit
from testkit import gaussian_columns, write_ply

import raygs_viewer.scene.content_hash as content_hash
from raygs_viewer.errors import UserError
from raygs_viewer.scene.demo import (
    DEMO_VIEW_NAMES,
    demo_cameras,
    demo_cameras_json,
    demo_scene,
)
from raygs_viewer.scene.io import load_scene
from raygs_viewer.scene.content_hash import arrays_sha256, file_sha256
from raygs_viewer.scene.loader import LoadedScene, SceneLoader, find_training_cameras, load_now
from raygs_viewer.scene.source import SceneSource

DEADLOCK = 30.0


def small_ply(path: Path, n: int = 5, **kwargs) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_ply(path, gaussian_columns(n, 1, **kwargs))


def write_cameras(path: Path, entries) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(entries), encoding="utf-8")
    return path


@pytest.fixture
def scene_loader():
    background = SceneLoader()
    yield background
    background.close()
    assert background.join(DEADLOCK), "a load thread never ended"


# --------------------------------------------------------------------------- discovery


def test_cameras_beside_the_scene(tmp_path):
    scene = small_ply(tmp_path / "scene.ply")
    assert find_training_cameras(scene) is None
    cameras = write_cameras(tmp_path / "cameras.json", demo_cameras_json())
    assert find_training_cameras(scene) == cameras
    assert find_training_cameras(str(scene)) == cameras


def test_cameras_in_the_inria_model_folder(tmp_path, monkeypatch):
    model = tmp_path / "model"
    scene = small_ply(model / "point_cloud" / "iteration_30000" / "point_cloud.ply")
    assert find_training_cameras(scene) is None
    cameras = write_cameras(model / "cameras.json", demo_cameras_json())
    assert find_training_cameras(scene) == cameras
    monkeypatch.chdir(scene.parent)  # a bare file name still finds its model folder
    assert find_training_cameras("point_cloud.ply").samefile(cameras)
    # One beside the scene wins.
    beside = write_cameras(scene.parent / "cameras.json", demo_cameras_json()[:1])
    assert find_training_cameras(scene) == beside


@pytest.mark.parametrize("layout", ["model/points/iteration_7/point_cloud.ply",       # not point_cloud/
                                    "model/point_cloud/iter_7/point_cloud.ply",        # not iteration_*
                                    "model/point_cloud/point_cloud.ply"])              # one level short
def test_other_layouts_do_not_look_in_the_model_folder(tmp_path, layout):
    scene = small_ply(tmp_path / layout)
    write_cameras(tmp_path / "model" / "cameras.json", demo_cameras_json())
    assert find_training_cameras(scene) is None


# --------------------------------------------------------------------------- load_now


def test_discovered_cameras_are_loaded_with_their_names(tmp_path):
    model = tmp_path / "model"
    scene = small_ply(model / "point_cloud" / "iteration_7000" / "point_cloud.ply")
    cameras_json = write_cameras(model / "cameras.json", demo_cameras_json())
    loaded = load_now(SceneSource(scene))
    assert isinstance(loaded, LoadedScene)
    assert loaded.path == str(scene) and loaded.scene.count == 5
    assert loaded.cameras_path == str(cameras_json)
    assert loaded.camera_names == list(DEMO_VIEW_NAMES)
    assert len(loaded.cameras) == 6
    for got, expected in zip(loaded.cameras, demo_cameras()):
        np.testing.assert_allclose(got.R, expected.R, atol=1e-9)
        np.testing.assert_allclose(got.t, expected.t, atol=1e-9)
    assert loaded.warnings == []


def test_camera_names_fall_back_to_numbers(tmp_path):
    entries = demo_cameras_json()[:3]
    del entries[0]["img_name"]
    entries[1]["img_name"] = ""
    entries[2]["img_name"] = "IMG_0002\n.jpg"  # kept on one line
    scene = small_ply(tmp_path / "scene.ply")
    write_cameras(tmp_path / "cameras.json", entries)
    assert load_now(SceneSource(scene)).camera_names == ["camera 0", "camera 1", "IMG_0002 .jpg"]
    write_cameras(tmp_path / "cameras.json", demo_cameras_json()[4])  # one object, not a list
    assert load_now(SceneSource(scene)).camera_names == ["sphere-close-up"]


BAD_CAMERAS = {
    "not_json": "{ this is not json",
    "empty_list": "[]",
    "missing_fx": json.dumps([{k: v for k, v in demo_cameras_json()[0].items() if k != "fx"}]),
    "not_a_rotation": json.dumps([{**demo_cameras_json()[0], "rotation": [[2, 0, 0], [0, 1, 0], [0, 0, 1]]}]),
}


@pytest.mark.parametrize("case", sorted(BAD_CAMERAS))
def test_a_bad_discovered_cameras_json_is_only_a_warning(tmp_path, case):
    scene = small_ply(tmp_path / "scene.ply")
    (tmp_path / "cameras.json").write_text(BAD_CAMERAS[case], encoding="utf-8")
    loaded = load_now(SceneSource(scene))
    assert loaded.scene.count == 5
    assert loaded.cameras == [] and loaded.camera_names == [] and loaded.cameras_path is None
    assert len(loaded.warnings) == 1
    warning = loaded.warnings[0]
    assert warning.startswith("training cameras skipped: ") and "cameras.json" in warning
    assert "\n" not in warning


@pytest.mark.parametrize("case", sorted(BAD_CAMERAS))
def test_a_bad_explicit_cameras_json_is_an_error(tmp_path, case, scene_loader):
    scene = small_ply(tmp_path / "scene.ply")
    explicit = tmp_path / "mine.json"
    explicit.write_text(BAD_CAMERAS[case], encoding="utf-8")
    testkit.assert_user_error(lambda: load_now(SceneSource(scene, explicit)), explicit)
    scene_loader.start(SceneSource(str(scene), str(explicit)))
    error = scene_loader.wait(DEADLOCK)
    assert isinstance(error, UserError)
    testkit.assert_user_error(lambda: _raise(error), explicit)


def test_a_missing_explicit_cameras_json_is_an_error(tmp_path):
    scene = small_ply(tmp_path / "scene.ply")
    testkit.assert_user_error(lambda: load_now(SceneSource(scene, tmp_path / "gone.json")), "gone.json", "no such file")


def test_explicit_cameras_replace_the_discovered_ones(tmp_path):
    scene = small_ply(tmp_path / "scene.ply")
    write_cameras(tmp_path / "cameras.json", demo_cameras_json())
    explicit = write_cameras(tmp_path / "two.json", demo_cameras_json()[2:4])
    loaded = load_now(SceneSource(scene, str(explicit)))
    assert loaded.cameras_path == str(explicit)
    assert loaded.camera_names == ["through-the-sheets", "high-behind"] and len(loaded.cameras) == 2


def test_dropped_gaussians_are_warnings(tmp_path):
    cols = gaussian_columns(4, 1)
    cols["x"][1] = np.nan
    loaded = load_now(SceneSource(write_ply(tmp_path / "nan.ply", cols)))
    assert loaded.scene.count == 3
    assert loaded.warnings == ["dropped 1 gaussian: nan"]


def test_sha256_is_the_files(tmp_path):
    scene = small_ply(tmp_path / "scene.ply", n=40)
    expected = hashlib.sha256(scene.read_bytes()).hexdigest()
    assert load_now(SceneSource(scene)).sha256 == expected
    calls = []
    assert file_sha256(scene, lambda f, s: calls.append((f, s)), chunk_bytes=100) == expected  # many reads, one buffer
    size = scene.stat().st_size
    assert len(calls) == -(-size // 100) and calls[-1] == (1.0, "hashing")
    assert [f for f, _ in calls] == sorted(f for f, _ in calls)
    splat = tmp_path / "scene.splat"
    splat.write_bytes(bytes(range(64)))
    assert load_now(SceneSource(splat)).sha256 == hashlib.sha256(bytes(range(64))).hexdigest()


def test_hash_read_failure_is_a_user_error(tmp_path):
    testkit.assert_user_error(lambda: file_sha256(tmp_path), tmp_path, "folder")


def test_progress_is_monotone_and_ends_at_done(tmp_path, monkeypatch):
    scene = small_ply(tmp_path / "scene.ply", n=30)
    monkeypatch.setattr(content_hash, "HASH_CHUNK_BYTES", 500)
    calls = []
    load_now(SceneSource(scene), progress=lambda f, s: calls.append((f, s)),
             read_scene=functools.partial(load_scene, chunk_bytes=200))
    fractions = [f for f, _ in calls]
    assert fractions == sorted(fractions) and 0.0 <= fractions[0] and fractions[-1] == 1.0
    assert calls[-1] == (1.0, "done") and [s for _, s in calls].count("done") == 1
    stages = [s for _, s in calls]
    assert stages.count("reading") > 5 and stages.count("hashing") >= 1


class SteeredHash:
    """Stands in for file_sha256 in load_now's hashing thread: reports half way, then
    waits for ``gate`` (or its stop event) before hashing for real."""

    def __init__(self) -> None:
        self.started = threading.Event()
        self.gate = threading.Event()
        self.stopped = threading.Event()

    def __call__(self, path, progress=None, cancel=None, **kwargs):
        self.started.set()
        progress(0.5, "hashing")
        while not self.gate.wait(0.01):
            if cancel.is_set():
                self.stopped.set()
                raise UserError("loading cancelled")
        return file_sha256(path, progress, cancel, **kwargs)


def test_the_hash_runs_beside_the_read(tmp_path, monkeypatch):
    """The read waits here until the hash has started: a hash run after the read never starts."""
    scene = small_ply(tmp_path / "scene.ply")
    hashing = SteeredHash()
    hashing.gate.set()
    monkeypatch.setattr(content_hash, "file_sha256", hashing)

    def read_scene(path, **kwargs):
        assert hashing.started.wait(DEADLOCK), "the hash did not start before the scene was read"
        return load_scene(path, **kwargs)

    loaded = load_now(SceneSource(scene), read_scene=read_scene)
    assert loaded.sha256 == hashlib.sha256(scene.read_bytes()).hexdigest()


def test_a_hash_still_running_after_the_read_reports_its_progress(tmp_path, monkeypatch):
    scene = small_ply(tmp_path / "scene.ply")
    hashing = SteeredHash()
    monkeypatch.setattr(content_hash, "file_sha256", hashing)
    calls = []

    def progress(fraction, stage):
        calls.append((fraction, stage))
        if [s for _, s in calls].count("hashing") == 4:  # the read is done; the hash still waits
            hashing.gate.set()

    loaded = load_now(SceneSource(scene), progress=progress)
    assert loaded.sha256 == hashlib.sha256(scene.read_bytes()).hexdigest()
    hashed = [f for f, s in calls if s == "hashing"]
    assert len(hashed) >= 4 and 0.85 < hashed[1] < hashed[-1] <= 0.98, calls  # 0.85 + 0.13 * 0.5, then 1
    assert [f for f, _ in calls] == sorted(f for f, _ in calls) and calls[-1] == (1.0, "done")


@pytest.mark.parametrize("how", ["read fails", "cancelled while hashing"])
def test_a_failed_or_cancelled_load_stops_its_hash(tmp_path, monkeypatch, how):
    scene = small_ply(tmp_path / "scene.ply")
    hashing = SteeredHash()
    monkeypatch.setattr(content_hash, "file_sha256", hashing)
    cancel = threading.Event()

    def read_scene(path, **kwargs):
        if how == "read fails":
            raise UserError(f"{path}: broken")
        return load_scene(path, **kwargs)

    def progress(fraction, stage):
        if stage == "hashing" and fraction > 0.85:
            cancel.set()

    with pytest.raises(UserError, match="broken" if how == "read fails" else "^loading cancelled$"):
        load_now(SceneSource(scene), progress=progress, cancel=cancel, read_scene=read_scene)
    assert hashing.stopped.wait(DEADLOCK), "the hash kept running"


def test_a_hash_that_fails_after_a_good_read_is_the_error(tmp_path, monkeypatch):
    scene = small_ply(tmp_path / "scene.ply")

    def failing_hash(path, *args, **kwargs):
        raise UserError(f"{path}: cannot read: Input/output error")

    monkeypatch.setattr(content_hash, "file_sha256", failing_hash)
    testkit.assert_user_error(lambda: load_now(SceneSource(scene)), scene, "Input/output error")


def test_cancel_stops_load_now(tmp_path):
    scene = small_ply(tmp_path / "scene.ply")
    cancel = threading.Event()
    cancel.set()
    with pytest.raises(UserError, match="^loading cancelled$"):
        load_now(SceneSource(scene), cancel=cancel)
    with pytest.raises(UserError, match="^loading cancelled$"):
        load_now(SceneSource.demo(), cancel=cancel)


# --------------------------------------------------------------------------- the demo


def test_the_demo_loads_with_its_six_cameras():
    loaded = load_now(SceneSource.demo())
    assert loaded.path == "demo" and loaded.scene.source == "demo"
    assert len(loaded.cameras) == 6 and loaded.camera_names == list(DEMO_VIEW_NAMES)
    assert loaded.cameras_path is None and loaded.warnings == []
    for got, expected in zip(loaded.cameras, demo_cameras()):
        np.testing.assert_array_equal(got.R, expected.R)
    digest = hashlib.sha256()
    for name in ("positions", "rotations", "scales", "opacities", "sh"):
        digest.update(getattr(loaded.scene, name).astype(np.float32).tobytes())
    assert loaded.sha256 == digest.hexdigest() == arrays_sha256(demo_scene())


def test_arrays_sha256_covers_every_array():
    scene = demo_scene()
    base = arrays_sha256(scene)
    for name in ("positions", "rotations", "scales", "opacities", "sh"):
        array = getattr(scene, name).copy()
        array.reshape(-1)[-1] += np.float32(1.0)
        changed = type(scene)(**{**scene.__dict__, name: array})
        assert arrays_sha256(changed) != base, name


def test_explicit_cameras_replace_the_demo_views(tmp_path):
    explicit = write_cameras(tmp_path / "one.json", demo_cameras_json()[5])
    loaded = load_now(SceneSource.demo(explicit))
    assert loaded.camera_names == ["grazing-floor"] and loaded.cameras_path == str(explicit)


# --------------------------------------------------------------------------- SceneLoader


def _raise(error: BaseException):
    raise error


def test_background_load_delivers_once_with_progress_at_one(tmp_path, scene_loader):
    scene = small_ply(tmp_path / "scene.ply")
    assert not scene_loader.busy and scene_loader.poll() is None and scene_loader.wait() is None
    scene_loader.start(SceneSource(str(scene)))
    loaded = scene_loader.wait(DEADLOCK)
    assert isinstance(loaded, LoadedScene) and loaded.scene.count == 5
    assert scene_loader.progress == 1.0 and scene_loader.stage == "done" and not scene_loader.busy
    assert scene_loader.poll() is None and scene_loader.wait(DEADLOCK) is None  # once only
    assert scene_loader.delivered == 1 and scene_loader.discarded == 0


def test_the_demo_loads_in_the_background(scene_loader):
    scene_loader.start(SceneSource.demo())
    loaded = scene_loader.wait(DEADLOCK)
    assert isinstance(loaded, LoadedScene) and len(loaded.cameras) == 6


@pytest.mark.parametrize("damage, fragment", [("garbage_header", "end_header"), ("truncated", "truncated")])
def test_a_corrupt_ply_is_a_one_line_error_from_poll(tmp_path, scene_loader, damage, fragment):
    path = tmp_path / "corrupt.ply"
    if damage == "garbage_header":
        path.write_bytes(b"ply\nformat binary_little_endian 1.0\n\xff\xfe garbage")
    else:
        path.write_bytes(small_ply(tmp_path / "whole.ply").read_bytes()[:-9])
    scene_loader.start(SceneSource(str(path)))
    assert scene_loader.join(DEADLOCK)
    error = scene_loader.poll()
    assert isinstance(error, UserError) and not scene_loader.busy
    message = testkit.assert_user_error(lambda: _raise(error), path, fragment)
    assert message.startswith(str(path))
    assert scene_loader.poll() is None


class SteeredLoad:
    """Stands in for the loader's read_scene: loads of "slow.ply" stop after their first progress
    report until the test says so; everything else loads for real."""

    def __init__(self, real, honour_cancel: bool) -> None:
        self.real = real
        self.honour_cancel = honour_cancel
        self.entered = threading.Event()
        self.gate = threading.Event()
        self.saw_cancel = threading.Event()

    def __call__(self, source, *, progress=None, cancel=None, **options):
        if Path(source.path).name != "slow.ply":
            return self.real(source, progress=progress, cancel=cancel, **options)
        progress(0.5, "reading")
        self.entered.set()
        if self.honour_cancel:
            assert cancel.wait(DEADLOCK), "the loader never cancelled the old load"
            self.saw_cancel.set()
            raise UserError("loading cancelled")
        assert self.gate.wait(DEADLOCK), "the test never released the slow load"
        progress(0.9, "activating")  # a stale load must not move the new one's progress
        return self.real(source, progress=progress, cancel=None, **options)


@pytest.fixture
def steered(scene_loader):
    def install(honour_cancel: bool) -> SteeredLoad:
        fake = SteeredLoad(load_scene, honour_cancel)
        scene_loader.read_scene = fake
        return fake
    return install


def test_a_new_start_cancels_and_discards_the_load_in_progress(tmp_path, steered, scene_loader):
    fake = steered(honour_cancel=True)
    slow, good = small_ply(tmp_path / "slow.ply", n=3), small_ply(tmp_path / "good.ply", n=7)
    scene_loader.start(SceneSource(str(slow)))
    assert fake.entered.wait(DEADLOCK)
    assert scene_loader.busy and scene_loader.stage == "reading"
    assert 0.0 < scene_loader.progress < 1.0
    scene_loader.start(SceneSource(str(good)))
    loaded = scene_loader.wait(DEADLOCK)
    assert fake.saw_cancel.wait(DEADLOCK)  # the old thread was told to stop
    assert isinstance(loaded, LoadedScene) and loaded.path == str(good) and loaded.scene.count == 7
    assert scene_loader.join(DEADLOCK)
    assert scene_loader.poll() is None  # the cancelled load's "loading cancelled" never shows
    assert (scene_loader.started, scene_loader.delivered, scene_loader.discarded) == (2, 1, 1)


def test_a_replaced_load_that_finishes_late_is_never_delivered(tmp_path, steered, scene_loader):
    fake = steered(honour_cancel=False)
    slow, good = small_ply(tmp_path / "slow.ply", n=3), small_ply(tmp_path / "good.ply", n=7)
    scene_loader.start(SceneSource(str(slow)))
    assert fake.entered.wait(DEADLOCK)
    scene_loader.start(SceneSource(str(good)))
    loaded = scene_loader.wait(DEADLOCK)
    assert loaded.path == str(good)
    fake.gate.set()  # the old load now completes successfully...
    assert scene_loader.join(DEADLOCK)
    assert scene_loader.poll() is None  # ...and its scene is dropped
    assert scene_loader.progress == 1.0 and scene_loader.stage == "done"
    assert scene_loader.discarded == 1


def test_cancel_and_close_do_not_wait_for_the_load(tmp_path, steered, scene_loader):
    fake = steered(honour_cancel=False)
    slow = small_ply(tmp_path / "slow.ply")
    scene_loader.start(SceneSource(str(slow)))
    assert fake.entered.wait(DEADLOCK)
    scene_loader.cancel()
    assert not scene_loader.busy and scene_loader.wait(DEADLOCK) is None
    scene_loader.start(SceneSource(str(slow)))
    scene_loader.close()  # returns with both slow loads still blocked
    assert not fake.gate.is_set()
    with pytest.raises(RuntimeError):
        scene_loader.start(SceneSource(str(slow)))
    fake.gate.set()
    assert scene_loader.join(DEADLOCK)
    assert scene_loader.poll() is None and scene_loader.discarded == 2


@pytest.mark.parametrize("exc, fragment", [
    (RuntimeError("boom\nsecond line"), "loading failed (RuntimeError: boom second line)"),
    (MemoryError(), "not enough memory"),
    (OSError(5, "Input/output error"), "cannot read: Input/output error"),
])
def test_unexpected_exceptions_become_one_line_errors(tmp_path, scene_loader, exc, fragment):
    def failing_load(path, **kwargs):
        raise exc

    scene_loader.read_scene = failing_load
    path = small_ply(tmp_path / "scene.ply")
    scene_loader.start(SceneSource(str(path)))
    error = scene_loader.wait(DEADLOCK)
    assert isinstance(error, UserError)
    testkit.assert_user_error(lambda: _raise(error), path, fragment)


def test_a_finished_result_not_yet_polled_is_dropped_by_a_new_start(tmp_path, steered, scene_loader):
    fake = steered(honour_cancel=True)
    good, slow = small_ply(tmp_path / "good.ply"), small_ply(tmp_path / "slow.ply")
    scene_loader.start(SceneSource(str(good)))
    assert scene_loader.join(DEADLOCK) and not scene_loader.busy  # finished, not polled
    scene_loader.start(SceneSource(str(slow)))
    assert fake.entered.wait(DEADLOCK)
    assert scene_loader.poll() is None  # the good scene is not shown over the newer request
    assert scene_loader.discarded == 1
    scene_loader.cancel()
