"""Measurement files: the distances measured in the window (pairs of picked world
points), the scale that converts them to a real unit, and the scene they were measured
on; their reading and writing. The window's Measure section saves and loads them, as
its Path section does camera paths (:mod:`raygs_viewer.capture.path_file`, the model
this follows).

Layout (version 1)::

    {"format": "raygs-viewer measurements", "version": 1,
     "program": {"name": "raygs-viewer", "version": "0.1.0"},
     "created": "2025-01-31T12:00:00Z",                           # UTC
     "scene": {"path": "/abs/scene.ply" or "demo",                # or null: unknown
               "sha256": "<64 hex digits>" or null},
     "scale": null or {"factor": 0.42,                            # units per scene unit
                       "unit": "m",                               # what the factor converts to
                       "reference": 0 or null},                   # the measurement it was set from
     "measurements": [{"a": [x, y, z], "b": [x, y, z]}, ...]}     # world space, scene units

Required: "format", "version" and "measurements" (it may be empty); the rest may be
left out. Loading is strict: an unknown field, a wrong type, a non-finite or huge
coordinate, a factor that is not a positive finite number, a unit that is empty, too
long or more than one line, and a reference that is no measurement's index are each a
one-line UserError naming the file and the field. Floats are written as the shortest
repr that reads back to the same bits, so points survive the round trip exactly.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from raygs_viewer.camera.pinhole import MAX_COORDINATE
from raygs_viewer.capture.image_io import check_output_path
from raygs_viewer.capture.sidecar import SHA256_HEX, document_head, scene_mismatch_warning
from raygs_viewer.errors import UserError
from raygs_viewer.files import write_atomically
from raygs_viewer.jsonfile import JsonFields, json_text, parse_json, read_json_file, show_json
from raygs_viewer.scene.source import SceneSource, is_demo

MEASURE_FORMAT = "raygs-viewer measurements"
MEASURE_VERSION = 1
MEASURE_SUFFIXES = (".json",)
#: The most measurements a file may hold (a panel list, not a point cloud).
MAX_MEASUREMENTS = 10_000
#: The longest unit text ("m", "mm", "ft", "metres").
MAX_UNIT_LENGTH = 32
#: The scene's own unit, shown while no scale is set.
SCENE_UNIT = "units"

_TOP_REQUIRED = ("format", "version", "measurements")
_TOP_OPTIONAL = ("program", "created", "scene", "scale")


@dataclass(frozen=True, eq=False)
class Measurement:
    """a, b: (3,) float64 world points (scene units), copied and made read-only."""

    a: np.ndarray
    b: np.ndarray

    def __post_init__(self) -> None:
        for name in ("a", "b"):
            point = np.array(getattr(self, name), dtype=np.float64).reshape(-1)
            if point.shape != (3,) or not np.all(np.abs(point) <= MAX_COORDINATE):
                raise UserError(f"a measured point must be 3 finite numbers, got {show_json(point.tolist())}")
            point.flags.writeable = False
            object.__setattr__(self, name, point)

    @property
    def distance(self) -> float:
        """The distance between the points, scene units."""
        return float(np.linalg.norm(self.b - self.a))


def check_unit(unit: str, where: str = "the unit") -> str:
    """``unit`` stripped; UserError when empty, over MAX_UNIT_LENGTH or not one line."""
    text = str(unit).strip()
    if not text or len(text) > MAX_UNIT_LENGTH or any(c in text for c in "\r\n"):
        raise UserError(f"{where} must be one line of 1 to {MAX_UNIT_LENGTH} characters, got {show_json(unit)}")
    return text


@dataclass(frozen=True)
class MeasureScale:
    """factor: ``unit``s per scene unit (a positive finite number); reference: the index
    of the measurement it was set from (None: unknown, or since deleted)."""

    factor: float
    unit: str
    reference: int | None = None

    def __post_init__(self) -> None:
        factor = float(self.factor)
        if not (np.isfinite(factor) and factor > 0):
            raise UserError(f"the scale must be a positive finite number, got {show_json(self.factor)}")
        object.__setattr__(self, "factor", factor)
        object.__setattr__(self, "unit", check_unit(self.unit))

    @classmethod
    def from_length(cls, measurement: Measurement, length: float, unit: str, reference: int | None = None
                    ) -> "MeasureScale":
        """The scale that makes ``measurement`` ``length`` ``unit``s long ("this is 1.20 m")."""
        distance = measurement.distance
        if not (np.isfinite(length) and length > 0):
            raise UserError(f"the known length must be a positive number, got {show_json(length)}")
        if not distance > 0:
            raise UserError("that measurement has no length (both points are the same): pick another")
        return cls(length / distance, unit, reference)


def convert(distance: float, scale: MeasureScale | None) -> tuple[float, str]:
    """(value, unit) of a distance in scene units: converted by ``scale``, or as it is."""
    if scale is None:
        return distance, SCENE_UNIT
    return distance * scale.factor, scale.unit


@dataclass(frozen=True)
class MeasureDocument:
    """measurements and their scale; scene_path: "demo" or an absolute path (None:
    unknown); scene_sha256: its hex digest (None: never checked); source: the file it
    was read from."""

    measurements: tuple[Measurement, ...] = ()
    scale: MeasureScale | None = None
    scene_path: str | None = None
    scene_sha256: str | None = None
    source: Path | None = None


# --------------------------------------------------------------------------- writing


def measure_document_json(doc: MeasureDocument) -> dict:
    scene = None
    if doc.scene_path is not None:
        scene = {"path": SceneSource(doc.scene_path).recorded_path,
                 "sha256": doc.scene_sha256}
    scale = None if doc.scale is None else {"factor": doc.scale.factor, "unit": doc.scale.unit,
                                            "reference": doc.scale.reference}
    return {
        **document_head(MEASURE_FORMAT, MEASURE_VERSION),
        "scene": scene,
        "scale": scale,
        "measurements": [{"a": m.a.tolist(), "b": m.b.tolist()} for m in doc.measurements],
    }


def save_measure_document(doc: MeasureDocument, file: str | os.PathLike, overwrite: bool = False) -> Path:
    """Writes ``doc`` atomically; an existing file is replaced only with ``overwrite``.
    Checked like a loaded file first, so nothing is written that :func:`load_measure_document`
    would refuse. Returns the path written."""
    file = check_output_path(file, overwrite, MEASURE_SUFFIXES)
    try:
        text = json_text(measure_document_json(doc))
    except ValueError:
        raise UserError(f"{file}: a measurement holds a non-finite number; not saved") from None
    read_measure_json(parse_json(text, file), file)
    write_atomically(file, text.encode("utf-8"), overwrite)
    return file


# --------------------------------------------------------------------------- reading


def load_measure_document(file: str | os.PathLike) -> MeasureDocument:
    """The measurement file ``file``, validated; any problem is a one-line UserError."""
    file = Path(file)
    return read_measure_json(read_json_file(file, "a measurements .json file"), file)


def read_measure_json(data, file: Path) -> MeasureDocument:
    """The document of a parsed measurement file (``file`` names it in messages)."""
    if not isinstance(data, dict) or data.get("format") != MEASURE_FORMAT:
        got = show_json(data.get("format")) if isinstance(data, dict) else "not a JSON object"
        raise UserError(f"{file}: not a measurements file ('format' should be {show_json(MEASURE_FORMAT)}, "
                        f"got {got})")
    fields = JsonFields(file, data)
    fields.version(MEASURE_VERSION, "measurements")
    fields.keys("", data, _TOP_REQUIRED, _TOP_OPTIONAL)
    if data.get("program") is not None:
        fields.keys("program", fields.get("program", dict), ("name", "version"))
        fields.get("program.name", str)
        fields.get("program.version", str)
    fields.optional("created", str)
    scene_path, sha = _load_scene(fields)
    entries = fields.get("measurements", list)
    if len(entries) > MAX_MEASUREMENTS:
        raise UserError(f"{file}: 'measurements' has {len(entries)} entries (at most {MAX_MEASUREMENTS})")
    measurements = tuple(_load_measurement(file, i, entry) for i, entry in enumerate(entries))
    scale = _load_scale(fields, len(measurements))
    return MeasureDocument(measurements, scale, scene_path, sha, source=file)


def _load_scene(fields: JsonFields) -> tuple[str | None, str | None]:
    if fields.data.get("scene") is None:
        return None, None
    fields.keys("scene", fields.get("scene", dict), ("path", "sha256"))
    path = fields.get("scene.path", str)
    if not is_demo(path) and not os.path.isabs(path):
        raise UserError(f"{fields.path}: 'scene.path' must be \"demo\" or an absolute path, got {show_json(path)}")
    sha = fields.optional("scene.sha256", str)
    if sha is not None and not SHA256_HEX.fullmatch(sha):
        raise UserError(f"{fields.path}: 'scene.sha256' must be 64 lowercase hex digits or null, got {show_json(sha)}")
    return path, sha


def _load_measurement(file: Path, index: int, entry) -> Measurement:
    name = f"measurements[{index}]"
    fields = JsonFields.entry(file, name, entry)
    fields.keys(name, entry, ("a", "b"))
    a, b = (fields.array(f"{name}.{end}", (3,)) for end in ("a", "b"))
    for end, point in (("a", a), ("b", b)):
        if np.abs(point).max() > MAX_COORDINATE:
            raise UserError(f"{file}: '{name}.{end}' has a coordinate beyond {MAX_COORDINATE:g}")
    return Measurement(a, b)


def _load_scale(fields: JsonFields, count: int) -> MeasureScale | None:
    if fields.data.get("scale") is None:
        return None
    file = fields.path
    fields.keys("scale", fields.get("scale", dict), ("factor", "unit"), ("reference",))
    factor = fields.get("scale.factor", float)
    if not factor > 0:
        raise UserError(f"{file}: 'scale.factor' must be a positive number, got {show_json(factor)}")
    unit = check_unit(fields.get("scale.unit", str), f"{file}: 'scale.unit'")
    reference = fields.optional("scale.reference", int)
    if reference is not None and not 0 <= reference < count:
        raise UserError(f"{file}: 'scale.reference' must be the index of a measurement (0 to {count - 1}), "
                        f"got {reference}")
    return MeasureScale(factor, unit, reference)


# --------------------------------------------------------------------------- the scene


def measure_scene_mismatch(doc: MeasureDocument, scene_name: str, actual_sha256: str | None = None) -> str | None:
    """A one-line warning when ``scene_name`` ("demo" or a file; ``actual_sha256`` its
    digest when known) is not the scene ``doc`` was measured on (by SHA-256); None when
    it is or when the document records no hash. A warning, not an error: another
    training run of the same scene measures the same."""
    return scene_mismatch_warning(
        document=doc.source.name if doc.source is not None else "the measurements", recorded_path=doc.scene_path,
        recorded_sha256=doc.scene_sha256, scene_name=scene_name, actual_sha256=actual_sha256, verb="measured",
        consequence="the points may not match")
