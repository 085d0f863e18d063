"""The imgui panel: scene, render settings, view, training cameras, screenshots, statistics.

Widgets edit ``viewer.panel`` (a PanelState) or call the viewer's methods; the
frame reads them, so an edit shows from the next frame on. ``item_rects`` keeps
where each labelled widget was drawn, for tests that click on them.
"""

from __future__ import annotations

import math

from imgui_bundle import imgui

from raygs_viewer.render.settings import (
    ACCURACY_PRESETS,
    MAX_MIP_SIGMA2,
    MAX_SUPERSAMPLE,
    MODE_LABELS,
    RENDER_MODES,
    RenderSettings,
)

P_MIN_RANGE = (1e-4, 0.5)
SIGMA2_RANGE = (0.0, 1.0)  # the slider's; ctrl-click types any value up to MAX_MIP_SIGMA2
FOV_RANGE = (10.0, 120.0)
SCALE_CHOICES = (1.0, 2.0, 4.0, 8.0)

#: label -> (x0, y0, x1, y1) in screen coordinates of the last frame's widget.
item_rects: dict[str, tuple[float, float, float, float]] = {}


def _remember(label: str) -> None:
    low, high = imgui.get_item_rect_min(), imgui.get_item_rect_max()
    item_rects[label] = (low.x, low.y, high.x, high.y)


def _tooltip(text: str) -> None:
    if imgui.is_item_hovered(imgui.HoveredFlags_.allow_when_disabled.value):
        imgui.set_tooltip(text)


def draw_panel(viewer) -> None:
    panel = viewer.panel
    imgui.set_next_window_pos((10, 10), imgui.Cond_.first_use_ever.value)
    imgui.set_next_window_size((360, 0), imgui.Cond_.first_use_ever.value)
    # Never taller than the window: a short window scrolls the panel instead of cutting it off.
    display = imgui.get_io().display_size
    imgui.set_next_window_size_constraints((0, 0), (1e9, max(display.y - 20, 100)))
    visible, _ = imgui.begin("raygs-viewer", None)
    if not visible:
        imgui.end()
        return
    _statistics(viewer)
    _scene_section(viewer)
    _render_section(viewer)
    _stereo_section(viewer)
    _view_section(viewer)
    _training_section(viewer)
    _screenshot_section(viewer)
    if panel.message:
        imgui.text_wrapped(panel.message)
    if panel.error:
        imgui.push_style_color(imgui.Col_.text.value, (1.0, 0.45, 0.4, 1.0))
        imgui.text_wrapped(panel.error)
        imgui.pop_style_color()
    imgui.end()


def _ms(seconds: float) -> str:
    return f"{seconds * 1000:6.2f} ms" if math.isfinite(seconds) else "     - ms"


def _statistics(viewer) -> None:
    stats, sorter = viewer.stats, viewer.sorter
    imgui.text(f"{stats.fps:6.1f} fps  frame {_ms(stats.frame_ms / 1000)}")
    _tooltip("frames per second and the median frame time of the last 60 frames")
    imgui.text(f"GPU   {_ms(stats.gpu_seconds)}  sort {_ms(stats.sort_seconds)}")
    _tooltip("GPU: preprocessing + draw of the last redraw (timer queries; both sides in the split view,\n"
             "both eyes in the stereo preview).\n"
             "sort: the last depth sort, on a background thread")
    age = "up to date" if stats.order_age == 0 else f"{stats.order_age} frames old"
    imgui.text(f"visible {stats.visible:,} of {viewer.loaded.scene.count:,}, order {age}")
    work = viewer.renderer.counters
    _tooltip(f"sorts: {sorter.requested} asked, {sorter.finished} done, {sorter.superseded} skipped "
             f"(superseded by a newer view before they started)\n"
             f"{'general' if viewer.renderer.general else 'specialised'} shaders: "
             + ("one variant switches every feature at run time (--general)" if viewer.renderer.general else
                "each variant carries only the features the scene and the settings use") + "\n"
             f"preprocessing: {work.preprocessed} passes, {work.preprocess_skipped} skipped (same view)\n"
             f"order uploads: {work.uploads}, {work.upload_skipped} skipped (same order)")
    imgui.separator()


