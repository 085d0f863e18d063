"""The panel's Screenshot section: the offscreen scale, the folder, and the button (F12
does the same)."""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.viewer.panel.widgets import beside, header, note
from raygs_viewer.viewer.part import Press, Reply
from raygs_viewer.viewer.state import ScreenshotOptions

SCALE_CHOICES = (1.0, 2.0, 4.0, 8.0)


def draw_screenshot_section(options: ScreenshotOptions, camera: Camera | None, *, stereo_shown: bool,
                            save_eyes: bool, split_shown: bool) -> Reply:
    """Edits ``options``; ``camera``: the last frame's (None before the first);
    ``stereo_shown``/``split_shown``: what a capture saves (the pair and with
    ``save_eyes`` each eye, or each side). Its button asks for a capture, as F12 does."""
    if not header("Screenshot"):
        return Reply()
    for scale in SCALE_CHOICES:
        if imgui.radio_button(f"{scale:g}x", options.scale == scale):
            options.scale = scale
        imgui.same_line()
    imgui.new_line()
    if camera is not None:
        width, height = round(camera.width * options.scale), round(camera.height * options.scale)
        if stereo_shown:
            note(f"{2 * width} x {height} px side-by-side pair ({width} x {height} per eye), offscreen")
        else:
            note(f"{width} x {height} px, offscreen")
    _, options.folder = imgui.input_text("folder", options.folder)
    requested = imgui.button("Save screenshot (F12)")
    files = ("(-pair, -left, -right)" if stereo_shown and save_eyes
             else "(each side, -left/-right)" if split_shown else "")
    if files:
        beside(imgui.calc_text_size(files).x)
        note(files)
    return Reply.of(Press("screenshot")) if requested else Reply()
