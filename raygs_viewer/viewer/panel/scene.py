"""The panel's Scene section: what is loaded, a path field to open another (or drop a
file on the window), and the progress of a load under way. For a ``.spz``, the axes it
was read in, with a switch between the two conventions when the file declares none."""

from __future__ import annotations

import os

from imgui_bundle import imgui

from raygs_viewer.scene.io import SCENE_SUFFIXES
from raygs_viewer.scene.loader import LoadedScene, SceneLoader
from raygs_viewer.scene.model import FileAxes
from raygs_viewer.viewer.file_dialog import FileDialog, dialog_problem
from raygs_viewer.viewer.panel.widgets import button_width, checkbox, header, labelled_progress, line, tooltip
from raygs_viewer.viewer.part import OpenScene, ReadAxes, Reply
from raygs_viewer.viewer.state import PanelState, failed


def draw_scene_section(loaded: LoadedScene, panel: PanelState, loader: SceneLoader,
                       dialog: FileDialog | None = None) -> Reply:
    """``panel``: its path field, which Open (or Enter) asks to open; ``loader``: the
    background load whose progress is shown; ``dialog``: the Open… button's file dialog
    (polled here, so a file chosen opens at once). A .spz's axes switched ask for it to
    be read again in the other convention ("rub" or "rdf")."""
    said = []
    if dialog is not None and (chosen := dialog.poll()) is not None:
        panel.open_path = chosen
        said.append(OpenScene(chosen))
    if not header("Scene"):
        return Reply.of(*said)
    scene = loaded.scene
    imgui.text_wrapped("built-in demo scene" if loaded.source.is_demo else loaded.path)
    if scene.format:
        line(scene.format)
    line(f"{scene.count:,} gaussians, SH degree {scene.sh_degree}, "
               f"3D filter {'fused' if scene.filter_fused else 'none'}")
    if scene.axes is not None:
        said.append(_draw_axes(scene.axes, loader.busy))
    # As wide as the buttons beside it leave. Selected whole when clicked: typing replaces the old path.
    imgui.set_next_item_width(-sum(button_width(label) for label in ("Open", "Open...")[:2 if dialog else 1]))
    entered, panel.open_path = imgui.input_text_with_hint(
        "##open", "a scene's path, or drop a file", panel.open_path,
        imgui.InputTextFlags_.enter_returns_true.value | imgui.InputTextFlags_.auto_select_all.value)
    tooltip(f"{' '.join(SCENE_SUFFIXES)}; Enter opens it")
    imgui.same_line()
    if imgui.button("Open") or entered:
        said.append(OpenScene(panel.open_path))
    if dialog is not None:
        imgui.same_line()
        if imgui.button("Open..."):
            problem = dialog.start(_folder_of(panel.open_path or loaded.path))
            if problem:
                said.append(failed(problem))
        tooltip("the desktop's file dialog" + (f" ({problem})" if (problem := dialog_problem()) else ""))
    if loader.busy:
        labelled_progress(loader.progress, loader.stage)
    return Reply.of(*said)


def _folder_of(path: str | None) -> str:
    """Where the dialog opens: the folder of ``path`` (the typed or the loaded scene),
    else the current one."""
    folder = os.path.dirname(os.path.abspath(path)) if path and path != "demo" else os.getcwd()
    return folder if os.path.isdir(folder) else os.getcwd()


def _draw_axes(axes: FileAxes, busy: bool) -> ReadAxes | None:
    if axes.declared:  # the file's word wins: nothing to switch
        line(f"axes: {axes.stored}, declared by the file")
        return None
    # Nothing in such a file tells the conventions apart; a scene upside down is the sign.
    rdf = checkbox("RDF axes (splat-transform's .spz)", axes.assumed == "rdf", not busy,
                   "off: RUB, the .spz specification's (Niantic, Scaniverse); on: RDF, the PLY's own axes,\n"
                   "which PlayCanvas's splat-transform and SuperSplat write. Switching reads the file again.")
    return ReadAxes("rdf" if rdf else "rub") if rdf != (axes.assumed == "rdf") else None
