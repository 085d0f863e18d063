"""The GL renderer against the float64 reference, with negative controls showing that
each comparison would catch the fault it names."""

import threading

import numpy as np
import pytest
from testkit import (
    shared_scene,
    SHARED_SCENES,
    assert_differs,
    assert_matches,
    make_scene,
    random_scene,
)

from raygs_viewer.camera.pinhole import Camera, frame_points, look_at
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.geometry import GeometryOutputs
from raygs_viewer.render.gl.per_pixel import PerPixelOrder
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.shaders import Programs
from raygs_viewer.render.gl.storage import SceneBuffers
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter


def _quaternion_z_to(normal):
    """Unit quaternion (w, x, y, z) rotating e_z onto ``normal``."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    half = np.array([0.0, 0.0, 1.0]) + normal
    half /= np.linalg.norm(half)
    axis = np.cross([0.0, 0.0, 1.0], half)
    return np.array([np.dot([0.0, 0.0, 1.0], half), *axis])


CAMERAS = {
    "front": look_at([0.3, -0.2, -3.0], [0, 0, 0], width=96, height=72),
    "above": look_at([0.0, -3.0, -0.5], [0, 0, 0], width=80, height=80, fov_y_degrees=50),
    "inside": look_at([0.1, 0.05, -0.6], [0.2, 0.0, 1.0], width=64, height=48, fov_y_degrees=90),
    # Odd size, fx != fy and an off-centre principal point: any half-pixel or axis
    # slip in the projection moves every edge.
    "offaxis": Camera(97, 61, 70.0, 55.0, 40.3, 35.7, look_at([1.0, 0.5, -2.5], [0, 0, 0]).R,
                      look_at([1.0, 0.5, -2.5], [0, 0, 0]).t),
}


@pytest.mark.parametrize("view", sorted(CAMERAS))
def test_gl_matches_reference(gl_render, view):
    scene = random_scene(n=400, seed=1)
    camera = CAMERAS[view]
    reference = render_reference(scene, camera)
    assert reference[..., 3].max() > 0.5  # the view shows something
    assert_matches(gl_render(scene, camera), reference)


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_every_sh_degree(gl_render, degree):
    scene = random_scene(n=200, seed=degree + 10, degree=degree)
    camera = CAMERAS["offaxis"]
    assert_matches(gl_render(scene, camera), render_reference(scene, camera))


def test_negative_controls_for_axes_and_order(gl_render):
    """A mirrored image, a reversed sort or another p_min in the GL path would fail."""
    scene = random_scene(n=400, seed=1)
    camera = CAMERAS["front"]
    image = gl_render(scene, camera)
    reference = render_reference(scene, camera)
    assert_matches(image, reference)
    assert_differs(image[:, ::-1], reference)          # x axis flipped
    assert_differs(image[::-1], reference)             # y axis flipped
    order = exact_order(DepthSorter(scene), camera, RenderSettings())
    assert_differs(gl_render(scene, camera, order=order.indices[::-1]), reference)  # front to back
    assert_differs(gl_render(scene, camera, RenderSettings(p_min=0.5 / 255)), reference)
    assert_differs(gl_render(scene, camera, RenderSettings(p_min=2 / 255)), reference)


@pytest.mark.parametrize("p_min", [1e-4, 1 / 255, 0.05, 0.3])
def test_p_min(gl_render, p_min):
    scene = random_scene(n=300, seed=3)
    camera = CAMERAS["front"]
    settings = RenderSettings(p_min=p_min)
    # A pixel whose opacity is within rounding of p_min may flip by one fragment of p_min.
    assert_matches(gl_render(scene, camera, settings), render_reference(scene, camera, settings),
                   max_error=max(2e-3, 2 * p_min))


def _near_plane_scene():
    """A pancake whose plane passes 5 mm from the camera (closer than GL's near plane at
    10 mm) and a needle straddling the camera plane: their quads cross z = near on screen."""
    normal = np.array([0.0, 0.9, 0.436])
    normal /= np.linalg.norm(normal)
    center = np.array([0.05, -0.15, 0.31])
    center -= (normal @ center - 0.005) * normal
    needle = _quaternion_z_to([0.05, 0.02, 1.0])
    return make_scene(
        positions=[center, [0.12, 0.06, -0.2]],
        scales=[[0.5, 0.5, 0.001], [0.01, 0.01, 1.0]],
        rotations=[_quaternion_z_to(normal), needle],
        opacities=[0.9, 1.0],
        colors=[[0.9, 0.5, 0.2], [0.2, 0.7, 1.0]],
    )


def test_near_plane_has_no_seam(gl_render):
    scene = _near_plane_scene()
    camera = Camera(96, 72, 60.0, 60.0, 48.0, 36.0, np.eye(3), np.zeros(3))
    reference = render_reference(scene, camera)
    assert (reference[..., 3] > 0.1).mean() > 0.3, "the test scene must cover the view"
    assert_matches(gl_render(scene, camera), reference)
    # Without depth clamp the near plane cuts the quads: a visible seam.
    assert_differs(gl_render(scene, camera, depth_clamp=False), reference)


def test_gaussian_behind_the_camera_is_not_mirrored_in_front(gl_render):
    """Peaks behind the camera (tau < 0) are not seen, although D is symmetric in x."""
    scene = make_scene(positions=[[0.0, 0.0, -1.0]], scales=[0.3, 0.3, 0.3], opacities=1.0)
    camera = Camera(64, 48, 50.0, 50.0, 32.0, 24.0, np.eye(3), np.zeros(3))
    reference = render_reference(scene, camera, order=np.array([0]))
    assert reference[..., 3].max() == 0
    assert gl_render(scene, camera, order=np.array([0], np.uint32))[..., 3].max() == 0


def test_storage_blocks_split_by_an_artificial_limit(gl_render):
    """A 4 KiB per-block limit cuts 300 gaussians into 5 splat blocks and 19 compute
    chunks; the picture must not change by a bit."""
    scene = random_scene(n=300, seed=4)
    camera = CAMERAS["front"]
    whole = gl_render(scene, camera)
    split = gl_render(scene, camera, block_limit=4096)
    np.testing.assert_array_equal(split, whole)
    assert_matches(split, render_reference(scene, camera))


def test_block_layout():
    from raygs_viewer.errors import UserError
    from raygs_viewer.render.gl.storage import StorageLayout
    layout = StorageLayout.plan(300, 16 * 12, 4096)
    assert (layout.splats_per_block, layout.chunk, layout.splat_blocks) == (64, 16, 5)
    big = StorageLayout.plan(2_000_000, 16 * 12, 1 << 27)
    assert big.splats_per_block * 64 <= 1 << 27 and big.chunk * 192 <= 1 << 27 and big.splat_blocks == 1
    huge = StorageLayout.plan(50_000_000, 3 * 12, (1 << 31) - 1)  # drivers reporting 2 GiB
    assert huge.chunk // 128 <= 65535 and huge.splats_per_block % huge.chunk == 0
    with pytest.raises(UserError):
        StorageLayout.plan(10, 16 * 12, 1024)


def test_background_and_alpha(gl_render):
    scene = random_scene(n=100, seed=5, spread=0.5)
    camera = CAMERAS["front"]
    settings = RenderSettings(background=(0.2, 0.4, 0.9))
    image = gl_render(scene, camera, settings)
    reference = render_reference(scene, camera, settings)
    assert_matches(image, reference)
    empty = reference[..., 3] == 0
    assert empty.any()
    np.testing.assert_allclose(image[empty][:, :3], np.broadcast_to([0.2, 0.4, 0.9], (empty.sum(), 3)), atol=1e-6)


def test_empty_scene_renders_background(gl_render):
    scene = make_scene(np.zeros((0, 3)), np.zeros((0, 3)))
    camera = CAMERAS["front"]
    image = gl_render(scene, camera, RenderSettings(background=(1.0, 0.5, 0.0)))
    np.testing.assert_array_equal(image[..., :3], np.broadcast_to(np.float32([1.0, 0.5, 0.0]), (72, 96, 3)))
    assert image[..., 3].max() == 0


def test_opacity_exactly_one_and_zero(gl_render):
    """Opacity 1 reaches alpha 1 at the peak; opacity 0 (logit -inf) draws nothing."""
    both = make_scene(positions=[[0, 0, 0], [0.2, 0, -0.5]], scales=[0.3, 0.2, 0.1], opacities=[1.0, 0.0])
    camera = look_at([0.0, 0.0, -3.0], [0, 0, 0], width=95, height=71)  # a pixel centre on the axis
    image = gl_render(both, camera)
    assert_matches(image, render_reference(both, camera))
    assert image[..., 3].max() == pytest.approx(1.0, abs=1e-6)
    alone = make_scene(positions=[[0, 0, 0]], scales=[0.3, 0.2, 0.1], opacities=[1.0])
    np.testing.assert_array_equal(image, gl_render(alone, camera))


def test_demo_scene_matches_reference(gl_render):
    from raygs_viewer.scene.demo import demo_camera, demo_scene
    scene = demo_scene()
    camera = demo_camera(160, 120)
    assert_matches(gl_render(scene, camera), render_reference(scene, camera))


def _shared_scene_names():
    if not SHARED_SCENES.is_dir():
        return ["(absent)"]
    return sorted(p.name for p in SHARED_SCENES.iterdir() if p.suffix in (".ply", ".splat"))


@pytest.mark.parametrize("name", _shared_scene_names())
@pytest.mark.parametrize("distance", ["framed", "close"])
def test_shared_scenes_match_reference(gl_render, name, distance):
    if not SHARED_SCENES.is_dir():
        pytest.skip(f"shared scenes folder {SHARED_SCENES} is absent")
    scene = shared_scene(name)
    camera = frame_points(scene.positions, 96, 72)
    if distance == "close":  # most of the way to the middle: large splats, some near the camera
        middle = np.median(scene.positions, axis=0).astype(np.float64)
        camera = look_at(camera.center + 0.7 * (middle - camera.center), middle, width=96, height=72)
    reference = render_reference(scene, camera)
    assert reference[..., 3].max() > 0.01, "the view must show the scene"
    assert_matches(gl_render(scene, camera), reference)


def test_osmesa_renders_the_same_image_as_egl(tmp_path):
    """The OSMesa fallback runs the whole RayGS pipeline (in its own process: OSMesa and
    EGL share Mesa's per-thread dispatch) and matches EGL bit for bit."""
    import os
    import subprocess
    import sys

    from raygs_viewer.render.gl.osmesa import find_osmesa_library
    if find_osmesa_library() is None:
        pytest.skip("libOSMesa not installed (apt-get install libosmesa6)")
    images = {}
    for backend in ("egl", "osmesa"):
        out = tmp_path / f"{backend}.npy"
        env = {k: v for k, v in os.environ.items() if k != "RAYGS_GL_BACKEND"}
        done = subprocess.run([sys.executable, "-m", "raygs_viewer", "render", "--width", "96",
                               "--gl-backend", backend, "--out", str(out)],
                              capture_output=True, text=True, env=env, timeout=120)
        assert done.returncode == 0, done.stderr
        images[backend] = np.load(out)
    assert images["egl"][..., 3].max() > 0.5
    np.testing.assert_array_equal(images["osmesa"], images["egl"])


def test_the_renderer_owns_no_sorter_and_its_release_leaves_the_caller_s_open(gl_ctx):
    """The sorter is the caller's: it outlives the renderer, and closing it (``with``)
    ends its thread pool."""
    scene = random_scene(50, seed=2)
    camera = frame_points(scene.positions, 64, 48)
    renderer = GLRenderer(gl_ctx, scene)
    assert not hasattr(renderer, "sorter")
    with DepthSorter(scene, workers=2, chunk_rows=8) as sorter:
        order = exact_order(sorter, camera, RenderSettings())
        renderer.render(camera, RenderSettings(), order)
        renderer.release()
        assert not sorter.closed and len(threads_of(sorter)) == 1
        np.testing.assert_array_equal(exact_order(sorter, camera, RenderSettings()).indices, order.indices)
    assert sorter.closed and threads_of(sorter) == []


def threads_of(sorter):
    return [t for t in threading.enumerate() if t.name.startswith(sorter.thread_prefix)]


def test_a_renderer_that_fails_half_made_releases_what_it_had_made_and_releases_once(gl_ctx, monkeypatch):
    """Its parts are released by one owner: a part that fails while the renderer is being
    made (here a forced order path that does not exist, refused after the scene's buffers
    are on the GPU) releases the parts made before it; release() releases each part once,
    however often it is called."""
    released = []

    def recorded(release):
        def recording(self):
            released.append(type(self))
            release(self)
        return recording

    for part in (SceneBuffers, Programs, PerPixelOrder, GeometryOutputs):
        monkeypatch.setattr(part, "release", recorded(part.release))
    scene = random_scene(50, seed=2)
    with pytest.raises(UserError, match="order path"):
        GLRenderer(gl_ctx, scene, order_path="sideways")
    assert released == [Programs, SceneBuffers]  # the last made first
    released.clear()
    renderer = GLRenderer(gl_ctx, scene)
    renderer.render(frame_points(scene.positions, 64, 48), RenderSettings(), np.arange(scene.count))
    renderer.release()
    renderer.release()
    assert released == [GeometryOutputs, PerPixelOrder, Programs, SceneBuffers]
