"""The progress line a command that loads a scene shows on a terminal
(raygs_viewer.cli.progress_line): redrawn in place, silent off a terminal and for quick
loads, erased before an error. Its clock is the test's own: nothing here measures time."""

from __future__ import annotations

import io

import pytest
from testkit import gaussian_columns, run_cli, write_ply

from raygs_viewer.cli.progress_line import TerminalProgress
from raygs_viewer.errors import UserError
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.source import SceneSource


class FakeTerminal(io.StringIO):
    def isatty(self):
        return True


def test_terminal_progress_redraws_one_line_and_erases_it():
    now = [0.0]
    stream = FakeTerminal()
    with TerminalProgress("big.ply", stream, delay=0.5, interval=0.2, clock=lambda: now[0]) as progress:
        for t, fraction in ((0.1, 0.05), (0.6, 0.3), (0.65, 0.35), (0.9, 0.6)):
            now[0] = t
            progress(fraction, "reading")
        now[0] = 1.2
        progress(0.9, "hashing")
        progress(1.0, "done")
    text = stream.getvalue()
    assert "\n" not in text
    frames = text.split("\r")
    assert frames[1:4] == ["loading big.ply: reading  30%", "loading big.ply: reading  60%",
                           "loading big.ply: hashing  90%"]  # before 0.5 s and within 0.2 s: nothing
    assert frames[-2:] == [" " * len(frames[3]), ""]  # erased once, at "done"


def test_terminal_progress_is_silent_off_a_terminal_and_for_quick_loads(tmp_path):
    scene = write_ply(tmp_path / "scene.ply", gaussian_columns(5, 1))
    piped = io.StringIO()
    with TerminalProgress("scene.ply", piped, delay=0.0, interval=0.0) as progress:
        load_now(SceneSource(scene), progress=progress)
    assert piped.getvalue() == ""
    quick = FakeTerminal()
    with TerminalProgress("scene.ply", quick, clock=lambda: 0.0) as progress:  # within the default delay
        load_now(SceneSource(scene), progress=progress)
    assert quick.getvalue() == ""


def test_a_failed_load_leaves_a_clean_line_for_its_error(tmp_path):
    stream = FakeTerminal()
    with pytest.raises(UserError):
        with TerminalProgress("gone.ply", stream, delay=0.0, interval=0.0) as progress:
            progress(0.2, "reading")
            load_now(SceneSource(tmp_path / "gone.ply"), progress=progress)
    assert stream.getvalue().endswith("\r" + " " * len("loading gone.ply: reading  20%") + "\r")


def test_view_shows_its_scene_load_on_the_terminal(capsys, monkeypatch):
    """The window loads the scene before it opens; the command line owns the line that shows it."""
    import raygs_viewer.viewer.app as app

    handed = []
    monkeypatch.setattr(app, "run_viewer", lambda options, progress=None: handed.append((options, progress)) or 0)
    assert run_cli(capsys, "view", "demo")[0] == 0
    (options, progress), = handed
    assert isinstance(progress, TerminalProgress) and progress.name == options.source.path == "demo"
