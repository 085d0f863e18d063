"""An INRIA model folder as the 3DGS training code leaves it: cameras.json (every camera,
named by its image's stem), cfg_args (the training arguments: the source folder, the
images folder, the resolution, the background) and point_cloud/iteration_N/."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from raygs_viewer.camera.pinhole import Camera, camera_from_json
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.jsonfile import read_json_file, typed

#: The folders of downscaled photos the INRIA loader takes with ``-i``, beside images/.
IMAGE_FOLDERS = ("images", "images_2", "images_4", "images_8")
#: The INRIA loader's widest photo at --resolution -1: wider ones are scaled down to it.
AUTO_MAX_WIDTH = 1600


def read_inria_cameras(path: Path) -> list[tuple[str, Camera]]:
    """(img_name, camera) of each entry of the cameras.json ``path``."""
    data = read_json_file(path, "a cameras.json file")
    if not isinstance(data, list) or not data:
        raise UserError(f"{path}: must be a non-empty JSON array of cameras")
    views = []
    for index, entry in enumerate(data):
        where = f"{path}: camera {index}"
        camera = camera_from_json(entry, where)
        if "img_name" not in entry:
            raise UserError(f"{where}: missing 'img_name'")
        views.append((typed(entry["img_name"], str, f"{where}: 'img_name'"), camera))
    return views


def read_cfg_args(path: Path) -> dict:
    """The training arguments in ``path`` (the repr of an argparse Namespace), read as
    literals only, never run: {} when the file is absent."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read: {getattr(exc, 'strerror', None) or one_line(exc)}") from None
    try:
        call = ast.parse(text.strip(), mode="eval").body
        if not (isinstance(call, ast.Call) and isinstance(call.func, ast.Name) and call.func.id == "Namespace"
                and not call.args):
            raise ValueError("expected Namespace(name=value, ...)")
        return {k.arg: ast.literal_eval(k.value) for k in call.keywords if k.arg is not None}
    except (SyntaxError, ValueError, TypeError, RecursionError, MemoryError) as exc:
        raise UserError(f"{path}: not the training code's cfg_args ({one_line(exc, 80)})") from None


def cfg_value(path: Path, args: dict, key: str, kind, default):
    """``args[key]`` checked to be a ``kind``; ``default`` when absent."""
    value = args.get(key, default)
    if kind is int and isinstance(value, bool) or not isinstance(value, kind):
        raise UserError(f"{path}: '{key}' must be {kind.__name__}, got {value!r}"[:200])
    return value


def latest_point_cloud(model: Path) -> Path | None:
    """model/point_cloud/iteration_<N>/point_cloud.ply of the highest N present, else None."""
    found = []
    for folder in (model / "point_cloud").glob("iteration_*"):
        match = re.fullmatch(r"iteration_(\d+)", folder.name)
        if match and (folder / "point_cloud.ply").is_file():
            found.append((int(match[1]), folder / "point_cloud.ply"))
    return max(found)[1] if found else None


def source_folder(model: Path, cfg: Path, args: dict) -> Path:
    """The source folder cfg_args names (as written, else beside the model folder, as a
    relative path would be from where training ran); UserError asking for --images."""
    if "source_path" not in args:
        raise UserError(f"{cfg}: no source_path (or no cfg_args): give the photos' folder with --images FOLDER")
    written = Path(cfg_value(cfg, args, "source_path", str, ""))
    for candidate in (written, model.parent / written, model / written):
        if candidate.is_dir():
            return candidate
    raise UserError(f"{cfg}: the source folder {written} is not here: give the photos' folder with --images FOLDER")


def loader_size(width: int, height: int, resolution: int | float) -> tuple[int, int]:
    """The size the INRIA loader (utils/camera_utils.py, loadCam) gives a photo of
    width x height at --resolution ``resolution``: 1, 2, 4, 8 divide (rounded); -1 caps
    the width at 1600; any other number is the width wanted."""
    if resolution in (1, 2, 4, 8):
        return round(width / resolution), round(height / resolution)
    if resolution == -1:
        scale = width / AUTO_MAX_WIDTH if width > AUTO_MAX_WIDTH else 1.0
    else:
        scale = width / resolution
    return int(width / scale), int(height / scale)
