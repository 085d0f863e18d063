"""Compositing each pixel's fragments in the order its ray meets them (maths page, section 11),
in float64: the per-pixel part of the reference renderer.

A fragment is one gaussian seen by one pixel (sample): its opacity alpha, its key t*
(the ray parameter of the gaussian's peak on that pixel's unit ray), the gaussian's
scene index (ties) and its rank in the global back-to-front order (its arrival: the
rasterizer meets a pixel's fragments front to back in the global order, highest rank
first). Two orders exist:

- exact (k = 0): every pixel composites its fragments front to back by (t*, index);
- a window of k (a k-buffer): fragments arrive front to back in the global order; a
  pixel keeps at most k; when one arrives with the window full, the smallest by
  (t*, index) among the k + 1 is composited and leaves; at the end the window is
  composited in ascending (t*, index). As k grows it becomes the exact order.

Both composite front to back; with the transmittance cut-off, INRIA's rule: the
fragment that would take the transmittance below the cut-off ends the pixel, itself
not drawn (section 10). Everything is vectorised over pixels; the loops run over
fragment layers (a pixel's first, second, ... fragment), not over pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Fragments:
    """F fragments of one band of samples, in any order.

    pixel: (F,) int64 flat sample index in the band (row * width + column).
    key: (F,) float64 t*. index: (F,) int64 scene index of the gaussian (ties).
    rank: (F,) int64 position in the global back-to-front order (arrival: highest first).
    alpha: (F,) float64 opacity, > 0. color: (F, 3) float64 the gaussian's colour.
    """

    pixel: np.ndarray
    key: np.ndarray
    index: np.ndarray
    rank: np.ndarray
    alpha: np.ndarray
    color: np.ndarray

    @classmethod
    def concatenate(cls, parts: list[tuple]) -> "Fragments":
        """Fragments from (pixel, key, index, rank, alpha, color) tuples of arrays."""
        if not parts:
            empty = np.zeros(0)
            return cls(empty.astype(np.int64), empty, empty.astype(np.int64), empty.astype(np.int64), empty,
                       np.zeros((0, 3)))
        columns = list(zip(*parts))
        return cls(*(np.concatenate(column) for column in columns))

    def take(self, selection: np.ndarray) -> "Fragments":
        return Fragments(self.pixel[selection], self.key[selection], self.index[selection],
                         self.rank[selection], self.alpha[selection], self.color[selection])


class FrontToBack:
    """Front-to-back accumulation over ``pixels`` samples: colour so far, transmittance,
    and (with ``cutoff``) which pixels INRIA's rule has ended."""

    def __init__(self, pixels: int, cutoff: float | None):
        self.color = np.zeros((pixels, 3))
        self.transmittance = np.ones(pixels)
        self.cutoff = cutoff
        self.done = np.zeros(pixels, dtype=bool)

    def add(self, pixels: np.ndarray, alpha: np.ndarray, color: np.ndarray) -> None:
        """Composites one fragment at each of ``pixels`` (distinct), behind what is there."""
        t = self.transmittance[pixels]
        after = t * (1.0 - alpha)
        take = np.ones(len(pixels), dtype=bool)
        if self.cutoff is not None:
            take = ~self.done[pixels]
            stop = take & (after < self.cutoff)
            self.done[pixels[stop]] = True
            take &= ~stop
        pixels, t, alpha, after = pixels[take], t[take], alpha[take], after[take]
        self.color[pixels] += (t * alpha)[:, None] * color[take]
        self.transmittance[pixels] = after

    def image(self, background) -> np.ndarray:
        """(pixels, 4): RGB over ``background`` and the accumulated alpha 1 - T."""
        out = np.empty((len(self.transmittance), 4))
        out[:, :3] = self.color + self.transmittance[:, None] * np.asarray(background, np.float64)
        out[:, 3] = 1.0 - self.transmittance
        return out


def composite_per_pixel(fragments: Fragments, pixels: int, background, *, window: int = 0,
                        cutoff: float | None = None) -> np.ndarray:
    """(pixels, 4) float64: RGB over ``background`` and accumulated alpha of every sample,
    its fragments composited per pixel: exactly by (t*, index) with ``window`` 0, else
    through a k-buffer of ``window`` entries (module docstring). ``cutoff``: the
    transmittance cut-off, or None."""
    accumulator = FrontToBack(pixels, cutoff)
    if window == 0:
        # By pixel, then t*, then index: each pixel's fragments in the order they composite.
        order = np.lexsort((fragments.index, fragments.key, fragments.pixel))
        _composite_layers(accumulator, fragments.take(order))
    else:
        # By pixel, then arrival (rank descending): the stream each pixel's window sees.
        order = np.lexsort((-fragments.rank, fragments.pixel))
        _stream_through_window(accumulator, fragments.take(order), pixels, window)
    return accumulator.image(background)


