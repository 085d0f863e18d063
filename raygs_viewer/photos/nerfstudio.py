"""nerfstudio's transforms.json (and the Blender/nerf-synthetic one it grew from): the
intrinsics at the top or per frame, each frame's photo and camera-to-world matrix in
OpenGL/Blender camera axes (x right, y up, z back)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import is_rotation
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import JsonFields, read_json_file, show_json

#: OpenCV camera axes from OpenGL ones: the y and z axes flip.
CV_FROM_GL = np.diag([1.0, -1.0, -1.0])
#: Models whose photos a pinhole render matches once the distortion terms are zero.
PINHOLE_MODELS = ("OPENCV", "PINHOLE", "SIMPLE_PINHOLE")
DISTORTION = ("k1", "k2", "k3", "k4", "p1", "p2")
#: As for cameras.json: the files are written with a few digits, re-orthonormalised on reading.
ROTATION_TOLERANCE = 1e-3


def read_transforms(path: Path, photo_size) -> list[tuple[str, Camera]]:
    """(file_path as written, camera in OpenCV axes) of each frame of the transforms.json
    ``path``. ``photo_size(file_path)`` -> (width, height) or None: the size of a frame's
    photo, for Blender files that give only camera_angle_x."""
    data = read_json_file(path, "a transforms.json file")
    if not isinstance(data, dict):
        raise UserError(f"{path}: must be a JSON object with 'frames'")
    top = JsonFields(path, data)
    model = top.optional("camera_model", str, "OPENCV")
    if model not in PINHOLE_MODELS:
        raise UserError(f"{path}: 'camera_model' {show_json(model)} is not a pinhole model (only "
                        f"{', '.join(PINHOLE_MODELS)} are read); undistort the photos first")
    frames = top.get("frames", list)
    if not frames:
        raise UserError(f"{path}: 'frames' is empty")
    views = []
    for index, entry in enumerate(frames):
        name = f"frames[{index}]"
        fields = JsonFields.entry(path, name, entry)
        file_path = fields.get(f"{name}.file_path", str)
        views.append((file_path, _camera(path, top, fields, name, photo_size=photo_size, file_path=file_path)))
    return views


def _camera(path: Path, top: JsonFields, fields: JsonFields, name: str, *, photo_size, file_path: str) -> Camera:
    """The camera of frame ``name`` (its ``fields``; the file's ``top`` ones where it has
    none), sized from its photo ``file_path`` by ``photo_size`` where neither gives w and h."""
    def value(key: str) -> float | None:
        # A frame's own value wins over the file's.
        frame_value = fields.optional(f"{name}.{key}", float)
        return frame_value if frame_value is not None else top.optional(key, float)

    for key in DISTORTION:
        term = value(key)
        if term:
            where = f"{name}.{key}" if fields.optional(f"{name}.{key}", float) is not None else key
            raise UserError(f"{path}: '{where}' is {term:g}: the photos have lens distortion; undistort them first")
    width, height = value("w"), value("h")
    if width is None or height is None:
        size = photo_size(file_path)
        if size is None:
            raise UserError(f"{path}: missing 'w' and 'h', and the photo of '{name}' cannot be read for its size")
        width, height = size
    if not (float(width).is_integer() and float(height).is_integer() and 1 <= width <= 65536 and 1 <= height <= 65536):
        raise UserError(f"{path}: '{name}' has a size of {width:g}x{height:g}: 'w' and 'h' must be whole numbers "
                        f"from 1 to 65536")
    fx, fy = value("fl_x"), value("fl_y")
    if fx is None:
        angle = value("camera_angle_x")
        if angle is None:
            raise UserError(f"{path}: '{name}' has no focal length ('fl_x' or 'camera_angle_x')")
        if not 0 < angle < math.pi:
            raise UserError(f"{path}: 'camera_angle_x' must be in (0, pi) radians, got {angle:g}")
        fx = 0.5 * width / math.tan(angle / 2)
    fy = fx if fy is None else fy
    if fx <= 0 or fy <= 0:
        raise UserError(f"{path}: '{name}' must have positive focal lengths, got {fx:g} and {fy:g}")
    cx, cy = value("cx"), value("cy")
    cx, cy = width / 2 if cx is None else cx, height / 2 if cy is None else cy
    matrix = fields.array(f"{name}.transform_matrix", (4, 4))
    if np.abs(matrix[3] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-6:
        raise UserError(f"{path}: '{name}.transform_matrix' must end in the row 0 0 0 1, "
                        f"got {show_json(matrix[3].tolist())}")
    if not is_rotation(matrix[:3, :3], ROTATION_TOLERANCE):
        raise UserError(f"{path}: '{name}.transform_matrix' is not a rotation and a translation "
                        f"(scaled, sheared or mirrored)")
    u, _, vt = np.linalg.svd(matrix[:3, :3])
    R = (u @ vt @ CV_FROM_GL).T  # world-to-camera in OpenCV axes
    return Camera(int(width), int(height), fx, fy, cx, cy, R, -R @ matrix[:3, 3])
