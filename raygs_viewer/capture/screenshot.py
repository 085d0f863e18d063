"""Screenshots: the offscreen camera at a chosen scale, tiled rendering, and saving a PNG
with its JSON sidecar (:mod:`raygs_viewer.capture.sidecar`) beside it.

The window (F12, the panel button, ``view --screenshot``) and ``render --sidecar`` both
render through :func:`render_tiled`, so a screenshot re-rendered headlessly on the same
GPU gives the same PNG, byte for byte.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import replace
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.capture.image_io import encode_image
from raygs_viewer.errors import UserError, finite_number
from raygs_viewer.files import check_writable_folder, write_atomically
from raygs_viewer.jsonfile import json_text
from raygs_viewer.render.channels import CHANNEL_WIDTHS, CHANNELS, ChannelImage
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import sort_request
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.request import Order

if TYPE_CHECKING:
    # Only for the annotations: importing the renderer pulls in moderngl, and the CLI's
    # option parsing (which reads MAX_SCALE from here) must not.
    from raygs_viewer.render.gl.renderer import GLRenderer

#: Largest screenshot side in pixels: 16384^2 float32 RGBA is already 4 GiB of read-back.
MAX_SCREENSHOT_SIDE = 16384
#: Largest offscreen scale of the window's view.
MAX_SCALE = 8.0
#: Default tile side: small enough for any GL 4.3 GPU's render-target limit and memory.
DEFAULT_TILE = 2048

SCREENSHOT_PREFIX = "raygs-"
SIDECAR_SUFFIX = ".json"
# Bounds the retries when other writers keep taking the names we pick.
_MAX_NAME_ATTEMPTS = 10000


def check_scale(scale: float) -> float:
    """``scale`` as a float if it is finite and in (0, MAX_SCALE], else UserError."""
    number = finite_number(scale)
    if number is None or not 0.0 < number <= MAX_SCALE:
        raise UserError(f"screenshot scale must be a finite number in (0, {MAX_SCALE:g}], got {scale!r}")
    return number


def scaled_camera(camera: Camera, scale: float) -> Camera:
    """The same view at round(width * scale) x round(height * scale); fx, fy, cx, cy
    scale with it (:meth:`Camera.resized`)."""
    scale = check_scale(scale)
    width, height = round(camera.width * scale), round(camera.height * scale)
    if width < 1 or height < 1:
        raise UserError(f"screenshot scale {scale:g} makes the {camera.width}x{camera.height} view "
                        f"{width}x{height} pixels")
    if max(width, height) > MAX_SCREENSHOT_SIDE:
        raise UserError(f"screenshot of {width}x{height} pixels ({camera.width}x{camera.height} at scale "
                        f"{scale:g}) exceeds {MAX_SCREENSHOT_SIDE} pixels a side")
    return camera.resized(width, height)


def tile_camera(camera: Camera, x0: int, y0: int, width: int, height: int) -> Camera:
    """The ``width`` x ``height`` window of ``camera``'s image whose top-left pixel is
    (x0, y0): the principal point moves by the offset, so pixel (u, v) of the tile
    has the ray of pixel (x0 + u, y0 + v) of the whole image."""
    return replace(camera, width=int(width), height=int(height), cx=camera.cx - x0, cy=camera.cy - y0)


def render_tiled(renderer: "GLRenderer", sorter: DepthSorter, order: Order, camera: Camera,
                 settings: RenderSettings, *, tile: int = DEFAULT_TILE,
                 color_origin: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 4) float32 image, top row first, like :meth:`GLRenderer.render` of
    ``order`` (``camera``'s, for ``settings``), drawn in tiles of at most ``tile`` x
    ``tile`` pixels so a large screenshot never needs one huge render target.

    Every tile composites the whole image's back-to-front order (restricted by
    ``sorter`` to the gaussians that can reach the tile, of the rows the order's
    level-of-detail choice holds), so blending sequences, and hence pixels, match a
    single render up to the rasterizer's float rounding.

    With ``settings.supersample`` k > 1 the renderer draws k x k samples per pixel, so
    tiles are at most ``tile // k`` pixels a side: the GPU target stays within ``tile``.
    GS clamps its rays to the whole image's borders (``frame=camera``), not the tile's.

    ``color_origin``: the (3,) world point every tile evaluates the SH colour from
    (:meth:`GLRenderer.render`'s; a headset eye's is the eyes' midpoint); None: the
    camera's centre, which every tile shares.
    """
    if _fits_one_tile(camera, settings, tile):
        return renderer.render(camera, settings, order, color_origin=color_origin)
    image = _allocate(camera, [(4,)], "float32 RGBA image")[0]
    for part, tile_order, rows, columns in _tiles(sorter, order, camera, settings, tile):
        pixels = renderer.render(part, settings, tile_order, frame=camera, color_origin=color_origin)
        image[rows, columns] = pixels[:rows.stop - rows.start, :columns.stop - columns.start]
    return image


