"""photos.dataset: the three layouts, built on the fly by datasets_kit, read back to the
cameras and photos they were made from; the split, alpha, resizing and bad input."""

from __future__ import annotations

import shutil
import struct

import numpy as np
import pytest
from datasets_kit import cfg_args_text, write_dataset, write_photo
from PIL import Image
from testkit import assert_user_error, random_rotation, random_scene

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.photos.dataset import (
    SPLITS,
    TEST_EVERY,
    load_photo,
    open_dataset,
    select_split,
)

W, H = 32, 24
LAYOUTS = [("inria", False), ("colmap", False), ("colmap", True), ("nerfstudio", False)]


def cameras(n, seed=0, centred=False):
    """``n`` cameras of W x H at random poses and intrinsics (off-centre unless ``centred``)."""
    rng = np.random.default_rng(seed)
    made = []
    for _ in range(n):
        R = random_rotation(rng)
        fx = rng.uniform(20, 40)
        cx, cy = (W / 2, H / 2) if centred else (rng.uniform(12, 20), rng.uniform(9, 15))
        made.append(Camera(W, H, fx, fx * rng.uniform(0.9, 1.1), cx, cy, R, rng.uniform(-3, 3, 3)))
    return made


def photos(n, seed=0, size=(H, W), channels=3):
    rng = np.random.default_rng(seed)
    # Whole 8-bit levels, so what is written is exactly what is read back.
    return [np.rint(rng.uniform(0, 1, (*size, channels)) * 255) / 255 for _ in range(n)]


def shuffled_names(n):
    # Written out of name order: the views must come back sorted by name.
    return [f"img_{i:02d}" for i in np.random.default_rng(1).permutation(n)]


@pytest.mark.parametrize("layout, text", LAYOUTS)
def test_layout_reads_back_its_cameras_and_photos(tmp_path, layout, text):
    n = 10
    cams, pics, names = cameras(n), photos(n), shuffled_names(n)
    path = write_dataset(tmp_path, layout, cams, pics, names, text=text)
    dataset = open_dataset(path)
    assert dataset.layout == layout and len(dataset.views) == n
    by_name = {name: (c, p) for name, c, p in zip(names, cams, pics)}
    view_names = [v.name for v in dataset.views]
    assert view_names == sorted(view_names) and [v.index for v in dataset.views] == list(range(n))
    for view in dataset.views:
        stem = view.name.split("/")[-1].split(".")[0]
        camera, photo = by_name[stem]
        got = view.camera
        assert (got.width, got.height) == (W, H)
        assert np.allclose([got.fx, got.fy, got.cx, got.cy], [camera.fx, camera.fy, camera.cx, camera.cy],
                           rtol=0, atol=1e-9)
        assert np.abs(got.R - camera.R).max() < 1e-6 and np.abs(got.t - camera.t).max() < 1e-6
        loaded = load_photo(view, dataset.background)
        assert loaded.shape == (H, W, 3) and loaded.dtype == np.float32
        assert np.abs(loaded - photo).max() < 1e-6


def test_split_every_eighth_view_is_a_test_view(tmp_path):
    n = 17
    dataset = open_dataset(write_dataset(tmp_path, "colmap", cameras(n), photos(n)))
    assert [v.index for v in select_split(dataset.views, "test")] == [0, 8, 16] == list(range(0, n, TEST_EVERY))
    train = select_split(dataset.views, "train")
    assert len(train) == n - 3 and all(v.index % 8 for v in train)
    assert select_split(dataset.views, "all") == dataset.views and "all" in SPLITS
    assert_user_error(lambda: select_split(dataset.views, "val"), "val", "test, train, all")