def _scene_section(viewer) -> None:
    panel, loaded = viewer.panel, viewer.loaded
    if not imgui.collapsing_header("Scene", imgui.TreeNodeFlags_.default_open.value):
        return
    scene = loaded.scene
    imgui.text_wrapped("built-in demo scene" if loaded.path == "demo" else loaded.path)
    imgui.text(f"{scene.count:,} gaussians, SH degree {scene.sh_degree}, "
               f"3D filter {'fused' if scene.filter_fused else 'none'}")
    entered, panel.open_path = imgui.input_text_with_hint(
        "##open", "scene.ply (or drop a file)", panel.open_path, imgui.InputTextFlags_.enter_returns_true.value)
    _remember("open path")
    imgui.same_line()
    if imgui.button("Open") or entered:
        viewer.open_scene(panel.open_path)
    _remember("Open")
    if viewer.loader.busy:
        imgui.progress_bar(viewer.loader.progress, (-1, 0), viewer.loader.stage)


def _choice(label: str, current: str, choices: dict[str, str], tag: str) -> str:
    """A combo of ``choices`` (value -> shown text), every entry visible when it opens;
    the combo's rect is remembered as ``tag`` and each open entry's as
    ``f"{tag} {value}"``. Returns the chosen value."""
    chosen = current
    if imgui.begin_combo(label, choices.get(current, current), imgui.ComboFlags_.height_largest.value):
        for value, text in choices.items():
            if imgui.selectable(text, value == current)[0]:
                chosen = value
            _remember(f"{tag} {value}")
            if value == current:
                imgui.set_item_default_focus()
        imgui.end_combo()
    _remember(tag)
    return chosen


def _checkbox(label: str, value: bool, tag: str, enabled: bool = True, tooltip: str = "") -> bool:
    imgui.begin_disabled(not enabled)
    _, value = imgui.checkbox(label, value)
    imgui.end_disabled()
    _remember(tag)
    if tooltip:
        _tooltip(tooltip)
    return value


def _render_section(viewer) -> None:
    panel, scene = viewer.panel, viewer.loaded.scene
    if not imgui.collapsing_header("Render", imgui.TreeNodeFlags_.default_open.value):
        return
    panel.mode = _choice("mode", panel.mode, {mode: MODE_LABELS[mode] for mode in RENDER_MODES}, "mode")
    _tooltip("RayGS: the ray-based opacity, with the pixel-invariant MIP filter when MIP is on.\n"
             "RayGS exact MIP: the per-pixel MIP filter (Appendix A.5), always on.\n"
             "GS (EWA): INRIA's linearised splats with a 0.3 px^2 dilation.")
    # The slider also shows the kappa = -2 ln(p_min / o) it implies at opacity 1.
    kappa = f"  kappa {-2 * math.log(panel.p_min):.2f}"
    changed, value = imgui.slider_float("p_min", panel.p_min, *P_MIN_RANGE, "%.5f" + kappa,
                                        imgui.SliderFlags_.logarithmic.value)
    _remember("p_min")
    _tooltip("opacity cut-off: a gaussian's support is kappa = -2 ln(p_min / o);\n"
             "the slider shows kappa at opacity o = 1")
    if changed and math.isfinite(value):
        panel.p_min = min(max(value, P_MIN_RANGE[0]), P_MIN_RANGE[1])
    _accuracy_controls(panel, viewer.renderer)
    changed, degree = imgui.slider_int("SH degree", panel.sh_degree, 0, scene.sh_degree)
    _remember("SH degree")
    if changed:
        panel.sh_degree = min(max(degree, 0), scene.sh_degree)
    changed, color = imgui.color_edit3("background", panel.background)
    if changed:
        panel.background = [min(max(float(c), 0.0), 1.0) for c in color]
    for name, value in (("black", 0.0), ("grey", 0.5), ("white", 1.0)):
        if imgui.small_button(name):
            panel.background = [value] * 3
        _remember(f"background {name}")
        imgui.same_line()
    imgui.same_line(0, 24)
    changed, vsync = imgui.checkbox("vsync", viewer.window.vsync)
    if changed:
        viewer.window.vsync = vsync
    imgui.same_line()
    panel.stereo = _checkbox("stereo", panel.stereo, "stereo preview",
                             tooltip="the stereo preview: both eyes as a headset shows them, one sort from their "
                                     "midpoint, each eye rendered offscreen at the headset's resolution and scaled "
                                     "into the window (its controls: the Stereo section)")
    _split_controls(viewer)


