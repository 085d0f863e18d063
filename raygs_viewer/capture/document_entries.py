"""The entries that screenshot sidecars and path files share, written from their types
and read back checked: "settings" (every ``RenderSettings`` field), "stereo" (the rig,
layout, lens and headset), and what "scene" records of how the scene was read: for a
``.spz``, ``"spz_axes": "rub" or "rdf"``, the axes it was read in (older files: absent,
"rub"); for a streamed SOG whose levels were chosen per view, ``"lod_levels": [1, 2]``,
the levels read (a sidecar's only). A key the file lacks takes its default (the file was written
before the field existed); an unknown key is refused (a newer program's option cannot be
honoured). :mod:`~raygs_viewer.capture.sidecar` and :mod:`~raygs_viewer.capture.path_file`
read and write them through here.
"""

from __future__ import annotations

import dataclasses
import types
import typing

from raygs_viewer.camera.lens_model import LensModel
from raygs_viewer.camera.stereo import LAYOUTS, HeadsetPreset, StereoRig, StereoView
from raygs_viewer.errors import UserError
from raygs_viewer.jsonfile import JsonFields, json_key, show_json, typed
from raygs_viewer.render.settings import MAX_LOD_LEVELS, RenderSettings
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.scene.spz_format import SPZ_AXES

#: The key of "scene" that records the axes its .spz was read in, and its dotted name
#: (messages name it).
AXES_KEY = "spz_axes"
AXES_FIELD = f"scene.{AXES_KEY}"


def reading_entry(axes: FileAxes | None, levels: tuple[int, ...] | None = None) -> dict:
    """The keys of "scene" that say how it was read (module docstring): ``axes`` a .spz's
    (None: another format), ``levels`` a streamed SOG's read (None: not chosen per view)."""
    return {**({} if axes is None else {AXES_KEY: axes.assumed}),
            **({} if levels is None else {"lod_levels": sorted(levels)})}


def load_axes_entry(fields: JsonFields) -> FileAxes | None:
    """The axes "scene" says its .spz was read in; None where it records none."""
    if fields.get("scene", dict).get(AXES_KEY) is None:
        return None
    return FileAxes(fields.choice(AXES_FIELD, SPZ_AXES, ""))


def load_levels_entry(fields: JsonFields) -> tuple[int, ...] | None:
    """The levels of a streamed SOG "scene" says were read, sorted; None where it records none."""
    levels = fields.optional("scene.lod_levels", list)
    if levels is None:
        return None
    if not levels or not all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < MAX_LOD_LEVELS
                             for v in levels):
        raise UserError(f"{fields.path}: 'scene.lod_levels' must list levels from 0 to {MAX_LOD_LEVELS - 1}, "
                        f"got {show_json(levels)}")
    return tuple(sorted(set(levels)))


def stereo_entry(view: StereoView) -> dict:
    """The "stereo" section: every field of the rig, then the layout, the lens and the headset."""
    return {**dataclasses.asdict(view.rig), "layout": view.layout,
            "lens": None if view.lens is None else dataclasses.asdict(view.lens),
            "headset": None if view.headset is None else dataclasses.asdict(view.headset)}


def load_stereo_entry(fields: JsonFields, rig_type: type[StereoRig] = StereoRig) -> StereoView:
    """The "stereo" section: the fields of ``rig_type``, the layout, the lens and the
    headset. A key the file lacks takes its default (the file was written before the
    field existed; a headset's fields have none, so they stay required); an unknown key
    is an error (a newer program's stereo option cannot be honoured)."""
    path = fields.path
    entry = fields.get("stereo", dict)
    view = {declared.name: declared.default for declared in dataclasses.fields(StereoView) if declared.name != "rig"}
    fields.keys("stereo", entry, (), (*(declared.name for declared in dataclasses.fields(rig_type)), *view))
    layout = fields.get("stereo.layout", str) if "layout" in entry else view["layout"]
    if layout not in LAYOUTS:
        raise UserError(f"{path}: 'stereo.layout' must be one of {', '.join(LAYOUTS)}, got {show_json(layout)}")
    try:
        rig = rig_type(**_field_values(fields, "stereo", entry, rig_type))
        lens, headset = (_nested_entry(fields, f"stereo.{name}", kind)
                         for name, kind in (("lens", LensModel), ("headset", HeadsetPreset)))
    except UserError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise UserError(f"{path}: 'stereo': {exc}") from None
    return StereoView(rig, layout, lens, headset)


