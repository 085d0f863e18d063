"""Camera path files: :class:`PathDocument`, a camera path with everything needed to
render it (the render size, settings, stereo view and the scene it was recorded on),
and its reading and writing. raygs-viewer's own path JSON is read and written here,
like a screenshot's sidecar (:mod:`raygs_viewer.capture.sidecar`) is for one frame;
nerfstudio's ``camera_path`` files (:mod:`raygs_viewer.capture.nerfstudio`) are told
apart by their content and read into the same document. The window saves and loads
documents; ``raygs-viewer render-path`` renders one.

Layout (version 1)::

    {"format": "raygs-viewer camera path", "version": 1,
     "program": {"name": "raygs-viewer", "version": "0.1.0"},
     "created": "2025-01-31T12:00:00Z",                           # UTC
     "scene": {"path": "/abs/scene.ply" or "demo",                # or null: unknown
               "sha256": "<64 hex digits>" or null,
               "count": N or null, "sh_degree": d or null,
               ...,                                               # how it was read: document_entries.reading_entry
               "relative_path": "../scene.ply"},                  # added when saved, from the file's folder
     "image": {"width": W, "height": H},                          # each frame's camera (each eye's in stereo)
     "settings": {every RenderSettings field} or null,            # null: the reader's defaults
     "stereo": null or the sidecar's "stereo" entry,
     "path": {"duration": 10.0, "fps": 30.0,                      # seconds (a loop: one lap), frames/s
              "loop": false, "alpha": 0.5, "tension": 0.0,        # camera.path.Interpolation
              "up": [0.0, -1.0, 0.0]},                            # world up, a unit vector
     "keyframes": [{"position": [x, y, z],                        # camera centre, world space
                    "rotation": 3x3,                              # camera-to-world (= R.T), like INRIA cameras.json
                    "fov": 60.0,                                  # vertical, degrees
                    "time": null or 2.5}, ...],                   # seconds from the start; null: paced
     "extra": {...}}                                              # free-form, from the window

Required: "format", "version", "image", "path" (with "duration" and "fps") and at least
one keyframe (each with "position", "rotation" and "fov"); the rest may be left out
(null, the defaults). Loading is strict: an unknown field anywhere outside "extra" (and
"settings", which follows the sidecar: missing settings take their defaults) is an
error, as are wrong types, non-finite numbers, a rotation that is not one, and numbers
beyond camera.path's limits (FOV_RANGE, FPS_RANGE, MAX_DURATION, MAX_KEYFRAMES,
MAX_FRAMES) or an image side beyond MAX_IMAGE_SIZE. Explicit keyframe times must
increase along the flight and lie within the path (a loop's before its end). Every
problem is one line naming the file and the field.

Python writes a float as the shortest repr that reads back to the same bits, so
positions, rotations, fields of view and times survive the round trip exactly.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from raygs_viewer.camera.navigation import Pose
from raygs_viewer.camera.path import (
    FOV_RANGE,
    FPS_RANGE,
    MAX_DURATION,
    MAX_FRAMES,
    MAX_KEYFRAMES,
    CameraPath,
    Interpolation,
    Keyframe,
)
from raygs_viewer.camera.rotation import is_rotation
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.capture.document_entries import (
    AXES_KEY,
    load_axes_entry,
    load_settings_entry,
    load_stereo_entry,
    reading_entry,
    stereo_entry,
)
from raygs_viewer.capture.camera_entries import ROTATION_TOLERANCE
from raygs_viewer.capture.edit_file import read_edit_json
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.capture.nerfstudio import NerfstudioPath, is_nerfstudio, read_nerfstudio, save_nerfstudio
from raygs_viewer.capture.screenshot import MAX_SCREENSHOT_SIDE, with_relative_scene_path
from raygs_viewer.capture.sidecar import (
    SHA256_HEX,
    document_head,
    scene_mismatch_warning,
)
from raygs_viewer.errors import UserError
from raygs_viewer.files import write_atomically
from raygs_viewer.jsonfile import JsonFields, json_text, parse_json, read_json_file, show_json
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.source import SceneSource, is_demo

#: The formats a document is read from.
RAYGS, NERFSTUDIO = "raygs", "nerfstudio"
KINDS = (RAYGS, NERFSTUDIO)
#: Largest render width or height a path file may ask for (pixels): a frame is rendered
#: as a screenshot is.
MAX_IMAGE_SIZE = MAX_SCREENSHOT_SIDE

PATH_FORMAT = "raygs-viewer camera path"
PATH_VERSION = 2
#: The first version with "edits" (the window's edit document: the scene was edited);
#: a file without edits is written as version 1, which every reader reads.
EDITS_PATH_VERSION = 2
PATH_SUFFIXES = (".json",)

_TOP_REQUIRED = ("format", "version", "image", "path", "keyframes")
_TOP_OPTIONAL = ("program", "created", "scene", "settings", "stereo", "extra", "edits")
# How far "path.up" may be from unit length (a hand-edited file writes 0.7071).
_UNIT_TOLERANCE = 1e-6


@dataclass(frozen=True)
class PathDocument:
    """path: the keyframes and their timing. width, height: the size of each frame's
    camera in pixels (with stereo, of each eye; capture.path_render.frame_size gives the frames').
    settings: None for the reader's defaults (a nerfstudio file has none). stereo: None
    for mono. scene_path: "demo" or an absolute path, None when unknown (nerfstudio);
    scene_sha256: its hex digest (None: unknown, never checked); scene_count,
    scene_sh_degree: the scene's gaussian count and SH degree, when known. scene_axes:
    the axes a .spz scene was read in (None: another format, or not recorded;
    render-path then reads it as its options say). source: the
    file it was read from. kind: the format it was read from (one of KINDS). extra:
    free-form details of the window (the file's "extra"). notes: one-line remarks about
    what the reader could not honour (e.g. a nerfstudio crop box), for the caller to show.
    edits: the edit document's JSON where the scene was edited in the window
    (``capture.edit_file``: render-path leaves its deleted gaussians out), else None."""

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
    scene_axes: FileAxes | None = None
    edits: dict | None = None


# --------------------------------------------------------------------------- writing


def path_document_json(doc: PathDocument, extra: dict | None = None) -> dict:
    """The path file's JSON object for ``doc`` (without "scene.relative_path", which
    depends on where it is saved). ``extra`` is merged over ``doc.extra``."""
    path = doc.path
    interpolation = path.interpolation
    scene = None
    if doc.scene_path is not None:
        scene = {"path": SceneSource(doc.scene_path).recorded_path,
                 "sha256": doc.scene_sha256,
                 "count": None if doc.scene_count is None else int(doc.scene_count),
                 "sh_degree": None if doc.scene_sh_degree is None else int(doc.scene_sh_degree),
                 **reading_entry(doc.scene_axes)}
    return {
        **document_head(PATH_FORMAT, EDITS_PATH_VERSION if doc.edits is not None else 1),
        "scene": scene,
        "image": {"width": int(doc.width), "height": int(doc.height)},
        "settings": None if doc.settings is None else dataclasses.asdict(doc.settings),
        "stereo": None if doc.stereo is None else stereo_entry(doc.stereo),
        "path": {"duration": float(path.duration), "fps": float(path.fps), "loop": bool(interpolation.loop),
                 "alpha": float(interpolation.alpha), "tension": float(interpolation.tension),
                 "up": [float(x) for x in interpolation.up]},
        "keyframes": [_keyframe_entry(k) for k in path.keyframes],
        "extra": {**doc.extra, **(extra or {})},
        **({} if doc.edits is None else {"edits": doc.edits}),
    }


def _keyframe_entry(keyframe: Keyframe) -> dict:
    pose = keyframe.pose
    return {"position": np.asarray(pose.position, np.float64).tolist(),
            "rotation": np.asarray(pose.R, np.float64).T.tolist(),
            "fov": float(keyframe.fov_y_degrees),
            "time": None if keyframe.time is None else float(keyframe.time)}


def save_path_document(doc: PathDocument, file: str | os.PathLike, overwrite: bool = False,
                       extra: dict | None = None) -> Path:
    """Writes ``doc`` as a path file, atomically; an existing file is replaced only with
    ``overwrite``. The document is checked like a loaded file first, so nothing is
    written that :func:`load_path_document` would refuse. Returns the path written."""
    file = check_output_path(file, overwrite, PATH_SUFFIXES)
    data = with_relative_scene_path(path_document_json(doc, extra), file.parent)
    try:
        text = json_text(data)
    except ValueError:
        raise UserError(f"{file}: the camera path holds a non-finite number; not saved") from None
    read_path_json(parse_json(text, file), file)
    write_atomically(file, text.encode("utf-8"), overwrite)
    return file


def export_nerfstudio(doc: PathDocument, file: str | os.PathLike, overwrite: bool = False) -> Path:
    """Writes ``doc``'s path at its size as a nerfstudio camera_path file (the format has
    no place for the rest), never replacing a file without ``overwrite``. Returns the
    path written."""
    return save_nerfstudio(NerfstudioPath(doc.path, doc.width, doc.height), file, overwrite)


# --------------------------------------------------------------------------- reading


def load_path_document(file: str | os.PathLike) -> PathDocument:
    """A camera path file of either format (raygs-viewer's or nerfstudio's
    ``camera_path``, told apart by the content), validated; any problem is a one-line
    UserError naming the file and the field."""
    file = Path(file)
    data = read_json_file(file, "a camera path .json file")
    if is_nerfstudio(data):
        sized = read_nerfstudio(data, str(file))
        return PathDocument(sized.path, sized.width, sized.height, source=file, kind=NERFSTUDIO, notes=sized.notes)
    return read_path_json(data, file)


def read_path_json(data, file: Path) -> PathDocument:
    """The document of a parsed raygs-viewer path file (``file`` names it in messages)."""
    what = "not a camera path file (expected a raygs-viewer camera path or a nerfstudio camera_path JSON"
    if not isinstance(data, dict):
        raise UserError(f"{file}: {what} object)")
    if "format" not in data:
        raise UserError(f"{file}: {what}; it has neither 'format' nor 'camera_path')")
    if data["format"] != PATH_FORMAT:
        raise UserError(f"{file}: {what}; 'format' is {show_json(data['format'])}, "
                        f"expected {show_json(PATH_FORMAT)})")
    fields = JsonFields(file, data)
    version = fields.version(PATH_VERSION, "camera path")
    fields.keys("", data, _TOP_REQUIRED, _TOP_OPTIONAL)
    _check_program(fields)

    scene = _load_scene(fields)
    fields.keys("image", fields.get("image", dict), ("width", "height"))
    width, height = (_image_side(fields, f"image.{key}") for key in ("width", "height"))
    settings = None if data.get("settings") is None else load_settings_entry(fields)
    stereo = None if data.get("stereo") is None else load_stereo_entry(fields)
    path = _load_path(fields)
    extra = {} if data.get("extra") is None else fields.get("extra", dict)
    edits = fields.get("edits", dict) if "edits" in data else None
    if edits is not None and version < EDITS_PATH_VERSION:
        raise UserError(f"{file}: 'edits' needs camera path version {EDITS_PATH_VERSION}, the file says {version}")
    if edits is not None:
        read_edit_json(edits, f"{file}: 'edits'")  # a broken record is refused here, not after a long render
    return PathDocument(path, width, height, settings, stereo, scene.get("path"), scene.get("sha256"),
                        source=file, kind=RAYGS, scene_count=scene.get("count"),
                        scene_sh_degree=scene.get("sh_degree"), extra=dict(extra),
                        scene_axes=scene.get("axes"), edits=edits)


def _check_program(fields: JsonFields) -> None:
    if fields.data.get("program") is not None:
        fields.keys("program", fields.get("program", dict), ("name", "version"))
        fields.get("program.name", str)
        fields.get("program.version", str)
    if fields.data.get("created") is not None:
        fields.get("created", str)


def _load_scene(fields: JsonFields) -> dict:
    """The "scene" record as {path, sha256, count, sh_degree, axes} ({} when null or absent)."""
    file = fields.path
    if fields.data.get("scene") is None:
        return {}
    scene = fields.get("scene", dict)
    fields.keys("scene", scene, ("path", "sha256"), ("count", "sh_degree", AXES_KEY, "relative_path"))
    path = fields.get("scene.path", str)
    if not is_demo(path) and not os.path.isabs(path):
        raise UserError(f"{file}: 'scene.path' must be \"demo\" or an absolute path, got {show_json(path)}")
    sha = None
    if scene["sha256"] is not None:
        sha = fields.get("scene.sha256", str)
        if not SHA256_HEX.fullmatch(sha):
            raise UserError(f"{file}: 'scene.sha256' must be 64 lowercase hex digits or null, got {show_json(sha)}")
    record = {"path": path, "sha256": sha, "count": None, "sh_degree": None,
              "axes": load_axes_entry(fields)}
    if scene.get("count") is not None:
        record["count"] = fields.get("scene.count", int)
        if record["count"] < 0:
            raise UserError(f"{file}: 'scene.count' must not be negative, got {record['count']}")
    if scene.get("sh_degree") is not None:
        record["sh_degree"] = fields.get("scene.sh_degree", int)
        if record["sh_degree"] not in (0, 1, 2, 3):
            raise UserError(f"{file}: 'scene.sh_degree' must be 0, 1, 2 or 3, got {record['sh_degree']}")
    if "relative_path" in scene:
        fields.get("scene.relative_path", str)
    return record


def _image_side(fields: JsonFields, dotted: str) -> int:
    value = fields.get(dotted, int)
    if not 1 <= value <= MAX_IMAGE_SIZE:
        raise UserError(f"{fields.path}: '{dotted}' must be from 1 to {MAX_IMAGE_SIZE}, got {show_json(value)}")
    return value


def _number_in(fields: JsonFields, dotted: str, low: float, high: float, low_open: bool = False) -> float:
    value = fields.get(dotted, float)
    if not (low < value if low_open else low <= value) or value > high:
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        raise UserError(f"{fields.path}: '{dotted}' must be in {interval}, got {show_json(value)}")
    return value


def _load_path(fields: JsonFields) -> CameraPath:
    file = fields.path
    section = fields.get("path", dict)
    defaults = Interpolation()
    fields.keys("path", section, ("duration", "fps"), ("loop", "alpha", "tension", "up"))
    duration = _number_in(fields, "path.duration", 0.0, MAX_DURATION, low_open=True)
    fps = _number_in(fields, "path.fps", *FPS_RANGE)
    frames = max(1, round(duration * fps))
    if frames > MAX_FRAMES:
        raise UserError(f"{file}: 'path.duration' {duration:g} s at 'path.fps' {fps:g} is {frames} frames "
                        f"(at most {MAX_FRAMES})")
    loop = fields.get("path.loop", bool) if "loop" in section else defaults.loop
    alpha = _number_in(fields, "path.alpha", 0.0, 1.0) if "alpha" in section else defaults.alpha
    tension = _number_in(fields, "path.tension", 0.0, 1.0) if "tension" in section else defaults.tension
    up = defaults.up
    if "up" in section:
        vector = fields.array("path.up", (3,))
        if abs(math.sqrt(float(vector @ vector)) - 1.0) > _UNIT_TOLERANCE:
            raise UserError(f"{file}: 'path.up' must be a unit vector, got {show_json(section['up'])}")
        up = tuple(float(x) for x in vector)

    entries = fields.get("keyframes", list)
    if not entries:
        raise UserError(f"{file}: 'keyframes' is empty (a camera path needs at least one keyframe)")
    if len(entries) > MAX_KEYFRAMES:
        raise UserError(f"{file}: 'keyframes' has {len(entries)} entries (at most {MAX_KEYFRAMES})")
    keyframes = [_load_keyframe(file, i, entry, duration, loop) for i, entry in enumerate(entries)]
    _check_times(file, keyframes)
    try:
        return CameraPath(tuple(keyframes), duration, fps, Interpolation(alpha, tension, loop, up))
    except (ValueError, UserError) as exc:  # a check of CameraPath's own that the file breaks
        raise UserError(f"{file}: 'path': {' '.join(str(exc).split())}") from None


def _load_keyframe(file: Path, index: int, entry, duration: float, loop: bool) -> Keyframe:
    name = f"keyframes[{index}]"
    fields = JsonFields.entry(file, name, entry)
    fields.keys(name, entry, ("position", "rotation", "fov"), ("time",))
    position = fields.array(f"{name}.position", (3,))
    rotation = fields.array(f"{name}.rotation", (3, 3))
    if not is_rotation(rotation, ROTATION_TOLERANCE):
        raise UserError(f"{file}: '{name}.rotation' is not a rotation matrix")
    fov = _number_in(fields, f"{name}.fov", *FOV_RANGE)
    time = None
    if entry.get("time") is not None:
        time = fields.get(f"{name}.time", float)
        if not 0.0 <= time <= duration or (loop and time == duration):
            raise UserError(f"{file}: '{name}.time' must be in [0, {duration:g}{')' if loop else ']'} "
                            f"('path.duration'{', a loop' if loop else ''}), got {show_json(time)}")
    return Keyframe(Pose(position, rotation.T), fov, time)


def _check_times(file: Path, keyframes: list[Keyframe]) -> None:
    last = None
    for index, keyframe in enumerate(keyframes):
        if keyframe.time is None:
            continue
        if last is not None and keyframe.time <= last[1]:
            raise UserError(f"{file}: 'keyframes[{index}].time' {keyframe.time:g} is not after "
                            f"'keyframes[{last[0]}].time' {last[1]:g} (times increase along the path)")
        last = index, keyframe.time


# --------------------------------------------------------------------------- the scene


def scene_mismatch(doc: PathDocument, scene_name: str, actual_sha256: str | None = None) -> str | None:
    """A one-line warning when ``scene_name`` ("demo" or a file) is not the scene the
    path was recorded on (by SHA-256; ``actual_sha256``: its digest when the caller
    already has it); None when it is, or when the document records no hash. A warning,
    not an error: a path recorded on one training run is often rendered on another run
    of the same scene."""
    return scene_mismatch_warning(
        document=doc.source.name if doc.source is not None else "the camera path", recorded_path=doc.scene_path,
        recorded_sha256=doc.scene_sha256, scene_name=scene_name, actual_sha256=actual_sha256, verb="recorded",
        consequence="the views may not match")
