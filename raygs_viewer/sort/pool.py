"""The threads that take a sorter's chunks in turn: the calling thread and a lazily made
pool of ``workers - 1`` more (numpy releases the GIL in its loops, so they run at once);
and what every object of the sort that owns a thread shares, :class:`Closable`."""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, TypeVar

T = TypeVar("T")
_Self = TypeVar("_Self", bound="Closable")
#: How a step hands its chunks out: ``run(task, count) -> [task(0), ..., task(count - 1)]``.
Runner = Callable[[Callable[[int], object], int], list]

#: Numbers the pools, so that each one's threads have a prefix of their own (tests find
#: a sorter's threads by it).
_POOL_SERIALS = itertools.count(1)


class Closable:
    """A base for a class whose :meth:`close` sets ``_closed``: ``with`` closes it on
    the way out, and :attr:`closed` says whether it has been closed."""

    _closed = False

    def close(self) -> None:
        raise NotImplementedError

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self: _Self) -> _Self:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


class ChunkPool(Closable):
    """``workers`` threads, the caller's among them, for independent tasks by index.

    ``workers`` may be changed before the first :meth:`run` that needs a pool. The pool
    is made on that run and shut down by :meth:`close`, after which every run takes
    the calling thread alone (with the same results: the tasks do not depend on the
    thread)."""

    def __init__(self, workers: int):
        self.workers = workers
        #: The pool's threads are named ``thread_prefix`` + "_0", "_1", ...
        self.thread_prefix = f"raygs-cull-{next(_POOL_SERIALS)}."
        self._executor: ThreadPoolExecutor | None = None

    def run(self, task: Callable[[int], T], count: int) -> list[T]:
        """[task(0), ..., task(count - 1)]: spread over the pool and the calling thread,
        each thread taking the next index as it finishes one."""
        threads = min(self.workers, count)
        if threads <= 1 or self._closed:
            return [task(index) for index in range(count)]
        if self._executor is None:
            self._executor = ThreadPoolExecutor(self.workers - 1, thread_name_prefix=self.thread_prefix)
        results: list = [None] * count
        indices = iter(range(count))  # next() on it is atomic under the GIL

        def drain() -> None:
            for index in indices:
                results[index] = task(index)

        helpers = [self._executor.submit(drain) for _ in range(threads - 1)]
        try:
            drain()
        finally:
            for helper in helpers:
                helper.result()  # re-raises a helper's exception here
        return results

    def close(self) -> None:
        """Shuts the threads down, waiting for them. Idempotent."""
        self._closed = True
        executor, self._executor = self._executor, None
        if executor is not None:
            executor.shutdown(wait=True)
