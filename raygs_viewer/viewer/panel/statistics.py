"""The panel's top lines: frame rate, GPU and sort times, what is visible, how old the
drawn order is; the tooltips break the work down."""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.render.gl.preprocess_pass import WorkCounters
from raygs_viewer.sort.worker import BackgroundSorter, InlineSorter
from raygs_viewer.viewer.panel.widgets import line, ms, note, tooltip
from raygs_viewer.viewer.stats import FrameStats, order_freshness


def draw_statistics(stats: FrameStats, scene_count: int, sorter: BackgroundSorter | InlineSorter, *,
                    work: WorkCounters, general: bool, sort: str = "cpu", measured: list[str] = ()) -> None:
    """``sorter``: its request counts; ``work``: the renderer's pass counters;
    ``general``: whether it draws with the all-features shader variant; ``sort``: which
    sort runs ("cpu", "gpu": ``render.sorting.SORTS``); ``measured``: what the automatic
    defaults chose and why (``viewer.auto_defaults``)."""
    line(f"{stats.fps:6.1f} fps  redraw {ms(stats.redraw_ms / 1000)}")
    tooltip(f"frames per second over the last 60 frames (median {ms(stats.frame_ms / 1000).strip()}); a still "
            "view is not drawn again, so its frames are quick.\nredraw: the median time of the last 60 frames "
            "that drew the scene again (what moving the view costs)")
    line(f"GPU   {ms(stats.gpu_seconds)}  {sort.upper()} sort {ms(stats.sort_seconds)}")
    where = ("on the GPU, in the frame it draws (--sort gpu): the order is that frame's own; its GPU time,\n"
             "from a timer query read a few frames late" if sort == "gpu"
             else "on the CPU, on a background thread (--sort cpu)")
    tooltip("GPU: preprocessing + draw of the last redraw (timer queries; both sides in the split view,\n"
            "both eyes in the stereo preview).\n"
            f"sort: the last sort (one cull, then a sort by each order key shown), {where}")
    for why in measured:
        note(why)
    if measured:
        tooltip("--sort auto and --precision auto: what this GL measured of itself (raygs-viewer doctor shows it "
                "all), remembered in gl-profile.json per renderer and driver")
    line(f"visible {stats.visible:,} of {scene_count:,}")
    tooltip(f"the gaussians the last cull kept, of the scene's {scene_count:,}")
    # One line whatever the age (a line that wraps at times would move every widget below it
    # between frames); the whole of it in the tooltip.
    line(f"order {order_freshness(stats, short=True)}")
    tooltip(f"order {order_freshness(stats)}\n"
            "the drawn order's age: frames and milliseconds since the view it was sorted for, and how far\n"
            "the camera has turned and moved (scene units) since; a fresher order blends more rightly\n"
            f"sorts: {sorter.requested} asked, {sorter.finished} done, {sorter.superseded} skipped "
            f"(superseded by a newer view before they started)\n"
            f"{'general' if general else 'specialised'} shaders: "
            + ("one variant switches every feature at run time (--general)" if general else
               "each variant carries only the features the scene and the settings use") + "\n"
            f"preprocessing: {work.preprocessed} passes, {work.preprocess_skipped} skipped (same view)\n"
            f"order uploads: {work.uploads}, {work.upload_skipped} skipped (same order)")
    imgui.separator()
