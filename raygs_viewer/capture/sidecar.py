"""The JSON sidecar saved beside every screenshot: everything needed to render it again.

``raygs-viewer render --sidecar SHOT.json --out SHOT2.png`` reads it back, finds the
scene (checking its SHA-256), and renders the same camera with the same settings
through :func:`raygs_viewer.capture.screenshot.render_tiled`, like the window did.

Layout (version 1)::

    {"format": "raygs-viewer screenshot", "version": 1,
     "program": {"name": "raygs-viewer", "version": "0.1.0"},
     "created": "2025-01-31T12:00:00Z",                        # UTC
     "image": {"width": W, "height": H, "scale": K},           # the screenshot's size
     "scene": {"path": "/abs/scene.ply" or "demo", "sha256": "...", "count": N,
               "sh_degree": d, "filter_fused": false,
               ...,                                            # how it was read: document_entries.reading_entry
               "relative_path": "../scene.ply"},               # added when saved, from the sidecar's folder
     "camera": {INRIA cameras.json entry, cx and cy always present},
     "world_to_camera": {"R": 3x3, "t": 3},                    # the exact float64 pose
     "window": {"camera": {...}, "world_to_camera": {...}},    # optional: the on-screen view before scaling
     "settings": {every RenderSettings field},
     "render_mode": "raygs",                                   # = settings.mode
     "stereo": {...},                                          # version 2, stereo images only (below)
     "order": {...},                                           # version 6, an order sorted elsewhere (below)
     "extra": {...}}                                           # free-form, from the window

A stereo image (version 2) adds::

     "stereo": {"ipd": 0.063, "convergence": 2.0, "scene_scale": 1.0,   # metres, metres, metres/unit
                "layout": "sbs",                                        # one of stereo.LAYOUTS
                "lens": null or {"k1": .., "k2": .., "chroma_red": .., "chroma_blue": ..},
                "headset": null or {"name", "label", "width", "height", "fov_x", "fov_y"}}

A picture of another channel than colour (version 3; docs/geometry.md) adds::

     "channel_view": {"channel": "depth",            # one of channel_pictures.PICTURE_CHANNELS
                      "depth_range": [near, far],    # the range the picture used; null if none
                      "normal_space": "camera",      # or "world"
                      "alpha_threshold": 0.05}       # the geometry pictures' mask; absent: 0

so that ``render --sidecar`` draws the same picture (a colour screenshot has none).

A ``.spz`` scene is read again in the axes it was read in (``SPZ_AXES``; older
sidecars: "rub"); "rdf" makes version 4, which a reader that would show it upside down (as "rub") refuses.

Its "camera" is the midpoint between the eyes (each eye has that size) and "image" is
the composed size (twice the width side by side). As in "settings", a key that a file
written before it existed lacks takes its default (a headset's fields have none), and
a key this version does not know is an error. A file is written with the lowest
version that describes it, so older readers keep reading mono sidecars and refuse
stereo ones instead of rendering them as one eye.

An image whose back-to-front order was not sorted from its own camera (version 6: each
eye of a headset, drawn with the order the window's background sort made from the eyes'
midpoint, possibly a frame earlier) adds::

     "order": {"sorted_from": {camera entry, "world_to_camera": {"R": 3x3, "t": 3}},  # the sort's camera
               "culled_for": [{camera entry, "world_to_camera": {...}}, ...] or null, # null: sorted_from's
               "colour_from": [x, y, z] or null}      # the SH colour's world viewpoint; null: "camera"'s centre

so that ``render --sidecar`` sorts from the same camera (its pose and intrinsics: the
cull's dilation reads its fx), keeps what the same frusta see, evaluates the colour from
the same point, and reproduces the image to the bit (:class:`OrderViewpoint`). Each
camera is written as "camera" and "world_to_camera" are, float64 exact, and every key
of "order" is required. An image that holds one eye is mono: a stereo sidecar with
"order" is refused (both its eyes share the midpoint's order, which "stereo" says).

"render_mode" mirrors ``settings.mode`` (one of :data:`raygs_viewer.render.settings.RENDER_MODES`).
Sidecars written before "settings" had a "mode" take the mode from "render_mode"; when
both are present they must agree.

"camera" and "world_to_camera" describe the screenshot's camera, already scaled to
the image size. Python writes a float as the shortest repr that reads back to the
same bits, so the pose and intrinsics survive the JSON round trip exactly.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import raygs_viewer
from raygs_viewer.camera.pinhole import (
    Camera,
    load_camera,
)
from raygs_viewer.camera.stereo import StereoView, composed_size
from raygs_viewer.capture.camera_entries import (
    OrderViewpoint,
    camera_entry,
    load_camera_entry,
    load_viewpoint_entry,
    pose_entry,
    viewpoint_entry,
)
from raygs_viewer.capture.document_entries import (
    AXES_FIELD,
    load_axes_entry,
    load_levels_entry,
    load_settings_entry,
    load_stereo_entry,
    reading_entry,
    stereo_entry,
)
from raygs_viewer.capture.screenshot import MAX_SCALE
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import JsonFields, read_json_file, show_json
from raygs_viewer.render.channel_pictures import ChannelView
from raygs_viewer.render.settings import RENDER_MODES, RenderSettings
from raygs_viewer.scene.content_hash import arrays_sha256, file_sha256
from raygs_viewer.scene.demo import demo_scene
from raygs_viewer.scene.model import FileAxes, Scene
from raygs_viewer.scene.source import DEMO, SceneSource, is_demo
from raygs_viewer.scene.spz_format import DEFAULT_SPZ_AXES

SIDECAR_FORMAT = "raygs-viewer screenshot"
SIDECAR_VERSION = 6            # the newest this program reads and writes
STEREO_SIDECAR_VERSION = 2     # the first with "stereo"
CHANNEL_SIDECAR_VERSION = 3    # the first with "channel_view"
RDF_SIDECAR_VERSION = 4        # the first with a .spz read in "rdf"
EDITS_SIDECAR_VERSION = 5      # the first with "edits" (capture.edit_file: the scene was edited)
VIEWPOINT_SIDECAR_VERSION = 6  # the first with "order" (sorted from another viewpoint: a headset's eye)

SHA256_HEX = re.compile(r"[0-9a-f]{64}")
# --------------------------------------------------------------------------- hashes


def scene_sha256(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of the file's bytes, streamed (the digest the window records)."""
    return file_sha256(path)


