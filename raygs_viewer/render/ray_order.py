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

Fragments may carry geometry (their peak's z and their normal, facing the ray): then
:class:`GeometrySums` accumulates the geometry outputs of
:mod:`raygs_viewer.render.channels` in the order the fragments are composited.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from raygs_viewer.render.channels import MEDIAN_ALPHA


@dataclass(frozen=True)
class Fragments:
    """F fragments of one band of samples, in any order.

    pixel: (F,) int64 flat sample index in the band (row * width + column).
    key: (F,) float64 t*. index: (F,) int64 scene index of the gaussian (ties).
    rank: (F,) int64 position in the global back-to-front order (arrival: highest first).
    alpha: (F,) float64 opacity, > 0. color: (F, 3) float64 the gaussian's colour.
    With geometry (else None): z (F,) float64 camera-space z of the peak point, normal
    (F, 3) float64 the gaussian's unit normal turned to face the pixel's ray.
    """

    pixel: np.ndarray
    key: np.ndarray
    index: np.ndarray
    rank: np.ndarray
    alpha: np.ndarray
    color: np.ndarray
    z: np.ndarray | None = None
    normal: np.ndarray | None = None

    @classmethod
    def concatenate(cls, parts: list[tuple]) -> "Fragments":
        """Fragments from (pixel, key, index, rank, alpha, color) tuples of arrays, each
        with (z, normal) after them for the geometry outputs. None at all: no fragment
        to composite, whatever the outputs."""
        if not parts:
            empty = np.zeros(0)
            return cls(empty.astype(np.int64), empty, empty.astype(np.int64), empty.astype(np.int64), empty,
                       np.zeros((0, 3)))
        columns = list(zip(*parts))
        return cls(*(np.concatenate(column) for column in columns))

    @property
    def has_geometry(self) -> bool:
        return self.z is not None

    def payload(self, owner: bool = False) -> dict[str, np.ndarray]:
        """What compositing needs of each fragment: alpha and colour, z and normal with
        geometry, and with ``owner`` the scene index as float64 (exact below 2^53: the
        k-buffer's slots are float) for :class:`LargestWeights` (the keyword arguments of
        :meth:`FrontToBack.add`)."""
        names = ("alpha", "color", "z", "normal") if self.has_geometry else ("alpha", "color")
        payload = {name: getattr(self, name) for name in names}
        if owner:
            payload["owner"] = self.index.astype(np.float64)
        return payload

    def take(self, selection: np.ndarray) -> "Fragments":
        return Fragments(*(None if (value := getattr(self, field.name)) is None else value[selection]
                           for field in fields(self)))


class GeometrySums:
    """The geometry accumulators of samples of any ``shape`` ((P,) or a band's (H, W)),
    front to back: depth_sum = sum w T z, normal_sum = sum w T n, and the median depth
    (z of the first fragment after which the accumulated alpha reaches MEDIAN_ALPHA)
    with ``found`` where it was reached."""

    def __init__(self, shape: tuple[int, ...]):
        self.depth_sum = np.zeros(shape)
        self.normal_sum = np.zeros(shape + (3,))
        self.median = np.zeros(shape)
        self.found = np.zeros(shape, dtype=bool)

    def add(self, where, weight: np.ndarray, accumulated: np.ndarray, z, normal: np.ndarray) -> None:
        """One fragment at each sample of ``where`` (distinct flat indices, or a tuple of
        slices): ``weight`` w T, ``accumulated`` the alpha 1 - T after it (0 where it was not
        composited), ``z`` its z (or one z for all), ``normal`` (..., 3)."""
        self.depth_sum[where] += weight * z
        self.normal_sum[where] += weight[..., None] * normal
        found = self.found[where]
        reached = ~found & (accumulated >= MEDIAN_ALPHA)
        self.median[where] = np.where(reached, z, self.median[where])
        self.found[where] = found | reached

    def stacked(self) -> np.ndarray:
        """(*shape, 6): depth_sum, normal_sum (x, y, z), median * found, found, the last
        two the ``median`` input of :func:`raygs_viewer.render.channels.finish`."""
        return np.concatenate((self.depth_sum[..., None], self.normal_sum, self.median[..., None],
                               self.found[..., None].astype(np.float64)), axis=-1)


class LargestWeights:
    """Each gaussian's largest weight T alpha (its share of a sample's colour) over the
    samples ``counted`` ((pixels,) bool), for ``owners`` gaussians: (owners,) float64
    ``largest``, 0 where a gaussian adds to no counted sample."""

    def __init__(self, owners: int, counted: np.ndarray):
        self.largest = np.zeros(owners)
        self.counted = counted

    def add(self, pixels: np.ndarray, weight: np.ndarray, owner: np.ndarray) -> None:
        counted = self.counted[pixels]
        np.maximum.at(self.largest, owner[counted].astype(np.int64), weight[counted])


class FrontToBack:
    """Front-to-back accumulation over ``pixels`` samples: colour so far, transmittance,
    (with ``cutoff``) which pixels INRIA's rule has ended, the geometry ``sums`` of
    those pixels (None: colour alone) and the gaussians' largest ``weights`` (None: not
    kept; the fragments then carry their owner)."""

    def __init__(self, pixels: int, cutoff: float | None, sums: GeometrySums | None = None,
                 weights: LargestWeights | None = None):
        self.color = np.zeros((pixels, 3))
        self.transmittance = np.ones(pixels)
        self.cutoff = cutoff
        self.done = np.zeros(pixels, dtype=bool)
        self.geometry = sums
        self.weights = weights

    def add(self, pixels: np.ndarray, alpha: np.ndarray, color: np.ndarray, *,
            z: np.ndarray | None = None, normal: np.ndarray | None = None, owner: np.ndarray | None = None) -> None:
        """Composites one fragment at each of ``pixels`` (distinct), behind what is there;
        ``z`` and ``normal`` are needed with geometry, ``owner`` with weights."""
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
        if self.geometry is not None:
            self.geometry.add(pixels, t * alpha, 1.0 - after, z[take], normal[take])
        if self.weights is not None:
            self.weights.add(pixels, t * alpha, owner[take])

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
    return _accumulate(fragments, pixels, window=window, cutoff=cutoff).image(background)


def composite_per_pixel_geometry(fragments: Fragments, pixels: int, background, *, window: int = 0,
                                 cutoff: float | None = None) -> np.ndarray:
    """(pixels, 10) float64: :func:`composite_per_pixel`'s RGBA, then the geometry sums
    (:meth:`GeometrySums.stacked`) accumulated in the order the fragments composite;
    ``fragments`` must carry geometry."""
    accumulator = _accumulate(fragments, pixels, window=window, cutoff=cutoff, sums=GeometrySums((pixels,)))
    return np.concatenate((accumulator.image(background), accumulator.geometry.stacked()), axis=-1)


def largest_weights(fragments: Fragments, pixels: int, counted: np.ndarray, owners: int, *,
                    window: int = 0, cutoff: float | None = None) -> np.ndarray:
    """(owners,) float64: each gaussian (``Fragments.index``)'s largest weight T alpha over
    the ``counted`` samples ((pixels,) bool), its fragments composited as
    :func:`composite_per_pixel` composites them."""
    weights = LargestWeights(owners, counted)
    _accumulate(fragments, pixels, window=window, cutoff=cutoff, weights=weights)
    return weights.largest


def _accumulate(fragments: Fragments, pixels: int, *, window: int, cutoff: float | None,
                sums: GeometrySums | None = None, weights: LargestWeights | None = None) -> FrontToBack:
    accumulator = FrontToBack(pixels, cutoff, sums, weights)
    if window == 0:
        # By pixel, then t*, then index: each pixel's fragments in the order they composite.
        order = np.lexsort((fragments.index, fragments.key, fragments.pixel))
        _composite_layers(accumulator, fragments.take(order))
    else:
        # By pixel, then arrival (rank descending): the stream each pixel's window sees.
        order = np.lexsort((-fragments.rank, fragments.pixel))
        _stream_through_window(accumulator, fragments.take(order), pixels, window)
    return accumulator


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
    payload = ordered.payload(owner=accumulator.weights is not None)
    for layer in range(depth):
        chosen = by_layer[bounds[layer]:bounds[layer + 1]]
        accumulator.add(ordered.pixel[chosen], **{name: column[chosen] for name, column in payload.items()})


def _stream_through_window(accumulator: FrontToBack, arriving: Fragments, pixels: int, k: int) -> None:
    """The k-buffer: fragments sorted by pixel and arrival go through a window of k per pixel."""
    key = np.full((pixels, k), np.inf)
    index = np.zeros((pixels, k), np.int64)
    # What each slot holds for compositing: alpha and colour, and z and normal with geometry.
    owner = accumulator.weights is not None
    slots = {name: np.zeros((pixels, k) + column.shape[1:]) for name, column in arriving.payload(owner).items()}
    held = np.zeros(pixels, np.int64)
    position, depth = _layers(arriving.pixel)
    by_layer = np.argsort(position, kind="stable")
    bounds = np.searchsorted(position[by_layer], np.arange(depth + 1))
    for layer in range(depth):
        new = arriving.take(by_layer[bounds[layer]:bounds[layer + 1]])
        payload = new.payload(owner)
        p = new.pixel
        room = held[p] < k
        # A free slot: the fragment joins the window.
        q, slot = p[room], held[p[room]]
        key[q, slot], index[q, slot] = new.key[room], new.index[room]
        for name, column in payload.items():
            slots[name][q, slot] = column[room]
        held[q] += 1
        # A full window: the smallest of the k + 1 leaves, composited.
        full = ~room
        q = p[full]
        if q.size == 0:
            continue
        slot = _smallest(key[q], index[q])
        window_first = _before(key[q, slot], index[q, slot], new.key[full], new.index[full])
        leaving = {name: np.where(window_first.reshape((-1,) + (1,) * (column.ndim - 1)), slots[name][q, slot],
                                  column[full]) for name, column in payload.items()}
        accumulator.add(q, **leaving)
        keep = window_first  # the arriving fragment takes the leaving one's slot
        qs, ss = q[keep], slot[keep]
        key[qs, ss], index[qs, ss] = new.key[full][keep], new.index[full][keep]
        for name, column in payload.items():
            slots[name][qs, ss] = column[full][keep]
    # Flush: every window in ascending (t*, index); empty slots (t* = inf) sort last.
    flush = np.lexsort((index, key), axis=1)
    rows = np.arange(pixels)
    for column in range(k):
        slot = flush[:, column]
        present = column < held
        q = rows[present]
        accumulator.add(q, **{name: held_values[q, slot[present]] for name, held_values in slots.items()})


def _smallest(key: np.ndarray, index: np.ndarray) -> np.ndarray:
    """(P,) column of the smallest (key, index) in each row of (P, k) arrays."""
    least = key.min(axis=1, keepdims=True)
    return np.where(key == least, index, np.iinfo(np.int64).max).argmin(axis=1)


def _before(key_a, index_a, key_b, index_b) -> np.ndarray:
    """Whether (key_a, index_a) sorts before (key_b, index_b), elementwise."""
    return (key_a < key_b) | ((key_a == key_b) & (index_a < index_b))
