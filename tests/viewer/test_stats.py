"""The panel's frame rate line: the frames that drew the scene again are timed apart from
the still frames that reused the image, so "redraw" reads like the GPU line beside it."""

from __future__ import annotations

import pytest

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.viewer.drawing import DrawReport, SortAsked
from raygs_viewer.viewer.frame import Frame, Framing
from raygs_viewer.viewer.stats import FrameStats


def drew(stats: FrameStats, index: int, drawn: bool) -> None:
    """What the draw of frame ``index`` reports: whether it drew the scene again."""
    camera = look_at((0.0, 0.0, -3.0), (0.0, 0.0, 0.0))
    frame = Frame.make(index, Framing(camera, (0, 0, camera.width, camera.height), None), stereo=None,
                       settings=RenderSettings(), right=None, lod=None)
    stats.record(DrawReport(frame, SortAsked(index, False), None, drawn, 0.0))


def test_redraw_time_counts_only_the_frames_that_drew():
    clock = iter([0.0, 0.3, 0.31, 0.32, 0.33, 0.63, 0.64])
    stats = FrameStats()
    stats.tick(next(clock))      # frame 1 starts at 0.0 and draws
    drew(stats, 1, True)
    for index, draws in enumerate((False, False, False, True, False), start=2):  # idle, idle, idle, a draw, idle
        stats.tick(next(clock))
        drew(stats, index, draws)
    stats.tick(next(clock))
    assert stats.draws == 2
    assert stats.redraw_ms == pytest.approx(300.0)   # frames 1 and 5 took 0.3 s each
    assert stats.frame_ms == pytest.approx(10.0)     # the median of all six is an idle one
    assert FrameStats().redraw_ms != FrameStats().redraw_ms  # nothing drawn yet: NaN
