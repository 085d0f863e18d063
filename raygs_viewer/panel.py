"""The imgui panel: scene, render settings, view, training cameras, screenshots, statistics.

Widgets edit ``viewer.panel`` (a PanelState) or call the viewer's methods; the
frame reads them, so an edit shows from the next frame on. ``item_rects`` keeps
where each labelled widget was drawn, for tests that click on them.
"""

from __future__ import annotations

import math

from imgui_bundle import imgui

from raygs_viewer.app import RENDER_MODES

P_MIN_RANGE = (1e-4, 0.5)
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
    visible, _ = imgui.begin("raygs-viewer", None)
    if not visible:
        imgui.end()
        return
    _statistics(viewer)
    _scene_section(viewer)
    _render_section(viewer)
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
    _tooltip("GPU: preprocessing + draw of the last redraw (timer queries).\n"
             "sort: the last depth sort, on a background thread")
    age = "up to date" if stats.order_age == 0 else f"{stats.order_age} frames old"
    imgui.text(f"visible {stats.visible:,} of {viewer.loaded.scene.count:,}, order {age}")
    _tooltip(f"sorts: {sorter.requested} asked, {sorter.finished} done, {sorter.superseded} skipped "
             f"(superseded by a newer view before they started)")
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


def _render_section(viewer) -> None:
    panel, scene = viewer.panel, viewer.loaded.scene
    if not imgui.collapsing_header("Render", imgui.TreeNodeFlags_.default_open.value):
        return
    current = RENDER_MODES.index(panel.render_mode) if panel.render_mode in RENDER_MODES else 0
    changed, index = imgui.combo("mode", current, list(RENDER_MODES))
    if changed:
        panel.render_mode = RENDER_MODES[index]
    changed, value = imgui.slider_float("p_min", panel.p_min, *P_MIN_RANGE, "%.5f",
                                        imgui.SliderFlags_.logarithmic.value)
    _remember("p_min")
    if changed and math.isfinite(value):
        panel.p_min = min(max(value, P_MIN_RANGE[0]), P_MIN_RANGE[1])
    imgui.text_disabled(f"kappa = -2 ln(p_min / o) = {-2 * math.log(panel.p_min):.2f} at opacity 1")
    imgui.begin_disabled()
    _, panel.mip_enabled = imgui.checkbox("MIP filter", panel.mip_enabled)
    _tooltip("MIP for RayGS (Eq. 17) arrives in a later version")
    _, panel.mip_sigma2 = imgui.slider_float("sigma^2 (px^2)", panel.mip_sigma2, 0.0, 1.0)
    _tooltip("MIP filter variance in pixel^2 units (later version)")
    _, panel.mip_modulation = imgui.checkbox("opacity modulation", panel.mip_modulation)
    _tooltip("MIP opacity modulation (later version)")
    imgui.end_disabled()
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
    imgui.new_line()
    changed, vsync = imgui.checkbox("vsync", viewer.window.vsync)
    if changed:
        viewer.window.vsync = vsync


def _view_section(viewer) -> None:
    from raygs_viewer.controls import UP_AXES
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
    imgui.text_disabled(f"speed {nav.speed:.3g} units/s (wheel in fly mode)")
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
        imgui.text_disabled(f"{round(viewer.camera.width * panel.screenshot_scale)} x "
                            f"{round(viewer.camera.height * panel.screenshot_scale)} px, offscreen")
    _, panel.screenshot_dir = imgui.input_text("folder", panel.screenshot_dir)
    if imgui.button("Save screenshot (F12)"):
        viewer.screenshot_requested = True
    _remember("Save screenshot")
