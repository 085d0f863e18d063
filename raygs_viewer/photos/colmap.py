"""COLMAP sparse models (sparse/0 or sparse/, binary or text), the layout of
scripts/python/read_write_model.py: only the pinhole models are read, since a render has
no lens distortion to compare with a distorted photo.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.errors import UserError, one_line

#: COLMAP's camera models by id: (name, parameter count), as read_write_model.py lists them.
MODELS = {0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4), 3: ("RADIAL", 5),
          4: ("OPENCV", 8), 5: ("OPENCV_FISHEYE", 8), 6: ("FULL_OPENCV", 12), 7: ("FOV", 5),
          8: ("SIMPLE_RADIAL_FISHEYE", 4), 9: ("RADIAL_FISHEYE", 5), 10: ("THIN_PRISM_FISHEYE", 12),
          11: ("RAD_TAN_THIN_PRISM_FISHEYE", 16)}
PARAMETER_COUNTS = dict(MODELS.values())
#: The most pixels along a side a camera may have (as cameras.json's reader allows).
MAX_SIDE = 65536


def sparse_folder(folder: Path) -> Path | None:
    """The folder holding the model's cameras and images files: sparse/0, sparse, or
    ``folder`` itself; None when there is none."""
    for candidate in (folder / "sparse" / "0", folder / "sparse", folder):
        for suffix in (".bin", ".txt"):
            if (candidate / f"cameras{suffix}").is_file() and (candidate / f"images{suffix}").is_file():
                return candidate
    return None


def read_colmap(sparse: Path) -> list[tuple[str, Camera]]:
    """(image name, camera in OpenCV axes) of every registered image in ``sparse``; the
    binary files when both kinds are present (COLMAP writes those)."""
    binary = (sparse / "cameras.bin").is_file() and (sparse / "images.bin").is_file()
    cameras_path, images_path = (sparse / f"cameras.{'bin' if binary else 'txt'}",
                                 sparse / f"images.{'bin' if binary else 'txt'}")
    try:
        cameras_data, images_data = cameras_path.read_bytes(), images_path.read_bytes()
    except OSError as exc:
        raise UserError(f"{exc.filename}: cannot read: {exc.strerror or one_line(exc)}") from None
    if binary:
        intrinsics = _binary_cameras(cameras_path, cameras_data)
        images = _binary_images(images_path, images_data)
    else:
        intrinsics = _text_cameras(cameras_path, _text(cameras_path, cameras_data))
        images = _text_images(images_path, _text(images_path, images_data))
    views = []
    for name, camera_id, qvec, tvec in images:
        if camera_id not in intrinsics:
            raise UserError(f"{images_path}: image {name!r} names camera {camera_id}, which {cameras_path.name} lacks")
        width, height, fx, fy, cx, cy = intrinsics[camera_id]
        # COLMAP's (w, x, y, z), normalised first: text files round it.
        rotation = quaternion_to_matrix((qvec / np.linalg.norm(qvec))[None])[0]
        views.append((name, Camera(width, height, fx, fy, cx, cy, rotation, tvec)))
    if not views:
        raise UserError(f"{images_path}: holds no images")
    return views


def _intrinsics(path: Path, camera_id: int, model: str, size: tuple, params) -> tuple:
    """(width, height, fx, fy, cx, cy) of one camera of ``size`` (width, height) and the
    ``model``'s ``params``; UserError for a model with distortion."""
    width, height = size
    if model not in ("SIMPLE_PINHOLE", "PINHOLE"):
        raise UserError(f"{path}: camera {camera_id} uses the {model} model, which has lens distortion; only "
                        f"PINHOLE and SIMPLE_PINHOLE are read (undistort first: colmap image_undistorter)")
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE):
        raise UserError(f"{path}: camera {camera_id} has a size of {width}x{height}")
    fx, fy, cx, cy = (params[0], params[0], params[1], params[2]) if model == "SIMPLE_PINHOLE" else params
    if not all(math.isfinite(p) for p in params) or fx <= 0 or fy <= 0:
        raise UserError(f"{path}: camera {camera_id} has focal lengths that are not positive finite numbers")
    return int(width), int(height), float(fx), float(fy), float(cx), float(cy)


def _pose(path: Path, name: str, values) -> tuple[np.ndarray, np.ndarray]:
    qvec, tvec = np.array(values[:4], np.float64), np.array(values[4:], np.float64)
    if not (np.all(np.isfinite(qvec)) and np.all(np.isfinite(tvec))) or np.linalg.norm(qvec) < 1e-6:
        raise UserError(f"{path}: image {name!r} has a pose that is not a finite rotation and translation")
    return qvec, tvec


