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
    ``history`` keeps every one. ``timer.time_ms(work)`` is the benchmarks': it runs
    ``work`` under a query and waits for its time."""

    def __init__(self, ctx: moderngl.Context, depth: int = 3):
        self._queries = [ctx.query(time=True) for _ in range(depth)]
        self._blocking = ctx.query(time=True)
        self._pending: deque = deque()
        self.seconds = math.nan
        self.history: deque = deque(maxlen=10000)

    def measure(self):
        query = self._queries[0]
        self._queries.append(self._queries.pop(0))
        if query in self._pending:  # the oldest: its result is due now
            self._pending.remove(query)
            self._record(query)
        self._pending.append(query)
        return query

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
