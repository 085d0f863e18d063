"""Gaussians a sort leaves out (deleted in the window), as a value a request carries.

A deletion is not a new scene: the scene stays on the GPU as it was read, and the sort
drops the deleted rows with the transparent ones (``sort.cull``'s candidates), so no
order holds them and nothing draws them, whichever sorter made the order.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class DeletedRows:
    """Gaussians a sort leaves out as if they were not in the scene (deleted in the window):
    ``mask`` (N,) bool, True where deleted, copied and made read-only; ``key``: its digest,
    what a request's identity compares (equal masks, equal keys)."""

    mask: np.ndarray
    key: bytes = field(init=False)

    def __post_init__(self) -> None:
        mask = np.array(self.mask, dtype=bool)
        mask.flags.writeable = False
        object.__setattr__(self, "mask", mask)
        object.__setattr__(self, "key", hashlib.sha1(np.packbits(mask).tobytes() + mask.size.to_bytes(8, "little")
                                                     ).digest())

    @classmethod
    def of(cls, mask: np.ndarray | None) -> "DeletedRows | None":
        """The deleted rows of ``mask``; None where none is deleted (the plain sort)."""
        return None if mask is None or not mask.any() else cls(mask)


def deleted_key(deleted: "DeletedRows | None") -> bytes:
    """What ``deleted`` adds to a cache's key: its digest, or nothing."""
    return b"" if deleted is None else deleted.key
