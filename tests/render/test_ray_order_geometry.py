"""ray_order's geometry sums: accumulated in the order fragments actually composite
(exact by (t*, index), or as they leave a k-buffer), with the cut-off's stopping
fragment adding nothing; checked against a heap per pixel."""

import heapq

import numpy as np
import pytest

from raygs_viewer.render.ray_order import Fragments, GeometrySums, composite_per_pixel, composite_per_pixel_geometry
from raygs_viewer.render.settings import TRANSMITTANCE_CUTOFF


def _random_fragments(seed, pixels=7, count=160):
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(count, 3))
    return Fragments(pixel=rng.integers(0, pixels, count), key=rng.integers(0, 25, count).astype(float),
                     index=rng.permutation(count), rank=rng.permutation(count),
                     alpha=rng.uniform(0.02, 0.6, count) ** 2 * 2.5, color=rng.uniform(0, 1, (count, 3)),
                     z=rng.uniform(0.5, 9.0, count), normal=normal / np.linalg.norm(normal, axis=1, keepdims=True))


def _composited_order(fragments, pixel, k):
    """Indices of ``pixel``'s fragments in the order they composite."""
    mine = np.flatnonzero(fragments.pixel == pixel)
    if k == 0:
        return sorted(mine, key=lambda i: (fragments.key[i], fragments.index[i]))
    window, out = [], []
    for i in mine[np.argsort(-fragments.rank[mine])]:
        heapq.heappush(window, (fragments.key[i], fragments.index[i], i))
        if len(window) > k:
            out.append(heapq.heappop(window)[2])
    return out + [entry[2] for entry in sorted(window)]


@pytest.mark.parametrize("k", [0, 1, 3])
@pytest.mark.parametrize("cutoff", [None, TRANSMITTANCE_CUTOFF])
def test_geometry_sums_follow_the_composited_order(k, cutoff):
    fragments, pixels = _random_fragments(seed=k), 7
    values = composite_per_pixel_geometry(fragments, pixels, (0.1, 0.2, 0.3), window=k, cutoff=cutoff)
    np.testing.assert_array_equal(values[:, :4], composite_per_pixel(fragments, pixels, (0.1, 0.2, 0.3),
                                                                     window=k, cutoff=cutoff))
    stopped = medians = 0
    for p in range(pixels):
        transmittance, depth, normal, median, found = 1.0, 0.0, np.zeros(3), 0.0, 0.0
        for i in _composited_order(fragments, p, k):
            after = transmittance * (1 - fragments.alpha[i])
            if cutoff is not None and after < cutoff:
                stopped += 1
                break
            depth += transmittance * fragments.alpha[i] * fragments.z[i]
            normal += transmittance * fragments.alpha[i] * fragments.normal[i]
            if not found and 1 - after >= 0.5:
                median, found = fragments.z[i], 1.0
            transmittance = after
        medians += found
        np.testing.assert_allclose(values[p, 4], depth, rtol=1e-12)
        np.testing.assert_allclose(values[p, 5:8], normal, rtol=1e-12, atol=1e-15)
        assert (values[p, 8], values[p, 9]) == (median, found)
    assert medians >= 3 and (cutoff is None or stopped >= 2)
    # The order matters: the exact order's sums differ from a window of one's.
    if k == 1:
        exact = composite_per_pixel_geometry(fragments, pixels, (0.1, 0.2, 0.3), cutoff=cutoff)
        assert np.abs(exact[:, 4] - values[:, 4]).max() > 1e-3


def test_geometry_sums_on_a_band_take_slices_and_one_z_for_all():
    sums = GeometrySums((2, 3))
    where = (slice(0, 2), slice(1, 3))
    sums.add(where, np.full((2, 2), 0.25), np.full((2, 2), 0.25), 4.0, np.broadcast_to([0.0, 0.0, -1.0], (2, 2, 3)))
    sums.add(where, np.full((2, 2), 0.375), np.array([[0.4, 0.625], [0.625, 0.0]]), np.full((2, 2), 6.0),
             np.broadcast_to([1.0, 0.0, 0.0], (2, 2, 3)))
    stacked = sums.stacked()
    assert stacked.shape == (2, 3, 6) and not stacked[:, 0].any()
    np.testing.assert_array_equal(stacked[:, 1:, 0], np.full((2, 2), 0.25 * 4 + 0.375 * 6))
    np.testing.assert_array_equal(stacked[0, 1, 1:4], [0.375, 0.0, -0.25])
    # Accumulated alpha 0.625 reaches one half; 0.4, and 0 (not composited), do not.
    np.testing.assert_array_equal(stacked[:, 1:, 4], [[0.0, 6.0], [6.0, 0.0]])
    np.testing.assert_array_equal(stacked[:, 1:, 5], [[0.0, 1.0], [1.0, 0.0]])
