"""The panel's Training cameras section: the scene's training views, to fly to one by
one or by picking from the list, whether they are drawn in the scene (with the legend
of their colours), and at one the Photo view's controls (panel.photo)."""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.photos.dataset import TEST_EVERY
from raygs_viewer.scene.loader import LoadedScene
from raygs_viewer.viewer.panel.photo import draw_photo_controls
from raygs_viewer.viewer.panel.widgets import checkbox, header, note
from raygs_viewer.viewer.part import FlyTo, Press, Reply
from raygs_viewer.viewer.photo_view import PhotoCompare
from raygs_viewer.viewer.training_frustums import TEST_COLOUR, TRAIN_COLOUR, TrainingFrustums


def draw_training_section(loaded: LoadedScene, current: int | None, photo: PhotoCompare,
                          frustums: TrainingFrustums) -> Reply:
    """``current``: the training camera flown to last (None: a free view); a camera
    picked asks to fly there (the next or the previous: as N and P do); ``photo``: the Photo
    view the controls under the list edit; ``frustums``: the cameras drawn in the scene
    (whether they are shown)."""
    label = f"Training cameras ({len(loaded.cameras)})"
    if not header(label + "###training", open_first=False):
        return Reply()
    if not loaded.cameras:
        note("none found (pass --cameras cameras.json)")
        return Reply()
    if loaded.cameras_path:
        note(loaded.cameras_path)
    flights = []
    if imgui.button("< previous (P)"):
        flights.append(Press("previous_camera"))
    imgui.same_line()
    if imgui.button("next (N) >"):
        flights.append(Press("next_camera"))
    if imgui.begin_list_box("##cameras", (-1, 160)):
        for i, name in enumerate(loaded.camera_names):
            if imgui.selectable(f"{i}: {name}", current == i)[0]:
                flights.append(FlyTo(i))
                current = i  # the entries below are drawn knowing it
        imgui.end_list_box()
    draw_frustum_controls(frustums)
    draw_photo_controls(photo)
    return Reply.of(*flights)


def draw_frustum_controls(frustums: TrainingFrustums) -> None:
    """Whether the cameras are drawn in the scene, what their colours mean, and why
    their photos are missing where they are."""
    frustums.show = checkbox("show in the scene##frustums", frustums.show,
                             help_text="each training camera drawn as a frustum, its photo inside when the photos "
                                       "are known; point at one to name it, click it to fly there (never in "
                                       "screenshots)")
    if not frustums.show:
        return
    _coloured("train", TRAIN_COLOUR)
    imgui.same_line()
    _coloured("test", TEST_COLOUR)
    imgui.same_line()
    note(f"(every {TEST_EVERY}th by name)")
    if frustums.thumbnails.status:
        note(frustums.thumbnails.status)


def _coloured(text: str, colour: tuple[int, int, int, int]) -> None:
    """``text`` in the frustums' ``colour`` (RGBA 0..255)."""
    imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(*(c / 255 for c in colour[:3]), 1.0))
    imgui.text(text)
    imgui.pop_style_color()
