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
    shown = choices.get(current, current)
    # The box shows as much of the choice as fits; the whole of it is named on hover.
    room = imgui.calc_item_width() - imgui.get_frame_height() - 2 * imgui.get_style().frame_padding.x
    cut = imgui.calc_text_size(shown).x > room
    if imgui.begin_combo(label, shown, imgui.ComboFlags_.height_largest.value):
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
    elif cut:
        tooltip(shown)
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


def button_width(label: str) -> float:
    """The room a button ``label`` takes on a line after another widget (its spacing included)."""
    style = imgui.get_style()
    return imgui.calc_text_size(label.split("##")[0]).x + 2 * style.frame_padding.x + style.item_spacing.x


def file_row(tag: str, file: str, hint: str, can_save: bool, room: float | None = None) -> tuple[str, bool, bool]:
    """A file-name field (``hint`` shown while empty) with Save (greyed out unless
    ``can_save``) and Load after it on its line, their ids ending in ``##tag``. The
    field leaves ``room`` of the line (by default the buttons' width). Returns the name,
    whether Save was pressed and whether Load was; Load is the last widget drawn, for a
    tooltip."""
    imgui.set_next_item_width(-(button_width("Save") + button_width("Load") if room is None else room))
    _, file = imgui.input_text_with_hint(f"##{tag} file", hint, file)
    imgui.same_line()
    save = button(f"Save##{tag}", can_save)
    imgui.same_line()
    load = imgui.button(f"Load##{tag}")
    return file, save, load


def slider(label: str, value: float, low: float, high: float, fmt: str, *, logarithmic: bool = False) -> float | None:
    """A float slider over [low, high] (ctrl-click types any value); the new value when
    it was moved to a finite one, else None."""
    flags = imgui.SliderFlags_.logarithmic.value if logarithmic else 0
    changed, new = imgui.slider_float(label, value, low, high, fmt, flags)
    return new if changed and math.isfinite(new) else None


def ms(seconds: float) -> str:
    return f"{seconds * 1000:6.2f} ms" if math.isfinite(seconds) else "     - ms"


def labelled_progress(fraction: float, label: str, room: float = 0.0) -> None:
    """A progress bar as wide as the panel leaves (less ``room`` for a widget beside it)
    that says ``label`` on it where it fits, else above it (wrapped) with the bar saying
    how far along it is: a label cut at the bar's end tells nothing."""
    fraction = min(max(fraction, 0.0), 1.0) if math.isfinite(fraction) else 0.0
    width = imgui.get_content_region_avail().x - room
    style = imgui.get_style()
    if imgui.calc_text_size(label).x + 2 * style.frame_padding.x > width:
        imgui.push_text_wrap_pos(0.0)
        imgui.text_disabled(label)
        imgui.pop_text_wrap_pos()
        label = f"{fraction * 100:.0f} %"
    imgui.progress_bar(fraction, (-room if room else -1, 0), label)


def line(text: str) -> None:
    """A line of text, wrapped at the panel's edge rather than cut there."""
    imgui.push_text_wrap_pos(0.0)
    imgui.text(text)
    imgui.pop_text_wrap_pos()


def note(text: str) -> None:
    """A greyed-out remark, wrapped at the panel's edge rather than cut there."""
    imgui.push_text_wrap_pos(0.0)
    imgui.text_disabled(text)
    imgui.pop_text_wrap_pos()


def beside(width: float) -> None:
    """The next widget, ``width`` wide, on the line of the last one where the panel has
    room for it, else on the next line (a row of widgets that would run past the edge)."""
    style = imgui.get_style()
    right = imgui.get_cursor_screen_pos().x + imgui.get_content_region_avail().x  # from the next line's start
    if imgui.get_item_rect_max().x + style.item_spacing.x + width <= right:
        imgui.same_line()
