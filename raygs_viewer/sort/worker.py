"""Depth sorting off the frame loop: the window asks for a sort and draws with the
newest finished order, never waiting for one.

One daemon thread per :class:`BackgroundSorter` runs ``sorter.sort`` on the
newest request (a :class:`~raygs_viewer.sort.request.SortRequest`): one cull, then one sort per key the request names (the A/B
split view may show a depth-ordered side beside a distance-ordered one), so a
result holds an order per key. A request that arrives while a sort runs waits in a
single slot; a newer request replaces it (only the newest view matters, and a
moving camera would otherwise build a backlog of stale sorts). Locks are held
only to swap references and bump counters, never across a sort, so
:meth:`BackgroundSorter.request` and :meth:`BackgroundSorter.latest` return at
once however long a sort takes.
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from typing import Protocol

from raygs_viewer.errors import one_line
from raygs_viewer.sort.pool import Closable
from raygs_viewer.sort.request import SortRequest, SortResult

__all__ = ["BackgroundSorter", "InlineSorter", "Sorter"]


class Sorter(Protocol):
    """What :class:`BackgroundSorter` runs: :class:`raygs_viewer.sort.depth.DepthSorter`
    or a test double. A ``close()`` is called when the worker exits."""

    def sort(self, request: SortRequest) -> SortResult: ...

    def close(self) -> None: ...


class _Answers(Closable):
    """What both sorters keep of the requests they answer: the counters, the last
    request (a repeat of it is answered, not sorted again), the newest result and the
    last failure's line."""

    def __init__(self, sorter: Sorter) -> None:
        self._sorter = sorter
        self._latest: SortResult | None = None
        self._last: SortRequest | None = None
        self._closed = False
        self.requested = self.repeated = self.started = self.finished = self.failed = self.superseded = 0
        self.error: str | None = None

    def _is_new(self, request: SortRequest, owner: str) -> bool:
        """Counts ``request``: False (``repeated``) when it equals the last one, which
        keeps its serial; else True, its serial the new ``requested``. Raises
        RuntimeError after close (the message names ``owner``, the sorter's class)."""
        if self._closed:
            raise RuntimeError(f"{owner}.request after close()")
        if request == self._last:
            self.repeated += 1
            return False
        self.requested += 1
        self._last = request
        return True

    def _failed(self, exc: Exception) -> None:
        self.failed += 1
        self.error = f"{type(exc).__name__}: {one_line(exc)}" if str(exc).strip() else type(exc).__name__