@functools.lru_cache(maxsize=1)
def demo_sha256(generator: Callable[[], Scene] = demo_scene) -> str:
    """:func:`arrays_sha256` of the built-in demo scene (made by ``generator``): a
    screenshot of the demo made by a version with another demo generator is detected
    like a changed scene file."""
    return arrays_sha256(generator())


def document_head(format_name: str, version: int) -> dict:
    """The keys every file this program writes starts with: its format and version,
    the program that wrote it and when (UTC)."""
    return {"format": format_name, "version": int(version),
            "program": {"name": "raygs-viewer", "version": raygs_viewer.__version__},
            "created": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}


def scene_mismatch_warning(*, document: str, recorded_path: str | None, recorded_sha256: str | None,
                           scene_name: str, actual_sha256: str | None, verb: str, consequence: str) -> str | None:
    """A one-line warning when ``scene_name`` ("demo" or a file; ``actual_sha256`` its
    digest when the caller has it) is not the scene a ``document`` (a path file, a
    measurements file) was ``verb`` ("recorded", "measured") on, by SHA-256; None when it
    is, or when nothing was recorded. A warning, not an error: another training run of
    the same scene is often what the user means, and ``consequence`` says what may be off."""
    if recorded_sha256 is None:
        return None
    if actual_sha256 is None:
        actual_sha256 = demo_sha256() if is_demo(scene_name) else scene_sha256(scene_name)
    if actual_sha256 == recorded_sha256:
        return None
    hashes = f"sha256 {recorded_sha256[:12]}… recorded, {actual_sha256[:12]}… now"
    if is_demo(scene_name) and is_demo(recorded_path):
        return f"{document} was {verb} on another version of the demo scene ({hashes}); {consequence}"
    recorded = "the demo scene" if is_demo(recorded_path) else (recorded_path or "another scene")
    scene = "the demo scene" if is_demo(scene_name) else scene_name
    return f"{document} was {verb} on {recorded}, not on {scene} ({hashes}); {consequence}"


# --------------------------------------------------------------------------- writing


