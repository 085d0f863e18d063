"""What the window remembers from one run to the next: the panel's width.

It lives in ``$XDG_CONFIG_HOME/raygs-viewer/window.json`` (``~/.config`` where that is
unset), written atomically when a resize ends and when the window closes. The file is a
convenience, never a reason to fail: one that cannot be read or written is said once,
on stderr, and the default is used.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from raygs_viewer.errors import UserError, one_line
from raygs_viewer.files import config_file, write_atomically
from raygs_viewer.jsonfile import json_text, read_json_file
from raygs_viewer.viewer.layout import MIN_PANEL_WIDTH, PANEL_WIDTH

#: The largest width remembered (screen units); a bigger number in the file is not one we wrote.
MAX_REMEMBERED_WIDTH = 8192.0


def remembered_path() -> Path:
    """Where the window's memory is kept."""
    return config_file("window.json")


class Remembered:
    """The panel's width as last left (``panel_width``, screen units), read once when the
    window opens; :meth:`keep` writes a new width."""

    def __init__(self, path: Path | None = None):
        self.path = remembered_path() if path is None else path
        self.panel_width = PANEL_WIDTH
        self._written = PANEL_WIDTH
        self._said = False
        if not self.path.exists():
            return
        try:
            data = read_json_file(self.path, "a JSON file")
            width = data.get("panel_width") if isinstance(data, dict) else None
            if (not isinstance(width, (int, float)) or isinstance(width, bool) or not math.isfinite(width)
                    or not MIN_PANEL_WIDTH <= width <= MAX_REMEMBERED_WIDTH):
                raise UserError(f"{self.path}: no panel width in {MIN_PANEL_WIDTH:g}..{MAX_REMEMBERED_WIDTH:g}")
        except UserError as exc:
            self._say(f"warning: the window's remembered layout is not used: {one_line(exc)}")
            return
        self.panel_width = self._written = float(width)

    def keep(self, panel_width: float) -> None:
        """Remembers ``panel_width`` (written only when it differs from the file's)."""
        width = round(float(panel_width), 1)
        if width == self._written or not math.isfinite(width):
            return
        self._written = width  # tried once: a folder that cannot be written is not tried every frame
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            write_atomically(self.path, json_text({"panel_width": width}).encode(), overwrite=True)
        except OSError as exc:
            self._say(f"warning: the panel's width is not remembered: {self.path.parent}: "
                      f"{exc.strerror or exc}")
        except UserError as exc:
            self._say(f"warning: the panel's width is not remembered: {one_line(exc)}")

    def _say(self, line: str) -> None:
        if not self._said:
            print(line, file=sys.stderr, flush=True)
            self._said = True