def render_tiled_channels(renderer: "GLRenderer", sorter: DepthSorter, order: Order, camera: Camera,
                          settings: RenderSettings, *, tile: int = DEFAULT_TILE, median: bool = True,
                          color_origin: np.ndarray | None = None) -> ChannelImage:
    """The ChannelImage of :meth:`GLRenderer.render_channels` (camera-space normals),
    drawn in tiles as :func:`render_tiled` draws colour, with the same order and colour
    origin per tile. ``median`` False leaves the median depth out (None; cheaper in a
    global order)."""
    if _fits_one_tile(camera, settings, tile):
        return renderer.render_channels(camera, settings, order, median=median, color_origin=color_origin)
    # CHANNELS are ChannelImage's per-pixel fields, in its constructor's order.
    shapes = [() if CHANNEL_WIDTHS[name] == 1 else (CHANNEL_WIDTHS[name],) for name in CHANNELS]
    arrays = _allocate(camera, shapes, "set of float32 channels")
    for part, tile_order, rows, columns in _tiles(sorter, order, camera, settings, tile):
        channels = renderer.render_channels(part, settings, tile_order, frame=camera, median=median,
                                            color_origin=color_origin)
        for name, array in zip(CHANNELS, arrays):
            if getattr(channels, name) is not None:
                array[rows, columns] = getattr(channels, name)[:rows.stop - rows.start, :columns.stop - columns.start]
    image = ChannelImage(*arrays)
    return image if median else replace(image, median_depth=None)


