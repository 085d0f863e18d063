"""The panel's Screenshot section: the offscreen scale, the folder, and the button (F12
does the same)."""

from __future__ import annotations

from typing import Callable

from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.viewer.panel.widgets import header
from raygs_viewer.viewer.state import ScreenshotOptions

SCALE_CHOICES = (1.0, 2.0, 4.0, 8.0)


def draw_screenshot_section(options: ScreenshotOptions, camera: Camera | None, stereo_shown: bool,
                            save_eyes: bool, split_shown: bool, request: Callable[[], None]) -> None:
    """Edits ``options``; ``camera``: the last frame's (None before the first);
    ``stereo_shown``/``split_shown``: what a capture saves (the pair and with
    ``save_eyes`` each eye, or each side); ``request`` asks for a capture."""
    if not header("Screenshot"):
        return
    for scale in SCALE_CHOICES:
        if imgui.radio_button(f"{scale:g}x", options.scale == scale):
            options.scale = scale
        imgui.same_line()
    imgui.new_line()
    if camera is not None:
        width, height = round(camera.width * options.scale), round(camera.height * options.scale)
        if stereo_shown:
            imgui.text_disabled(f"{2 * width} x {height} px side-by-side pair ({width} x {height} per eye), offscreen")
        else:
            imgui.text_disabled(f"{width} x {height} px, offscreen")
    _, options.folder = imgui.input_text("folder", options.folder)
    if imgui.button("Save screenshot (F12)"):
        request()
    if stereo_shown and save_eyes:
        imgui.same_line()
        imgui.text_disabled("(-pair, -left, -right)")
    elif split_shown:
        imgui.same_line()
        imgui.text_disabled("(each side, -left/-right)")
