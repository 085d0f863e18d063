"""The one GPU timer: timer queries around passes, for the window's statistics and for
every benchmark."""

from __future__ import annotations

import math
from collections import deque
from typing import Callable

import moderngl

#: An elapsed time some drivers report for a query whose result is not valid.
INVALID_ELAPSED = 0xFFFFFFFF


def elapsed_ms(query) -> float:
    """The query's GPU time in milliseconds (waits for it); NaN where the driver marks
    it invalid."""
    elapsed = query.elapsed
    return math.nan if elapsed >= INVALID_ELAPSED else elapsed / 1e6


class GpuTimer:
    """GPU time of passes from timer queries, two ways.

    ``with timer.measure(): ...`` is the window's: the result is read ``depth`` frames
    late, so reading never stalls the CPU on a real GPU; ``seconds`` is the newest and
    ``history`` keeps every one. Work measured only in some frames (the GPU sort: when
    the view changed) counts the frames with :meth:`frame`, which reads what was
    measured ``depth`` frames before. ``timer.time_ms(work)`` is the benchmarks': it runs
    ``work`` under a query and waits for its time."""

    def __init__(self, ctx: moderngl.Context, depth: int = 3):
        self.depth = depth
        self._queries = [ctx.query(time=True) for _ in range(depth)]
        self._blocking = ctx.query(time=True)
        self._pending: deque = deque()
        self._frames = 0
        self._measured_in: dict[int, int] = {}  # id(query) -> the frame it was measured in
        self.seconds = math.nan
        self.history: deque = deque(maxlen=10000)

    def measure(self):
        query = self._queries[0]
        self._queries.append(self._queries.pop(0))
        if query in self._pending:  # the oldest: its result is due now
            self._pending.remove(query)
            self._record(query)
        self._pending.append(query)
        self._measured_in[id(query)] = self._frames
        return query

    def frame(self) -> None:
        """Counts a frame and reads the results measured ``depth`` frames ago or before:
        the window has shown those frames since, so the GPU has done that work and the
        read does not wait, though no measurement followed to push it out."""
        self._frames += 1
        while self._pending and self._frames - self._measured_in[id(self._pending[0])] >= self.depth:
            self._record(self._pending.popleft())

    def flush(self) -> None:
        """Reads every pending result (waits for the GPU: for the end of a run)."""
        while self._pending:
            self._record(self._pending.popleft())

    def time_ms(self, work: Callable[[], object]) -> float:
        """Runs ``work`` under a query of its own and returns its GPU time in ms (NaN
        where invalid); waits for the GPU. Results of ``measure`` stay pending."""
        with self._blocking:
            work()
        return elapsed_ms(self._blocking)

    def _record(self, query) -> None:
        self.seconds = query.elapsed * 1e-9
        self.history.append(self.seconds)
