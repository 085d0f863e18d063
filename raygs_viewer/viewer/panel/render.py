"""The panel's Render section: the render settings (mode, p_min, the accuracy options,
SH degree, background), then vsync, the stereo preview's switch and the A/B split view.

The settings are one frozen RenderSettings: each widget's value replaces its field,
and an edited whole goes back through ``set_settings``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.render.setting_info import applies, setting_field
from raygs_viewer.render.settings import (
    ACCURACY_PRESETS,
    MODE_LABELS,
    PRECISION_LABELS,
    RENDER_MODES,
    RenderSettings,
)
from raygs_viewer.viewer.panel.order import with_mode
from raygs_viewer.viewer.panel.widgets import checkbox, choice, header, slider, tooltip
from raygs_viewer.viewer.part import Reply
from raygs_viewer.viewer.state import SplitView, StereoPreview, note
from raygs_viewer.viewer.window import Window

P_MIN_RANGE = (1e-4, 0.5)
SIGMA2_RANGE = (0.0, 1.0)  # the slider's; ctrl-click types any value within the setting's limits
SIGMA2 = setting_field(RenderSettings, "mip_sigma2").info
SUPERSAMPLE = setting_field(RenderSettings, "supersample").info

#: renderer.supports: why the GPU cannot render these settings, or None.
Supports = Callable[[RenderSettings], "str | None"]


def draw_render_section(settings: RenderSettings, set_settings: Callable[[RenderSettings], None], *,
                        scene_sh_degree: int, supports: Supports, window: Window, stereo: StereoPreview,
                        split: SplitView) -> Reply:
    """``set_settings`` receives the edited settings (when an edit changed them);
    ``window``: its vsync; ``stereo``: its on/off; ``split``: on/off and the preset.
    Returns a note for the panel (GS switches a per-pixel order to distance)."""
    if not header("Render"):
        return Reply()
    edited, words = with_mode(settings, choice("mode", settings.mode, {m: MODE_LABELS[m] for m in RENDER_MODES}))
    tooltip("RayGS: the ray-based opacity, with the pixel-invariant MIP filter when MIP is on.\n"
            "RayGS exact MIP: the per-pixel MIP filter (Appendix A.5), always on.\n"
            "GS (EWA): INRIA's linearised splats with a 0.3 px^2 dilation.")
    # The slider also shows the kappa = -2 ln(p_min / o) it implies at opacity 1.
    kappa = f"  kappa {-2 * math.log(edited.p_min):.2f}"
    p_min = slider("p_min", edited.p_min, *P_MIN_RANGE, "%.5f" + kappa, logarithmic=True)
    tooltip("opacity cut-off: a gaussian's support is kappa = -2 ln(p_min / o);\n"
            "the slider shows kappa at opacity o = 1")
    if p_min is not None:
        edited = replace(edited, p_min=min(max(p_min, P_MIN_RANGE[0]), P_MIN_RANGE[1]))
    edited = _accuracy_controls(edited, supports)
    changed, degree = imgui.slider_int("SH degree", edited.sh_degree, 0, scene_sh_degree)
    if changed:
        edited = replace(edited, sh_degree=min(max(degree, 0), scene_sh_degree))
    changed, color = imgui.color_edit3("background", list(edited.background))
    if changed:
        edited = replace(edited, background=tuple(min(max(float(c), 0.0), 1.0) for c in color))
    for name, value in (("black", 0.0), ("grey", 0.5), ("white", 1.0)):
        if imgui.small_button(name):
            edited = replace(edited, background=(value,) * 3)
        imgui.same_line()
    if edited != settings:
        set_settings(edited)
    imgui.same_line(0, 24)
    changed, vsync = imgui.checkbox("vsync", window.vsync)
    if changed:
        window.vsync = vsync
    imgui.same_line()
    stereo.on = checkbox("stereo", stereo.on,
                         help_text="the stereo preview: both eyes as a headset shows them, one sort from their "
                                   "midpoint, each eye rendered offscreen at the headset's resolution and scaled "
                                   "into the window (its controls: the Stereo section)")
    _split_controls(split, stereo.on)
    return Reply.of(note(words)) if words else Reply()


def _accuracy_controls(settings: RenderSettings, supports: Supports) -> RenderSettings:
    """MIP, GS compensation, supersampling, the blend precision and the INRIA/GOF parity switches; what does
    not apply to the current mode, or what this GPU cannot render, is greyed out."""
    mode = settings.mode
    exact = mode == "raygs-exact-mip"
    mip_help = ("RayGS mode: the pixel-invariant MIP filter of Eq. 17 (a pixel-sized gaussian convolved into "
                "every splat). Always on in exact MIP mode; not used by GS.")
    if exact:  # on by definition: shown checked, the RayGS mode's choice kept
        checkbox("MIP filter", True, enabled=False, help_text=mip_help)
    else:
        settings = replace(settings, mip=checkbox("MIP filter", settings.mip,
                                                  enabled=applies(settings, "mip"), help_text=mip_help))
    filtered = applies(settings, "mip_sigma2")
    imgui.same_line()
    modulation = checkbox("opacity modulation", settings.mip_modulation, enabled=filtered,
                          help_text="scale the filtered opacity so a gaussian keeps its total opacity "
                                    "(the root of Eq. 17; per pixel in exact MIP mode)")
    imgui.begin_disabled(not filtered)
    sigma2 = slider("sigma^2 (px^2)", settings.mip_sigma2, *SIGMA2_RANGE, "%.3f")
    imgui.end_disabled()
    tooltip("the MIP filter's variance in px^2 of the rendered image (default 0.1).\n"
            f"Ctrl-click to type a value (up to {SIGMA2.limits[1]:g}).")
    if sigma2 is not None:
        settings = replace(settings, mip_sigma2=SIGMA2.clamp(float(sigma2)))
    settings = replace(settings, mip_modulation=modulation, gs_compensation=checkbox(
        "GS compensation", settings.gs_compensation, enabled=applies(settings, "gs_compensation"),
        help_text="GS mode: scale opacity by sqrt(det(S) / det(S + 0.3 px^2)), as Mip-Splatting does"))
    low, high = SUPERSAMPLE.limits
    factors = {str(k): f"{k}\u00d7{k}" for k in range(low, high + 1)}
    # Two short choices on one line: the panel already reaches below a 720-px window.
    imgui.set_next_item_width(imgui.get_font_size() * 4.5)
    settings = replace(settings, supersample=int(choice("supersampling", str(settings.supersample), factors)))
    tooltip("render k x k samples per pixel and average them (a box filter)")
    imgui.same_line()
    imgui.set_next_item_width(imgui.get_font_size() * 6.3)
    settings = replace(settings, precision=choice("blend", settings.precision, PRECISION_LABELS))
    tooltip("what the blended colour accumulates in: float32 (exact), float16 or 8-bit, which cost a GPU less "
            "fill at the error bench accuracy states.\nThe per-pixel order and the transmittance cut-off "
            "composite in float32 whatever is chosen here.")
    parity = "matches the images of INRIA 3DGS and GOF (section 10)"
    settings = replace(settings, alpha_clamp=checkbox("alpha clamp 0.99", settings.alpha_clamp,
                                                      help_text=f"clamp each splat's alpha to 0.99: {parity}"))
    unsupported = supports(RenderSettings(transmittance_cutoff=True))
    return replace(settings, transmittance_cutoff=checkbox(
        "transmittance cut-off 1e-4", settings.transmittance_cutoff,
        enabled=not unsupported or settings.transmittance_cutoff,
        help_text=unsupported or f"stop compositing a pixel before its transmittance falls below 1e-4: {parity}.\n"
                                 f"INRIA's rule skips the splat that would cross it, so without the alpha clamp "
                                 f"a nearly opaque splat leaves a hole"))


def _split_controls(split: SplitView, stereo_on: bool) -> None:
    split.on = checkbox("split view", split.on, enabled=not stereo_on,
                        help_text="A/B: left of the divider the settings above, right of it the chosen "
                                  "preset applied to them. Drag the divider with the left mouse button."
                                  + ("\n(Off in the stereo preview.)" if stereo_on else ""))
    imgui.same_line()
    imgui.begin_disabled(not split.on)
    imgui.set_next_item_width(-1)
    split.preset = choice("##right side", split.preset, {name: name for name in ACCURACY_PRESETS})
    imgui.end_disabled()
    tooltip("the right side's accuracy preset: the settings above with these options")
