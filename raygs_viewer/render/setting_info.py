"""What every describer of a render setting needs, kept on the setting's own field.

Each :class:`~raygs_viewer.render.settings.RenderSettings` field carries a
:class:`Setting` in its dataclass metadata (:func:`setting` makes the field): the
values it takes, the render modes it applies in, what the command line calls it and
says of it, and how the split view's label and verify's line show it. The describers
(the settings' own checks, the command line's options, the overlay, verify, the
sidecar reader) loop over the fields and read this, so a field added with its Setting
reaches every one of them, and a field without one is an error rather than a gap.
"""

from __future__ import annotations

import dataclasses
import functools
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field

from raygs_viewer.errors import UserError, is_number

_KEY = "raygs_viewer.setting"


@dataclass(frozen=True)
class Shown:
    """How one describer shows a field: ``text`` formatted with the value (a switch's
    as "on"/"off"), or ``worded`` formatted with the value's word (Setting.words) for
    a value that has one. ``always``: shown even at the default value, where the
    describer shows only what differs from the defaults. ``joined``: continues the
    part before it instead of starting a part of its own."""

    text: str
    worded: str | None = None
    always: bool = False
    joined: bool = False

    def format(self, value, words: Mapping) -> str:
        if self.worded is not None and value in words:
            return self.worded.format(words[value])
        return self.text.format(("on" if value else "off") if isinstance(value, bool) else value)


@dataclass(frozen=True)
class Setting:
    """What the describers of one settings field read (a switch needs only ``help``).

    help, metavar: the command line's. choices: the values it takes (the command line
    offers strings as choices). limits: the interval a number lies in, closed unless
    ``open``; unit: its unit in messages. words: a word for a value that means more
    than its number or name ({0: "exact"}), or a value's name for people. what: its
    name in messages (default the field's). accuracy: an accuracy option, which a
    preset sets or resets (not p_min, background, SH degree). modes, needs: it applies
    only in these render modes (None: all), and only where this property of the
    settings is true. implies: giving it on the command line also sets (field, value)
    unless that option is given too. line, label: how verify's line and the split
    view's label show it (None: they do not)."""

    help: str
    metavar: str | None = None
    choices: tuple = ()
    limits: tuple[float, float] | None = None
    open: bool = False
    unit: str = ""
    words: Mapping = field(default_factory=dict)
    what: str | None = None
    accuracy: bool = True
    modes: tuple[str, ...] | None = None
    needs: str | None = None
    implies: tuple[str, object] | None = None
    line: Shown | None = None
    label: Shown | None = None

    def low_words(self) -> str:
        """The lower limit as messages write it: "0 (exact)" where it has a word."""
        low = self.limits[0]
        return f"{low} ({self.words[low]})" if low in self.words else f"{low:g}"

    def interval(self) -> str:
        """The limits as an interval, "[0, 100] px^2" or "(0, 1)"."""
        low, high = self.limits
        brackets = "()" if self.open else "[]"
        return f"{brackets[0]}{low:g}, {high:g}{brackets[1]}" + (f" {self.unit}" if self.unit else "")

    def within(self, value) -> bool:
        low, high = self.limits
        return low < value < high if self.open else low <= value <= high

    def clamp(self, value):
        """``value`` moved into the (closed) limits."""
        low, high = self.limits
        return min(max(value, low), high)


class SettingField(typing.NamedTuple):
    """A settings field: its name, its Setting and its type hint (resolved)."""

    name: str
    info: Setting
    hint: object


def setting(default, info: Setting):
    """A settings field with its default and what its describers read."""
    return field(default=default, metadata={_KEY: info})


@functools.lru_cache(maxsize=None)
def settings_table(settings_type: type) -> tuple[SettingField, ...]:
    """Each field of ``settings_type`` in order; TypeError for a field without a
    Setting, which no describer would know."""
    hints = typing.get_type_hints(settings_type)
    table = []
    for declared in dataclasses.fields(settings_type):
        if _KEY not in declared.metadata:
            raise TypeError(f"{settings_type.__name__}.{declared.name} has no Setting: make it with setting()")
        table.append(SettingField(declared.name, declared.metadata[_KEY], hints[declared.name]))
    return tuple(table)


def setting_field(settings_type: type, name: str) -> SettingField:
    return next(row for row in settings_table(settings_type) if row.name == name)


@functools.lru_cache(maxsize=None)
def defaults(settings_type: type) -> Mapping[str, object]:
    return {declared.name: declared.default for declared in dataclasses.fields(settings_type)}


def applies(settings, name: str) -> bool:
    """Whether the field ``name`` has an effect with the rest of ``settings``."""
    info = setting_field(type(settings), name).info
    return ((info.modes is None or settings.mode in info.modes)
            and (info.needs is None or bool(getattr(settings, info.needs))))


def setting_parts(settings, which: str, changes_only: bool) -> list[str]:
    """The parts of a description of ``settings``: each field's ``which`` ("line" or
    "label") where it applies; ``changes_only``: only the fields that differ from
    their defaults, besides those shown always. The accuracy options come first: they
    say how the image is made."""
    parts: list[str] = []
    default = defaults(type(settings))
    table = sorted(settings_table(type(settings)), key=lambda row: not row.info.accuracy)
    for name, info, _ in table:
        shown, value = getattr(info, which), getattr(settings, name)
        if shown is None or value is None or not applies(settings, name):  # None: not set, nothing to show
            continue
        if changes_only and not shown.always and value == default[name]:
            continue
        text = shown.format(value, info.words)
        if shown.joined and parts:
            parts[-1] += text
        else:
            parts.append(text)
    return parts


def or_list(values) -> str:
    """"0, 1, 2 or 3"."""
    words = [str(v) for v in values]
    return ", ".join(words[:-1]) + f" or {words[-1]}" if len(words) > 1 else words[0]


def checked(name: str, info: Setting, hint, value):
    """``value`` of the field ``name`` as the settings keep it, or UserError saying
    what the field takes. Checks the field's type (by its hint), choices and limits;
    anything else (a tuple's shape, a rule between fields) is the class's to check."""
    what = info.what or name
    if value is None and type(None) in typing.get_args(hint):
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise UserError(f"{what} must be true or false, got {value!r}")
        return value
    whole = int in (hint, *typing.get_args(hint))
    if info.choices:
        if whole and (isinstance(value, bool) or value not in info.choices):
            raise UserError(f"{what} must be {or_list(info.choices)}, got {value!r}")
        if not whole and value not in info.choices:
            raise UserError(f"{what} must be one of {', '.join(info.choices)}, got {value!r}")
        return value
    if info.limits is None:
        return value
    if whole:
        if isinstance(value, bool) or not isinstance(value, int) or not info.within(value):
            raise UserError(f"{what} must be a whole number from {info.low_words()} to {info.limits[1]}, "
                            f"got {value!r}")
        return value
    if not (is_number(value) and info.within(value)):
        raise UserError(f"{what} must be a number in {info.interval()}, got {value!r}")
    return float(value)