def build_sidecar(*, scene_path: str, scene_sha256: str, scene, camera: Camera, settings: RenderSettings,
                  scale: float, window_camera: Camera | None = None, extra: dict | None = None,
                  stereo: StereoView | None = None, channel_view: ChannelView | None = None,
                  levels: tuple[int, ...] | None = None, edits: dict | None = None,
                  viewpoint: OrderViewpoint | None = None) -> dict:
    """The sidecar of a screenshot rendered at ``camera`` (the window's camera already
    scaled by ``scale``) with ``settings``. ``scene_path`` is the loaded file ("demo"
    for the demo), recorded as an absolute path; ``window_camera`` is the on-screen
    view; ``extra`` holds free-form details of the window (up axis, navigation, GL
    renderer, ...). ``stereo``: the image is that stereo view around ``camera``.
    ``channel_view``: the image is that picture of a channel (its ``depth_range`` the
    range the picture used); colour (None, or the rgb channel) records nothing.
    ``levels``: a streamed SOG's levels read when the levels were chosen per view
    (the choice depends on them: a screenshot taken while finer levels were still being
    read, or on a GPU that held fewer, re-renders from those alone). ``edits``: the edit
    document (``capture.edit_file``) of a scene edited in the window, whose deletions
    the image shows. ``viewpoint``: where the image's order was sorted from when not
    from ``camera`` (a headset's eye; mono images only)."""
    if viewpoint is not None and stereo is not None:
        raise ValueError("a stereo image's eyes share the midpoint's order: it records no viewpoint")
    recorded_path = SceneSource(scene_path).recorded_path
    width, height = (camera.width, camera.height) if stereo is None else \
        composed_size(camera.width, camera.height, stereo.layout)
    axes = scene.axes  # a .spz's (scene.model.FileAxes)
    sidecar = {
        **document_head(SIDECAR_FORMAT, max(STEREO_SIDECAR_VERSION if stereo is not None else 1,
                                            CHANNEL_SIDECAR_VERSION if _is_picture(channel_view) else 1,
                                            RDF_SIDECAR_VERSION if axes and axes.assumed != DEFAULT_SPZ_AXES else 1,
                                            EDITS_SIDECAR_VERSION if edits is not None else 1,
                                            VIEWPOINT_SIDECAR_VERSION if viewpoint is not None else 1)),
        "image": {"width": int(width), "height": int(height), "scale": float(scale)},
        "scene": {"path": recorded_path, "sha256": scene_sha256, "count": int(scene.count),
                  "sh_degree": int(scene.sh_degree), "filter_fused": bool(scene.filter_fused),
                  **reading_entry(axes, levels)},
        "camera": camera_entry(camera),
        "world_to_camera": pose_entry(camera),
        "settings": dataclasses.asdict(settings),
        "render_mode": settings.mode,
        "extra": dict(extra or {}),
    }
    if stereo is not None:
        sidecar["stereo"] = stereo_entry(stereo)
    if _is_picture(channel_view):
        sidecar["channel_view"] = channel_view_entry(channel_view)
    if window_camera is not None:
        sidecar["window"] = {"camera": camera_entry(window_camera), "world_to_camera": pose_entry(window_camera)}
    if edits is not None:
        sidecar["edits"] = edits
    if viewpoint is not None:
        sidecar["order"] = viewpoint_entry(viewpoint)
    return sidecar


def channel_view_entry(view: ChannelView) -> dict:
    """The "channel_view" section: the channel, its depth range, the normals' space, the
    alpha threshold."""
    return {"channel": view.channel, "depth_range": None if view.depth_range is None else list(view.depth_range),
            "normal_space": view.normal_space, "alpha_threshold": view.alpha_threshold}


def _is_picture(view: ChannelView | None) -> bool:
    return view is not None and view.channel != "rgb"


# --------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class ImageView:
    """What an image shows, as a sidecar records it and the window hands a screenshot:
    the camera, the render settings, the stereo view (None: mono) and the picture of a
    channel shown instead of the colour (None: colour)."""

    camera: Camera
    settings: RenderSettings
    stereo: StereoView | None
    channel_view: ChannelView | None


@dataclass(frozen=True)
class Sidecar(ImageView):
    """A validated sidecar: the screenshot's view (camera: R (3, 3), t (3,) float64,
    exactly as written) and where it came from. path: the .json file. scene_path: the
    recorded scene (absolute path or "demo"). scene_sha256: hex digest of the scene
    file (or of the demo's arrays). scale: the window-to-screenshot scale
    (informational: camera already has the screenshot's size). render_mode: the
    settings' mode (one of RENDER_MODES).
    raw: the parsed JSON, for fields only the window reads. axes: the axes a .spz
    scene was read in (None: another format, or an older sidecar: read it as the
    default). levels: the levels of a streamed SOG to read (None: every level that fits).
    edits: the edit document's JSON where the scene was edited (``capture.edit_file``
    reads it), else None. viewpoint: where the order was sorted from when not from
    ``camera`` (its "order"; None: from ``camera``, as a mono image's)."""

    path: Path
    scene_path: str
    scene_sha256: str
    scale: float
    render_mode: str
    raw: dict
    axes: FileAxes | None = None
    levels: tuple[int, ...] | None = None
    edits: dict | None = None
    viewpoint: OrderViewpoint | None = None

    def source(self, scene_path: str) -> SceneSource:
        """The scene ``scene_path`` (:func:`resolve_scene`'s) read as the screenshot's was."""
        return SceneSource(scene_path, levels=self.levels).with_axes(self.axes)


