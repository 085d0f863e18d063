"""The panel's Level of detail section, shown for a streamed SOG (``lod-meta.json``):
the levels read (and the reading still under way), one level everywhere or a choice per
view, the budget of gaussians and the distance where level 1 begins, colour by level,
and what the last frame drew: its gaussians against the budget, the parts at each level,
whether the budget is below the coarsest level, and the choice's age (the order's: the
sort thread makes both at once)."""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import LoadedScene, SceneLoader
from raygs_viewer.scene.lod_file import LodScene
from raygs_viewer.sort.lod_choice import LodChoice, automatic_distance, level_distances
from raygs_viewer.viewer.lod_window import DEFAULT_WINDOW_BUDGET, LEVEL_COLOURS, WindowLod, reading
from raygs_viewer.viewer.panel.widgets import checkbox, choice, header, labelled_progress, line, slider, tooltip
from raygs_viewer.viewer.part import ColourByLevel, Reply
from raygs_viewer.viewer.stats import FrameStats, order_freshness

PER_VIEW = "view"
WARNING_COLOUR = (1.0, 0.7, 0.3, 1.0)
#: The distance slider spans this factor either side of the automatic distance.
DISTANCE_RANGE = 64.0
_INT_MAX = 2**31 - 1  # imgui's sliders hold an int32

LEVEL_HELP = ("per view: each part of the scene draws the level its distance asks for (level 1 from\n"
              "the distance below, level l from 2^(l-1) times it), within the budget.\n"
              "a level: that level everywhere (--lod N); a level not read yet is read.")
BUDGET_HELP = (f"the most gaussians a view draws (the window starts at {DEFAULT_WINDOW_BUDGET:,}):\n"
               "over it, every part in view starts at its coarsest level and what is largest on screen\n"
               "is refined first. Parts out of view draw their coarsest level and are not counted.")
TINT_HELP = ("each gaussian in its level's colour (the environment grey), to see the choice;\n"
             "screenshots need the scene's own colours")


def draw_lod_section(window: WindowLod, loaded: LoadedScene, loader: SceneLoader, settings: RenderSettings, *,
                     set_settings: Callable[[RenderSettings], None], stats: FrameStats) -> Reply:
    """``window``: the drawn choice and colour by level of the scene ``loaded`` (its
    levels), whose reading ``loader`` may be under way; ``set_settings`` receives the
    edited settings; ``stats``: the order's age. Colour by level turned on or off is a
    request."""
    lod = loaded.lod
    if lod is None or not header("Level of detail"):
        return Reply()
    _draw_reading(lod, reading(loaded, loader), loader)
    edited = _edit_level(lod, settings)
    imgui.begin_disabled(edited.lod is not None)  # one level everywhere: no budget, no distances
    edited = _edit_budget(lod, _edit_distance(lod, edited))
    imgui.end_disabled()
    if edited != settings:
        set_settings(edited)
    tint = checkbox("colour by level", window.tint, help_text=TINT_HELP)
    if window.tint:
        _draw_legend(lod.levels)
    _draw_choice(window.choice, lod, edited, stats)
    imgui.separator()
    return Reply.of(ColourByLevel(tint)) if tint != window.tint else Reply()


def _draw_reading(lod: LodScene, reading: bool, loader: SceneLoader) -> None:
    read = ", ".join(str(level) for level in np.flatnonzero(lod.loaded)[::-1])
    line(f"levels read: {read} of 0..{lod.levels - 1} (0 the finest)")
    tooltip(f"gaussians per level: {', '.join(f'{level}: {n:,}' for level, n in enumerate(lod.index.counts))}"
            + (f"; environment {lod.environment[1]:,}" if lod.environment[1] else ""))
    if reading:
        labelled_progress(loader.progress, f"reading finer levels: {loader.stage}")
    if lod.unread:
        imgui.push_style_color(imgui.Col_.text.value, WARNING_COLOUR)
        imgui.text_wrapped(lod.unread)
        imgui.pop_style_color()


