"""What each panel section is handed: the part of the window's state it shows and edits.

The wiring lives here, apart from the frame loop (``app.Viewer``): each section is a
closure over the viewer, read when the panel draws it, so an edit shows in the
sections below it at once.
"""

from __future__ import annotations

from typing import Callable

from raygs_viewer.viewer.feedback import draw_history
from raygs_viewer.viewer.panel.edit import draw_edit_section
from raygs_viewer.viewer.panel.geometry import draw_geometry_section
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


def panel_sections(viewer) -> list[Callable[[], None]]:
    """Each section of the panel of ``viewer`` (the window: ``app.Viewer``, which calls
    this and is not imported here), in order, with the state it edits."""
    v = viewer
    loaded, renderer, view, stats = v.loaded, v.scene.renderer, v.view, v.stats
    shown = v.shown

    def set_tint(on: bool) -> None:  # colour by level, the Level of detail section's
        if problem := v.scene.set_tint(on, loaded.lod):
            v.panel.error = f"error: colour by level: {problem}"

    split_shown = v.split.on and v.shown_stereo is None
    return [
        lambda: draw_statistics(stats, loaded.scene.count, v.scene.sorter, renderer.counters, renderer.general,
                                v.scene.sort, v.auto.lines(loaded.scene.count)),
        lambda: draw_scene_section(loaded, v.panel, v.scenes.open, v.scenes.loader,
                                   lambda axes: v.scenes.switch_axes(loaded, axes), v.file_dialog),
        lambda: draw_lod_section(v.scene.lod, loaded, v.scenes.loader, v.settings, v.set_settings, set_tint, stats),
        lambda: draw_render_section(v.settings, v.set_settings, loaded.scene.sh_degree, renderer.supports,
                                    v.window, v.stereo, v.split, v.panel.note),
        lambda: draw_order_section(v.settings, v.set_settings, stats, v.right_settings() is not None),
        lambda: draw_stereo_section(v.stereo, stats, shown),
        lambda: draw_view_section(view, v.reset_view),
        lambda: draw_training_section(loaded, view.training_index, view.select_training_camera,
                                      view.step_training_camera, v.photo, v.frustums),
        lambda: draw_screenshot_section(v.captures.options, shown and shown.full_camera,
                                        v.shown_stereo is not None,
                                        v.stereo.save_eyes, split_shown, v.captures.request),
        lambda: draw_geometry_section(v.view_mode, v.drawer.view_range, v.picker.last, v.measure.scale, v.stereo,
                                      split_shown),
        lambda: draw_path_section(v.camera_path),
        lambda: draw_measure_section(v.measure),
        lambda: draw_edit_section(v.edit_tool),
        lambda: draw_history(v.feedback),
    ]