class BackgroundSorter(_Answers):
    """Sorts on a daemon worker thread; the frame loop only calls :meth:`request` and :meth:`latest`.

    Counters (plain ints, read without locking by the statistics panel and tests):

    - ``requested``: requests queued, i.e. serials handed out (identical repeats not counted);
    - ``repeated``: requests identical to the last one queued, answered with its serial;
    - ``started``: sorts begun; ``finished``: sorts that produced a result;
    - ``failed``: sorts whose ``orders`` raised;
    - ``superseded``: queued requests replaced by a newer one before they started.

    ``requested == started + superseded + (1 if a request is waiting else 0)``.
    ``error`` is the one-line message of the last failed sort, cleared by the next
    successful one; a failed request is not retried until a different one is made, so a frame loop re-requesting the same view cannot
    spin on it.
    """

    def __init__(self, sorter: Sorter) -> None:
        super().__init__(sorter)
        self._cond = threading.Condition()
        self._pending: tuple[int, SortRequest, float] | None = None  # serial, request, when
        self._answered = 0  # highest serial whose sort finished or failed; wait() compares with it
        self._thread = threading.Thread(target=self._run, name="raygs-sort", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ frame-loop side

    def request(self, request: SortRequest) -> int:
        """Non-blocking. Queues ``request`` and returns its serial; a request not yet
        started is replaced by the newer one (only the newest view matters). A request
        equal to the last one queued is not queued again: returns the old serial.
        Raises RuntimeError after :meth:`close`."""
        with self._cond:
            if not self._is_new(request, "BackgroundSorter"):
                return self.requested
            if self._pending is not None:
                self.superseded += 1
            self._pending = (self.requested, request, time.perf_counter())
            self._cond.notify_all()
            return self.requested

    def latest(self) -> SortResult | None:
        """Non-blocking: the newest finished result (None before the first)."""
        return self._latest  # one reference read: atomic, no lock needed

    # ------------------------------------------------------------------ scripted side

    def wait(self, serial: int, timeout: float | None = None) -> SortResult | None:
        """Blocks until request ``serial`` is answered (for screenshots and tests, never
        the frame loop) and returns the newest result, whose serial is >= ``serial``.

        Returns None when ``timeout`` (seconds) passes first, when the sorter is closed
        first, or when that request's sort failed with no newer result (see ``error``).
        """
        with self._cond:
            self._cond.wait_for(lambda: self._answered >= serial or self._closed, timeout)
            latest = self._latest
        return latest if latest is not None and latest.serial >= serial else None

    def close(self) -> None:
        """Stops the worker and drops a queued request. Returns at once even while a
        sort runs: the daemon thread finishes that sort, publishes it, closes the sorter
        (a :class:`DepthSorter`'s thread pool) and exits;
        :meth:`join` waits for that."""
        with self._cond:
            self._closed = True
            self._pending = None
            self._cond.notify_all()

    def join(self, timeout: float | None = None) -> bool:
        """Waits until the worker has exited after :meth:`close` (and closed the sorter);
        True when it has."""
        self._thread.join(timeout)
        return not self._thread.is_alive()

    # ------------------------------------------------------------------ worker

    def _run(self) -> None:
        try:
            self._serve()
        finally:
            self._sorter.close()

    def _serve(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._closed)
                if self._closed:
                    return
                (serial, request, requested_at), self._pending = self._pending, None
                self.started += 1
            try:
                result = self._sorter.sort(request)
            except Exception as exc:  # reported in .error; the thread must keep serving
                with self._cond:
                    self._failed(exc)
                    self._answered = max(self._answered, serial)
                    self._cond.notify_all()
                continue
            result = replace(result, serial=serial, requested_at=requested_at, finished_at=time.perf_counter())
            with self._cond:
                self._latest = result
                self.finished += 1
                self.error = None
                self._answered = max(self._answered, serial)
                self._cond.notify_all()


class InlineSorter(_Answers):
    """Sorts on the calling thread when asked, with :class:`BackgroundSorter`'s interface
    and counters: the frame draws the order of its own view. For the GPU sort, which
    must run on the thread that holds the GL context (and whose work the GPU queues
    beside the draw's); a CPU sort this way would stall every frame for its length.

    A request equal to the last one is answered with the last result (``repeated``);
    ``superseded`` stays 0 (nothing waits), and ``wait`` has nothing to wait for."""

    def request(self, request: SortRequest) -> int:
        """Sorts ``request`` now (unless it is the last one) and returns its serial; a
        failed sort is reported in ``error`` and not retried until another request."""
        if not self._is_new(request, "InlineSorter"):
            return self.requested
        self.started += 1
        requested_at = time.perf_counter()
        try:
            result = self._sorter.sort(request)
        except Exception as exc:  # reported in .error, as the background sorter does
            self._failed(exc)
            return self.requested
        self._latest = replace(result, serial=self.requested, requested_at=requested_at,
                               finished_at=time.perf_counter())
        self.finished += 1
        self.error = None
        return self.requested

    def latest(self) -> SortResult | None:
        return self._latest

    def wait(self, serial: int, timeout: float | None = None) -> SortResult | None:
        """The newest result when it answers ``serial`` or a later one (a request is
        answered before :meth:`request` returns), else None (that sort failed)."""
        latest = self._latest
        return latest if latest is not None and latest.serial >= serial else None

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._sorter.close()

    def join(self, timeout: float | None = None) -> bool:
        return True
