"""Datasets built on the fly for the photos tests: the three layouts users have (an INRIA
model folder, a COLMAP folder in binary or text, a nerfstudio transforms.json), written
from Camera objects and float images with writers independent of the readers in
raygs_viewer.photos (the COLMAP layout follows COLMAP's scripts/python/read_write_model.py).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
from PIL import Image

from raygs_viewer.camera.pinhole import Camera, camera_to_json
from raygs_viewer.jsonfile import json_text
from raygs_viewer.scene.writing import write_scene

#: COLMAP's camera model ids and parameter counts (read_write_model.py's CAMERA_MODELS).
COLMAP_MODELS = {"SIMPLE_PINHOLE": (0, 3), "PINHOLE": (1, 4), "SIMPLE_RADIAL": (2, 4), "RADIAL": (3, 5),
                 "OPENCV": (4, 8), "OPENCV_FISHEYE": (5, 8), "FULL_OPENCV": (6, 12), "FOV": (7, 5),
                 "SIMPLE_RADIAL_FISHEYE": (8, 4), "RADIAL_FISHEYE": (9, 5), "THIN_PRISM_FISHEYE": (10, 12)}
#: OpenCV camera axes (x right, y down, z forward) from OpenGL/Blender ones (x right, y up, z back).
FLIP_YZ = np.diag([1.0, -1.0, -1.0])


def default_names(count: int) -> list[str]:
    return [f"view_{i:03d}" for i in range(count)]


def write_photo(path: Path, photo: np.ndarray) -> Path:
    """``photo``: (H, W, 3) or (H, W, 4) float in 0..1, written as an 8-bit PNG (or JPEG by suffix)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = np.clip(np.rint(np.asarray(photo, np.float64) * 255), 0, 255).astype(np.uint8)
    Image.fromarray(data, "RGBA" if data.shape[2] == 4 else "RGB").save(path)
    return path


