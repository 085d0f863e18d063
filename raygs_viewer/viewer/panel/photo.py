"""The Training cameras section's Photo controls: at a training camera, what the window
shows (the render, the photo, |difference| as a heat map, or a split between them) and
the PSNR of the render against the photo (see viewer.photo_view)."""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.viewer.panel.widgets import beside, checkbox, line, note, slider, tooltip
from raygs_viewer.viewer.photo_view import MODES, PhotoCompare


def draw_photo_controls(photo: PhotoCompare) -> None:
    """Edits ``photo``'s mode, divider and heat map scale; shows its status line."""
    line("Photo:")
    for index, (mode, label) in enumerate(MODES.items()):  # a row of their own, wrapped where the panel is narrow
        if index:
            beside(imgui.get_frame_height() + imgui.get_style().item_inner_spacing.x + imgui.calc_text_size(label).x)
        if imgui.radio_button(f"{label}##photo", photo.mode == mode):
            photo.choose(mode)
    at_camera = checkbox("at the camera's size##photo", photo.at_camera_size,
                         help_text="render the training camera at its own size and intrinsics and compare "
                                   "as `evaluate` does (the same PSNR); shown scaled into the view")
    if at_camera != photo.at_camera_size:
        photo.set_camera_size(at_camera)
    if photo.mode == "split":
        fraction = slider("divider##photo", photo.fraction, 0.0, 1.0, "%.2f")
        if fraction is not None:
            photo.fraction = min(max(fraction, 0.0), 1.0)
        tooltip("the photo left of it, the render right")
    if photo.mode == "difference":
        top = slider("heat scale##photo", photo.heat_max, 0.01, 1.0, "%.2f", logarithmic=True)
        if top is not None:
            photo.heat_max = min(max(top, 0.01), 1.0)
        tooltip("|render - photo| (mean over RGB) shown at the top colour (magma)")
    if photo.at is None:
        note("at a training camera (N / P) the window compares with its photo")
    elif photo.status:
        imgui.text_wrapped(photo.status)
