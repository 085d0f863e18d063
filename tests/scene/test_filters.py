"""Keep rules on their own: edges inside, float32 bounds, the sphere in float64, the
3D filter's sizes from the file, and each rule's refusal of a value out of range."""

from __future__ import annotations

import numpy as np
import pytest

from raygs_viewer.scene.filters import CropBox, CropSphere, KeepValues, MaxScale, MinOpacity, apply_rules


def values(positions, opacities=None, largest=None):
    positions = np.asarray(positions, np.float32)
    n = positions.shape[0]
    return KeepValues(positions, np.asarray(opacities if opacities is not None else np.ones(n), np.float32),
                      np.asarray(largest if largest is not None else np.ones(n), np.float32))


def test_box_edges_are_inside_even_where_float32_rounds_the_edge_down():
    assert float(np.float32(0.7)) < 0.7  # the trap: a float64 comparison would leave this centre out
    kept = CropBox((0.7, -1, -1), (1, 1, 1)).keeps(values([[0.7, 0, 0], [1, 1, 1], [0.69999, 0, 0], [1.0001, 0, 0]]))
    assert kept.tolist() == [True, True, False, False]


def test_each_box_axis_is_its_own():
    box = CropBox((0, 10, 20), (1, 11, 21))
    kept = box.keeps(values([[0.5, 10.5, 20.5], [10.5, 0.5, 20.5], [0.5, 20.5, 10.5], [0.5, 10.5, 21.5]]))
    assert kept.tolist() == [True, False, False, False]


def test_sphere_includes_its_surface_and_measures_from_its_centre():
    sphere = CropSphere((1, 2, 3), 2)
    kept = sphere.keeps(values([[3, 2, 3], [1, 2, 5.0001], [1, 0.5, 3], [-1, 2, 3], [-1.01, 2, 3]]))
    assert kept.tolist() == [True, False, True, True, False]


def test_opacity_and_scale_thresholds_include_their_value():
    v = values(np.zeros((4, 3)), opacities=[0.1, 0.5, 0.50001, 0.9], largest=[0.01, 0.2, 0.20001, 3])
    assert MinOpacity(0.5).keeps(v).tolist() == [False, True, True, True]
    assert MaxScale(0.2).keeps(v).tolist() == [True, True, False, False]


def test_rules_apply_in_turn_and_count_what_each_removed():
    v = values([[0, 0, 0], [5, 0, 0], [0, 0, 0], [0, 0, 0]], opacities=[1, 1, 0.1, 1], largest=[1, 1, 1, 9])
    kept, removed = apply_rules(v, [CropBox((-1, -1, -1), (1, 1, 1)), MinOpacity(0.5), MaxScale(2)])
    assert kept.tolist() == [True, False, False, False]
    assert [(r.rule, r.count) for r in removed] == [("crop box -1,-1,-1,1,1,1", 1), ("min opacity 0.5", 1),
                                                    ("max scale 2", 1)]


def test_a_fused_3d_filter_takes_the_files_sizes(tmp_path):
    from testkit import make_scene
    scene = make_scene(np.zeros((2, 3)), np.array([[0.1, 0.2, 0.3], [1, 1, 1]]))
    log_scales = np.log(np.array([[0.05, 0.1, 0.2], [0.5, 0.5, 0.5]], np.float32))
    assert KeepValues.of_scene(scene).largest_scales.tolist() == pytest.approx([0.3, 1])
    assert KeepValues.of_scene(scene, log_scales).largest_scales.tolist() == pytest.approx([0.2, 0.5])


@pytest.mark.parametrize("make, words", [
    (lambda: CropBox((1, 0, 0), (0, 1, 1)), "X0 = 1 is greater than X1 = 0"),
    (lambda: CropBox((0, 0), (1, 1, 1)), "expected 3 finite numbers"),
    (lambda: CropSphere((0, 0, 0), -0.5), "R = -0.5"),
    (lambda: MinOpacity(1.01), "outside 0..1"),
    (lambda: MaxScale(-1), "not a finite number > 0"),
])
def test_out_of_range_rules_are_refused(make, words):
    with pytest.raises(ValueError, match=words):
        make()
