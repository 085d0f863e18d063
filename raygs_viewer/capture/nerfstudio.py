"""nerfstudio's ``camera_path`` JSON (what its viewer's *Render* tab writes and
``ns-render camera-path`` reads), imported and exported as a :class:`NerfstudioPath`:
a camera path, its render size and the notes of what an import could not honour.
:mod:`raygs_viewer.capture.path_file` reads either format into its path document.

The fields (nerfstudio's ``cameras/camera_paths.get_path_from_json``,
``scripts/render.py`` and ``viewer/render_panel.py``)::

    {"render_width": W, "render_height": H,       # pixels
     "fps": 30.0, "seconds": 5.0,                   # ns-render plays len(camera_path) / seconds
     "camera_type": "perspective",                  # optional (perspective when absent)
     "is_cycle": false, "smoothness_value": 0.0,    # optional: the viewer's loop and spline tension
     "keyframes": [...],                            # optional: the viewer's own keyframes (below)
     "crop": null or {...},                         # optional: a crop box
     "camera_path": [{"camera_to_world": 16 numbers,  # row-major 4x4 camera-to-world
                      "fov": 50.0,                     # vertical, degrees: focal = H / 2 / tan(fov / 2)
                      "aspect": 1.777}, ...]}          # W / H (not read by ns-render)

Axes: a nerfstudio camera is an OpenGL camera (x right, y up, z back: it looks down its
-z), ours an OpenCV one (x right, y down, z forward), so the camera-to-world rotation
converts as ``c2w_cv = c2w_gl @ diag(1, -1, -1)`` (its own inverse) and the centre
stays. The world frame passes through unchanged: a nerfstudio path lives in
nerfstudio's world (its dataparser's orientation and scale), which is the world of a
splatfacto PLY export (``ns-export gaussian-splat``) but not of an INRIA PLY trained on
the same capture.

Import: each ``camera_path`` entry becomes a keyframe with an explicit time
``k * seconds / (n - 1)`` (a cycle: ``k * seconds / n``), the path's duration is
``seconds`` and its frame rate ``n / seconds`` (as ns-render plays it), so the path's
frames land exactly on the entries. The size comes from render_width/height; the file
has no render settings or scene. The world's up axis is the coordinate axis nearest
the cameras' mean image-up direction. A crop box and per-frame ``render_time`` cannot
be honoured and become the document's notes.

Export: one ``camera_path`` entry per frame of the path (its frame_times), ``fps``,
``seconds = frames / fps``, the render size and aspect, and "keyframes" in the viewer's
format (``matrix``: the keyframe's camera-to-world as in camera_path; ``fov``;
``aspect``; ``override_transition_sec``: seconds from the previous keyframe, so the
viewer's *Load path* puts the keyframes at our times), with no "default_fov", so that the
viewer takes every keyframe's field of view as its own (it ignores a keyframe fov
within 1e-3 of "default_fov" and uses its slider's instead). The viewer interpolates
with its own spline, so only the keyframes and their times carry over, not every
in-between frame; ns-render renders camera_path, which is ours frame for frame. Stereo
and render settings have no place in the format and are not written.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from raygs_viewer.camera.navigation import UP_AXES, Pose
from raygs_viewer.camera.path import (
    FOV_RANGE,
    FPS_RANGE,
    MAX_DURATION,
    MAX_KEYFRAMES,
    CameraPath,
    Interpolation,
    Keyframe,
)
from raygs_viewer.camera.rotation import is_rotation
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.capture.screenshot import MAX_SCREENSHOT_SIDE
from raygs_viewer.capture.camera_entries import ROTATION_TOLERANCE
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import JsonFields, json_text, show_json
from raygs_viewer.files import write_atomically

#: Camera axes: OpenCV from OpenGL and back (a diagonal of signs, its own inverse).
CV_FROM_GL = np.diag([1.0, -1.0, -1.0])
NERFSTUDIO_SUFFIXES = (".json",)
_REQUIRED = ("render_width", "render_height", "seconds", "camera_path")
# A camera_to_world's last row is (0, 0, 0, 1); one far from it is a projective or
# column-major (transposed) matrix, not a pose.
_LAST_ROW_TOLERANCE = 1e-6
_DEFAULT_FPS = 30.0


@dataclass(frozen=True)
class NerfstudioPath:
    """What a nerfstudio camera_path holds for us: the path, each frame's size in pixels
    (render_width, render_height), and one-line notes of what the reader could not
    honour (a crop box, per-frame render times), for the caller to show."""

    path: CameraPath
    width: int
    height: int
    notes: tuple[str, ...] = ()


def is_nerfstudio(data) -> bool:
    """Whether parsed JSON looks like a nerfstudio camera path (an object with
    "camera_path" and no raygs-viewer "format")."""
    return isinstance(data, dict) and "camera_path" in data and "format" not in data


# --------------------------------------------------------------------------- import


def read_nerfstudio(data: dict, where: str) -> NerfstudioPath:
    """The path of a parsed nerfstudio camera path file; ``where`` (the file) starts every
    message. Any problem is a one-line UserError naming the field."""
    if not isinstance(data, dict):
        raise UserError(f"{where}: a nerfstudio camera path must be a JSON object")
    fields = JsonFields(where, data)
    for key in _REQUIRED:
        if key not in data:
            raise UserError(f"{where}: missing '{key}' (a nerfstudio camera path needs {', '.join(_REQUIRED)})")
    if "camera_type" in data:
        camera_type = fields.get("camera_type", str)
        if camera_type.lower() != "perspective":
            raise UserError(f"{where}: nerfstudio 'camera_type' {show_json(camera_type)} is not supported "
                            f"(raygs-viewer renders perspective cameras)")
    width, height = (_size(fields, key) for key in ("render_width", "render_height"))
    seconds = fields.get("seconds", float)
    if not 0.0 < seconds <= MAX_DURATION:
        raise UserError(f"{where}: 'seconds' must be in (0, {MAX_DURATION:g}], got {show_json(seconds)}")
    loop = False if data.get("is_cycle") is None else fields.get("is_cycle", bool)
    tension = Interpolation().tension
    if data.get("smoothness_value") is not None:
        tension = fields.get("smoothness_value", float)
        if not 0.0 <= tension <= 1.0:
            raise UserError(f"{where}: 'smoothness_value' must be in [0, 1], got {show_json(tension)}")
    if data.get("keyframes") is not None:
        fields.get("keyframes", list)  # the viewer's own; the frames in camera_path are what ns-render plays

    entries = fields.get("camera_path", list)
    count = len(entries)
    if count == 0:
        raise UserError(f"{where}: 'camera_path' is empty (a camera path needs at least one camera)")
    if count > MAX_KEYFRAMES:
        raise UserError(f"{where}: 'camera_path' has {count} entries (at most {MAX_KEYFRAMES})")
    if count > 1:
        fps = count / seconds
        if not FPS_RANGE[0] <= fps <= FPS_RANGE[1]:
            raise UserError(f"{where}: {count} 'camera_path' entries in 'seconds' {seconds:g} are {fps:g} frames "
                            f"per second (raygs-viewer plays {FPS_RANGE[0]:g} to {FPS_RANGE[1]:g})")
        duration = seconds
    else:  # one still frame, whatever "seconds" says: shown for one frame of the file's rate
        fps = _DEFAULT_FPS if data.get("fps") is None else fields.get("fps", float)
        fps = min(max(fps, FPS_RANGE[0]), FPS_RANGE[1])
        duration = 1.0 / fps
    step = duration / (count if loop else max(count - 1, 1))  # as CameraPath.frame_times spaces its frames

    keyframes, ups, render_time = [], [], False
    for index, entry in enumerate(entries):
        pose, fov, up = _camera(where, index, entry)
        time = min(index * step, duration)  # k * step may round one ulp past the end
        keyframes.append(Keyframe(pose, fov, time))
        ups.append(up)
        render_time = render_time or "render_time" in entry
    notes = []
    if data.get("crop") is not None:
        notes.append(f"{Path(where).name}: nerfstudio's 'crop' box is ignored (raygs-viewer renders the whole scene)")
    if render_time:
        notes.append(f"{Path(where).name}: nerfstudio's per-frame 'render_time' is ignored (the scene is static)")
    interpolation = Interpolation(tension=tension, loop=loop, up=_nearest_axis(np.mean(ups, axis=0)))
    path = CameraPath(tuple(keyframes), duration, fps, interpolation)
    return NerfstudioPath(path, width, height, tuple(notes))


def _size(fields: JsonFields, key: str) -> int:
    # A whole number, also when written as a float (scripts often do: 1920.0); a frame
    # is rendered as a screenshot is, so its side has the screenshot's limit.
    value = fields.get(key, float)
    if not (value.is_integer() and 1 <= value <= MAX_SCREENSHOT_SIDE):
        raise UserError(f"{fields.path}: '{key}' must be a whole number from 1 to {MAX_SCREENSHOT_SIDE}, "
                        f"got {show_json(fields.data[key])}")
    return int(value)


def _camera(where: str, index: int, entry) -> tuple[Pose, float, np.ndarray]:
    """One camera_path entry: its pose (OpenCV axes), vertical fov and image-up direction."""
    name = f"camera_path[{index}]"
    fields = JsonFields.entry(where, name, entry)
    matrix = fields.array(f"{name}.camera_to_world", (16,)).reshape(4, 4)
    if np.abs(matrix[3] - [0.0, 0.0, 0.0, 1.0]).max() > _LAST_ROW_TOLERANCE:
        raise UserError(f"{where}: '{name}.camera_to_world' must end in the row 0 0 0 1 (a row-major camera-to-world "
                        f"matrix), got {show_json(matrix[3].tolist())}")
    rotation = matrix[:3, :3]
    if not is_rotation(rotation, ROTATION_TOLERANCE):
        raise UserError(f"{where}: '{name}.camera_to_world' is not a rotation and a translation "
                        f"(scaled, sheared or mirrored)")
    fov = fields.get(f"{name}.fov", float)
    if not FOV_RANGE[0] <= fov <= FOV_RANGE[1]:
        raise UserError(f"{where}: '{name}.fov' must be in [{FOV_RANGE[0]:g}, {FOV_RANGE[1]:g}] degrees, "
                        f"got {show_json(fov)}")
    if "aspect" in entry:
        aspect = fields.get(f"{name}.aspect", float)
        if aspect <= 0:
            raise UserError(f"{where}: '{name}.aspect' must be positive, got {show_json(aspect)}")
    return Pose(matrix[:3, 3], (rotation @ CV_FROM_GL).T), fov, rotation[:, 1]


def _nearest_axis(direction: np.ndarray) -> tuple[float, float, float]:
    """The UP_AXES direction nearest ``direction`` (the cameras' mean up)."""
    axes = list(UP_AXES.values())
    return axes[int(np.argmax([np.dot(axis, direction) for axis in axes]))]


# --------------------------------------------------------------------------- export


def _matrix(pose: Pose) -> list[float]:
    """Row-major 4x4 camera-to-world of ``pose`` in OpenGL camera axes, 16 floats."""
    matrix = np.eye(4)
    matrix[:3, :3] = np.asarray(pose.R, np.float64).T @ CV_FROM_GL
    matrix[:3, 3] = pose.position
    return matrix.reshape(-1).tolist()


def nerfstudio_json(sized: NerfstudioPath) -> dict:
    """nerfstudio's camera_path JSON of ``sized``: one entry per frame (see the module's
    docstring; its notes are not written). UserError for a path without keyframes."""
    path = sized.path
    if not path.keyframes:
        raise UserError("the camera path has no keyframes: nothing to export")
    width, height = int(sized.width), int(sized.height)
    aspect = width / height
    times = path.frame_times()
    frames = [path.pose_at(float(t)) for t in times]
    loop = bool(path.interpolation.loop)
    key_times = path.keyframe_times()
    keyframes = []
    for index, keyframe in enumerate(path.keyframes):
        if index > 0:
            transition = float(key_times[index] - key_times[index - 1])
        else:  # the viewer's first keyframe's transition is the loop's closing one
            transition = float(path.duration - key_times[-1]) if loop else None
        keyframes.append({"matrix": _matrix(keyframe.pose), "fov": float(keyframe.fov_y_degrees), "aspect": aspect,
                          "override_transition_enabled": transition is not None,
                          "override_transition_sec": transition})
    spans = len(path.keyframes) if loop else max(len(path.keyframes) - 1, 1)
    return {
        "camera_type": "perspective",
        "render_width": width,
        "render_height": height,
        "fps": float(path.fps),
        "seconds": len(frames) / float(path.fps),
        "is_cycle": loop,
        "smoothness_value": float(path.interpolation.tension),
        "default_transition_sec": float(path.duration) / spans,
        "keyframes": keyframes,
        "camera_path": [{"camera_to_world": _matrix(frame.pose), "fov": float(frame.fov_y_degrees), "aspect": aspect}
                        for frame in frames],
    }


def save_nerfstudio(sized: NerfstudioPath, file: str | os.PathLike, overwrite: bool = False) -> Path:
    """Writes ``sized`` as a nerfstudio camera_path file, atomically; an existing file is
    replaced only with ``overwrite``. Checked like an imported file first, so nothing is
    written that :func:`read_nerfstudio` would refuse. Returns the path written."""
    file = check_output_path(file, overwrite, NERFSTUDIO_SUFFIXES)
    data = nerfstudio_json(sized)
    try:
        text = json_text(data)
    except ValueError:
        raise UserError(f"{file}: the camera path holds a non-finite number; not saved") from None
    read_nerfstudio(data, str(file))
    write_atomically(file, text.encode("utf-8"), overwrite)
    return file
