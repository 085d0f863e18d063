"""Scenes made for the editing tests: INRIA PLY rows with every kind of column (SH degree
3, extra properties, a 3D filter, invalid rows), written with plyfile, and the rows the
documented filter rules keep, computed from the file's columns alone; and the window
driver's gestures of the edit tool (a drag, a chord, waiting for a weighing)."""

from __future__ import annotations

import numpy as np
from appkit import click_choice
from plyfile import PlyData, PlyElement

EXTRAS = [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"), ("label", "u1"), ("weight", "<f8")]


def rich_rows(n=400, seed=3, filter_3d=True, invalid=(5, 77)):
    """PLY vertex rows of SH degree 3 with extra properties, a 3D filter where asked, and
    the rows ``invalid`` holding a NaN (the reader drops them)."""
    rng = np.random.default_rng(seed)
    names = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", *[f"f_rest_{i}" for i in range(45)], "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    dtype = [(name, "<f4") for name in names] + ([("filter_3D", "<f4")] if filter_3d else []) + EXTRAS
    rows = np.zeros(n, dtype=dtype)
    for name in "xyz":
        rows[name] = rng.uniform(-2, 2, n)
    for name in names[3:51]:
        rows[name] = rng.normal(0, 0.5, n)
    rows["opacity"] = rng.normal(0, 3, n)
    for a in range(3):
        rows[f"scale_{a}"] = rng.uniform(-6, 0.5, n)
    for a in range(4):
        rows[f"rot_{a}"] = rng.normal(size=n)
    if filter_3d:
        rows["filter_3D"] = rng.uniform(0, 0.05, n)
    rows["nx"], rows["label"], rows["weight"] = rng.normal(size=n), rng.integers(0, 256, n), rng.normal(size=n)
    for row in invalid:
        rows["x"][row] = np.nan
    return rows


def write_rows(path, rows):
    PlyData([PlyElement.describe(rows, "vertex")], text=False, byte_order="<",
            comments=["made for a test"]).write(str(path))
    return path


def numpy_truth(rows, low=None, high=None, centre=None, radius=None, min_opacity=None, max_scale=None):
    """The kept rows by the documented rules, computed from the file's columns alone."""
    xyz = np.stack([rows["x"], rows["y"], rows["z"]], axis=1)
    keep = ~np.isnan(rows["x"])
    if low is not None:
        keep &= np.all((xyz >= np.float32(low)) & (xyz <= np.float32(high)), axis=1)
    if centre is not None:
        keep &= np.sum((xyz.astype(np.float64) - centre) ** 2, axis=1) <= radius ** 2
    log_scales = np.stack([rows[f"scale_{a}"] for a in range(3)], axis=1).astype(np.float64)
    if min_opacity is not None:
        opacity = 1 / (1 + np.exp(-rows["opacity"].astype(np.float64)))
        if "filter_3D" in rows.dtype.names:
            s2 = np.exp(2 * log_scales)
            opacity = opacity * np.sqrt(np.prod(s2 / (s2 + rows["filter_3D"].astype(np.float64)[:, None] ** 2), axis=1))
        keep &= opacity.astype(np.float32) >= np.float32(min_opacity)
    if max_scale is not None:
        keep &= np.exp(log_scales.max(axis=1)).astype(np.float32) <= np.float32(max_scale)
    return np.flatnonzero(keep)


# -- driving the window's edit tool (tests/appkit.py's driver) ---------------------------
def on_view(viewer, *fractions):
    """Screen points at these fractions of the view, whole (imgui's mouse positions are)."""
    x, y, w, h = viewer.viewport
    return [(float(round(x + fx * w)), float(round(y + fy * h))) for fx, fy in fractions]


def drag(drive, points, modifier=None):
    """A left drag through ``points`` (screen), one frame a point, ``modifier`` held."""
    if modifier is not None:
        drive.key(modifier, True)
    drive.move_mouse(*points[0])
    drive.frames(1)
    drive.button(0, True)
    drive.frames(1)
    for point in points[1:]:
        drive.move_mouse(*point)
        drive.frames(1)
    drive.button(0, False)
    drive.frames(1)
    if modifier is not None:
        drive.key(modifier, False)
        drive.frames(1)


def weighed(drive, viewer, most=200):
    """Frames until the selection of what the view shows is weighed (a slice a frame)."""
    for _ in range(most):
        if viewer.edit_tool.weighing is None:
            return
        drive.frames(1)
    raise AssertionError(f"still weighing after {most} frames")


def chord(drive, *keys):
    for key in keys:
        drive.key(key, True)
    drive.frames(1)
    for key in reversed(keys):
        drive.key(key, False)
    drive.frames(1)


def rectangle_tool(drive):
    """The Edit section opened and its rectangle tool chosen, through the panel."""
    drive.frames(2)
    drive.reveal("Edit")
    drive.click("Edit")
    drive.frames(1)
    drive.reveal("tool##edit")
    click_choice(drive, "tool##edit", "rectangle")
