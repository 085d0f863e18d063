"""The panel's frame rate line: the frames that drew the scene again are timed apart from
the still frames that reused the image, so "redraw" reads like the GPU line beside it."""

from __future__ import annotations

import pytest

from raygs_viewer.viewer import stats as stats_module
from raygs_viewer.viewer.stats import FrameStats


def test_redraw_time_counts_only_the_frames_that_drew(monkeypatch):
    clock = iter([0.0, 0.3, 0.31, 0.32, 0.33, 0.63, 0.64])
    monkeypatch.setattr(stats_module.time, "perf_counter", lambda: next(clock))
    stats = FrameStats()
    stats.tick()                 # frame 1 starts at 0.0 and draws
    stats.draws += 1
    for draws in (0, 0, 0, 1, 0):  # frames 2..6: idle, idle, idle, a draw, idle
        stats.tick()
        stats.draws += draws
    stats.tick()
    assert stats.redraw_ms == pytest.approx(300.0)   # frames 1 and 5 took 0.3 s each
    assert stats.frame_ms == pytest.approx(10.0)     # the median of all six is an idle one
    assert FrameStats().redraw_ms != FrameStats().redraw_ms  # nothing drawn yet: NaN