def quaternion_wxyz(R: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z) of the rotation ``R`` (Shepperd's method)."""
    R = np.asarray(R, np.float64)
    trace = np.trace(R)
    if trace > 0:
        s = 2 * np.sqrt(trace + 1)
        q = [s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2 * np.sqrt(1 + R[i, i] - R[j, j] - R[k, k])
        q = np.empty(4)
        q[0] = (R[k, j] - R[j, k]) / s
        q[1 + i] = s / 4
        q[1 + j] = (R[j, i] + R[i, j]) / s
        q[1 + k] = (R[k, i] + R[i, k]) / s
    q = np.asarray(q, np.float64)
    return q / np.linalg.norm(q)


def colmap_params(camera: Camera, model: str) -> list[float]:
    """The COLMAP parameter list of ``camera`` under ``model``; distortion terms zero."""
    if model == "SIMPLE_PINHOLE":
        return [camera.fx, camera.cx, camera.cy]
    if model == "PINHOLE":
        return [camera.fx, camera.fy, camera.cx, camera.cy]
    count = COLMAP_MODELS[model][1]
    if model in ("OPENCV", "OPENCV_FISHEYE", "FULL_OPENCV", "THIN_PRISM_FISHEYE"):
        return [camera.fx, camera.fy, camera.cx, camera.cy] + [0.0] * (count - 4)
    return [camera.fx, camera.cx, camera.cy] + [0.0] * (count - 3)


def write_colmap_model(sparse: Path, cameras: list[Camera], names: list[str], text: bool = False,
                       model: str = "PINHOLE") -> Path:
    """cameras.{bin,txt} and images.{bin,txt} in ``sparse`` (one COLMAP camera per view,
    ids from 1; two observed 2D points per image, so the points are skipped right)."""
    sparse.mkdir(parents=True, exist_ok=True)
    model_id, _ = COLMAP_MODELS[model]
    rows = [(i + 1, quaternion_wxyz(c.R), np.asarray(c.t, np.float64), i + 1, name)
            for i, (c, name) in enumerate(zip(cameras, names))]
    points = [(1.5, 2.5, -1), (3.25, 4.75, 7)]
    if text:
        lines = ["# Camera list with one line of data per camera:", f"# Number of cameras: {len(cameras)}"]
        lines += [f"{i + 1} {model} {c.width} {c.height} " + " ".join(repr(float(p)) for p in colmap_params(c, model))
                  for i, c in enumerate(cameras)]
        (sparse / "cameras.txt").write_text("\n".join(lines) + "\n")
        lines = ["# Image list with two lines of data per image:", f"# Number of images: {len(rows)}"]
        for image_id, q, t, camera_id, name in rows:
            lines.append(" ".join([str(image_id), *(repr(float(v)) for v in (*q, *t)), str(camera_id), name]))
            lines.append(" ".join(f"{x} {y} {p}" for x, y, p in points) if image_id % 2 else "")
        (sparse / "images.txt").write_text("\n".join(lines) + "\n")
        return sparse
    data = bytearray(struct.pack("<Q", len(cameras)))
    for i, c in enumerate(cameras):
        params = colmap_params(c, model)
        data += struct.pack("<iiQQ", i + 1, model_id, c.width, c.height)
        data += struct.pack(f"<{len(params)}d", *params)
    (sparse / "cameras.bin").write_bytes(bytes(data))
    data = bytearray(struct.pack("<Q", len(rows)))
    for image_id, q, t, camera_id, name in rows:
        data += struct.pack("<i7di", image_id, *q, *t, camera_id)
        data += name.encode("utf-8") + b"\0"
        data += struct.pack("<Q", len(points))
        for x, y, p in points:
            data += struct.pack("<ddq", x, y, p)
    (sparse / "images.bin").write_bytes(bytes(data))
    return sparse


def cfg_args_text(source: Path, images: str = "images", resolution: int = -1, white_background: bool = False) -> str:
    """The cfg_args the INRIA training code writes (the repr of its argparse Namespace)."""
    return (f"Namespace(data_device='cuda', eval=True, images={images!r}, model_path='./output/x', "
            f"resolution={resolution}, sh_degree=3, source_path={str(source)!r}, "
            f"white_background={white_background!r})")


def transforms_json(cameras: list[Camera], files: list[str], per_frame: bool) -> dict:
    """A nerfstudio transforms.json: intrinsics at the top (or per frame), camera-to-world in OpenGL axes."""
    def intrinsics(c: Camera) -> dict:
        return {"fl_x": c.fx, "fl_y": c.fy, "cx": c.cx, "cy": c.cy, "w": c.width, "h": c.height}

    frames = []
    for c, file in zip(cameras, files):
        matrix = np.eye(4)
        matrix[:3, :3] = np.asarray(c.R).T @ FLIP_YZ
        matrix[:3, 3] = c.center
        frame = {"file_path": file, "transform_matrix": matrix.tolist()}
        if per_frame:
            frame.update(intrinsics(c))
        frames.append(frame)
    data = {"camera_model": "OPENCV"} if per_frame else {"camera_model": "OPENCV", **intrinsics(cameras[0])}
    data["frames"] = frames
    return data


def write_dataset(root: Path, layout: str, cameras: list[Camera], photos: list[np.ndarray],
                  names: list[str] | None = None, scene=None, *, white_background: bool = False,
                  resolution: int = -1, text: bool = False, model: str = "PINHOLE", suffix: str = ".png") -> Path:
    """A dataset of ``layout`` ("inria", "colmap", "nerfstudio") under ``root``: view i has
    camera ``cameras[i]`` and photo ``photos[i]`` ((H, W, 3) or (H, W, 4) float in 0..1,
    8-bit on disk, at any size), named ``names[i]`` (default view_000...). Returns what
    open_dataset opens: the INRIA model folder (its photos in root/source/images, its
    cfg_args naming that source; ``scene`` written to point_cloud/iteration_7000), the
    COLMAP folder (sparse/0, binary or ``text``, camera ``model``), or the transforms.json."""
    root = Path(root)
    names = list(names) if names is not None else default_names(len(cameras))
    if not len(cameras) == len(photos) == len(names):
        raise ValueError("cameras, photos and names must have the same length")
    if layout == "inria":
        source, model_dir = root / "source", root / "model"
        for name, photo in zip(names, photos):
            write_photo(source / "images" / f"{name}{suffix}", photo)
        model_dir.mkdir(parents=True, exist_ok=True)
        entries = [camera_to_json(c, i, name) for i, (c, name) in enumerate(zip(cameras, names))]
        (model_dir / "cameras.json").write_text(json_text(entries))
        (model_dir / "cfg_args").write_text(cfg_args_text(source, resolution=resolution,
                                                          white_background=white_background))
        if scene is not None:
            (model_dir / "point_cloud" / "iteration_7000").mkdir(parents=True)
            write_scene(scene, model_dir / "point_cloud" / "iteration_7000" / "point_cloud.ply")
        return model_dir
    if layout == "colmap":
        for name, photo in zip(names, photos):
            write_photo(root / "images" / f"{name}{suffix}", photo)
        write_colmap_model(root / "sparse" / "0", cameras, [f"{n}{suffix}" for n in names], text, model)
        return root
    if layout == "nerfstudio":
        files = [f"images/{n}{suffix}" for n in names]
        for file, photo in zip(files, photos):
            write_photo(root / file, photo)
        per_frame = len({(c.width, c.height, c.fx, c.fy, c.cx, c.cy) for c in cameras}) > 1
        path = root / "transforms.json"
        path.write_text(json_text(transforms_json(cameras, files, per_frame)))
        return path
    raise ValueError(f"unknown layout {layout!r}")
