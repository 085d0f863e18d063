"""A camera path with everything needed to render it: the render size, settings, stereo
view and the scene it was recorded on. :mod:`raygs_viewer.capture.path_file` reads and
writes it (raygs-viewer's own path JSON, or nerfstudio's ``camera_path`` through
:mod:`raygs_viewer.capture.nerfstudio`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from raygs_viewer.camera.path import CameraPath
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.render.settings import RenderSettings

#: The formats a document is read from.
RAYGS, NERFSTUDIO = "raygs", "nerfstudio"
KINDS = (RAYGS, NERFSTUDIO)
#: Largest render width or height a path file may ask for (pixels).
MAX_IMAGE_SIZE = 16384


@dataclass(frozen=True)
class PathDocument:
    """path: the keyframes and their timing. width, height: the size of each frame's
    camera in pixels (with stereo, of each eye; capture.path_render.frame_size gives the frames').
    settings: None for the reader's defaults (a nerfstudio file has none). stereo: None
    for mono. scene_path: "demo" or an absolute path, None when unknown (nerfstudio);
    scene_sha256: its hex digest (None: unknown, never checked); scene_count,
    scene_sh_degree: the scene's gaussian count and SH degree, when known. source: the
    file it was read from. kind: the format it was read from (one of KINDS). extra:
    free-form details of the window (the file's "extra"). notes: one-line remarks about
    what the reader could not honour (e.g. a nerfstudio crop box), for the caller to show."""

    path: CameraPath
    width: int
    height: int
    settings: RenderSettings | None = None
    stereo: StereoView | None = None
    scene_path: str | None = None
    scene_sha256: str | None = None
    source: Path | None = None
    kind: str = RAYGS
    scene_count: int | None = None
    scene_sh_degree: int | None = None
    extra: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()

