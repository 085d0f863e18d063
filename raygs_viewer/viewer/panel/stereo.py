"""The panel's Stereo section, shown while the preview is on: lens preview, layout, the
rig (IPD, convergence, scene scale), the headset, whether the eyes are drawn at its
size, and the GPU time of both eyes (at the headset's size: measured, or estimated
from the size drawn) against a headset's frame budget."""

from __future__ import annotations

import math
from dataclasses import replace

from imgui_bundle import imgui

from raygs_viewer.camera.stereo import (
    MAX_EYE_SIZE,
    MAX_FOV,
    MIN_FOV,
    PRESETS,
    at_headset_size,
    frame_budget,
    rig_quantities,
)
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.panel.widgets import checkbox, choice, header, line, ms, note, slider, tooltip
from raygs_viewer.viewer.state import StereoPreview
from raygs_viewer.viewer.stats import FrameStats

STEREO_LAYOUT_LABELS = {"sbs": "side by side (parallel)", "cross": "side by side (cross-eyed)",
                        "anaglyph": "anaglyph (red/cyan)", "left": "left eye only", "right": "right eye only"}
IPD_MM_RANGE = (0.0, 80.0)          # the slider's; ctrl-click types any value within the rig's limits
CONVERGENCE_RANGE = (0.1, 100.0)    # metres, logarithmic
SCENE_SCALE_RANGE = (0.001, 1000.0)  # metres per unit, logarithmic
#: Each rig field's Quantity: the values it takes, whatever the slider's range.
RIG = rig_quantities()


def draw_stereo_section(stereo: StereoPreview, stats: FrameStats, shown: Frame | None) -> None:
    """Edits ``stereo``; ``stats``: the GPU times of the last redraw; ``shown``: the
    last frame (the eyes' size drawn and the headset's)."""
    # Only while the preview is on (the Render section's checkbox): the panel stays short.
    if not stereo.on or not header("Stereo"):
        return
    imgui.push_item_width(-imgui.calc_text_size("scene scale (m/unit)").x - 12)  # room for the longest label
    stereo.lens_preview = checkbox("lens preview", stereo.lens_preview,
                                   help_text="the barrel distortion and chromatic aberration correction a headset's "
                                             "compositor applies: what the headset's panel receives")
    stereo.layout = choice("layout", stereo.layout, STEREO_LAYOUT_LABELS)
    _rig_controls(stereo)
    headsets = {name: f"{p.label}: {p.width}x{p.height}, {p.fov_x:g}x{p.fov_y:g} deg" for name, p in PRESETS.items()}
    headsets["custom"] = "custom"
    stereo.headset = choice("headset", stereo.headset, headsets)
    tooltip("per-eye resolution and field of view; each eye renders offscreen at this size")
    if stereo.headset == "custom":
        changed, size = imgui.input_int2("per-eye size", stereo.custom_size)
        if changed:
            stereo.custom_size = [min(max(int(v), 1), MAX_EYE_SIZE) for v in size]
        changed, fov = imgui.input_float2("field of view (deg)", stereo.custom_fov, "%.1f")
        if changed and all(math.isfinite(v) for v in fov):
            stereo.custom_fov = [min(max(float(v), MIN_FOV), MAX_FOV) for v in fov]
    stereo.headset_size = checkbox("eyes at the headset's size", stereo.headset_size,
                                   help_text="draw each eye at the headset's per-eye resolution (slower), shrunk to "
                                             "fit; off: at the size the window shows.\nScreenshots and videos are "
                                             "at the headset's size either way.")
    stereo.save_eyes = checkbox("screenshots also save each eye", stereo.save_eyes,
                                help_text="F12 saves the side-by-side pair; this adds -left and -right files")
    imgui.pop_item_width()
    if shown is not None and shown.stereo is not None:
        _budget(stats, shown)


def _rig_controls(stereo: StereoPreview) -> None:
    rig = stereo.rig
    ipd_mm = slider("IPD (mm)", rig.ipd * 1000.0, *IPD_MM_RANGE, "%.1f")
    tooltip("distance between the eyes (default 63 mm). Ctrl-click to type a value.")
    if ipd_mm is not None:
        rig = replace(rig, ipd=RIG["ipd"].clamp(ipd_mm / 1000.0))
    convergence = slider("convergence (m)", rig.convergence, *CONVERGENCE_RANGE, "%.2f", logarithmic=True)
    tooltip("distance of the plane both eyes see at the same pixel (zero disparity)")
    if convergence is not None:
        rig = replace(rig, convergence=RIG["convergence"].clamp(convergence))
    scale = slider("scene scale (m/unit)", rig.scene_scale, *SCENE_SCALE_RANGE, "%.4g", logarithmic=True)
    tooltip("metres per scene unit: how big the scene feels (larger: the scene looks smaller)")
    if scale is not None and scale > 0:
        rig = replace(rig, scene_scale=RIG["scene_scale"].clamp(scale))
    stereo.rig = rig
    note(f"eyes {2 * rig.half_baseline:.4g} units apart, convergence at "
                        f"{rig.convergence_units:.4g} units")


def _budget(stats: FrameStats, shown: Frame) -> None:
    """What was timed (both eyes at the size drawn), and the headset-size frame it
    stands for against each refresh rate's budget: measured when the eyes are drawn at
    the headset's size, else estimated from the fill measured."""
    drawn, full = shown.camera, shown.full_camera
    size, headset = (drawn.width, drawn.height), (full.width, full.height)
    line(f"both eyes at {size[0]}x{size[1]}: {ms(stats.gpu_seconds)}")
    tooltip("GPU time of drawing both eyes at the size drawn (timer queries; lens preview and layout: "
            f"{ms(stats.post_seconds)} more)")
    seconds = stats.gpu_seconds
    if size != headset:
        seconds = at_headset_size(stats.gpu_seconds, size, headset)
        line(f"at {headset[0]}x{headset[1]}: ~{ms(seconds)} (est.)")
        tooltip(f"the headset's per-eye size has {headset[0] * headset[1] / (size[0] * size[1]):.1f}x the pixels "
                "of the eyes drawn; splatting is bound by fill, so the time is estimated at that many times "
                "the one measured.\nTick \"eyes at the headset's size\" to measure it.")
    for rate, budget, fraction in frame_budget(seconds):
        over = math.isfinite(fraction) and fraction > 1.0
        if over:
            imgui.push_style_color(imgui.Col_.plot_histogram.value, (0.85, 0.25, 0.2, 1.0))
        text = (f"{rate} Hz ({budget * 1000:.1f} ms): "
                + (f"{fraction:.1f}x over" if over else f"{fraction * 100:.0f} %" if math.isfinite(fraction) else "-"))
        imgui.progress_bar(min(fraction, 1.0) if math.isfinite(fraction) else 0.0, (-1, 0), text)
        if over:
            imgui.pop_style_color()
