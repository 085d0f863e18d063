"""``closed`` and the context manager of the sort's objects that own a thread."""

from __future__ import annotations

from typing import TypeVar

_Self = TypeVar("_Self", bound="Closable")


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
