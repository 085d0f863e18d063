"""The panel's Headset section: Enter headset (an OpenXR session on the window's own
context) and Leave headset; before entering, the eyes' resolution scale (a session takes
it when it starts); the choices that act at once, in or out of the headset (depth for
the runtime's reprojection, what the desktop mirrors, how the right stick turns); in
the headset, Recentre, the runtime and the eyes' size, and the headset frames'
statistics.

The section is always there (closed until opened), with or without pyopenxr and a
runtime: Enter then says in the panel's error line, in one line, what is missing
(``HeadsetMode.enter``)."""

from __future__ import annotations

from imgui_bundle import imgui

from raygs_viewer.viewer.headset import HeadsetMode
from raygs_viewer.viewer.panel.widgets import (
    button,
    checkbox,
    choice,
    header,
    line,
    note,
    slider,
    tooltip,
)
from raygs_viewer.viewer.part import Headset, Reply

#: The resolution scale's range: a fraction of the runtime's recommended per-eye size
#: (``view --xr-scale`` takes the same).
SCALE_RANGE = (0.1, 2.0)
MIRROR_LABELS = {"both": "both eyes", "left": "left eye"}
TURN_LABELS = {"snap": "snap", "smooth": "smooth"}


def draw_headset_section(headset: HeadsetMode) -> Reply:
    """Edits ``headset.choices`` (the scale while no session is open, the rest at any
    time: the headset reads them each frame); its buttons ask the window to enter,
    leave or recentre (``part.Headset``)."""
    # Closed at first: most windows never see a headset, and the panel stays short; open
    # the first time it is drawn in the headset (``view --xr``).
    active = headset.active
    if active:
        imgui.set_next_item_open(True, imgui.Cond_.once.value)
    if not header("Headset", open_first=False):
        return Reply()
    asked = _enter_or_leave(active)
    recentre = None
    if active:
        imgui.same_line()
        recentre = Headset("recentre") if button("Recentre") else None
        tooltip("put the scene back where the desktop view shows it, facing the way you face now")
    imgui.push_item_width(-imgui.calc_text_size("resolution scale").x - 12)  # room for the longest label
    if not active:
        _scale(headset)
    _live_choices(headset)
    imgui.pop_item_width()
    if active:
        _session_lines(headset)
    return Reply.of(asked, recentre)


def _enter_or_leave(active: bool) -> Headset | None:
    if active:
        return Headset("leave") if button("Leave headset") else None
    pressed = button("Enter headset")
    tooltip("open a session of the active OpenXR runtime (SteamVR, Monado, WiVRn, Quest Link, ...); the desktop "
            "then mirrors the eyes, and the panel's settings reach the headset at once")
    return Headset("enter") if pressed else None


def _scale(headset: HeadsetMode) -> None:
    choices = headset.choices
    scale = slider("resolution scale", choices.scale, *SCALE_RANGE, "%.2fx")
    tooltip("each eye's size as a fraction of the runtime's recommended size; taken at the next Enter headset")
    if scale is not None:
        choices.scale = min(max(scale, SCALE_RANGE[0]), SCALE_RANGE[1])


def _live_choices(headset: HeadsetMode) -> None:
    choices = headset.choices
    choices.depth = checkbox("Depth for reprojection", choices.depth,
                             help_text="submit each eye's median depth with its colour where the runtime takes "
                                       "it, so its reprojection of a late frame follows the scene's depth; it "
                                       "costs several colour frames (the GPU per eye line shows how many)")
    choices.mirror = choice("mirror", choices.mirror, MIRROR_LABELS)
    tooltip("what the desktop window shows of the eyes")
    choices.turn = choice("turning", choices.turn, TURN_LABELS)
    tooltip("the right stick turns the world a step at a time (snap) or continuously (smooth)")


def _session_lines(headset: HeadsetMode) -> None:
    """The runtime, the eyes' size and depth, then the frames' statistics."""
    session = headset.session
    line(session.info.describe() + ("" if headset.running else f" (session {session.phase})"))
    width, height = session.sizes[0]
    depth = ("depth submitted" if headset.choices.depth and session.depth else
             "depth off" if session.depth else "no depth (the runtime takes none)")
    line(f"{width}x{height} per eye, {depth}")
    for text in headset.stats.lines():
        note(text)
