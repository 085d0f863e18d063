"""What happened is visible where the eye is: a result over the view for a few seconds,
an error until it is seen, both in the panel's short history and on stderr."""

from __future__ import annotations

import io

from appkit import PANEL_HEIGHT, PANEL_WIDTH
from imgui_bundle import imgui

from raygs_viewer.viewer import feedback as feedback_module
from raygs_viewer.viewer.feedback import RESULT_SECONDS, SEEN_AFTER, Feedback


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def _with_clock(viewer) -> tuple[Clock, io.StringIO]:
    clock, out = Clock(), io.StringIO()
    viewer.feedback = Feedback(out, clock)
    return clock, out


def test_an_error_shows_over_the_view_until_seen_and_goes_to_stderr(open_viewer, tmp_path):
    """F12 into a folder that cannot be made, the panel hidden: the error is over the
    view (the only place left to see it), stays past any timeout, and goes when a click
    comes after it has been up SEEN_AFTER seconds."""
    viewer, drive = open_viewer(hide_panel=True)
    clock, out = _with_clock(viewer)
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("x")
    viewer.captures.options.folder = str(blocker / "shots")
    drive.frames(1)
    drive.tap(imgui.Key.f12)
    drive.frames(1)
    error = viewer.panel.error
    assert error.startswith("error: ") and error in drive.panel.labels("text_wrapped")
    assert out.getvalue() == error + "\n"
    clock.now += 60.0  # a minute later: still there
    drive.frames(1)
    assert error in drive.panel.labels("text_wrapped")
    drive.click_at(200, 100)  # a click on the view: seen
    drive.frames(1)
    assert error not in drive.panel.labels("text_wrapped")


def test_a_result_shows_for_a_few_seconds_and_stays_in_the_history(open_viewer, tmp_path):
    viewer, drive = open_viewer(width=PANEL_WIDTH, height=PANEL_HEIGHT)
    clock, out = _with_clock(viewer)
    viewer.captures.options.folder = str(tmp_path / "shots")
    drive.frames(1)
    drive.tap(imgui.Key.f12)
    drive.frames(2)
    message = viewer.panel.message
    assert message.startswith("saved ") and out.getvalue() == f"raygs-viewer: {message}\n"
    over_view = [w for w in drive.panel.widgets if w.label == message and w.rect[0] > PANEL_WIDTH * 0.4]
    assert over_view  # drawn right of the panel, over the view
    clock.now += RESULT_SECONDS + 0.1
    drive.frames(1)
    assert not [w for w in drive.panel.widgets if w.label == message and w.rect[0] > PANEL_WIDTH * 0.4]
    drive.reveal("Messages (1)")
    assert "Messages (1)" in drive.panel


def test_an_error_is_seen_by_a_click_after_it_has_been_up_a_while():
    clock, out = Clock(), io.StringIO()
    feedback = Feedback(out, clock)
    feedback.post("error: nope", error=True)
    clock.now += SEEN_AFTER / 2
    feedback.clicked()  # too soon to have been read
    assert [note.text for note in feedback.shown()] == ["error: nope"]
    clock.now += SEEN_AFTER
    feedback.clicked()
    assert feedback.shown() == [] and len(feedback.history) == 1
    for n in range(feedback_module.HISTORY + 3):
        feedback.post(f"saved {n}", error=False)
    assert len(feedback.history) == feedback_module.HISTORY  # a short history