def _layers(pixel: np.ndarray) -> tuple[np.ndarray, int]:
    """For fragments sorted by pixel: each one's position within its pixel (0 = first),
    and the most fragments any pixel has."""
    if pixel.size == 0:
        return np.zeros(0, np.int64), 0
    starts = np.flatnonzero(np.r_[True, pixel[1:] != pixel[:-1]])
    lengths = np.diff(np.r_[starts, pixel.size])
    position = np.arange(pixel.size) - np.repeat(starts, lengths)
    return position, int(lengths.max())


def _composite_layers(accumulator: FrontToBack, ordered: Fragments) -> None:
    """Composites fragments sorted by pixel and, within a pixel, front to back: layer
    by layer (every pixel's first fragment, then every pixel's second, ...)."""
    position, depth = _layers(ordered.pixel)
    by_layer = np.argsort(position, kind="stable")
    bounds = np.searchsorted(position[by_layer], np.arange(depth + 1))
    for layer in range(depth):
        chosen = by_layer[bounds[layer]:bounds[layer + 1]]
        accumulator.add(ordered.pixel[chosen], ordered.alpha[chosen], ordered.color[chosen])


def _stream_through_window(accumulator: FrontToBack, arriving: Fragments, pixels: int, k: int) -> None:
    """The k-buffer: fragments sorted by pixel and arrival go through a window of k per pixel."""
    key = np.full((pixels, k), np.inf)
    index = np.zeros((pixels, k), np.int64)
    alpha = np.zeros((pixels, k))
    color = np.zeros((pixels, k, 3))
    held = np.zeros(pixels, np.int64)
    position, depth = _layers(arriving.pixel)
    by_layer = np.argsort(position, kind="stable")
    bounds = np.searchsorted(position[by_layer], np.arange(depth + 1))
    for layer in range(depth):
        new = arriving.take(by_layer[bounds[layer]:bounds[layer + 1]])
        p = new.pixel
        room = held[p] < k
        # A free slot: the fragment joins the window.
        q, slot = p[room], held[p[room]]
        key[q, slot], index[q, slot], alpha[q, slot], color[q, slot] = (
            new.key[room], new.index[room], new.alpha[room], new.color[room])
        held[q] += 1
        # A full window: the smallest of the k + 1 leaves, composited.
        full = ~room
        q = p[full]
        if q.size == 0:
            continue
        slot = _smallest(key[q], index[q])
        window_first = _before(key[q, slot], index[q, slot], new.key[full], new.index[full])
        leave_alpha = np.where(window_first, alpha[q, slot], new.alpha[full])
        leave_color = np.where(window_first[:, None], color[q, slot], new.color[full])
        accumulator.add(q, leave_alpha, leave_color)
        keep = window_first  # the arriving fragment takes the leaving one's slot
        qs, ss = q[keep], slot[keep]
        key[qs, ss], index[qs, ss] = new.key[full][keep], new.index[full][keep]
        alpha[qs, ss], color[qs, ss] = new.alpha[full][keep], new.color[full][keep]
    # Flush: every window in ascending (t*, index); empty slots (t* = inf) sort last.
    flush = np.lexsort((index, key), axis=1)
    rows = np.arange(pixels)
    for column in range(k):
        slot = flush[:, column]
        present = column < held
        q = rows[present]
        accumulator.add(q, alpha[q, slot[present]], color[q, slot[present]])


def _smallest(key: np.ndarray, index: np.ndarray) -> np.ndarray:
    """(P,) column of the smallest (key, index) in each row of (P, k) arrays."""
    least = key.min(axis=1, keepdims=True)
    return np.where(key == least, index, np.iinfo(np.int64).max).argmin(axis=1)


def _before(key_a, index_a, key_b, index_b) -> np.ndarray:
    """Whether (key_a, index_a) sorts before (key_b, index_b), elementwise."""
    return (key_a < key_b) | ((key_a == key_b) & (index_a < index_b))