# --------------------------------------------------------------------------- binary


class _Reader:
    """Little-endian values read in order from ``data``; UserError naming ``path`` past its end."""

    def __init__(self, path: Path, data: bytes):
        self.path, self.data, self.offset = path, data, 0

    def read(self, fmt: str) -> tuple:
        size = struct.calcsize("<" + fmt)
        if self.offset + size > len(self.data):
            raise UserError(f"{self.path}: ends early (truncated, or not a COLMAP {self.path.name})")
        values = struct.unpack_from("<" + fmt, self.data, self.offset)
        self.offset += size
        return values

    def skip(self, size: int) -> None:
        if self.offset + size > len(self.data):
            raise UserError(f"{self.path}: ends early (truncated, or not a COLMAP {self.path.name})")
        self.offset += size

    def name(self) -> str:
        end = self.data.find(b"\0", self.offset)
        if end < 0:
            raise UserError(f"{self.path}: ends early (truncated, or not a COLMAP {self.path.name})")
        raw, self.offset = self.data[self.offset:end], end + 1
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            raise UserError(f"{self.path}: an image name is not UTF-8 text") from None


def _binary_cameras(path: Path, data: bytes) -> dict[int, tuple]:
    reader, cameras = _Reader(path, data), {}
    (count,) = reader.read("Q")
    for _ in range(count):
        camera_id, model_id, width, height = reader.read("iiQQ")
        if model_id not in MODELS:
            raise UserError(f"{path}: camera {camera_id} has an unknown model id {model_id}")
        model, n = MODELS[model_id]
        cameras[camera_id] = _intrinsics(path, camera_id, model, (width, height), reader.read(f"{n}d"))
    return cameras


def _binary_images(path: Path, data: bytes) -> list[tuple]:
    reader, images = _Reader(path, data), []
    (count,) = reader.read("Q")
    for _ in range(count):
        values = reader.read("i7di")
        name = reader.name()
        (points,) = reader.read("Q")
        reader.skip(24 * points)  # (x, y, point3D_id) per observation, unused here
        images.append((name, values[8], *_pose(path, name, values[1:8])))
    return images


# --------------------------------------------------------------------------- text


def _text(path: Path, data: bytes) -> list[str]:
    try:
        return data.decode("utf-8").splitlines()
    except UnicodeDecodeError:
        raise UserError(f"{path}: not UTF-8 text") from None


def _numbers(path: Path, line_number: int, fields: list[str], kind) -> list:
    try:
        return [kind(f) for f in fields]
    except ValueError:
        raise UserError(f"{path}: line {line_number}: expected numbers, got {' '.join(fields)[:60]!r}") from None


def _text_cameras(path: Path, lines: list[str]) -> dict[int, tuple]:
    cameras = {}
    for number, line in enumerate(lines, 1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        if len(fields) < 4 or fields[1] not in PARAMETER_COUNTS:
            raise UserError(f"{path}: line {number}: expected 'CAMERA_ID MODEL WIDTH HEIGHT PARAMS...' with a COLMAP "
                            f"model, got {line.strip()[:60]!r}")
        model, count = fields[1], PARAMETER_COUNTS[fields[1]]
        if len(fields) != 4 + count:
            raise UserError(f"{path}: line {number}: the {model} model has {count} parameters, got {len(fields) - 4}")
        camera_id, width, height = _numbers(path, number, [fields[0], fields[2], fields[3]], int)
        cameras[camera_id] = _intrinsics(path, camera_id, model, (width, height),
                                         _numbers(path, number, fields[4:], float))
    return cameras


def _text_images(path: Path, lines: list[str]) -> list[tuple]:
    # Two lines an image; the second (the observed points) may be empty, so it is taken
    # whatever it holds, as read_write_model.py does.
    images, number = [], 0
    while number < len(lines):
        line, number = lines[number], number + 1
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        if len(fields) < 10:
            raise UserError(f"{path}: line {number}: expected 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME', "
                            f"got {line.strip()[:60]!r}")
        values = _numbers(path, number, fields[1:8], float)
        (camera_id,) = _numbers(path, number, fields[8:9], int)
        # A name may hold spaces: everything after CAMERA_ID.
        name = line.strip().split(maxsplit=9)[9]
        images.append((name, camera_id, *_pose(path, name, values)))
        number += 1
    return images
