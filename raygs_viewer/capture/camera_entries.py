"""Cameras as the screenshot sidecar writes and reads them (``capture.sidecar``): an
INRIA cameras.json entry (cx and cy always there) beside its exact float64 pose
("world_to_camera"), both checked to agree when read; and where an image's order was
sorted from when not from its own camera (:class:`OrderViewpoint`, the sidecar's
"order": a headset eye, sorted from the eyes' midpoint and culled for both).

Python writes a float as the shortest repr that reads back to the same bits, so every
pose and intrinsic survives the round trip exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raygs_viewer.camera.pinhole import (
    MAX_COORDINATE,
    Camera,
    camera_from_json,
    camera_to_json,
)
from raygs_viewer.camera.rotation import is_rotation
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import JsonFields

# A pose written by this program is orthonormal to ~1e-15; anything far off is an
# edited or corrupted file, not rounding.
ROTATION_TOLERANCE = 1e-5
# "camera" repeats the pose of "world_to_camera" (for INRIA tools); they must agree,
# or an edit to one of them would silently be ignored.
POSE_AGREEMENT = 1e-6


@dataclass(frozen=True)
class OrderViewpoint:
    """Where an image's back-to-front order was sorted from, when not from the image's
    own camera (a headset's eye draws the order its window sorted from the eyes'
    midpoint): what ``render --sidecar`` needs to draw the same order and colours.

    camera: the camera the sort request was made from (its pose, and the intrinsics
    whose fx the cull's dilation reads). cull_cameras: the cameras whose frusta the cull
    kept (a headset's: both eyes); None: ``camera``'s own. color_origin: (3,) float64
    world point the SH colour was evaluated from (``GLRenderer.render``'s
    ``color_origin``); None: the image camera's centre."""

    camera: Camera
    cull_cameras: tuple[Camera, ...] | None = None
    color_origin: np.ndarray | None = None

    def __post_init__(self):
        if self.cull_cameras is not None:
            object.__setattr__(self, "cull_cameras", tuple(self.cull_cameras))
            if not self.cull_cameras:
                raise ValueError("cull_cameras must hold a camera, or be None (the sort camera's own)")
        if self.color_origin is not None:
            origin = np.array(self.color_origin, dtype=np.float64)  # a copy: the frozen value cannot change
            if origin.shape != (3,):
                raise ValueError(f"color_origin must be a (3,) point, got shape {origin.shape}")
            object.__setattr__(self, "color_origin", origin)


def viewpoint_entry(viewpoint: OrderViewpoint) -> dict:
    """The "order" section (module docstring): each camera as "camera" and
    "world_to_camera" are written, float64 exact."""
    return {"sorted_from": posedcamera_entry(viewpoint.camera),
            "culled_for": None if viewpoint.cull_cameras is None
            else [posedcamera_entry(camera) for camera in viewpoint.cull_cameras],
            "colour_from": None if viewpoint.color_origin is None else viewpoint.color_origin.tolist()}


def posedcamera_entry(camera: Camera) -> dict:
    return {**camera_entry(camera), "world_to_camera": pose_entry(camera)}


def camera_entry(camera: Camera) -> dict:
    entry = camera_to_json(camera)
    # Plain Python numbers: json cannot write numpy's ints or float32.
    entry.update(width=int(camera.width), height=int(camera.height), fx=float(camera.fx), fy=float(camera.fy),
                 cx=float(camera.cx), cy=float(camera.cy))  # cx, cy always: INRIA readers default to the centre
    return entry


def pose_entry(camera: Camera) -> dict:
    return {"R": np.asarray(camera.R, np.float64).tolist(), "t": np.asarray(camera.t, np.float64).tolist()}


def load_viewpoint_entry(fields: JsonFields) -> OrderViewpoint:
    """The "order" section (module docstring): every key required, each camera with its
    exact pose and no key a camera entry does not have, "culled_for" null or a non-empty
    array, "colour_from" null or a finite point."""
    entry = fields.get("order", dict)
    fields.keys("order", entry, ("sorted_from", "culled_for", "colour_from"))
    camera = load_posed_camera(fields, "order.sorted_from")
    cull_cameras = None
    if entry["culled_for"] is not None:
        listed = fields.get("order.culled_for", list)
        if not listed:
            raise UserError(f"{fields.path}: 'order.culled_for' must list the cameras the cull kept, or be null "
                            f"(the sort camera's own)")
        # Each entry through its own fields, named "order.culled_for[i]" in messages.
        cull_cameras = tuple(load_posed_camera(JsonFields(fields.path, {"order": {f"culled_for[{i}]": item}}),
                                                f"order.culled_for[{i}]") for i, item in enumerate(listed))
    origin = None
    if entry["colour_from"] is not None:
        origin = fields.array("order.colour_from", (3,))
        if np.abs(origin).max() > MAX_COORDINATE:  # bounded as a camera position is
            raise UserError(f"{fields.path}: 'order.colour_from' is beyond {MAX_COORDINATE:g} in magnitude")
    return OrderViewpoint(camera, cull_cameras, origin)


#: The keys of a camera entry of "order": what ``camera_entry`` writes, and its pose.
POSED_CAMERA_KEYS = (("width", "height", "position", "rotation", "fx", "fy", "cx", "cy", "world_to_camera"),
                      ("id", "img_name"))


def load_posed_camera(fields: JsonFields, dotted: str) -> Camera:
    """The camera entry at ``dotted`` with its required "world_to_camera" (no key of
    either beyond what this program writes)."""
    entry = fields.get(dotted, dict)
    fields.keys(dotted, entry, *POSED_CAMERA_KEYS)
    fields.keys(f"{dotted}.world_to_camera", fields.get(f"{dotted}.world_to_camera", dict), ("R", "t"))
    return load_camera_entry(fields, dotted)


def load_camera_entry(fields: JsonFields, dotted: str = "camera") -> Camera:
    """The camera at ``dotted``: intrinsics from its INRIA entry, the exact pose from
    "world_to_camera" (beside the top level's "camera", inside any other; older or
    hand-made files without it: the INRIA pose)."""
    path = fields.path
    entry = fields.get(dotted, dict)
    camera = camera_from_json(entry, f"{path}: '{dotted}'")
    pose = "world_to_camera" if dotted == "camera" else f"{dotted}.world_to_camera"
    parent, _, key = pose.rpartition(".")
    if key not in (fields.get(parent, dict) if parent else fields.data):
        return camera
    fields.get(pose, dict)
    R = fields.array(f"{pose}.R", (3, 3))
    t = fields.array(f"{pose}.t", (3,))
    # Entries of a rotation lie in [-1, 1]: bounded first, the product cannot overflow.
    if not is_rotation(R, ROTATION_TOLERANCE):
        raise UserError(f"{path}: '{pose}.R' is not a rotation matrix")
    center = -R.T @ t
    rotation = np.array(entry["rotation"], dtype=np.float64)  # shape and finiteness checked by camera_from_json
    position = np.array(entry["position"], dtype=np.float64)
    if (np.abs(rotation - R.T).max() > POSE_AGREEMENT
            or np.abs(position - center).max() > POSE_AGREEMENT * (1.0 + np.abs(center).max())):
        remedy = "edit both, or remove 'world_to_camera'" if dotted == "camera" else "edit both"
        raise UserError(f"{path}: '{dotted}' position/rotation and '{pose}' describe different poses ({remedy})")
    return Camera(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy, R, t)
