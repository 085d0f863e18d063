"""The window's frame statistics: what the panel shows (the last 60 frames), how old the
drawn order is, what the per-pixel order did, and the one-line summary of a scripted
run (the whole history)."""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from raygs_viewer.camera.navigation import MAX_DT
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import StereoView
from raygs_viewer.render.gl.results import OrderStats
from raygs_viewer.render.gl.timing import GpuTimer
from raygs_viewer.sort.request import SortResult
from raygs_viewer.viewer.drawing import DrawReport


@dataclass
class FrameStats:
    """Times in seconds."""

    all_frame_times: deque = field(default_factory=lambda: deque(maxlen=10000))
    #: The times of the last 60 frames that drew the scene again (a still view's frames
    #: reuse the image and take a fraction of it).
    redraw_times: deque = field(default_factory=lambda: deque(maxlen=60))
    all_sort_times: deque = field(default_factory=lambda: deque(maxlen=10000))
    sort_seconds: float = float("nan")
    gpu_seconds: float = float("nan")     # the scene's draw: both sides in the split view, both eyes in stereo
    post_seconds: float = float("nan")    # stereo: lens preview and layout
    visible: int = 0
    order_age: int = 0          # frames since the drawn order's view was current; 0: up to date
    #: How stale the drawn order is (all 0 while it is up to date): milliseconds since its
    #: view was asked for, and how far the camera has turned (degrees) and moved (scene
    #: units) since that view.
    order_age_ms: float = 0.0
    order_turned_degrees: float = 0.0
    order_moved: float = 0.0
    drawn_serial: int = 0       # sort request whose order the last draw used
    draws: int = 0              # frames that re-rendered the scene (others reused the image)
    frames_with_sort_running: int = 0  # frames completed while a sort was in progress
    #: sort request serial -> the frame that first asked for it, while unanswered.
    request_frames: dict[int, int] = field(default_factory=dict)
    #: What the per-pixel order did in the last redraw: (left side or the only one, right
    #: side of the split view); None for a side drawn in a global order (stereo: one eye's).
    order_stats: tuple[OrderStats | None, OrderStats | None] = (None, None)
    last_time: float | None = None   # the clock at the start of the last frame
    draws_at_last_tick: int = 0
    #: The GPU sort's timer (the window's ``ShownScene.sort_timer``, each frame): where
    #: set, the sort time is the GPU's, read frames late, since a sort that does not wait
    #: for the GPU has only its issue on the CPU's clock; None: the result's own times.
    sort_timer: GpuTimer | None = None

    def sort_times(self) -> Sequence[float]:
        """Every sort's seconds so far: the GPU sort's from its timer (the last ones
        included: this waits for the GPU), else the results'."""
        if self.sort_timer is None:
            return self.all_sort_times
        self.sort_timer.flush()
        return self.sort_timer.history

    @property
    def recent_frame_times(self) -> list[float]:
        return list(itertools.islice(reversed(self.all_frame_times), 60))

    @property
    def fps(self) -> float:
        recent = self.recent_frame_times
        return len(recent) / sum(recent) if recent and sum(recent) > 0 else 0.0

    @property
    def frame_ms(self) -> float:
        recent = self.recent_frame_times
        return 1000 * float(np.median(recent)) if recent else float("nan")

    @property
    def redraw_ms(self) -> float:
        """The median time of the last 60 frames that drew the scene again."""
        return 1000 * float(np.median(self.redraw_times)) if self.redraw_times else float("nan")

    def tick(self, now: float) -> float:
        """Starts a frame at ``now`` (a clock's seconds): records the time since the last
        one and returns the frame time to move by: at most the navigator's MAX_DT, 0 for
        the first frame and for a time that is no number >= 0 (a clock gone wrong moves
        nothing)."""
        last, self.last_time = self.last_time, now
        if last is None:
            return 0.0
        elapsed = now - last
        self.all_frame_times.append(elapsed)
        if self.draws > self.draws_at_last_tick:
            self.redraw_times.append(elapsed)
        self.draws_at_last_tick = self.draws
        return min(elapsed, MAX_DT) if elapsed >= 0 and math.isfinite(elapsed) else 0.0

    @property
    def last_frame_time(self) -> float:
        """The last frame's seconds (0 before the second frame)."""
        return self.all_frame_times[-1] if self.all_frame_times else 0.0

    def new_sorter(self, kept: SortResult | None, frame_index: int) -> None:
        """A new scene's sorter: the requests asked of the old one are gone; ``kept``, the
        old one's result drawn until the new one's first (as serial 0), stays as old as it
        was (frame ``frame_index`` asked for it if no request is known)."""
        asked = None if kept is None else self.request_frames.get(kept.serial, frame_index)
        self.request_frames.clear()
        if kept is not None:
            self.request_frames[0] = asked

    def record(self, report: DrawReport) -> None:
        """What a frame's draw did: the sort it asked for, the age of the order it drew
        (frames; and, against the frame's camera at the report's time, milliseconds,
        degrees turned and distance moved), the sort's time (the GPU sort's timer, read
        frames late, where it sorts) and what it keeps visible, and the draw itself (its
        GPU times, what the per-pixel order did). An up-to-date result answers the frame's
        own sort request."""
        frame, result = report.frame, report.result
        self.request_frames.setdefault(report.asked.serial, frame.index)
        self.frames_with_sort_running += report.asked.running
        self.sort_timer = report.sort_timer
        self.order_age_ms = self.order_turned_degrees = self.order_moved = 0.0
        if result is None:
            self.order_age = frame.index - min(self.request_frames.values(), default=frame.index)
        else:
            self._age(report, result)
        if report.problem is not None:
            return
        if report.drew:
            self.drawn_serial, self.draws = report.serial, self.draws + 1
            self.order_stats = report.order_stats
        self.gpu_seconds, self.post_seconds = report.gpu_seconds, report.post_seconds

    def _age(self, report: DrawReport, result: SortResult) -> None:
        frame, camera = report.frame, report.frame.camera
        for older in [n for n in self.request_frames if n < result.serial]:  # answered or skipped
            del self.request_frames[older]
        current = result.order.answers(frame.sort)
        self.order_age = 0 if current else frame.index - self.request_frames.get(result.serial, frame.index)
        if not current:
            self.order_age_ms = max(0.0, 1000.0 * (report.at - result.requested_at))
            self.order_turned_degrees = turned_degrees(result.request.camera.R, camera.R)
            self.order_moved = float(np.linalg.norm(camera.center - result.request.camera.center))
        if self.sort_timer is not None:
            self.sort_timer.frame()
            self.sort_seconds = self.sort_timer.seconds
        else:
            if result.serial != self.drawn_serial:
                self.all_sort_times.append(result.seconds)
            self.sort_seconds = result.seconds
        self.visible = result.order.count


