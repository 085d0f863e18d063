"""Rendering a camera path's frames, each with its own exact sort, into a
:class:`~raygs_viewer.capture.video.FrameSink`; and the frames' cameras as an INRIA
``cameras.json``, from which ``render --camera`` reproduces any frame bit for bit.

A frame's camera is *canonical*: the camera its ``cameras.json`` entry loads to
(:func:`frame_camera_entries`). The path's own camera would differ from it in the
last bits (the entry stores the centre and camera-to-world rotation, and loading
re-orthonormalises), so rendering the path's camera would not equal ``render
--camera`` of the written file. Re-canonicalising a canonical camera does not give it
back either (measured: most frames move in the last bit again), so the file is written
from the entries, never from cameras.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from raygs_viewer.camera.path import CameraPath
from raygs_viewer.camera.pinhole import Camera, camera_from_json, camera_to_json
from raygs_viewer.camera.stereo import StereoView, composed_size
from raygs_viewer.capture.channel_io import colour_channels
from raygs_viewer.capture.image_io import check_output_path, to_rgb8
from raygs_viewer.capture.progress import Progress
from raygs_viewer.capture.screenshot import render_tiled, render_tiled_channels
from raygs_viewer.capture.video import FRAME_PREFIX, FrameSink
from raygs_viewer.errors import UserError
from raygs_viewer.files import write_atomically
from raygs_viewer.jsonfile import json_text, parse_json
from raygs_viewer.render.channels import ChannelImage, needs_geometry
from raygs_viewer.render.gl.stereo_frame import render_stereo_view, stereo_order
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.lod_choice import LodRequest

if TYPE_CHECKING:
    # Only for the annotations: importing the renderer pulls in moderngl.
    from raygs_viewer.render.gl.renderer import GLRenderer


def frame_camera_entries(path: CameraPath, width: int, height: int) -> list[dict]:
    """One INRIA cameras.json entry per frame of ``path`` at ``width`` x ``height``:
    ``id`` k, ``img_name`` ``frame_0000k`` (as the PNG folder names the frame)."""
    digits = max(5, len(str(max(path.frame_count, 1) - 1)))
    return [camera_to_json(camera, k, f"{FRAME_PREFIX}{k:0{digits}d}")
            for k, camera in enumerate(path.cameras(width, height))]


def cameras_of_entries(entries: list[dict]) -> list[Camera]:
    """The cameras ``entries`` load to, exactly as ``render --camera`` loads them."""
    # Through JSON text, as the file goes: a float's repr round-trips, and this keeps
    # any value JSON would change (a tuple, a numpy scalar) from passing unnoticed.
    return [camera_from_json(entry, f"frame {k}") for k, entry in enumerate(parse_json(json_text(entries), "frame cameras"))]


def frame_cameras(path: CameraPath, width: int, height: int) -> list[Camera]:
    """Each frame's camera, canonicalised through its cameras.json entry (module docstring)."""
    return cameras_of_entries(frame_camera_entries(path, width, height))


def write_cameras_json(entries: list[dict], file: str | Path, overwrite: bool = False) -> Path:
    """Writes :func:`frame_camera_entries`' ``entries`` as an INRIA cameras.json,
    atomically, never replacing a file without ``overwrite``. Entries, not cameras:
    only they load back to the frames' cameras bit for bit (module docstring)."""
    if any(isinstance(entry, Camera) for entry in entries):
        raise TypeError("write_cameras_json takes frame_camera_entries(...), not cameras: "
                        "a camera written again would not load back to itself bit for bit")
    file = check_output_path(file, overwrite, suffixes=(".json",))
    write_atomically(file, json_text(entries).encode("utf-8"), overwrite)
    return file


def frame_size(width: int, height: int, stereo: StereoView | None) -> tuple[int, int]:
    """The size of a frame of a ``width`` x ``height`` camera: twice as wide for a
    side-by-side stereo layout. What the sink is opened with."""
    return (width, height) if stereo is None else composed_size(width, height, stereo.layout)


def render_frame(renderer: "GLRenderer", sorter: DepthSorter, camera: Camera, settings: RenderSettings,
                 stereo: StereoView | None = None, *, levels: LodRequest | None = None,
                 deleted: DeletedRows | None = None) -> np.ndarray:
    """(H, W, 4) float32, top row first: the image ``render`` makes of ``camera``, with
    an exact sort of its own by ``sorter`` (a stereo frame composed per
    ``stereo.layout``); ``levels``: a streamed scene's, chosen for ``camera`` (for a
    stereo frame, the eyes' midpoint); ``deleted``: rows left out (deleted in the window)."""
    if stereo is not None:
        order = stereo_order(sorter, camera, settings, stereo.rig, levels=levels, deleted=deleted)
        return render_stereo_view(renderer, order, camera, settings, stereo)[0]
    return render_tiled(renderer, sorter, exact_order(sorter, camera, settings, levels=levels, deleted=deleted), camera,
                        settings)


def render_frame_channels(renderer: "GLRenderer", sorter: DepthSorter, camera: Camera, settings: RenderSettings,
                          stereo: StereoView | None = None, *, channels: tuple[str, ...],
                          normal_space: str = "camera", levels: LodRequest | None = None,
                          deleted: DeletedRows | None = None) -> ChannelImage:
    """The ChannelImage of one frame, normals in ``normal_space`` of ``camera``: the
    geometry render where ``channels`` need it (not with ``stereo``: its layouts compose
    colour), else :func:`render_frame`'s colour."""
    if not needs_geometry(channels):
        return colour_channels(render_frame(renderer, sorter, camera, settings, stereo, levels=levels,
                                            deleted=deleted))
    if stereo is not None:
        raise UserError("--stereo composes colour; its frames cannot carry depth or normals")
    order = exact_order(sorter, camera, settings, levels=levels, deleted=deleted)
    return render_tiled_channels(renderer, sorter, order, camera, settings,
                                 median="median_depth" in channels).in_space(normal_space, camera)


def render_frames(renderer: "GLRenderer", sorter: DepthSorter, cameras: list[Camera], settings: RenderSettings,
                  sink: FrameSink, *, stereo: StereoView | None = None, progress: Progress | None = None,
                  channels: tuple[str, ...] | None = None, normal_space: str = "camera",
                  lod: LodRequest | None = None, deleted: DeletedRows | None = None) -> int:
    """Renders each camera (:func:`render_frame`; ``stereo`` as it takes it), converts it
    to 8 bits as a PNG screenshot is, and writes it to ``sink``; returns the frames written. With
    ``channels`` each frame goes to the sink as a ChannelImage instead
    (:func:`render_frame_channels`; an ExrFolderSink). ``lod``: a streamed scene's
    levels, chosen for each frame's camera; ``deleted``: rows every frame leaves out (the
    path document's edits). A KeyboardInterrupt propagates
    between or inside frames: the caller aborts the sink, whose ``frames_written`` then
    says what it holds."""
    written = 0
    for camera in cameras:
        if channels is not None:
            sink.write(render_frame_channels(renderer, sorter, camera, settings, stereo, channels=channels,
                                             normal_space=normal_space, levels=lod, deleted=deleted))
        else:
            sink.write(to_rgb8(render_frame(renderer, sorter, camera, settings, stereo, levels=lod, deleted=deleted)))
        written += 1
        if progress is not None:
            progress.update(sink.frames_written)
    return written
