"""The command line's progress: the line a scene's load shows on a terminal (redrawn in
place, silent off a terminal and for quick loads, erased before an error), a render's
bar, and the versioned JSON lines render-path prints for the window, written and read
back by one module. Clocks are the tests' own: nothing here measures time."""

from __future__ import annotations

import io
import json

import pytest
from testkit import gaussian_columns, write_ply

from raygs_viewer.capture.progress import (
    PROTOCOL,
    FrameProgress,
    Progress,
    RenderDone,
    RenderInterrupted,
    TerminalProgress,
    format_duration,
    progress_line,
    read_progress_line,
)
from raygs_viewer.errors import UserError
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.source import SceneSource

RECORDS = [FrameProgress(0, 3), FrameProgress(37, 120, 2.3, 36.1), FrameProgress(3, 3, 5.0, 0.0),
           RenderDone("fly.mp4", 120), RenderDone("frames/", 0), RenderInterrupted(37, "fly.mp4"),
           RenderInterrupted(0, None)]


# --------------------------------------------------------------------------- the JSON lines


@pytest.mark.parametrize("record", RECORDS, ids=repr)
def test_every_record_round_trips_through_one_line(record):
    line = progress_line(record)
    assert line.endswith("\n") and line.count("\n") == 1
    assert json.loads(line)["progress"] == PROTOCOL == 1
    assert read_progress_line(line) == record
    assert read_progress_line(line.rstrip("\n")) == record   # with or without its newline


def test_the_lines_are_the_documented_objects():
    assert [json.loads(progress_line(r)) for r in RECORDS[1:2] + RECORDS[3:4] + RECORDS[6:]] == [
        {"progress": 1, "frame": 37, "frames": 120, "fps": 2.3, "eta_s": 36.1},
        {"progress": 1, "done": True, "out": "fly.mp4", "frames": 120},
        {"progress": 1, "interrupted": True, "frames": 0, "out": None}]


@pytest.mark.parametrize("line", [
    "", "\n", "rendering...", "{", "[1, 2]", "null", "7", '"frame"', "{}",
    '{"frame": 1, "frames": 3, "fps": null, "eta_s": null}',                        # no version: before version 1
    '{"progress": 2, "frame": 1, "frames": 3, "fps": null, "eta_s": null}',         # a newer version
    '{"progress": 0, "done": true, "out": "a.mp4", "frames": 3}',
    '{"progress": true, "done": true, "out": "a.mp4", "frames": 3}',                # true == 1 in Python
    '{"progress": 1.0, "done": true, "out": "a.mp4", "frames": 3}',
    '{"progress": "1", "done": true, "out": "a.mp4", "frames": 3}',
    '{"progress": 1, "frame": "1", "frames": 3, "fps": null, "eta_s": null}',
    '{"progress": 1, "frame": 1.5, "frames": 3, "fps": null, "eta_s": null}',
    '{"progress": 1, "frame": -1, "frames": 3, "fps": null, "eta_s": null}',
    '{"progress": 1, "frame": 1, "frames": 3, "fps": "fast", "eta_s": null}',
    '{"progress": 1, "frame": 1, "frames": 3, "fps": NaN, "eta_s": null}',
    '{"progress": 1, "frame": 1, "frames": 3, "fps": null}',                        # a field missing
    '{"progress": 1, "frame": 1, "frames": 3, "fps": null, "eta_s": null, "x": 1}', # a field unknown
    '{"progress": 1, "done": false, "out": "a.mp4", "frames": 3}',
    '{"progress": 1, "done": true, "out": null, "frames": 3}',
    '{"progress": 1, "interrupted": true, "frames": 3}',
    '{"progress": 1, "interrupted": 1, "frames": 3, "out": null}',
    "\x00\xff garbage",
], ids=repr)
def test_a_line_of_another_version_or_garbage_is_none(line):
    assert read_progress_line(line) is None


# --------------------------------------------------------------------------- a scene's load


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


# --------------------------------------------------------------------------- a render's bar