def turned_degrees(before: np.ndarray, after: np.ndarray) -> float:
    """The angle (degrees) of the rotation taking the (3, 3) orientation ``before`` to ``after``."""
    cosine = (np.trace(after @ before.T) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))


def order_freshness(stats: FrameStats, short: bool = False) -> str:
    """How old the drawn order is, in words: "up to date", or frames, milliseconds and
    how far the camera has turned and moved since its view; ``short``: frames and
    milliseconds only (a line that fits the panel, the rest in its tooltip)."""
    if stats.order_age == 0:
        return "up to date"
    if short:
        return f"{stats.order_age} frames old ({stats.order_age_ms:.0f} ms)"
    return (f"{stats.order_age} frames old ({stats.order_age_ms:.0f} ms, turned {stats.order_turned_degrees:.1f}°, "
            f"moved {stats.order_moved:.3g})")


def order_stats_lines(stats: OrderStats) -> list[str]:
    """What one per-pixel-order render did, in the panel's words: fragments per covered
    pixel (mean and most), the pool's use, the parts drawn, and the path."""
    lines = [f"fragments/px {stats.mean_per_covered_pixel:.1f} mean, {stats.max_per_pixel:,} max "
             f"({stats.covered_pixels:,} px covered)"]
    if stats.pool_fragments:
        lines.append(f"pool {100 * stats.pool_use:.0f} % of {stats.pool_fragments:,} fragments "
                     f"({stats.pool_bytes / 2**20:.1f} MiB), {stats.parts} part{'s' if stats.parts != 1 else ''}")
    else:
        lines.append(f"no pool, {stats.parts} part{'s' if stats.parts != 1 else ''}")
    lines.append(f"path: {PATH_LABELS.get(stats.path, stats.path)}")
    return lines


#: OrderStats.path -> how the panel names it.
PATH_LABELS = {"lists": "per-pixel fragment lists + resolve (storage-buffer atomics)",
               "fetch": "k-buffer through framebuffer fetch"}


def camera_size(camera: Camera | None) -> str:
    return "-" if camera is None else f"{camera.width}x{camera.height}"


def median_ms(values: Sequence[float]) -> str:
    return f"{1000 * float(np.median(values)):.1f} ms" if values else "n/a"


def summary(stats: FrameStats, frames: int, *, camera: Camera | None, stereo: StereoView | None,
            gpu_times: Sequence[float], post_times: Sequence[float], scene_count: int, general: bool) -> str:
    """One line of frame statistics after ``frames`` frames; gpu_times and post_times:
    every draw's GPU seconds (post: the stereo lens preview and layout)."""
    frame = float(np.median(stats.all_frame_times)) if stats.all_frame_times else float("nan")
    visible = f"{stats.visible:,} of {scene_count:,} visible"
    sorts = median_ms(stats.sort_times())
    per_pixel = stats.order_stats[0]
    if per_pixel is not None:  # the last redraw's per-pixel order (the left side's, one eye's)
        visible += (f", per-pixel order {per_pixel.mean_per_covered_pixel:.1f} fragments/px "
                    f"(max {per_pixel.max_per_pixel:,}) in {per_pixel.parts} part{'s' if per_pixel.parts != 1 else ''}")
    if stereo is not None:
        return (f"{frames} frames ({stats.draws} drawn), stereo {stereo.headset.name} "
                f"{camera_size(camera)} per eye: median frame {median_ms(stats.all_frame_times)}, "
                f"both eyes GPU {median_ms(gpu_times)}, lens+layout {median_ms(post_times)}, "
                f"sort {sorts}, {visible}")
    return (f"{frames} frames ({stats.draws} drawn) at {camera_size(camera)}: "
            f"median frame {median_ms(stats.all_frame_times)} ({1 / frame if frame > 0 else 0:.1f} fps), "
            f"GPU {median_ms(gpu_times)}, sort {sorts}, {visible}"
            + (", general shaders" if general else ""))