def _fits_one_tile(camera: Camera, settings: RenderSettings, tile: int) -> bool:
    if tile < 1:
        raise ValueError(f"tile must be positive, got {tile}")
    tile = max(1, tile // settings.supersample)
    return camera.width <= tile and camera.height <= tile


def _allocate(camera: Camera, shapes: list[tuple[int, ...]], what: str) -> list[np.ndarray]:
    """Empty float32 (H, W, *shape) arrays, or UserError when the image is too large."""
    width, height = camera.width, camera.height
    if max(width, height) > MAX_SCREENSHOT_SIDE:
        # Tiling lifts the GPU's size limit; this one keeps the read-back within memory.
        raise UserError(f"image size {width}x{height} exceeds {MAX_SCREENSHOT_SIDE} pixels a side")
    try:
        return [np.empty((height, width, *shape), np.float32) for shape in shapes]
    except MemoryError:
        raise UserError(f"not enough memory for a {width}x{height} {what}") from None


def _tiles(sorter: DepthSorter, order: Order, camera: Camera, settings: RenderSettings, tile: int
           ) -> Iterator[tuple[Camera, Order, slice, slice]]:
    """(tile camera, its order, rows, columns of the image it fills) for each tile;
    the tile's pixels beyond those rows and columns (an edge tile) are to be cropped."""
    tile = max(1, tile // settings.supersample)
    width, height = camera.width, camera.height
    indices = order.host_indices()
    # Edge tiles are drawn at full tile size and cropped: one render target for all
    # tiles (the renderer reallocates its target whenever the size changes).
    tile_w, tile_h = min(tile, width), min(tile, height)
    for y0 in range(0, height, tile_h):
        for x0 in range(0, width, tile_w):
            part = tile_camera(camera, x0, y0, tile_w, tile_h)
            # The sorter's cull is conservative, so dropping what it culls for the tile
            # changes no pixel; the whole image's order keeps the blending sequence.
            visible = sorter.sort(sort_request(part, settings, levels=order.choice)).order.host_indices()
            tile_order = order.with_indices(indices[np.isin(indices, visible, assume_unique=True)])
            yield part, tile_order, slice(y0, min(y0 + tile_h, height)), slice(x0, min(x0 + tile_w, width))


# --------------------------------------------------------------------------- saving


def check_screenshot_path(path: str | Path) -> Path:
    """Validates an explicit screenshot path before any slow work: ends in .png, its
    folder exists and is writable, and neither the PNG nor its .json sidecar exists."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise UserError(f"{path}: a screenshot must end in .png")
    check_writable_folder(path, path.parent)
    for existing in (path, sidecar_path(path)):
        if os.path.lexists(existing):
            raise UserError(f"{existing}: already exists (screenshots never replace a file)")
    return path


def sidecar_path(png: Path) -> Path:
    """The JSON sidecar beside a screenshot: same stem, ``.json``."""
    return png.with_suffix(SIDECAR_SUFFIX)


def next_screenshot_path(folder: str | Path, now: datetime | None = None) -> Path:
    """``folder/raygs-YYYYmmdd-HHMMSS.png``, local time; ``-2``, ``-3``, ... appended while
    that PNG or its .json sidecar exists."""
    folder = Path(folder)
    stem = SCREENSHOT_PREFIX + (now or datetime.now()).strftime("%Y%m%d-%H%M%S")
    return _free_path(folder, stem, 1)


def _free_path(folder: Path, stem: str, number: int) -> Path:
    """The first of stem.png (number 1), stem-2.png, ... from ``number`` on whose PNG and
    sidecar are both free."""
    for n in range(number, number + _MAX_NAME_ATTEMPTS):
        candidate = folder / (f"{stem}.png" if n == 1 else f"{stem}-{n}.png")
        if not (os.path.lexists(candidate) or os.path.lexists(sidecar_path(candidate))):
            return candidate
    raise UserError(f"{folder}: no free screenshot name from {stem}-{number}.png on")


def save_screenshot(image: np.ndarray, sidecar: dict, path: str | Path | None = None,
                    folder: str | Path | None = None) -> tuple[Path, Path]:
    """Writes ``image`` ((H, W, >=3) float, as :func:`render_tiled` returns) as an 8-bit
    PNG and ``sidecar`` as JSON beside it; returns (png, json).

    Give exactly one of ``path`` (an explicit .png: UserError if it or its sidecar
    exists) or ``folder`` (created if missing; a fresh ``raygs-<time>.png`` name, the
    next suffix taken whenever another writer claims a name first). Both files are
    written atomically and never replace an existing file; if the sidecar cannot be
    written the PNG is removed again, so no screenshot is left without its sidecar.
    """
    if (path is None) == (folder is None):
        raise ValueError("save_screenshot takes exactly one of path and folder")
    png_bytes = encode_image(image, ".png")
    if path is not None:
        png = check_screenshot_path(path)
        try:
            return png, _write_pair(png, png_bytes, sidecar)
        except _NameTaken as taken:  # appeared since the check: still never replaced
            raise UserError(f"{taken}: already exists (screenshots never replace a file)") from None

    folder = _screenshot_folder(folder)
    png = next_screenshot_path(folder)
    stem = png.stem
    number = 1
    for _ in range(_MAX_NAME_ATTEMPTS):
        try:
            return png, _write_pair(png, png_bytes, sidecar)
        except _NameTaken:
            number = _suffix_number(png, stem) + 1
            png = _free_path(folder, stem, number)
    raise UserError(f"{folder}: no free screenshot name after {_MAX_NAME_ATTEMPTS} attempts")


def save_screenshots(shots: list[tuple[np.ndarray, dict, str]], path: str | Path | None = None,
                     folder: str | Path | None = None) -> list[tuple[Path, Path]]:
    """Saves several images of one view (the split view's sides), each ``(image,
    sidecar, tag)``, as PNG + sidecar pairs named ``<name>-<tag>.png`` and
    ``<name>-<tag>.json``; returns the (png, json) pairs in order.

    ``path`` (an explicit .png) gives ``<name>``: UserError, before anything is written,
    if any of the files exists. ``folder`` gives ``raygs-<time>``, with ``-2``, ``-3``,
    ... where any of the tagged names is taken, so the pairs of one capture share a
    number. Like :func:`save_screenshot`, nothing is ever replaced."""
    if (path is None) == (folder is None):
        raise ValueError("save_screenshots takes exactly one of path and folder")
    tags = [tag for _, _, tag in shots]
    if len(set(tags)) != len(tags) or not all(tags):
        raise ValueError(f"screenshot tags must be distinct and non-empty, got {tags}")
    encoded = [(encode_image(image, ".png"), sidecar, tag) for image, sidecar, tag in shots]
    if path is not None:
        path = Path(path)
        pngs = [check_screenshot_path(path.with_name(f"{path.stem}-{tag}{path.suffix}")) for tag in tags]
        written = []
        for png, (data, sidecar, _) in zip(pngs, encoded):
            try:
                written.append((png, _write_pair(png, data, sidecar)))
            except _NameTaken as taken:
                raise UserError(f"{taken}: already exists (screenshots never replace a file)") from None
        return written

    folder = _screenshot_folder(folder)
    stem = next_screenshot_path(folder).stem  # a fresh time stamp
    number, written = 1, []
    for data, sidecar, tag in encoded:
        for _ in range(_MAX_NAME_ATTEMPTS):
            number = _free_number(folder, stem, number, tags[len(written):])
            png = folder / (f"{stem}-{tag}.png" if number == 1 else f"{stem}-{number}-{tag}.png")
            try:
                written.append((png, _write_pair(png, data, sidecar)))
                break
            except _NameTaken:
                number += 1
        else:
            raise UserError(f"{folder}: no free screenshot name after {_MAX_NAME_ATTEMPTS} attempts")
    return written


def _free_number(folder: Path, stem: str, number: int, tags: list[str]) -> int:
    """The first n >= ``number`` for which every tag's PNG and sidecar name is free."""
    for n in range(number, number + _MAX_NAME_ATTEMPTS):
        pngs = [folder / (f"{stem}-{tag}.png" if n == 1 else f"{stem}-{n}-{tag}.png") for tag in tags]
        if not any(os.path.lexists(p) or os.path.lexists(sidecar_path(p)) for p in pngs):
            return n
    raise UserError(f"{folder}: no free screenshot name from {stem}-{number}-{tags[0]}.png on")


def _screenshot_folder(folder: str | Path) -> Path:
    """``folder``, created if missing; UserError if it cannot be."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise UserError(f"{folder}: cannot save screenshots there: not a folder") from None
    except OSError as exc:
        raise UserError(f"{folder}: cannot create the screenshot folder: {exc.strerror or exc}") from None
    if not folder.is_dir():
        raise UserError(f"{folder}: cannot save screenshots there: not a folder")
    return folder


class _NameTaken(Exception):
    """Another writer created the PNG or sidecar name between our check and our write."""


def _suffix_number(png: Path, stem: str) -> int:
    rest = png.stem[len(stem):]
    return int(rest[1:]) if rest.startswith("-") else 1


def _write_pair(png: Path, png_bytes: bytes, sidecar: dict) -> Path:
    """Writes the PNG, then the sidecar; removes the PNG if the sidecar fails. Raises
    _NameTaken when either name turns out to exist, else UserError."""
    json_path = sidecar_path(png)
    text = _sidecar_text(with_relative_scene_path(sidecar, png.parent), json_path)
    _write_new(png, png_bytes)
    try:
        _write_new(json_path, text.encode("utf-8"))
    except BaseException as exc:
        try:
            os.unlink(png)
        except OSError:
            pass  # the sidecar's error is the one worth reporting
        if isinstance(exc, UserError):  # it names the sidecar already
            raise UserError(f"{exc} (its PNG was removed: no screenshot without its sidecar)") from None
        raise
    return json_path


def _write_new(path: Path, data: bytes) -> None:
    try:
        write_atomically(path, data, overwrite=False)
    except UserError:
        # write_atomically reports a name that appeared meanwhile as "already exists";
        # telling that apart from other failures lets the folder mode try the next name.
        if os.path.lexists(path):
            raise _NameTaken(str(path)) from None
        raise


def _sidecar_text(sidecar: dict, where: Path) -> str:
    try:
        return json_text(sidecar)
    except (TypeError, ValueError) as exc:
        raise UserError(f"{where}: screenshot sidecar is not valid JSON: {exc}") from None


def with_relative_scene_path(sidecar: dict, folder: Path) -> dict:
    """Adds scene.relative_path (from the sidecar's folder) when the scene path is
    absolute, so a folder tree moved as a whole still finds its scene."""
    scene = sidecar.get("scene")
    if not isinstance(scene, dict) or not isinstance(scene.get("path"), str) or not os.path.isabs(scene["path"]):
        return sidecar
    try:
        relative = os.path.relpath(scene["path"], os.path.abspath(folder))
    except ValueError:  # another drive on Windows: no relative path exists
        return sidecar
    return {**sidecar, "scene": {**scene, "relative_path": relative}}
