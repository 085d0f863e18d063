"""The built-in demo scene and its cameras (raygs_viewer.scene.demo)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.rotation import quaternion_to_matrix
from raygs_viewer.scene.demo import FLOOR_Y, build_demo_scene, demo_camera, demo_cameras, demo_scene
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.sh import sh_to_rgb

ARRAYS = ("positions", "rotations", "scales", "opacities", "sh")
P_MIN = 1 / 255


@pytest.fixture(scope="module")
def scene() -> Scene:
    return demo_scene()


def _camera_space(scene: Scene, camera: Camera) -> np.ndarray:
    return scene.positions.astype(np.float64) @ camera.R.T + camera.t


def _inside_image(scene: Scene, camera: Camera) -> np.ndarray:
    mu = _camera_space(scene, camera)
    z = mu[:, 2]
    front = z > 1e-6
    zs = np.where(front, z, 1.0)
    u = mu[:, 0] / zs * camera.fx + camera.cx
    v = mu[:, 1] / zs * camera.fy + camera.cy
    return front & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)


# --- determinism -----------------------------------------------------------------------

@pytest.mark.parametrize("make", [demo_scene, build_demo_scene], ids=["built once", "generated again"])
def test_two_calls_give_identical_arrays(scene, make):
    again = make()
    for name in ARRAYS:
        a, b = getattr(scene, name), getattr(again, name)
        assert a.dtype == b.dtype == np.float32
        assert np.array_equal(a, b), name
    assert again.sh_degree == scene.sh_degree == 3
    assert again.source == "demo"


def test_each_call_owns_its_arrays():
    first = demo_scene()
    first.positions[:] = 0
    first.sh[:] = 0
    first.dropped["by a caller"] = 1
    again = demo_scene()
    assert np.array_equal(again.positions, build_demo_scene().positions) and again.sh.any()
    assert "by a caller" not in again.dropped


# The generator's output is pinned: a change to any of these numbers means the demo
# scene changed, which must be a deliberate decision (update them in the same commit).
EXPECTED_COUNT = 3914
EXPECTED_SUMS = {  # name: (sum, sum of |x|), float64 sums of the float32 arrays
    "positions": (7908.249, 16198.465),
    "rotations": (2612.006, 6684.741),
    "scales": (892.875, 892.875),
    "opacities": (3093.162, 3093.162),
    "sh": (2606.065, 14423.097),
}
from testkit import DEMO_ARRAYS_SHA256


def test_stable_summary(scene):
    assert scene.count == EXPECTED_COUNT
    for name, (total, absolute) in EXPECTED_SUMS.items():
        a = getattr(scene, name).astype(np.float64)
        assert float(a.sum()) == pytest.approx(total, abs=2e-3), name
        assert float(np.abs(a).sum()) == pytest.approx(absolute, abs=2e-3), name


def test_stable_bytes(scene):
    """Bit-identical on every machine: the generator rounds in float64 before the cast."""
    digest = hashlib.sha256()
    for name in ARRAYS:
        digest.update(np.ascontiguousarray(getattr(scene, name)).tobytes())
    assert digest.hexdigest() == DEMO_ARRAYS_SHA256


# --- valid ranges ----------------------------------------------------------------------

def test_shapes_and_types(scene):
    n = scene.count
    assert 3000 <= n <= 6000
    assert scene.sh_degree == 3
    assert scene.positions.shape == (n, 3)
    assert scene.rotations.shape == (n, 4)
    assert scene.scales.shape == (n, 3)
    assert scene.opacities.shape == (n,)
    assert scene.sh.shape == (n, 16, 3)
    for name in ARRAYS:
        array = getattr(scene, name)
        assert array.dtype == np.float32
        assert np.all(np.isfinite(array)), name
    assert scene.dropped == {}
    assert not scene.filter_fused


def test_valid_ranges(scene):
    norms = np.linalg.norm(scene.rotations.astype(np.float64), axis=1)
    assert np.abs(norms - 1).max() < 1e-6
    assert np.all(scene.scales > 0)
    assert np.all((scene.opacities >= 0) & (scene.opacities <= 1))
    assert np.all(scene.opacities > P_MIN)  # nothing invisible by construction


def test_inside_a_ten_unit_box_above_the_floor(scene):
    p = scene.positions
    assert np.abs(p).max() <= 8.0
    extent = p.max(axis=0) - p.min(axis=0)
    assert np.all(extent <= 12.0)
    # +y is down: everything is on or above the floor plane.
    assert p[:, 1].max() <= FLOOR_Y + 1e-3
    # The floor is there: many flat gaussians at y = FLOOR_Y.
    assert np.sum(np.abs(p[:, 1] - FLOOR_Y) < 1e-3) >= 500


def test_base_colours_are_sensible(scene):
    d = scene.positions.astype(np.float64) - demo_camera().center
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rgb = sh_to_rgb(scene.sh.astype(np.float64), scene.sh_degree, d)
    assert np.all(np.isfinite(rgb))
    assert rgb.max() <= 1.5
    assert 0.2 < rgb.mean() < 0.8


# --- the features the demo is there to show ------------------------------------------

def test_needles(scene):
    s = np.sort(scene.scales.astype(np.float64), axis=1)
    assert np.sum(s[:, 2] >= 100 * s[:, 0]) >= 200
    # Truly needle-shaped (one long axis, the other two both tiny), not only flat.
    needle = s[:, 2] >= 50 * s[:, 1]
    assert needle.sum() >= 200
    assert np.sum(s[:, 2] >= 100 * s[:, 1]) >= 50


def test_pancakes(scene):
    s = np.sort(scene.scales.astype(np.float64), axis=1)
    pancake = (s[:, 0] * 50 <= s[:, 1]) & (s[:, 1] * 5 >= s[:, 2])
    assert pancake.sum() >= 200


def test_translucent_layers(scene):
    o = scene.opacities
    assert np.sum((o >= 0.2) & (o <= 0.6)) >= 0.1 * scene.count
    assert np.sum(o == 1.0) >= 5
    assert np.sum(o < 1.0) >= 0.3 * scene.count  # a mix, not all opaque


def test_translucent_sheets_overlap_in_depth(scene):
    """Semi-transparent flat gaussians of several distinct colours, stacked along the
    default view: their blending order matters."""
    cam = demo_camera()
    o = scene.opacities
    s = np.sort(scene.scales, axis=1)
    flat = (s[:, 0] * 50 <= s[:, 1]) & (o >= 0.2) & (o <= 0.6) & (s[:, 1] >= 0.04)
    rgb = sh_to_rgb(scene.sh[flat].astype(np.float64), 0, np.zeros((flat.sum(), 3)))
    colours = {tuple(np.round(c, 2)) for c in rgb}
    assert len(colours) >= 3
    z = _camera_space(scene, cam)[flat, 2]
    assert z.max() - z.min() >= 1.0


def test_view_dependent_colour(scene):
    higher = np.linalg.norm(scene.sh[:, 1:].astype(np.float64), axis=(1, 2))
    dc = np.linalg.norm(scene.sh[:, 0].astype(np.float64), axis=1)
    strong = higher > np.maximum(dc, 0.5)
    assert strong.sum() >= 100
    # Degrees 1, 2 and 3 all carry energy in that group.
    for band in (slice(1, 4), slice(4, 9), slice(9, 16)):
        energy = np.linalg.norm(scene.sh[strong, band].astype(np.float64), axis=(1, 2))
        assert np.median(energy) > 0.05
    # The colour actually changes with the viewpoint.
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(64, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    sh = scene.sh[strong].astype(np.float64)
    lo, hi = np.full((sh.shape[0], 3), np.inf), np.full((sh.shape[0], 3), -np.inf)
    for d in dirs:
        rgb = sh_to_rgb(sh, 3, np.tile(d, (sh.shape[0], 1)))
        lo, hi = np.minimum(lo, rgb), np.maximum(hi, rgb)
    spread = (hi - lo).max(axis=1)
    assert np.median(spread) >= 0.3


def test_gaussians_near_the_camera(scene):
    cam = demo_camera()
    mu = _camera_space(scene, cam)
    dist = np.linalg.norm(mu, axis=1)
    largest = scene.scales.astype(np.float64).max(axis=1)
    z = mu[:, 2]
    near = dist < 0.5
    in_front = near & (z > 0)
    straddling = near & (np.abs(z) <= largest)
    assert in_front.sum() >= 3
    assert straddling.sum() >= 2
    # The camera is outside their support (c^2 > kappa), so a RayGS renderer draws
    # them instead of skipping them as "camera inside".
    idx = np.flatnonzero(near)
    rot = cam.R[None] @ quaternion_to_matrix(scene.rotations[idx].astype(np.float64))
    w = np.einsum("nji,nj->ni", rot, mu[idx]) / scene.scales[idx].astype(np.float64)
    c2 = np.sum(w * w, axis=1)
    kappa = -2 * np.log(P_MIN / scene.opacities[idx].astype(np.float64))
    assert np.all(c2 > kappa)


# --- cameras ---------------------------------------------------------------------------

def test_demo_camera_sees_the_scene(scene):
    cam = demo_camera()
    assert (cam.width, cam.height) == (640, 480)
    assert _inside_image(scene, cam).mean() >= 0.8
    # World "up" is -y: the camera's down axis points along +y.
    assert cam.R[1, 1] > 0.9


def test_demo_camera_size():
    cam = demo_camera(320, 240)
    assert (cam.width, cam.height) == (320, 240)
    assert cam.cx == 160 and cam.cy == 120
    assert np.allclose(cam.center, demo_camera().center)


def test_demo_cameras(scene):
    cams = demo_cameras()
    assert 4 <= len(cams) <= 8
    assert np.allclose(cams[0].R, demo_camera().R) and np.allclose(cams[0].t, demo_camera().t)
    centres = np.array([c.center for c in cams])
    assert len({tuple(np.round(c, 3)) for c in centres}) == len(cams)
    for cam in cams:
        assert (cam.width, cam.height) == (640, 480)
        assert np.allclose(cam.R @ cam.R.T, np.eye(3))
        assert _inside_image(scene, cam).mean() >= 0.3
    # A grazing view: just above the floor, looking along it.
    grazing = [c for c in cams if 0 < FLOOR_Y - c.center[1] < 0.25 and abs(c.R[2, 1]) < 0.1]
    assert grazing
    # A close-up: half the centres it sees are within a few units.
    close = [c for c in cams
             if np.median(np.linalg.norm(scene.positions[_inside_image(scene, c)] - c.center, axis=1)) < 4.0]
    assert close
    assert all((c.width, c.height) == (320, 240) for c in demo_cameras(320, 240))


def test_shipped_demo_cameras_match_the_generator():
    """assets/demo_cameras.json is the demo's views, loadable with --camera."""
    from pathlib import Path

    from raygs_viewer.camera.pinhole import load_cameras
    shipped = load_cameras(Path(__file__).resolve().parents[2] / "assets" / "demo_cameras.json")
    generated = demo_cameras()
    assert len(shipped) == len(generated)
    for a, b in zip(shipped, generated):
        assert (a.width, a.height) == (b.width, b.height)
        np.testing.assert_allclose([a.fx, a.fy, a.cx, a.cy], [b.fx, b.fy, b.cx, b.cy], rtol=1e-12)
        np.testing.assert_allclose(a.R, b.R, atol=1e-9)
        np.testing.assert_allclose(a.center, b.center, atol=1e-9)

