"""The panel's Scene section: what is loaded, a path field to open another (or drop a
file on the window), and the progress of a load under way."""

from __future__ import annotations

from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.scene.io import SCENE_SUFFIXES
from raygs_viewer.scene.loader import LoadedScene, SceneLoader
from raygs_viewer.viewer.panel.widgets import header
from raygs_viewer.viewer.state import PanelState


def draw_scene_section(loaded: LoadedScene, panel: PanelState, open_scene: Callable[[str], None],
                       loader: SceneLoader) -> None:
    """``panel``: its path field; ``open_scene``: what Open (or Enter) does with it;
    ``loader``: the background load whose progress is shown."""
    if not header("Scene"):
        return
    scene = loaded.scene
    imgui.text_wrapped("built-in demo scene" if loaded.path == "demo" else loaded.path)
    if scene.format:
        imgui.text(scene.format)
    imgui.text(f"{scene.count:,} gaussians, SH degree {scene.sh_degree}, "
               f"3D filter {'fused' if scene.filter_fused else 'none'}")
    entered, panel.open_path = imgui.input_text_with_hint(
        "##open", f"{' '.join(SCENE_SUFFIXES)} (or drop a file)", panel.open_path,
        imgui.InputTextFlags_.enter_returns_true.value)
    imgui.same_line()
    if imgui.button("Open") or entered:
        open_scene(panel.open_path)
    if loader.busy:
        imgui.progress_bar(loader.progress, (-1, 0), loader.stage)
