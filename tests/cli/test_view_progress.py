"""The line a command that loads a scene shows on a terminal is the command line's
(raygs_viewer.capture.progress.TerminalProgress, tested in tests/capture/test_progress.py):
``view`` hands it to the window, which loads its scene before it opens."""

from __future__ import annotations

from testkit import run_cli

from raygs_viewer.capture.progress import TerminalProgress


def test_view_shows_its_scene_load_on_the_terminal(capsys, monkeypatch):
    """The window loads the scene before it opens; the command line owns the line that shows it."""
    import raygs_viewer.viewer.app as app

    handed = []
    monkeypatch.setattr(app, "run_viewer", lambda options, progress=None: handed.append((options, progress)) or 0)
    assert run_cli(capsys, "view", "demo")[0] == 0
    (options, progress), = handed
    assert isinstance(progress, TerminalProgress) and progress.name == options.source.path == "demo"