def _nested_entry(fields: JsonFields, dotted: str, kind: type):
    """``kind`` from the object at ``dotted``, or None where it is null or absent: a key
    it lacks takes the field's default where ``kind`` has one, an unknown key is an error."""
    parent, _, key = dotted.rpartition(".")
    if fields.get(parent, dict).get(key) is None:
        return None
    entry = fields.get(dotted, (dict, type(None)))
    declared = dataclasses.fields(kind)
    fields.keys(dotted, entry, tuple(f.name for f in declared if f.default is dataclasses.MISSING),
                tuple(f.name for f in declared if f.default is not dataclasses.MISSING))
    return kind(**_field_values(fields, dotted, entry, kind))


def _field_values(fields: JsonFields, dotted: str, entry: dict, kind: type) -> dict:
    """The values ``entry`` (the object at ``dotted``) gives for the fields of the
    dataclass ``kind``, each checked against its annotated type (:func:`_setting`); the
    fields it lacks are left out, to take their defaults."""
    hints = typing.get_type_hints(kind)
    return {f.name: _setting(entry[f.name], hints[f.name], f"{fields.path}: '{dotted}.{f.name}'")
            for f in dataclasses.fields(kind) if f.name in entry}


def load_settings_entry(fields: JsonFields, render_mode: str | None = None,
                        settings_type: type[RenderSettings] = RenderSettings) -> RenderSettings:
    """``settings_type`` from "settings": every key must be a field (a newer program's
    setting cannot be honoured, so it is an error); missing fields take their defaults
    (sidecars written before the field existed), except "mode", which older sidecars
    recorded only as ``render_mode``: a "settings.mode" must equal it."""
    path = fields.path
    raw = fields.get("settings", dict)
    if render_mode is not None:
        if "mode" not in raw:
            raw = {**raw, "mode": render_mode}
        elif raw["mode"] != render_mode:
            raise UserError(f"{path}: 'settings.mode' {show_json(raw['mode'])} differs from 'render_mode' "
                            f"{show_json(render_mode)} (they must agree; edit both)")
    known = {f.name for f in dataclasses.fields(settings_type)}
    for name in raw:
        if name not in known:
            raise UserError(f"{path}: unknown setting 'settings.{json_key(name)}' "
                            f"(it may come from a newer raygs-viewer)")
    values = _field_values(fields, "settings", raw, settings_type)
    try:
        return settings_type(**values)
    except UserError as exc:
        raise UserError(f"{path}: 'settings': {exc}") from None
    except (TypeError, ValueError) as exc:  # a field type _setting does not know how to check
        raise UserError(f"{path}: 'settings': {exc}") from None


def _setting(value, hint, where: str):
    """A JSON value converted to a RenderSettings field's annotated type: float, int,
    bool, str, tuple[...] (from a JSON array) and X | None are checked; other types pass
    through to RenderSettings' own validation."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        options = [a for a in args if a is not type(None)]
        errors = []
        for option in options:
            try:
                return _setting(value, option, where)
            except UserError as exc:
                errors.append(exc)
        if len(options) == 1:
            raise errors[0]
        raise UserError(f"{where} has the wrong type, got {show_json(value)}")
    if origin is tuple:
        if not isinstance(value, list):
            raise UserError(f"{where} must be a JSON array, got {show_json(value)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_setting(v, args[0], where) for v in value)
        if len(value) != len(args):
            raise UserError(f"{where} must have {len(args)} entries, got {show_json(value)}")
        return tuple(_setting(v, a, where) for v, a in zip(value, args))
    if hint in (float, int, bool, str):
        if hint is int and isinstance(value, bool):
            raise UserError(f"{where} must be a whole number, got {show_json(value)}")
        return typed(value, hint, where)
    return value