def _accuracy_controls(panel, renderer) -> None:
    """MIP, GS compensation, supersampling and the INRIA/GOF parity switches; what does
    not apply to the current mode, or what this GPU cannot render, is greyed out."""
    exact = panel.mode == "raygs-exact-mip"
    mip_help = ("RayGS mode: the pixel-invariant MIP filter of Eq. 17 (a pixel-sized gaussian convolved into "
                "every splat). Always on in exact MIP mode; not used by GS.")
    if exact:  # on by definition: shown checked, the RayGS mode's choice kept
        _checkbox("MIP filter", True, "MIP filter", enabled=False, tooltip=mip_help)
    else:
        panel.mip = _checkbox("MIP filter", panel.mip, "MIP filter", enabled=panel.mode == "raygs", tooltip=mip_help)
    filtered = exact or (panel.mode == "raygs" and panel.mip)
    imgui.same_line()
    modulation = _checkbox("opacity modulation", panel.mip_modulation, "opacity modulation", enabled=filtered,
                           tooltip="scale the filtered opacity so a gaussian keeps its total opacity "
                                   "(the root of Eq. 17; per pixel in exact MIP mode)")
    imgui.begin_disabled(not filtered)
    changed, value = imgui.slider_float("sigma^2 (px^2)", panel.mip_sigma2, *SIGMA2_RANGE, "%.3f")
    imgui.end_disabled()
    _remember("sigma^2")
    _tooltip("the MIP filter's variance in px^2 of the rendered image (default 0.1).\n"
             "Ctrl-click to type a value (up to 100).")
    if changed and math.isfinite(value):
        panel.mip_sigma2 = min(max(float(value), 0.0), MAX_MIP_SIGMA2)
    panel.mip_modulation = modulation
    panel.gs_compensation = _checkbox("GS compensation", panel.gs_compensation, "GS compensation",
                                      enabled=panel.mode == "gs",
                                      tooltip="GS mode: scale opacity by sqrt(det(S) / det(S + 0.3 px^2)), "
                                              "as Mip-Splatting does")
    factors = {k: f"{k}\u00d7{k}" for k in range(1, MAX_SUPERSAMPLE + 1)}
    chosen = _choice("supersampling", str(panel.supersample), {str(k): text for k, text in factors.items()},
                     "supersampling")
    panel.supersample = int(chosen)
    _tooltip("render k x k samples per pixel and average them (a box filter)")
    parity = "matches the images of INRIA 3DGS and GOF (section 10)"
    panel.alpha_clamp = _checkbox("alpha clamp 0.99", panel.alpha_clamp, "alpha clamp",
                                  tooltip=f"clamp each splat's alpha to 0.99: {parity}")
    unsupported = renderer.supports(RenderSettings(transmittance_cutoff=True))
    panel.transmittance_cutoff = _checkbox("transmittance cut-off 1e-4", panel.transmittance_cutoff,
                                           "transmittance cut-off", enabled=not unsupported or panel.transmittance_cutoff,
                                           tooltip=unsupported or f"stop compositing a pixel before its transmittance "
                                                                  f"falls below 1e-4: {parity}.\nINRIA's rule skips the "
                                                                  f"splat that would cross it, so without the alpha clamp "
                                                                  f"a nearly opaque splat leaves a hole")


def _split_controls(viewer) -> None:
    panel = viewer.panel
    panel.split_view = _checkbox("split view", panel.split_view, "split view", enabled=not panel.stereo,
                                 tooltip="A/B: left of the divider the settings above, right of it the chosen "
                                         "preset applied to them. Drag the divider with the left mouse button."
                                         + ("\n(Off in the stereo preview.)" if panel.stereo else ""))
    imgui.same_line()
    imgui.begin_disabled(not panel.split_view)
    imgui.set_next_item_width(-1)
    panel.split_preset = _choice("##right side", panel.split_preset, {name: name for name in ACCURACY_PRESETS},
                                 "split preset")
    imgui.end_disabled()
    _tooltip("the right side's accuracy preset: the settings above with these options")