def _edit_level(lod: LodScene, settings: RenderSettings) -> RenderSettings:
    last = lod.levels - 1
    names = {PER_VIEW: "per view"}
    for level in range(lod.levels):
        words = " (finest)" if level == 0 else " (coarsest)" if level == last else ""
        names[str(level)] = f"level {level}{words}" + ("" if lod.loaded[level] else ", not read")
    current = PER_VIEW if settings.lod is None else str(min(settings.lod, last))
    picked = choice("level", current, names)
    tooltip(LEVEL_HELP)
    return replace(settings, lod=None if picked == PER_VIEW else int(picked)) if picked != current else settings


def _edit_distance(lod: LodScene, settings: RenderSettings) -> RenderSettings:
    automatic = automatic_distance(lod)
    on = checkbox("automatic distance", settings.lod_distance is None, help_text=(
        f"level 1 begins {automatic:.3g} away: four half-diagonals of the median part"))
    if on != (settings.lod_distance is None):
        settings = replace(settings, lod_distance=None if on else automatic)
    if settings.lod_distance is not None:
        value = slider("distance", settings.lod_distance, automatic / DISTANCE_RANGE, automatic * DISTANCE_RANGE,
                       "%.3g", logarithmic=True)
        tooltip("where level 1 begins, in scene units (ctrl-click to type)")
        if value is not None and value > 0:
            settings = replace(settings, lod_distance=float(value))
    begins = level_distances(lod, settings.lod_distance)
    line("levels begin at " + (", ".join(f"{level + 1}: {d:.3g}" for level, d in enumerate(begins)) or "-"))
    return settings


def _edit_budget(lod: LodScene, settings: RenderSettings) -> RenderSettings:
    limited = checkbox("budget##on", settings.lod_budget is not None, help_text=BUDGET_HELP)
    if limited != (settings.lod_budget is not None):
        settings = replace(settings, lod_budget=DEFAULT_WINDOW_BUDGET if limited else None)
    if settings.lod_budget is not None:
        # The most a view can draw: every part at its largest level, and the environment.
        most = max(2, min(_INT_MAX, lod.environment[1] + int(lod.index.ranges[:, :, 2].max(axis=1).sum())))
        changed, value = imgui.slider_int("##budget", min(settings.lod_budget, _INT_MAX), 1, max(most, 2), "%d",
                                          imgui.SliderFlags_.logarithmic.value)
        tooltip("gaussians (ctrl-click to type)")
        if changed and value >= 1:
            settings = replace(settings, lod_budget=int(value))
    return settings


def _draw_legend(levels: int) -> None:
    for level in range(levels):
        if level % 4:
            imgui.same_line()
        imgui.text_colored((*LEVEL_COLOURS[level % len(LEVEL_COLOURS)], 1.0), f"level {level}")


def _draw_choice(drawn: LodChoice | None, lod: LodScene, settings: RenderSettings, stats: FrameStats) -> None:
    if drawn is None:
        line("drawn: waiting for the first sort")
        return
    budget = settings.lod_budget if settings.lod is None else None
    line(f"drawn {drawn.count:,} gaussians" + ("" if budget is None else f" of a budget of {budget:,}"))
    tooltip("the gaussians of the levels chosen for the view (and the environment), before the cull")
    per_level = drawn.per_level(lod.levels)
    line("parts at each level: " + ", ".join(f"{level}: {n}" for level, n in enumerate(per_level)))
    if drawn.over_budget:
        imgui.push_style_color(imgui.Col_.text.value, WARNING_COLOUR)
        imgui.text_wrapped("the budget is below the coarsest level: the parts in view draw their coarsest")
        imgui.pop_style_color()
    line(f"choice {order_freshness(stats, short=True)}")
    tooltip(f"choice {order_freshness(stats)}")
    tooltip("made with the order, on the sort thread, for the view it was sorted for")
