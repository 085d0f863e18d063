"""What a render returns: what it did, for the panel and the benchmarks (the per-pixel
order's figures, see :mod:`raygs_viewer.render.settings`, ``order``; the depth range a
depth picture used)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class OrderStats:
    """One per-pixel-order render (one eye, one side or one tile).

    path: how the fragments were ordered, "lists" (per-pixel fragment lists in a
    storage-buffer pool, then a resolve pass: any OpenGL 4.3 driver) or "fetch" (a
    k-buffer in colour attachments through framebuffer fetch). fragments: fragments
    kept (alpha >= p_min) over the whole image; max_per_pixel: the most at one
    pixel; covered_pixels: pixels with at least one. pool_fragments, pool_bytes:
    the pool's capacity (0 on the fetch path); parts: how many rectangles the image
    was drawn in so that each part's fragments fit the pool (1: all at once; the fetch
    path draws in one); largest_part: the fragments of the fullest part.
    """

    path: str
    width: int
    height: int
    fragments: int
    max_per_pixel: int
    covered_pixels: int
    pool_fragments: int
    pool_bytes: int
    parts: int
    largest_part: int = 0

    @property
    def mean_per_covered_pixel(self) -> float:
        return self.fragments / self.covered_pixels if self.covered_pixels else 0.0

    @property
    def pool_use(self) -> float:
        """The largest part's share of the pool, 0..1 (0 on the fetch path)."""
        if not self.pool_fragments:
            return 0.0
        return min(1.0, self.largest_part / self.pool_fragments)


@dataclass(frozen=True)
class RenderResult:
    """What one render did.

    order_stats: what the per-pixel order's passes did (None for a global order).
    view_range:  the depth range a depth picture used (None: not a depth picture).
    """

    order_stats: OrderStats | None = None
    view_range: tuple[float, float] | None = None
