"""The widgets every panel section shares."""

from __future__ import annotations

import math

from imgui_bundle import imgui


def tooltip(text: str) -> None:
    """``text`` while the mouse is over the last widget (greyed out or not)."""
    if imgui.is_item_hovered(imgui.HoveredFlags_.allow_when_disabled.value):
        imgui.set_tooltip(text)


def header(label: str, open_first: bool = True) -> bool:
    """A collapsing section header; whether the section is open."""
    return imgui.collapsing_header(label, imgui.TreeNodeFlags_.default_open.value if open_first else 0)


def choice(label: str, current: str, choices: dict[str, str], unavailable: dict[str, str] | None = None) -> str:
    """A combo of ``choices`` (value -> shown text), every entry visible when it opens.
    ``unavailable``: value -> why it cannot be chosen now (the entry is greyed out, the
    reason its tooltip). Returns the chosen value."""
    chosen = current
    unavailable = unavailable or {}
    if imgui.begin_combo(label, choices.get(current, current), imgui.ComboFlags_.height_largest.value):
        for value, text in choices.items():
            imgui.begin_disabled(value in unavailable)
            if imgui.selectable(text, value == current)[0] and value not in unavailable:
                chosen = value
            imgui.end_disabled()
            if value in unavailable:
                tooltip(unavailable[value])
            if value == current:
                imgui.set_item_default_focus()
        imgui.end_combo()
    return chosen


def checkbox(label: str, value: bool, enabled: bool = True, help_text: str = "") -> bool:
    """A checkbox greyed out unless ``enabled``; the new value."""
    imgui.begin_disabled(not enabled)
    _, value = imgui.checkbox(label, value)
    imgui.end_disabled()
    if help_text:
        tooltip(help_text)
    return value


def button(label: str, enabled: bool = True) -> bool:
    """A button, greyed out (and never pressed) unless ``enabled``; True when pressed."""
    imgui.begin_disabled(not enabled)
    pressed = imgui.button(label)
    imgui.end_disabled()
    return pressed and enabled


def slider(label: str, value: float, low: float, high: float, fmt: str, logarithmic: bool = False) -> float | None:
    """A float slider over [low, high] (ctrl-click types any value); the new value when
    it was moved to a finite one, else None."""
    flags = imgui.SliderFlags_.logarithmic.value if logarithmic else 0
    changed, new = imgui.slider_float(label, value, low, high, fmt, flags)
    return new if changed and math.isfinite(new) else None


def ms(seconds: float) -> str:
    return f"{seconds * 1000:6.2f} ms" if math.isfinite(seconds) else "     - ms"