class FakeClock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_progress_json_lines(tmp_path):
    clock, stream = FakeClock(), io.StringIO()
    progress = Progress(4, "json", stream, clock)
    for done in (1, 2, 3, 4):
        clock.now += 0.5
        progress.update(done)
    progress.finish(tmp_path / "fly.mp4")
    progress.interrupted(3, None)
    lines = [json.loads(line) for line in stream.getvalue().splitlines()]
    assert lines[0] == {"progress": 1, "frame": 1, "frames": 4, "fps": 2.0, "eta_s": 1.5}
    assert lines[3] == {"progress": 1, "frame": 4, "frames": 4, "fps": 2.0, "eta_s": 0.0}
    assert lines[4] == {"progress": 1, "done": True, "out": str(tmp_path / "fly.mp4"), "frames": 4}
    assert lines[5] == {"progress": 1, "interrupted": True, "frames": 3, "out": None}
    assert len(lines) == 6


def test_progress_json_before_any_rate_and_on_stdout(capsys):
    clock = FakeClock()
    progress = Progress(3, "json", clock=clock)
    progress.update(0)
    progress.interrupted(0, "fly.mp4")
    out, err = capsys.readouterr()
    assert err == ""
    assert [json.loads(line) for line in out.splitlines()] == [
        {"progress": 1, "frame": 0, "frames": 3, "fps": None, "eta_s": None},
        {"progress": 1, "interrupted": True, "frames": 0, "out": "fly.mp4"}]


def test_progress_bar_text_rate_window_and_time_left():
    clock, stream = FakeClock(), io.StringIO()
    progress = Progress(120, "bar", stream, clock, label="fly.mp4")
    assert progress.bar_text() == "fly.mp4: 0/120 frames [--------------------] 0%  -- fps  --:-- left"
    for done in range(1, 38):
        clock.now += 0.1 if done <= 20 else 0.5     # slower from frame 21 on
        progress.update(done)
    # The rate is over the last 10 frames (2 fps), not the whole run: 83 frames in 41.5 s.
    assert progress.bar_text() == "fly.mp4: 37/120 frames [######--------------] 30%  2.0 fps  0:42 left"
    assert stream.getvalue().startswith("\rfly.mp4: 1/120 frames [")
    assert stream.getvalue().endswith("\rfly.mp4: 37/120 frames [######--------------] 30%  2.0 fps  0:42 left")
    assert "\n" not in stream.getvalue()  # redrawn in place
    progress.interrupted(37, "fly.mp4")
    assert stream.getvalue().endswith("\ninterrupted after 37/120 frames: kept fly.mp4 (37 frames)\n")


def test_progress_bar_redraws_at_most_ten_times_a_second_and_ends_its_line():
    clock, stream = FakeClock(), io.StringIO()
    progress = Progress(50, "bar", stream, clock)
    for done in range(1, 51):
        clock.now += 0.01
        progress.update(done)
    progress.finish("fly.mp4")
    text = stream.getvalue()
    assert 5 <= text.count("\r") <= 8 and text.endswith("50/50 frames [####################] 100%  100 fps  0:00 left\n")


def test_progress_auto_and_none():
    class Terminal(io.StringIO):
        def isatty(self):
            return True
    assert Progress(3, "auto", Terminal()).mode == "bar"
    assert Progress(3, "auto", io.StringIO()).mode == "none"
    stream = io.StringIO()
    quiet = Progress(3, "none", stream)
    quiet.update(1)
    quiet.finish("fly.mp4")
    assert stream.getvalue() == ""
    quiet.interrupted(1, None)  # the one line every mode prints
    assert stream.getvalue() == "interrupted after 1/3 frames: nothing written\n"
    with pytest.raises(ValueError):
        Progress(3, "loud")


def test_format_duration():
    assert [format_duration(s) for s in (0, 0.2, 59.5, 62, 3600, 3725.1)] == [
        "0:00", "0:01", "1:00", "1:02", "1:00:00", "1:02:06"]

