"""The Open… button's file dialog: the desktop's own, through portable-file-dialogs
(which imgui-bundle ships). It runs the desktop's dialog program beside the window and
is polled once a frame, so the window keeps drawing while it is open. Where the desktop
has no dialog program, :func:`dialog_problem` says so in one line and the typed path
stays the way to open a scene."""

from __future__ import annotations

import shutil
import sys

from imgui_bundle import portable_file_dialogs as pfd

from raygs_viewer.scene.io import SCENE_SUFFIXES

#: The programs portable-file-dialogs runs on Linux and the BSDs (in its order).
DIALOG_PROGRAMS = ("zenity", "matedialog", "qarma", "kdialog")


def dialog_problem() -> str | None:
    """One line saying why this desktop shows no file dialog; None where it can."""
    if sys.platform in ("win32", "darwin"):
        return None
    if not any(shutil.which(program) for program in DIALOG_PROGRAMS):
        return "no file dialog here (it needs zenity or kdialog): type the scene's path and press Enter"
    return None


class FileDialog:
    """At most one dialog open at a time; :meth:`poll` hands over the chosen file once."""

    def __init__(self) -> None:
        self._dialog = None

    @property
    def open(self) -> bool:
        return self._dialog is not None

    def start(self, folder: str = "") -> str | None:
        """Opens the dialog in ``folder``; returns why it cannot (one line), else None."""
        problem = dialog_problem()
        if problem or self._dialog is not None:
            return problem
        patterns = " ".join(f"*{suffix}" for suffix in SCENE_SUFFIXES)
        self._dialog = pfd.open_file("Open a scene", folder, ["Scenes", patterns, "All files", "*"])
        return None

    def poll(self) -> str | None:
        """The file chosen, once, when the dialog has closed with one; else None."""
        if self._dialog is None or not self._dialog.ready(0):
            return None
        chosen, self._dialog = self._dialog.result(), None
        return chosen[0] if chosen else None