STEREO_LAYOUT_LABELS = {"sbs": "side by side (parallel)", "cross": "side by side (cross-eyed)",
                        "anaglyph": "anaglyph (red/cyan)", "left": "left eye only", "right": "right eye only"}
IPD_MM_RANGE = (0.0, 80.0)          # the slider's; ctrl-click types up to 1000 mm
CONVERGENCE_RANGE = (0.1, 100.0)    # metres, logarithmic
SCENE_SCALE_RANGE = (0.001, 1000.0)  # metres per unit, logarithmic


def _stereo_section(viewer) -> None:
    from raygs_viewer.camera.stereo import (
        MAX_EYE_SIZE,
        MAX_FOV,
        MIN_FOV,
        PRESETS,
        StereoRig,
        frame_budget,
    )
    panel = viewer.panel
    # Only while the preview is on (the Render section's checkbox): the panel stays short.
    if not panel.stereo or not imgui.collapsing_header("Stereo", imgui.TreeNodeFlags_.default_open.value):
        return
    imgui.push_item_width(-imgui.calc_text_size("scene scale (m/unit)").x - 12)  # room for the longest label
    panel.lens_preview = _checkbox("lens preview", panel.lens_preview, "lens preview",
                                   tooltip="the barrel distortion and chromatic aberration correction a headset's "
                                           "compositor applies: what the headset's panel receives")
    panel.stereo_layout = _choice("layout", panel.stereo_layout, STEREO_LAYOUT_LABELS, "stereo layout")
    changed, ipd_mm = imgui.slider_float("IPD (mm)", panel.ipd * 1000.0, *IPD_MM_RANGE, "%.1f")
    _remember("IPD")
    _tooltip("distance between the eyes (default 63 mm). Ctrl-click to type a value.")
    if changed and math.isfinite(ipd_mm):
        panel.ipd = min(max(ipd_mm / 1000.0, 0.0), 1.0)
    changed, value = imgui.slider_float("convergence (m)", panel.convergence, *CONVERGENCE_RANGE, "%.2f",
                                        imgui.SliderFlags_.logarithmic.value)
    _remember("convergence")
    _tooltip("distance of the plane both eyes see at the same pixel (zero disparity)")
    if changed and math.isfinite(value):
        panel.convergence = min(max(value, 1e-3), 1e6)
    changed, value = imgui.slider_float("scene scale (m/unit)", panel.scene_scale, *SCENE_SCALE_RANGE, "%.4g",
                                        imgui.SliderFlags_.logarithmic.value)
    _remember("scene scale")
    _tooltip("metres per scene unit: how big the scene feels (larger: the scene looks smaller)")
    if changed and math.isfinite(value) and value > 0:
        panel.scene_scale = min(max(value, 1e-9), 1e9)
    rig = StereoRig(panel.ipd, panel.convergence, panel.scene_scale)
    imgui.text_disabled(f"eyes {2 * rig.half_baseline:.4g} units apart, convergence at "
                        f"{rig.convergence_units:.4g} units")
    headsets = {name: f"{p.label}: {p.width}x{p.height}, {p.fov_x:g}x{p.fov_y:g} deg" for name, p in PRESETS.items()}
    headsets["custom"] = "custom"
    panel.headset = _choice("headset", panel.headset, headsets, "headset")
    _tooltip("per-eye resolution and field of view; each eye renders offscreen at this size")
    if panel.headset == "custom":
        changed, size = imgui.input_int2("per-eye size", panel.custom_size)
        if changed:
            panel.custom_size = [min(max(int(v), 1), MAX_EYE_SIZE) for v in size]
        changed, fov = imgui.input_float2("field of view (deg)", panel.custom_fov, "%.1f")
        if changed and all(math.isfinite(v) for v in fov):
            panel.custom_fov = [min(max(float(v), MIN_FOV), MAX_FOV) for v in fov]
    panel.save_eyes = _checkbox("screenshots also save each eye", panel.save_eyes, "save eyes",
                                tooltip="F12 saves the side-by-side pair; this adds -left and -right files")
    imgui.pop_item_width()
    stats = viewer.stats
    imgui.text(f"both eyes {_ms(stats.gpu_seconds)}  lens+layout {_ms(stats.post_seconds)}")
    _tooltip("GPU time of drawing both eyes (timer queries), against a headset's frame budget")
    for rate, budget, fraction in frame_budget(stats.gpu_seconds):
        over = math.isfinite(fraction) and fraction > 1.0
        if over:
            imgui.push_style_color(imgui.Col_.plot_histogram.value, (0.85, 0.25, 0.2, 1.0))
        text = (f"{rate} Hz ({budget * 1000:.1f} ms): "
                + (f"{fraction:.1f}x over" if over else f"{fraction * 100:.0f} %" if math.isfinite(fraction) else "-"))
        imgui.progress_bar(min(fraction, 1.0) if math.isfinite(fraction) else 0.0, (-1, 0), text)
        _remember(f"budget {rate}")
        if over:
            imgui.pop_style_color()


