"""The panel's Geometry section: the view mode (colour, or a picture of alpha, depth,
median depth or normals), the alpha below which the depth and normal pictures mask a
pixel, the depth pictures' range (automatic, or set by two fields) and the range in
use, the normals' space, and the point the last double-click picked.
In the stereo preview, whether a double-click sets the convergence."""

from __future__ import annotations

import math

from imgui_bundle import imgui

from raygs_viewer.capture.measure_file import MeasureScale
from raygs_viewer.render.channels import NORMAL_SPACES
from raygs_viewer.viewer.measure import format_distance
from raygs_viewer.viewer.panel.widgets import checkbox, choice, header, line, note, slider, tooltip
from raygs_viewer.viewer.picking import Picked
from raygs_viewer.viewer.state import VIEW_SIDES, StereoPreview, ViewMode

VIEW_LABELS = {"rgb": "colour", "alpha": "alpha", "depth": "depth", "median_depth": "median depth",
               "normal": "normal"}
VIEW_HELP = ("what the view shows (both sides of the split view, both stereo eyes, and screenshots):\n"
             "depth: the expected z of each pixel's fragments, weighted as they blend;\n"
             "median depth: the z where the pixel's alpha reaches 0.5 (black where it never does);\n"
             "normal: each gaussian's shortest axis, facing the camera, blended, as 0.5 + 0.5 n;\n"
             "alpha: the pixel's coverage. Depths are viridis, near bright, far dark.")
PICK_HELP = ("double-click the view: orbit mode orbits around the point under the mouse (the view keeps its\n"
             "direction and centres it), fly mode turns to face it. The point is the pixel's median depth.")


def draw_geometry_section(mode: ViewMode, range_in_use: tuple[float, float] | None, *, picked: Picked | None,
                          scale: MeasureScale | None, stereo: StereoPreview, split: bool = False) -> None:
    """Edits ``mode`` (and ``stereo.converge_on_pick`` while the preview is on);
    ``range_in_use``: the depth range the last draw used; ``picked``: the last
    double-click's point, its distance shown in ``scale``'s unit when one is set;
    ``split``: the split view is shown (then ``mode.side`` picks the sides)."""
    if not header("Geometry"):
        return
    mode.channel = choice("show", mode.channel, VIEW_LABELS)
    tooltip(VIEW_HELP)
    if split and mode.channel != "rgb":
        mode.side = choice("on", mode.side, VIEW_SIDES)
        tooltip("which side of the split view shows the picture; the other shows the colour")
    if mode.channel in ("depth", "median_depth", "normal"):
        _alpha_threshold(mode)
    if mode.channel in ("depth", "median_depth"):
        _depth_range(mode, range_in_use)
    elif mode.channel == "normal":
        line("normals in")
        for space in NORMAL_SPACES:
            imgui.same_line()
            if imgui.radio_button(f"{space}##normals", mode.normal_space == space):
                mode.normal_space = space
    if stereo.on:
        stereo.converge_on_pick = checkbox("double-click sets convergence", stereo.converge_on_pick,
                                           help_text="in the stereo preview, a double-click sets the convergence "
                                                     "to the picked point's depth instead of aiming the view")
    if picked is None:
        note("double-click the view to pick a point")
    else:
        x, y, z = picked.point
        line(f"picked ({x:.4g}, {y:.4g}, {z:.4g})")
        line(f"distance from the camera {format_distance(picked.distance, scale)}")
    tooltip(PICK_HELP)


def _alpha_threshold(mode: ViewMode) -> None:
    imgui.set_next_item_width(160)
    threshold = slider("mask below alpha", mode.alpha_threshold, 0.0, 1.0, "%.3f")
    if threshold is not None:
        mode.alpha_threshold = min(max(threshold, 0.0), 1.0)  # a ctrl-click may type beyond the slider
    tooltip("pixels whose alpha is below this are black, as undefined: depth and normals are defined wherever\n"
            "alpha > 0, so without it faint haze paints at full strength. 0: off (every covered pixel)")


def _depth_range(mode: ViewMode, range_in_use: tuple[float, float] | None) -> None:
    mode.automatic = checkbox("automatic range", mode.automatic,
                              help_text="span the depths of each image (1st to 99th percentile); off: the two "
                                        "fields below")
    imgui.begin_disabled(mode.automatic)
    imgui.set_next_item_width(100)
    changed, near = imgui.input_float("near##depth", mode.near, 0.0, 0.0, "%.4g")
    if changed and math.isfinite(near):
        mode.near = near
    imgui.same_line()
    imgui.set_next_item_width(100)
    changed, far = imgui.input_float("far##depth", mode.far, 0.0, 0.0, "%.4g")
    if changed and math.isfinite(far):
        mode.far = far
    imgui.end_disabled()
    if range_in_use is None:
        note("range in use: none (nothing has a depth)")
    else:
        line(f"range in use: {range_in_use[0]:.4g} to {range_in_use[1]:.4g} units")
