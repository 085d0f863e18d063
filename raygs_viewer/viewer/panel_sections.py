"""What each panel section is handed: the part of the window's state it shows and edits.

The window's one composition of the panel: which section shows which part, in which
order. Each section is a closure, read when the panel draws it, over the parts and the
state of the window it is handed (never stored); it returns what it said and asked for
(``part.Reply``). The render settings are edited through a :class:`Draft`, so an edit
shows in the sections below it at once and the frame made after the panel takes them
whole.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.viewer.feedback import draw_history
from raygs_viewer.viewer.panel.edit import draw_edit_section
from raygs_viewer.viewer.panel.geometry import draw_geometry_section
from raygs_viewer.viewer.panel.headset import draw_headset_section
from raygs_viewer.viewer.panel.lod import draw_lod_section
from raygs_viewer.viewer.panel.measure import draw_measure_section
from raygs_viewer.viewer.panel.order import draw_order_section
from raygs_viewer.viewer.panel.path import draw_path_section
from raygs_viewer.viewer.panel.render import draw_render_section
from raygs_viewer.viewer.panel.scene import draw_scene_section
from raygs_viewer.viewer.panel.screenshot import draw_screenshot_section
from raygs_viewer.viewer.panel.statistics import draw_statistics
from raygs_viewer.viewer.panel.stereo import draw_stereo_section
from raygs_viewer.viewer.panel.training import draw_training_section
from raygs_viewer.viewer.panel.view import draw_view_section
from raygs_viewer.viewer.part import Reply


@dataclass
class Draft:
    """The render settings as the panel edits them, section by section."""

    settings: RenderSettings

    def set(self, settings: RenderSettings) -> None:
        self.settings = settings


def quiet(draw: Callable[[], object]) -> Callable[[], Reply]:
    """A section that says nothing, as one that returns a Reply."""
    def section() -> Reply:
        draw()
        return Reply()
    return section


def panel_sections(viewer, draft: Draft) -> list[Callable[[], Reply]]:
    """Each section of the panel of ``viewer`` (the window: ``app.Viewer``, which calls
    this and is not imported here), in order, with the state it edits; the render
    settings through ``draft``."""
    v = viewer
    loaded, renderer, view, stats, shown = v.loaded, v.scene.renderer, v.view, v.stats, v.shown
    split_shown = v.split.on and (shown is None or shown.stereo is None)
    return [
        quiet(lambda: draw_statistics(stats, loaded.scene.count, v.scene.sorter, work=renderer.counters,
                                     general=renderer.general, sort=v.scene.sort,
                                     measured=v.auto.lines(loaded.scene.count))),
        lambda: draw_scene_section(loaded, v.panel, v.scenes.loader, v.file_dialog),
        lambda: draw_lod_section(v.scene.lod, loaded, v.scenes.loader, draft.settings, set_settings=draft.set,
                                 stats=stats),
        lambda: draw_render_section(draft.settings, draft.set, scene_sh_degree=loaded.scene.sh_degree,
                                    supports=renderer.supports, window=v.window, stereo=v.stereo, split=v.split),
        quiet(lambda: draw_order_section(draft.settings, draft.set, stats, v.split.on and not v.stereo.on)),
        quiet(lambda: draw_stereo_section(v.stereo, stats, shown)),
        lambda: draw_headset_section(v.headset),
        lambda: draw_view_section(view),
        lambda: draw_training_section(loaded, view.training_index, v.photo, v.frustums),
        lambda: draw_screenshot_section(v.captures.options, shown and shown.full_camera,
                                        stereo_shown=shown is not None and shown.stereo is not None,
                                        save_eyes=v.stereo.save_eyes, split_shown=split_shown),
        quiet(lambda: draw_geometry_section(v.view_mode, v.drawer.view_range, picked=v.picker.last,
                                           scale=v.measure.scale, stereo=v.stereo, split=split_shown)),
        lambda: draw_path_section(v.camera_path, v.path_scene(draft.settings)),
        lambda: draw_measure_section(v.measure, loaded),
        lambda: draw_edit_section(v.edit_tool, loaded),
        quiet(lambda: draw_history(v.feedback)),
    ]