@pytest.mark.parametrize("background", [(0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (0.2, 0.5, 0.9)])
def test_rgba_photos_are_composited_over_the_background(tmp_path, background):
    pics = photos(2, channels=4)
    pics[0][0, 0, 3] = 0.0  # one fully transparent pixel: the background alone
    dataset = open_dataset(write_dataset(tmp_path, "nerfstudio", cameras(2), pics))
    loaded = load_photo(dataset.views[0], background)
    rgb, alpha = pics[0][..., :3], pics[0][..., 3:]
    assert np.abs(loaded - (rgb * alpha + np.asarray(background) * (1 - alpha))).max() < 1e-5
    assert np.allclose(loaded[0, 0], background)


def test_inria_cfg_args_white_background_and_highest_iteration(tmp_path):
    model = write_dataset(tmp_path, "inria", cameras(3, centred=True), photos(3), scene=random_scene(5),
                          white_background=True)
    for iteration in (500, 30000):  # numerically highest, not by text (iteration_7000 > iteration_30000)
        (model / "point_cloud" / f"iteration_{iteration}").mkdir()
        shutil.copy(model / "point_cloud" / "iteration_7000" / "point_cloud.ply",
                    model / "point_cloud" / f"iteration_{iteration}" / "point_cloud.ply")
    (model / "point_cloud" / "iteration_90000").mkdir()  # no point_cloud.ply in it: not a model
    dataset = open_dataset(model)
    assert dataset.background == (1.0, 1.0, 1.0)
    assert dataset.scene_path == model / "point_cloud" / "iteration_30000" / "point_cloud.ply"
    (model / "cfg_args").write_text(cfg_args_text(tmp_path / "source"))
    assert open_dataset(model).background == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("text", ["__import__('os').system('echo hi')", "Namespace(x=open('f'))", "Namespace(",
                                  "[1, 2]"])
def test_cfg_args_is_read_as_literals_only(tmp_path, text):
    model = write_dataset(tmp_path, "inria", cameras(2, centred=True), photos(2))
    (model / "cfg_args").write_text(text)
    assert_user_error(lambda: open_dataset(model), "cfg_args", "cfg_args")


def test_inria_without_source_asks_for_images(tmp_path):
    pics = photos(2)
    model = write_dataset(tmp_path, "inria", cameras(2, centred=True), pics)
    (model / "cfg_args").unlink()
    assert_user_error(lambda: open_dataset(model), "cfg_args", "--images")
    dataset = open_dataset(model, images=tmp_path / "source" / "images")
    assert np.abs(load_photo(dataset.views[1], dataset.background) - pics[1]).max() < 1e-6


def test_inria_takes_the_downscaled_folder_nearest_the_camera(tmp_path):
    cams = cameras(2, centred=True)
    model = write_dataset(tmp_path, "inria", cams, photos(2, size=(2 * H, 2 * W)))
    source = tmp_path / "source"
    (source / "images").rename(source / "images_4")  # cfg_args' images/ gone: the nearest size is taken
    small = photos(2, seed=5)
    for name, pic in zip(["view_000", "view_001"], small):
        write_photo(source / "images_2" / f"{name}.png", pic)
    dataset = open_dataset(model)
    assert dataset.views[0].image_path == source / "images_2" / "view_000.png"
    assert np.abs(load_photo(dataset.views[0], dataset.background) - small[0]).max() < 1e-6


@pytest.mark.parametrize("layout", ["inria", "colmap", "nerfstudio"])
def test_a_photo_twice_the_camera_size_is_resized_as_the_inria_loader_does(tmp_path, layout):
    cams = cameras(2, centred=layout == "inria")
    path = write_dataset(tmp_path, layout, cams, photos(2, size=(2 * H, 2 * W)))
    dataset = open_dataset(path)
    view = dataset.views[1]
    assert (view.camera.width, view.camera.height) == (W, H)
    loaded = load_photo(view, dataset.background)
    # Independently: Pillow's default resize of the 8-bit file, as INRIA's PILtoTorch calls it.
    with Image.open(view.image_path) as image:
        expected = np.asarray(image.convert("RGB").resize((W, H)), np.float32) / 255
    assert loaded.shape == (H, W, 3) and np.array_equal(loaded, expected)


def test_a_smaller_photo_sets_the_compared_size(tmp_path):
    cams = cameras(2)
    dataset = open_dataset(write_dataset(tmp_path, "colmap", cams, photos(2, size=(H // 2, W // 2))))
    got, expected = dataset.views[0].camera, cams[0].resized(W // 2, H // 2)
    assert (got.width, got.height) == (W // 2, H // 2)
    assert np.allclose([got.fx, got.fy, got.cx, got.cy], [expected.fx, expected.fy, expected.cx, expected.cy])
    assert load_photo(dataset.views[0], (0, 0, 0)).shape == (H // 2, W // 2, 3)


def test_inria_resolution_halves_the_compared_size(tmp_path):
    cams = cameras(2, centred=True)
    model = write_dataset(tmp_path, "inria", cams, photos(2), resolution=2)
    view = open_dataset(model).views[0]
    assert (view.camera.width, view.camera.height) == (W // 2, H // 2)
    assert np.isclose(view.camera.fx, cams[0].fx / 2) and np.abs(view.camera.R - cams[0].R).max() < 1e-6
    assert load_photo(view, (0, 0, 0)).shape == (H // 2, W // 2, 3)


@pytest.mark.parametrize("layout", ["inria", "colmap", "nerfstudio"])
def test_a_missing_photo_is_one_line_naming_it(tmp_path, layout):
    path = write_dataset(tmp_path, layout, cameras(3, centred=True), photos(3))
    victim = next(tmp_path.rglob("view_001.png"))
    victim.unlink()
    dataset = open_dataset(path)
    assert dataset.views[1].image_path is None
    # INRIA names the stem: which suffix was meant is not known.
    named = victim.with_suffix("") if layout == "inria" else victim
    message = assert_user_error(lambda: load_photo(dataset.views[1], (0, 0, 0)), named, "no such photo")
    assert str(named) in message
    load_photo(dataset.views[2], (0, 0, 0))  # the others still load


def test_an_unreadable_photo_or_wrong_aspect_is_one_line_naming_it(tmp_path):
    path = write_dataset(tmp_path, "colmap", cameras(3), photos(2) + photos(1, size=(H, H)))
    bad = tmp_path / "images" / "view_001.png"
    bad.write_bytes(b"not a png")
    dataset = open_dataset(path)
    assert_user_error(lambda: load_photo(dataset.views[1], (0, 0, 0)), bad, "cannot read the photo")
    assert_user_error(lambda: load_photo(dataset.views[2], (0, 0, 0)), "view_002.png", "aspect ratio", "24x24")


@pytest.mark.parametrize("model, text", [("OPENCV", False), ("SIMPLE_RADIAL", True), ("OPENCV_FISHEYE", False)])
def test_colmap_refuses_camera_models_with_distortion(tmp_path, model, text):
    path = write_dataset(tmp_path, "colmap", cameras(2), photos(2), text=text, model=model)
    assert_user_error(lambda: open_dataset(path), "cameras.txt" if text else "cameras.bin", model,
                      "colmap image_undistorter")


def test_colmap_simple_pinhole_and_bad_files(tmp_path):
    cams = [Camera(W, H, 25.0, 25.0, 15.5, 11.0, c.R, c.t) for c in cameras(2)]
    path = write_dataset(tmp_path, "colmap", cams, photos(2), text=True, model="SIMPLE_PINHOLE")
    assert open_dataset(path).views[1].camera.fy == 25.0
    path = write_dataset(tmp_path / "b", "colmap", cams, photos(2))
    images = path / "sparse" / "0" / "images.bin"
    images.write_bytes(images.read_bytes()[:-10])
    assert_user_error(lambda: open_dataset(path), images, "ends early")
    cameras_bin = path / "sparse" / "0" / "cameras.bin"
    cameras_bin.write_bytes(struct.pack("<QiiQQ", 1, 1, 99, W, H))
    assert_user_error(lambda: open_dataset(path), cameras_bin, "unknown model id 99")


def test_nerfstudio_refuses_distortion_and_bad_matrices(tmp_path):
    path = write_dataset(tmp_path, "nerfstudio", cameras(2), photos(2))
    original = path.read_text()
    path.write_text(original.replace('"camera_model": "OPENCV"', '"camera_model": "OPENCV", "k1": 0.1'))
    assert_user_error(lambda: open_dataset(path), path, "'k1'", "undistort")
    path.write_text(original.replace('"file_path"', '"file_pth"', 1))
    assert_user_error(lambda: open_dataset(path), path, "frames[0].file_path")
    path.write_text(original.replace("[0.0, 0.0, 0.0, 1.0]", "[0.0, 0.0, 0.0, 2.0]", 1))
    assert_user_error(lambda: open_dataset(path), path, "transform_matrix")
    path.write_text("{")
    assert_user_error(lambda: open_dataset(path), path, "not valid JSON")


def test_blender_transforms_with_camera_angle_only(tmp_path):
    write_photo(tmp_path / "train" / "r_0.png", photos(1)[0])
    (tmp_path / "transforms_train.json").write_text(
        '{"camera_angle_x": 1.0, "frames": [{"file_path": "./train/r_0", "transform_matrix": '
        '[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]}]}')
    view = open_dataset(tmp_path / "transforms_train.json").views[0]
    assert (view.camera.width, view.camera.height) == (W, H)
    assert np.isclose(view.camera.fx, 0.5 * W / np.tan(0.5))
    assert np.allclose(view.camera.center, [0, 0, 4]) and np.allclose(view.camera.R, np.diag([1, -1, -1]))
    assert view.image_path == tmp_path / "train" / "r_0.png"


def test_not_a_dataset(tmp_path):
    assert_user_error(lambda: open_dataset(tmp_path), tmp_path, "not a dataset")
    assert_user_error(lambda: open_dataset(tmp_path / "nope"), "nope", "no such file or folder")
    assert_user_error(lambda: open_dataset(tmp_path, images=tmp_path / "pics"), "pics", "--images")
