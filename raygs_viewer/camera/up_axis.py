"""Which way is up for a scene, from its training cameras (the window's start up axis,
unless ``--up-axis`` names one: ``viewer.view_control.start_up``)."""

from __future__ import annotations

import math

import numpy as np

from raygs_viewer.camera.navigation import UP_AXES


def cameras_up(cameras) -> str | None:
    """The :data:`UP_AXES` name nearest the mean "up" of ``cameras`` (Camera objects in
    OpenCV axes, whose up is -(image down) = -R[1] in world space), as SIBR and
    nerfstudio take up from the training cameras; None without cameras or where their
    up vectors cancel out (no axis is nearer than another by a clear margin).

    Snapped to an axis, not kept as a vector: the navigator, the panel's combo, the
    framing's default direction and the screenshots' sidecars all take an axis name,
    and a capture's cameras are mostly level about one of them anyway.
    """
    ups = [-np.asarray(camera.R, np.float64)[1] for camera in cameras]
    if not ups:
        return None
    mean = np.mean(ups, axis=0)
    length = float(np.linalg.norm(mean))
    if not math.isfinite(length) or length < 1e-6:
        return None
    names = list(UP_AXES)
    closeness = [float(np.dot(mean / length, UP_AXES[name])) for name in names]
    best = int(np.argmax(closeness))
    # Two axes equally near (a mean half-way between them) is no answer either.
    if sorted(closeness)[-2] > closeness[best] - 1e-6:
        return None
    return names[best]
