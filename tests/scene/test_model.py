"""Scene (raygs_viewer.scene.model): a scene's rows as a scene of their own."""

import numpy as np

from raygs_viewer.scene.demo import demo_scene

ARRAYS = ("positions", "rotations", "scales", "opacities", "sh")


def test_rows_keeps_the_rows_given_in_their_order_with_every_attribute():
    scene = demo_scene()
    picked = np.array([7, 3, 3900, 0])
    part = scene.rows(picked)
    for name in ARRAYS:
        assert np.array_equal(getattr(part, name), getattr(scene, name)[picked]), name
    assert (part.count, part.sh_degree, part.source, part.format, part.axes) == \
        (4, scene.sh_degree, scene.source, scene.format, scene.axes)
    mask = np.zeros(scene.count, bool)
    mask[[0, 3, 7]] = True
    assert np.array_equal(scene.rows(mask).positions, scene.positions[[0, 3, 7]])
    assert scene.rows(mask, "mine").format == "mine" and scene.rows(np.zeros(0, np.int64)).count == 0