def load_sidecar(path: str | os.PathLike) -> Sidecar:
    """Reads and validates a screenshot sidecar; any problem is a one-line UserError
    naming the file and the field."""
    path = Path(path)
    data = read_json_file(path, "a screenshot's .json sidecar")
    if not isinstance(data, dict):
        raise UserError(f"{path}: not a raygs-viewer screenshot sidecar (expected a JSON object)")
    fields = JsonFields(path, data)

    if "format" not in data:
        raise UserError(f"{path}: not a raygs-viewer screenshot sidecar (no 'format' field)")
    if data["format"] != SIDECAR_FORMAT:
        raise UserError(f"{path}: not a raygs-viewer screenshot sidecar ('format' is "
                        f"{show_json(data.get('format'))}, expected {show_json(SIDECAR_FORMAT)})")
    version = fields.version(SIDECAR_VERSION, "sidecar")

    scene = fields.get("scene", dict)
    scene_path = fields.get("scene.path", str)
    if not scene_path:
        raise UserError(f"{path}: 'scene.path' is empty")
    sha = fields.get("scene.sha256", str)
    if not SHA256_HEX.fullmatch(sha):
        raise UserError(f"{path}: 'scene.sha256' must be 64 lowercase hex digits, got {show_json(sha)}")
    if "relative_path" in scene:
        fields.get("scene.relative_path", str)
    axes = load_axes_entry(fields)
    if axes is not None and axes.assumed != DEFAULT_SPZ_AXES and version < RDF_SIDECAR_VERSION:
        raise UserError(f"{path}: '{AXES_FIELD}' {axes.assumed} needs sidecar version {RDF_SIDECAR_VERSION}, "
                        f"the file says {version}")
    levels = load_levels_entry(fields)

    camera = load_camera_entry(fields)
    stereo = load_stereo_entry(fields) if "stereo" in data else None
    if stereo is not None and version < STEREO_SIDECAR_VERSION:
        raise UserError(f"{path}: 'stereo' needs sidecar version {STEREO_SIDECAR_VERSION}, the file says {version}")
    image = fields.get("image", dict)
    width, height = (camera.width, camera.height) if stereo is None else \
        composed_size(camera.width, camera.height, stereo.layout)
    for key, value in (("width", width), ("height", height)):
        if fields.get(f"image.{key}", int) != value:
            raise UserError(f"{path}: 'image.{key}' {image[key]} differs from the camera's {value}" if stereo is None
                        else f"{path}: 'image.{key}' {image[key]} differs from {value}, the {stereo.layout} "
                             f"image of two {camera.width}x{camera.height} eyes")
    scale = fields.get("image.scale", float)
    if not 0.0 < scale <= MAX_SCALE:
        raise UserError(f"{path}: 'image.scale' must be in (0, {MAX_SCALE:g}], got {show_json(scale)}")

    render_mode = fields.get("render_mode", str)
    if render_mode not in RENDER_MODES:
        raise UserError(f"{path}: unknown 'render_mode' {show_json(render_mode)} (this raygs-viewer renders "
                        f"{', '.join(map(repr, RENDER_MODES))}; the sidecar may come from a newer one)")
    settings = load_settings_entry(fields, render_mode)
    if "extra" in data:
        fields.get("extra", dict)
    channel_view = load_channel_view_entry(fields) if "channel_view" in data else None
    if channel_view is not None and version < CHANNEL_SIDECAR_VERSION:
        raise UserError(f"{path}: 'channel_view' needs sidecar version {CHANNEL_SIDECAR_VERSION}, "
                        f"the file says {version}")
    edits = fields.get("edits", dict) if "edits" in data else None
    if edits is not None and version < EDITS_SIDECAR_VERSION:
        raise UserError(f"{path}: 'edits' needs sidecar version {EDITS_SIDECAR_VERSION}, the file says {version}")
    viewpoint = load_viewpoint_entry(fields) if "order" in data else None
    if viewpoint is not None and version < VIEWPOINT_SIDECAR_VERSION:
        raise UserError(f"{path}: 'order' needs sidecar version {VIEWPOINT_SIDECAR_VERSION}, the file says {version}")
    if viewpoint is not None and stereo is not None:
        raise UserError(f"{path}: 'order' is a mono image's (a headset eye), but the file has 'stereo', whose eyes "
                        f"share the midpoint's order; remove one of them")
    return Sidecar(camera, settings, stereo, channel_view, path=path, scene_path=scene_path, scene_sha256=sha,
                   scale=scale, render_mode=render_mode, raw=data, axes=axes, levels=levels, edits=edits,
                   viewpoint=viewpoint)


