"""The panel's Training cameras section: the scene's training views, to fly to one by
one or by picking from the list, and at one the Photo view's controls (panel.photo)."""

from __future__ import annotations

from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.panel.photo import draw_photo_controls
from raygs_viewer.viewer.panel.widgets import header, note
from raygs_viewer.viewer.photo_view import PhotoCompare


def draw_training_section(loaded: LoadedScene, current: int | None, select: Callable[[int], None],
                          step: Callable[[int], None], photo: PhotoCompare) -> None:
    """``current``: the training camera flown to last (None: a free view); ``select``
    flies to a camera by index, ``step`` to the next (+1) or previous (-1); ``photo``:
    the Photo view the controls under the list edit."""
    label = f"Training cameras ({len(loaded.cameras)})"
    if not header(label + "###training", open_first=False):
        return
    if not loaded.cameras:
        note("none found (pass --cameras cameras.json)")
        return
    if loaded.cameras_path:
        note(loaded.cameras_path)
    if imgui.button("< previous (P)"):
        step(-1)
    imgui.same_line()
    if imgui.button("next (N) >"):
        step(+1)
    if imgui.begin_list_box("##cameras", (-1, 160)):
        for i, name in enumerate(loaded.camera_names):
            if imgui.selectable(f"{i}: {name}", current == i)[0]:
                select(i)
                current = i  # the entries below are drawn knowing it
        imgui.end_list_box()
    draw_photo_controls(photo)