def _view_section(viewer) -> None:
    from raygs_viewer.camera.navigation import UP_AXES
    nav = viewer.navigator
    if not imgui.collapsing_header("View", imgui.TreeNodeFlags_.default_open.value):
        return
    for mode in ("fly", "orbit"):
        if imgui.radio_button(mode, nav.mode == mode):
            nav.set_mode(mode)
        _remember(mode)
        imgui.same_line()
    imgui.text_disabled("(Tab)")
    axes = list(UP_AXES)
    changed, index = imgui.combo("up axis", axes.index(nav.up), axes)
    if changed:
        nav.set_up(axes[index])
    changed, fov = imgui.slider_float("field of view", viewer.lens.fov_y_degrees, *FOV_RANGE, "%.1f deg")
    if changed and math.isfinite(fov):
        viewer.set_fov(min(max(fov, FOV_RANGE[0]), FOV_RANGE[1]))
    imgui.text_disabled(f"speed {nav.speed:.3g} units/s")
    _tooltip("the mouse wheel changes it in fly mode")
    imgui.same_line()
    if imgui.button("Reset view (R)"):
        viewer.reset_view()
    _remember("Reset view")


def _training_section(viewer) -> None:
    loaded = viewer.loaded
    label = f"Training cameras ({len(loaded.cameras)})"
    if not imgui.collapsing_header(label + "###training"):
        return
    if not loaded.cameras:
        imgui.text_disabled("none found (pass --cameras cameras.json)")
        return
    if loaded.cameras_path:
        imgui.text_disabled(loaded.cameras_path)
    if imgui.button("< previous (P)"):
        viewer.step_training_camera(-1)
    imgui.same_line()
    if imgui.button("next (N) >"):
        viewer.step_training_camera(+1)
    if imgui.begin_list_box("##cameras", (-1, 160)):
        for i, name in enumerate(loaded.camera_names):
            if imgui.selectable(f"{i}: {name}", viewer.training_index == i)[0]:
                viewer.select_training_camera(i)
        imgui.end_list_box()


def _screenshot_section(viewer) -> None:
    panel = viewer.panel
    if not imgui.collapsing_header("Screenshot", imgui.TreeNodeFlags_.default_open.value):
        return
    for scale in SCALE_CHOICES:
        if imgui.radio_button(f"{scale:g}x", panel.screenshot_scale == scale):
            panel.screenshot_scale = scale
        imgui.same_line()
    imgui.new_line()
    if viewer.camera is not None:
        width = round(viewer.camera.width * panel.screenshot_scale)
        height = round(viewer.camera.height * panel.screenshot_scale)
        if viewer.shown_stereo is not None:
            imgui.text_disabled(f"{2 * width} x {height} px side-by-side pair ({width} x {height} per eye), offscreen")
        else:
            imgui.text_disabled(f"{width} x {height} px, offscreen")
    _, panel.screenshot_dir = imgui.input_text("folder", panel.screenshot_dir)
    if imgui.button("Save screenshot (F12)"):
        viewer.screenshot_requested = True
    _remember("Save screenshot")
    if viewer.shown_stereo is not None and panel.save_eyes:
        imgui.same_line()
        imgui.text_disabled("(-pair, -left, -right)")
    elif panel.split_view and viewer.shown_stereo is None:
        imgui.same_line()
        imgui.text_disabled("(each side, -left/-right)")