def is_sidecar_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a JSON object that says it is a screenshot sidecar (its
    "format"); False for anything unreadable, so the caller's own reader words that error."""
    try:
        data = read_json_file(path, "a JSON file")
    except UserError:
        return False
    return isinstance(data, dict) and data.get("format") == SIDECAR_FORMAT


def load_camera_source(path: str | os.PathLike, index: int = 0) -> Camera:
    """Camera ``index`` of an INRIA cameras.json, or the camera of a screenshot's sidecar
    (its only one, index 0): a screenshot then renders again at another size or with
    other settings (``render --camera SHOT.json``)."""
    if not is_sidecar_file(path):
        return load_camera(path, index)
    camera = load_sidecar(path).camera
    if index != 0:
        raise UserError(f"{path}: --camera-index must be 0..0, got {index} (a screenshot sidecar holds one camera)")
    return camera


def load_channel_view_entry(fields: JsonFields) -> ChannelView:
    """The "channel_view" section: "channel" required; "depth_range" (null: automatic)
    and "normal_space" take ChannelView's defaults where absent; an absent
    "alpha_threshold" is 0, as the pictures were drawn before it existed (unmasked)."""
    entry = fields.get("channel_view", dict)
    fields.keys("channel_view", entry, ("channel",), ("depth_range", "normal_space", "alpha_threshold"))
    channel = fields.get("channel_view.channel", str)
    depth_range = None
    if entry.get("depth_range") is not None:
        depth_range = tuple(float(v) for v in fields.array("channel_view.depth_range", (2,)))
    normal_space = fields.optional("channel_view.normal_space", str, "camera")
    alpha_threshold = fields.optional("channel_view.alpha_threshold", float, 0.0)
    try:
        return ChannelView(channel, depth_range, normal_space, alpha_threshold)
    except UserError as exc:
        raise UserError(f"{fields.path}: 'channel_view': {exc}") from None


# --------------------------------------------------------------------------- the scene


def resolve_scene(sidecar: Sidecar, override: str | None = None) -> str:
    """The scene to load for ``sidecar``: ``override`` if given; else "demo"; else the
    recorded absolute path; else, if that file is gone, the recorded path relative to
    the sidecar's folder (a folder tree moved as a whole), then the same file name in
    the sidecar's folder (scene and screenshot moved together)."""
    if override is not None:
        return override
    recorded = sidecar.scene_path
    if is_demo(recorded):
        return DEMO
    candidates = [Path(recorded)]
    relative = sidecar.raw.get("scene", {}).get("relative_path")
    if relative:
        candidates.append(sidecar.path.parent / relative)
    candidates.append(sidecar.path.parent / Path(recorded).name)
    for candidate in candidates:
        if candidate.exists():  # a file, or the folder of an unbundled SOG scene
            return str(candidate)
    tried = ", ".join(dict.fromkeys(str(c) for c in candidates[1:]))
    raise UserError(f"{sidecar.path}: scene {recorded} not found (nor {tried}); "
                    f"give the scene file as the SCENE argument")


def verify_scene_hash(sidecar: Sidecar, scene_path: str) -> None:
    """UserError unless ``scene_path`` ("demo" or a file) hashes to the sidecar's sha256."""
    if is_demo(scene_path):
        actual = demo_sha256()
        what = "the built-in demo scene differs from the one the screenshot was taken with (another demo " \
               "generator)"
    else:
        actual = scene_sha256(scene_path)
        what = f"{scene_path}: scene file differs from the one the screenshot was taken with"
    if actual != sidecar.scene_sha256:
        raise UserError(f"{what} (sha256 {actual[:12]}… vs {sidecar.scene_sha256[:12]}… in {sidecar.path.name})")
