"""The panel's Scene section: what is loaded, a path field to open another (or drop a
file on the window), and the progress of a load under way. For a ``.spz``, the axes it
was read in, with a switch between the two conventions when the file declares none."""

from __future__ import annotations

import os
from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.scene.io import SCENE_SUFFIXES
from raygs_viewer.scene.loader import LoadedScene, SceneLoader
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.viewer.file_dialog import FileDialog, dialog_problem
from raygs_viewer.viewer.panel.widgets import button_width, checkbox, header, labelled_progress, line, tooltip
from raygs_viewer.viewer.state import PanelState


def draw_scene_section(loaded: LoadedScene, panel: PanelState, open_scene: Callable[[str], None],
                       loader: SceneLoader, switch_axes: Callable[[str], None],
                       dialog: FileDialog | None = None) -> None:
    """``panel``: its path field; ``open_scene``: what Open (or Enter) does with it;
    ``loader``: the background load whose progress is shown; ``switch_axes(axes)``:
    reads the .spz again in the other convention ("rub" or "rdf"); ``dialog``: the
    Open… button's file dialog (polled here, so a file chosen opens at once)."""
    if dialog is not None and (chosen := dialog.poll()) is not None:
        panel.open_path = chosen
        open_scene(chosen)
    if not header("Scene"):
        return
    scene = loaded.scene
    imgui.text_wrapped("built-in demo scene" if loaded.source.is_demo else loaded.path)
    if scene.format:
        line(scene.format)
    line(f"{scene.count:,} gaussians, SH degree {scene.sh_degree}, "
               f"3D filter {'fused' if scene.filter_fused else 'none'}")
    if scene.axes is not None:
        _draw_axes(scene.axes, switch_axes, loader.busy)
    # As wide as the buttons beside it leave. Selected whole when clicked: typing replaces the old path.
    imgui.set_next_item_width(-sum(button_width(label) for label in ("Open", "Open...")[:2 if dialog else 1]))
    entered, panel.open_path = imgui.input_text_with_hint(
        "##open", "a scene's path, or drop a file", panel.open_path,
        imgui.InputTextFlags_.enter_returns_true.value | imgui.InputTextFlags_.auto_select_all.value)
    tooltip(f"{' '.join(SCENE_SUFFIXES)}; Enter opens it")
    imgui.same_line()
    if imgui.button("Open") or entered:
        open_scene(panel.open_path)
    if dialog is not None:
        imgui.same_line()
        if imgui.button("Open..."):
            problem = dialog.start(_folder_of(panel.open_path or loaded.path))
            if problem:
                panel.error = f"error: {problem}"
        tooltip("the desktop's file dialog" + (f" ({problem})" if (problem := dialog_problem()) else ""))
    if loader.busy:
        labelled_progress(loader.progress, loader.stage)


def _folder_of(path: str | None) -> str:
    """Where the dialog opens: the folder of ``path`` (the typed or the loaded scene),
    else the current one."""
    folder = os.path.dirname(os.path.abspath(path)) if path and path != "demo" else os.getcwd()
    return folder if os.path.isdir(folder) else os.getcwd()


def _draw_axes(axes: FileAxes, switch_axes: Callable[[str], None], busy: bool) -> None:
    if axes.declared:  # the file's word wins: nothing to switch
        line(f"axes: {axes.stored}, declared by the file")
        return
    # Nothing in such a file tells the conventions apart; a scene upside down is the sign.
    rdf = checkbox("RDF axes (splat-transform's .spz)", axes.assumed == "rdf", not busy,
                   "off: RUB, the .spz specification's (Niantic, Scaniverse); on: RDF, the PLY's own axes,\n"
                   "which PlayCanvas's splat-transform and SuperSplat write. Switching reads the file again.")
    if rdf != (axes.assumed == "rdf"):
        switch_axes("rdf" if rdf else "rub")
