"""A capture's photos and the cameras they were taken with, read as users have them
(docs/evaluation.md): an INRIA model folder (cameras.json, cfg_args), a COLMAP folder
(sparse/0, binary or text; PINHOLE and SIMPLE_PINHOLE), a nerfstudio transforms.json.

THE INTERFACE (skeleton: the dataset helper fills it in; others build on these names).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from PIL import Image

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.photos.colmap import read_colmap, sparse_folder
from raygs_viewer.photos.inria import (IMAGE_FOLDERS, cfg_value, latest_point_cloud, loader_size, read_cfg_args,
                                       read_inria_cameras, source_folder)
from raygs_viewer.photos.nerfstudio import read_transforms

#: --split: the paper's protocol, every TEST_EVERY-th view (index % 8 == 0 in name order) is a test view.
SPLITS = ("test", "train", "all")
TEST_EVERY = 8
LAYOUTS = ("inria", "colmap", "nerfstudio")
#: The suffixes tried after a name without one (INRIA's img_name is the file's stem).
PHOTO_SUFFIXES = (".png", ".jpg", ".jpeg", ".JPG", ".PNG", ".JPEG")
#: The INRIA loader resizes with Pillow's Image.resize default, which is BICUBIC for RGB
#: photos since Pillow 7 (and still in Pillow 13): named here so a new default cannot move it.
RESAMPLE = Image.Resampling.BICUBIC
#: What reading a photo raises for a bad file: Pillow's errors are OSError (unknown or
#: truncated), ValueError, SyntaxError (some plugins) and its decompression-bomb guard.
PHOTO_ERRORS = (OSError, ValueError, SyntaxError, Image.DecompressionBombError)


@dataclass(frozen=True)
class PhotoView:
    """One photo: ``name`` (the image's name as the dataset gives it), ``camera`` (OpenCV
    axes, at the size the render is compared at), ``image_path`` (the photo file, None
    when it was not found: loading it is then a one-line UserError), ``index`` (its
    place in name order, which the split uses)."""

    name: str
    camera: Camera
    image_path: Path | None
    index: int
    #: Where the photo was looked for ("DIR/NAME.{png,jpg,...}"), for the message when it is missing.
    expected: str = ""


@dataclass(frozen=True)
class Dataset:
    """``layout`` (one of LAYOUTS), ``root`` (the folder or file opened), ``views`` (in
    name order), ``background`` (the model's: white where its cfg_args says so, else
    black), ``scene_path`` (the trained model's point cloud when the layout names one:
    an INRIA folder's point_cloud/iteration_<highest>/point_cloud.ply; else None)."""

    layout: str
    root: Path
    views: tuple[PhotoView, ...]
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scene_path: Path | None = None


#: How a message about missing photos says where to point: the option of evaluate and
#: the window that names the photos' folder.
IMAGES_HINT = "give the photos' folder with --images FOLDER"


def with_images_hint(message: str) -> str:
    """``message`` ending in how to point at the photos, unless it already names --images."""
    return message if "--images" in message else f"{message} ({IMAGES_HINT})"


def open_dataset(path: str | Path, images: str | Path | None = None) -> Dataset:
    """The dataset at ``path`` (an INRIA model folder, a COLMAP folder, a transforms.json
    or its folder); ``images``: the photos' folder where the layout does not say.
    UserError (one line) for anything unreadable or unsupported.

    Each view's camera is at the size the render is compared at: the camera's own, or
    the photo's where that is smaller (for an INRIA model, the size the training code's
    loader gives the photo at the cfg_args resolution), never larger than the camera."""
    path = Path(path)
    folder = Path(images) if images is not None else None
    if folder is not None and not folder.is_dir():
        raise UserError(f"{folder}: no such folder (--images)")
    if path.is_file() and path.name == "cameras.json":
        path = path.parent
    if path.is_file():
        if path.suffix.lower() != ".json":
            raise UserError(f"{path}: not a dataset: expected a transforms.json, an INRIA model folder "
                            f"or a COLMAP folder")
        return _open_nerfstudio(path, folder)
    if not path.is_dir():
        raise UserError(f"{path}: no such file or folder")
    if (path / "cameras.json").is_file():
        return _open_inria(path, folder)
    if (path / "transforms.json").is_file():
        return _open_nerfstudio(path / "transforms.json", folder)
    sparse = sparse_folder(path)
    if sparse is None:
        raise UserError(f"{path}: not a dataset: expected cameras.json (an INRIA model folder), sparse/0 with "
                        f"cameras and images files (a COLMAP folder) or transforms.json (nerfstudio)")
    found = [(name, camera, *find_photo(folder or path / "images", name)) for name, camera in read_colmap(sparse)]
    return Dataset("colmap", path, _views(found, None))


def select_split(views: tuple[PhotoView, ...], split: str) -> tuple[PhotoView, ...]:
    """The views of ``split`` (one of SPLITS): "test" every TEST_EVERY-th by index, "train" the others."""
    if split not in SPLITS:
        raise UserError(f"unknown split {split!r} (expected {', '.join(SPLITS)})")
    if split == "all":
        return tuple(views)
    test = split == "test"
    return tuple(v for v in views if (v.index % TEST_EVERY == 0) == test)


def load_photo(view: PhotoView, background: tuple[float, float, float]) -> np.ndarray:
    """(H, W, 3) float32 in 0..1, at ``view.camera``'s size (resized as the INRIA loader
    does where the file is larger), alpha (RGBA photos) composited over ``background``.
    UserError (one line naming the file) for a missing or unreadable photo, or one whose
    aspect ratio does not match the camera."""
    path, camera = view.image_path, view.camera
    if path is None or not path.is_file():
        raise UserError(f"{path or view.expected or view.name}: no such photo ({IMAGES_HINT})")
    try:
        with Image.open(path) as image:
            image.load()
            alpha = "A" in image.getbands() or "transparency" in image.info
            pixels = np.asarray(image.convert("RGBA" if alpha else "RGB"))
    except PHOTO_ERRORS as exc:
        raise UserError(f"{path}: cannot read the photo ({one_line(exc, 100)})") from None
    height, width = pixels.shape[:2]
    if not same_aspect((width, height), (camera.width, camera.height)):
        raise UserError(f"{path}: the photo is {width}x{height}, which does not have the aspect ratio of its "
                        f"camera ({camera.width}x{camera.height})")
    rgb = pixels[..., :3].astype(np.float32) / 255
    if alpha:
        # As the INRIA nerf-synthetic loader does: rgb * a + background * (1 - a).
        a = pixels[..., 3:4].astype(np.float32) / 255
        rgb = rgb * a + np.asarray(background, np.float32) * (1 - a)
    if (width, height) != (camera.width, camera.height):
        # The INRIA loader resizes 8-bit images (its nerf-synthetic loader composites to
        # 8 bits first), so this does too, to give the same pixels.
        eight = np.clip(np.rint(rgb * 255), 0, 255).astype(np.uint8) if alpha else pixels[..., :3]
        resized = Image.fromarray(np.ascontiguousarray(eight), "RGB").resize((camera.width, camera.height), RESAMPLE)
        rgb = np.asarray(resized, np.float32) / 255
    return np.ascontiguousarray(rgb, np.float32)


def load_thumbnail(view: PhotoView, background: tuple[float, float, float], width: int) -> np.ndarray:
    """(h, w, 3) uint8: ``view``'s photo scaled down to at most ``width`` pixels wide, its
    aspect kept (never scaled up), alpha composited over ``background``: a preview, not
    the pixels :func:`load_photo` compares. Pillow's thumbnail decodes a JPEG at a
    reduced size (its draft mode), so a large photo costs a few milliseconds, not a full
    decode. UserError (one line naming the file) as load_photo."""
    path = view.image_path
    if path is None or not path.is_file():
        raise UserError(f"{path or view.expected or view.name}: no such photo ({IMAGES_HINT})")
    try:
        with Image.open(path) as image:
            image.thumbnail((width, max(1, round(width * image.height / image.width))), RESAMPLE)
            alpha = "A" in image.getbands() or "transparency" in image.info
            pixels = np.asarray(image.convert("RGBA" if alpha else "RGB"))
    except PHOTO_ERRORS as exc:
        raise UserError(f"{path}: cannot read the photo ({one_line(exc, 100)})") from None
    if not alpha:
        return np.ascontiguousarray(pixels)
    a = pixels[..., 3:4].astype(np.float32) / 255
    rgb = pixels[..., :3].astype(np.float32) / 255 * a + np.asarray(background, np.float32) * (1 - a)
    return np.clip(np.rint(rgb * 255), 0, 255).astype(np.uint8)


def same_aspect(photo: tuple[int, int], camera: tuple[int, int]) -> bool:
    """Whether a photo of size ``photo`` (width, height) scaled to ``camera``'s width, or
    to its height, lands within a pixel of the camera's other side (downscaled folders
    round or truncate each side)."""
    (pw, ph), (cw, ch) = photo, camera
    return abs(ph * cw / pw - ch) <= 1 or abs(pw * ch / ph - cw) <= 1


def find_photo(folder: Path, name: str) -> tuple[Path | None, str]:
    """(the photo file of ``name`` in ``folder`` or None, where it was looked for): the
    name as given, else with each of PHOTO_SUFFIXES added."""
    candidates = [folder / name] if Path(name).suffix else []
    candidates += [folder / f"{name}{suffix}" for suffix in PHOTO_SUFFIXES]
    for candidate in candidates:
        if candidate.is_file():
            return candidate, str(candidate)
    expected = str(folder / name) if Path(name).suffix else f"{folder / name}.{{png,jpg,jpeg}}"
    return None, expected


def photo_size(path: Path | None) -> tuple[int, int] | None:
    """(width, height) from the photo's header (nothing decoded), None when unreadable:
    load_photo then says why."""
    if path is None:
        return None
    try:
        with Image.open(path) as image:
            return image.size
    except PHOTO_ERRORS:
        return None


def compared_camera(camera: Camera, path: Path | None, resolution: int | None) -> Camera:
    """``camera`` at the size its render is compared at: the photo's (at the INRIA
    loader's ``resolution`` when given) where smaller than the camera's, else its own."""
    size = photo_size(path)
    if size is None:
        return camera
    width, height = size if resolution is None else loader_size(*size, resolution)
    if width >= camera.width or not same_aspect((width, height), (camera.width, camera.height)):
        return camera
    return camera.resized(width, height)


def _views(found: list[tuple[str, Camera, Path | None, str]], resolution: int | None) -> tuple[PhotoView, ...]:
    found = sorted(found, key=lambda view: view[0])
    return tuple(PhotoView(name, compared_camera(camera, image_path, resolution), image_path, index, expected)
                 for index, (name, camera, image_path, expected) in enumerate(found))


def _open_inria(model: Path, folder: Path | None) -> Dataset:
    cameras = read_inria_cameras(model / "cameras.json")
    cfg = model / "cfg_args"
    args = read_cfg_args(cfg)
    resolution = cfg_value(cfg, args, "resolution", int, -1)
    if resolution != -1 and resolution < 1:
        raise UserError(f"{cfg}: 'resolution' must be -1 or a positive number of pixels, got {resolution}")
    background = (1.0, 1.0, 1.0) if cfg_value(cfg, args, "white_background", bool, False) else (0.0, 0.0, 0.0)
    if folder is None:
        folder = _inria_images(cfg, source_folder(model, cfg, args), cfg_value(cfg, args, "images", str, "images"),
                               cameras[0])
    found = [(name, camera, *find_photo(folder, name)) for name, camera in cameras]
    return Dataset("inria", model, _views(found, resolution), background, latest_point_cloud(model))


def _inria_images(cfg: Path, source: Path, configured: str, first: tuple[str, Camera]) -> Path:
    """The photos' folder: the one training used (cfg_args' images) when present, else the
    one of images, images_2, images_4, images_8 whose photo is nearest the camera's size."""
    if (source / configured).is_dir():
        return source / configured
    present = [source / name for name in IMAGE_FOLDERS if (source / name).is_dir()]
    if not present:
        raise UserError(f"{cfg}: the source folder {source} has no {configured}/ folder: {IMAGES_HINT}")
    name, camera = first

    def distance(folder: Path) -> float:
        size = photo_size(find_photo(folder, name)[0])
        return abs(size[0] - camera.width) if size else float("inf")

    return min(present, key=distance)


def _open_nerfstudio(path: Path, folder: Path | None) -> Dataset:
    def photo_path(file_path: str) -> tuple[Path | None, str]:
        return find_photo(folder, Path(file_path).name) if folder else find_photo(path.parent, file_path)

    views = read_transforms(path, lambda file_path: photo_size(photo_path(file_path)[0]))
    return Dataset("nerfstudio", path, _views([(name, camera, *photo_path(name)) for name, camera in views], None))
