"""Gaussians a sort leaves out (deleted in the window), as a value a request carries.

A deletion is not a new scene: the scene stays on the GPU as it was read, and the sort
drops the hidden rows with the transparent ones (``sort.cull``'s candidates), so no
order holds them and nothing draws them, whichever sorter made the order.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class HiddenRows:
    """Gaussians a sort leaves out as if they were not in the scene (deleted in the window):
    ``mask`` (N,) bool, True where hidden, copied and made read-only; ``key``: its digest,
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
    def of(cls, mask: np.ndarray | None) -> "HiddenRows | None":
        """The hidden rows of ``mask``; None where none is hidden (the plain sort)."""
        return None if mask is None or not mask.any() else cls(mask)


def hidden_key(hidden: "HiddenRows | None") -> bytes:
    """What ``hidden`` adds to a cache's key: its digest, or nothing."""
    return b"" if hidden is None else hidden.key
