"""The per-pixel order on the GL path (render/gl/per_pixel.py: fragment lists, exact and
bounded, and the k-buffer through framebuffer fetch) against the float64 per-pixel
reference, on scenes built to need per-ray order and on the shared real scenes; with
every option it composes with; negative controls (global orders, a reversed t*, a
dropped fragment); the pool cut into parts bit for bit; the statistics."""

from dataclasses import replace

import numpy as np
import pytest
from testkit import (
    shared_scene,
    patched_glsl,
    PER_RAY_TIE_ERROR,
    SHARED_SCENES,
    assert_differs,
    assert_matches,
    assert_matches_per_ray,
    make_scene,
    random_rotation,
    random_scene,
    rendered,
    sorted_render,
)

from raygs_viewer.camera.pinhole import frame_points, look_at
from raygs_viewer.camera.stereo import StereoRig, eye_cameras
from raygs_viewer.capture.screenshot import render_tiled
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.fragment_lists import plan_parts
from raygs_viewer.render.gl.kbuffer import max_window
from raygs_viewer.render.gl.per_pixel import storage_block_problem
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

EXACT = RenderSettings(order="per-pixel", background=(0.1, 0.2, 0.3))
CAMERA = look_at([0.3, -0.2, -3.0], [0, 0, 0], width=64, height=48, fov_y_degrees=40)


def _quaternion(rotation):
    """w-first unit quaternion of a proper rotation matrix."""
    m = rotation
    w = np.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = np.copysign(np.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return (w, x, y, z)


def needles(seed=0, n=16):
    """Long thin needles through one another at random angles."""
    rng = np.random.default_rng(seed)
    rotations = [_quaternion(random_rotation(rng)) for _ in range(n)]
    scales = np.column_stack([rng.uniform(0.6, 1.0, n), np.full(n, 0.05), np.full(n, 0.05)])
    return make_scene(rng.uniform(-0.3, 0.3, (n, 3)), scales, rotations=rotations,
                      opacities=rng.uniform(0.6, 0.95, n), colors=rng.uniform(0, 1, (n, 3)))


def sheets(seed=1, n=10):
    """Flat discs crossing one another."""
    rng = np.random.default_rng(seed)
    rotations = [_quaternion(random_rotation(rng)) for _ in range(n)]
    scales = np.column_stack([rng.uniform(0.4, 0.8, n), rng.uniform(0.4, 0.8, n), np.full(n, 0.01)])
    return make_scene(rng.uniform(-0.3, 0.3, (n, 3)), scales, rotations=rotations,
                      opacities=rng.uniform(0.5, 0.95, n), colors=rng.uniform(0, 1, (n, 3)))


def big_and_small():
    """A large flat gaussian tilted across the view and a small one through it: which is
    in front flips across the image, while both centres keep one global order."""
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(1.2), -np.sin(1.2)], [0.0, np.sin(1.2), np.cos(1.2)]])
    return make_scene([(0.0, 0.0, 0.0), (0.05, 0.0, 0.1)], [(1.5, 1.5, 0.02), (0.25, 0.25, 0.25)],
                      rotations=[_quaternion(tilt), (1, 0, 0, 0)], opacities=[0.9, 0.9],
                      colors=[(1.0, 0.1, 0.1), (0.1, 0.1, 1.0)])


SCENES = {"needles": needles, "sheets": sheets, "big and small": big_and_small}


@pytest.fixture(scope="module")
def renderers(gl_session_ctx):
    """renderer(scene name or Scene, **options), made once per (scene, options)."""
    made = {}

    def get(scene, **options):
        gl_session_ctx.__enter__()
        key = (scene if isinstance(scene, str) else id(scene), tuple(sorted(options.items())))
        if key not in made:
            made[key] = GLRenderer(gl_session_ctx, SCENES[scene]() if isinstance(scene, str) else scene, **options)
        return made[key]

    yield get
    for renderer in made.values():
        renderer.release()


@pytest.mark.parametrize("k", [0, 1, 4])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_lists_match_the_per_pixel_reference_where_global_orders_fail(renderers, name, k):
    renderer = renderers(name, order_path="lists")
    settings = replace(EXACT, order_k=k)
    reference = render_reference(renderer.scene, CAMERA, settings)
    assert reference[..., 3].max() > 0.5
    image, result = rendered(renderer, CAMERA, settings)
    assert_matches(image, reference)
    assert result.order_stats.path == "lists"
    if k == 0:  # the negative controls: either global order, drawn as today
        for order in ("depth", "distance"):  # even with the allowance for near-ties of t*
            image, result = rendered(renderer, CAMERA, replace(EXACT, order=order))
            assert_differs(image, reference, max_error=PER_RAY_TIE_ERROR)
            assert result.order_stats is None


@pytest.mark.parametrize("k", [1, 3, 4])
@pytest.mark.parametrize("path", ["lists", "fetch"])
def test_both_paths_match_the_window_reference(renderers, gl_session_ctx, path, k):
    if path == "fetch" and k > max_window(gl_session_ctx):
        pytest.skip("this GPU's colour attachments hold a smaller window")
    renderer = renderers("sheets", order_path=path)
    settings = replace(EXACT, order_k=k, transmittance_cutoff=k == 3)
    image, result = rendered(renderer, CAMERA, settings)
    assert result.order_stats.path == path
    assert_matches(image, render_reference(renderer.scene, CAMERA, settings))
    if k == 1:  # a window of one is not the exact order on these sheets
        assert_differs(image, render_reference(renderer.scene, CAMERA, EXACT))


def test_paths_agree_and_auto_takes_fetch_where_it_can(renderers, gl_session_ctx):
    settings = replace(EXACT, order_k=4)
    lists = sorted_render(renderers("needles", order_path="lists"), CAMERA, settings)
    auto = renderers("needles")
    fetched, result = rendered(auto, CAMERA, settings)
    can_fetch = "GL_EXT_shader_framebuffer_fetch" in gl_session_ctx.extensions
    assert result.order_stats.path == ("fetch" if can_fetch else "lists")
    np.testing.assert_array_equal(lists, fetched)  # the same arithmetic, in the same order
    assert rendered(auto, CAMERA, EXACT)[1].order_stats.path == "lists"  # the exact order always takes the lists


def test_forcing_fetch_where_it_cannot_run_is_a_one_line_error(renderers, gl_session_ctx):
    renderer = renderers("needles", order_path="fetch")
    for settings in (EXACT, replace(EXACT, order_k=max_window(gl_session_ctx) + 1)):
        assert renderer.supports(settings)
        with pytest.raises(UserError) as info:
            sorted_render(renderer, CAMERA, settings)
        assert "\n" not in str(info.value)
    with pytest.raises(UserError):
        GLRenderer(gl_session_ctx, SCENES["needles"](), order_path="sideways")


COMBINATIONS = {
    "MIP": RenderSettings(mip=True, mip_sigma2=0.5),
    "exact MIP": RenderSettings(mode="raygs-exact-mip", mip_sigma2=0.5),
    "2x2": RenderSettings(supersample=2),
    "alpha clamp": RenderSettings(alpha_clamp=True),
    "cut-off": RenderSettings(transmittance_cutoff=True),
    "clamp, cut-off, 2x2, MIP": RenderSettings(alpha_clamp=True, transmittance_cutoff=True, supersample=2, mip=True),
}


@pytest.mark.parametrize("k", [0, 4])
@pytest.mark.parametrize("name", sorted(COMBINATIONS))
def test_per_pixel_composes_with_every_option(renderers, name, k):
    """On opaque crossing sheets (where the clamp and the cut-off act) and thin needles
    (where the MIP filters act)."""
    settings = replace(COMBINATIONS[name], order="per-pixel", order_k=k, background=(0.1, 0.2, 0.3))
    for scene in ("sheets", "needles"):
        renderer = renderers(scene)
        assert_matches(sorted_render(renderer, CAMERA, settings), render_reference(renderer.scene, CAMERA, settings))


def test_stereo_eyes_and_tiles(renderers):
    renderer = renderers("needles", order_path="lists")
    for k in (0, 4):
        settings = replace(EXACT, order_k=k)
        for eye in eye_cameras(CAMERA, StereoRig()):
            assert_matches(sorted_render(renderer, eye, settings), render_reference(renderer.scene, eye, settings))
        whole = sorted_render(renderer, CAMERA, settings)
        with DepthSorter(renderer.scene) as sorter:
            tiled = render_tiled(renderer, sorter, exact_order(sorter, CAMERA, settings), CAMERA, settings, tile=20)
        np.testing.assert_allclose(tiled, whole, atol=2e-5)


def _lists_image(ctx, scene):
    """The exact per-pixel image of ``scene`` through the lists, with the shaders as patched."""
    renderer = GLRenderer(ctx, scene, order_path="lists")
    try:
        return sorted_render(renderer, CAMERA, EXACT)
    finally:
        renderer.release()


def test_a_reversed_t_star_fails(gl_session_ctx, monkeypatch):
    scene = needles()
    reference = render_reference(scene, CAMERA, EXACT)
    patched_glsl(monkeypatch, "raygs.frag", "v_color_opacity.a * exp(-0.5 * divergence), t_star)",
                  "v_color_opacity.a * exp(-0.5 * divergence), -t_star)")
    assert_differs(_lists_image(gl_session_ctx, scene), reference)


def test_a_dropped_fragment_is_reported_and_would_fail(gl_session_ctx, monkeypatch):
    scene = needles()
    reference = render_reference(scene, CAMERA, EXACT)
    # The fill pass loses each list's first fragment: the resolve's check reports it.
    patched_glsl(monkeypatch, "fragment_output.glsl", "if (!in_part(p)) return;",
                  "if (!in_part(p) || v_rank == 3u) return;")
    with pytest.raises(RuntimeError, match="left short"):
        _lists_image(gl_session_ctx, scene)
    # Without the check, the image would be wrong.
    patched_glsl(monkeypatch, "lists_resolve.comp", "if (cursors[i] != start + n) atomicAdd(status[1], 1u);",
                  "n = cursors[i] - start;")
    assert_differs(_lists_image(gl_session_ctx, scene), reference)


@pytest.mark.parametrize("k", [0, 2])
def test_a_tiny_pool_draws_in_parts_bit_for_bit(renderers, k):
    settings = replace(EXACT, order_k=k, transmittance_cutoff=True)
    whole = renderers("sheets", order_path="lists")
    one, result = rendered(whole, CAMERA, settings)
    assert result.order_stats.parts == 1
    most = result.order_stats.max_per_pixel
    # Smaller than a row's fragments: rows are cut into spans too.
    tiny = renderers("sheets", order_path="lists", pool_fragments=most + 3)
    parts, tiny_result = rendered(tiny, CAMERA, settings)
    stats = tiny_result.order_stats
    assert stats.parts > CAMERA.height and stats.pool_fragments == most + 3
    assert 0 < stats.pool_use <= 1 and stats.fragments == result.order_stats.fragments
    np.testing.assert_array_equal(parts, one)
    banded = renderers("sheets", order_path="lists", pool_fragments=result.order_stats.fragments // 5)
    banded_image, banded_result = rendered(banded, CAMERA, settings)
    np.testing.assert_array_equal(banded_image, one)
    assert 5 <= banded_result.order_stats.parts < CAMERA.height
    np.testing.assert_array_equal(sorted_render(banded, CAMERA, settings), one)  # render() draws the same


def test_a_pixel_over_the_pool_is_a_one_line_error(renderers):
    renderer = renderers("sheets", order_path="lists", pool_fragments=2)
    with pytest.raises(UserError, match="more than the per-pixel order's pool of 2") as info:
        sorted_render(renderer, CAMERA, EXACT)
    assert "\n" not in str(info.value)


def test_plan_parts():
    counts = {0: [1, 1], 1: [3, 2], 2: [0, 0], 3: [2, 2]}
    parts, bases = plan_parts(np.array([2, 5, 0, 4]), 2, 4, lambda y: np.array(counts[y]))
    assert [(p.x0, p.y0, p.x1, p.y1, p.fragments) for p in parts] == [
        (0, 0, 2, 1, 2), (0, 1, 1, 2, 3), (1, 1, 2, 2, 2), (0, 2, 2, 4, 4)]
    assert bases.tolist() == [0, 0, 0, 0]
    with pytest.raises(UserError, match=r"pixel \(0, 2\) has 3 fragments"):
        plan_parts(np.array([2, 5, 0, 4]), 2, 2, lambda y: np.array(counts[y]))


def test_order_stats_count_what_was_drawn(renderers):
    """Three wide, flat, nearly opaque gaussians fill the whole view: three fragments a
    pixel, on both paths."""
    scene = make_scene([(0, 0, 0), (0, 0, 0.5), (0, 0, 1.0)], [(50.0, 50.0, 0.01)], opacities=0.9)
    camera = look_at([0, 0, -3.0], [0, 0, 0], width=32, height=24, fov_y_degrees=30)
    for path, k in (("lists", 0), ("fetch", 2)):
        renderer = renderers(scene, order_path=path)
        stats = rendered(renderer, camera, replace(EXACT, order_k=k))[1].order_stats
        assert (stats.path, stats.width, stats.height) == (path, 32, 24)
        assert (stats.fragments, stats.max_per_pixel, stats.covered_pixels) == (3 * 32 * 24, 3, 32 * 24)
        assert stats.mean_per_covered_pixel == 3.0
        assert stats.parts == 1
        assert stats.pool_use == (stats.fragments / stats.pool_fragments if path == "lists" else 0.0)


def _shared_scene_names():
    if not SHARED_SCENES.is_dir():
        return ["(absent)"]
    return sorted(p.name for p in SHARED_SCENES.iterdir() if p.suffix in (".ply", ".splat"))


@pytest.mark.parametrize("name", _shared_scene_names())
def test_shared_scenes_match_the_per_pixel_reference(gl_render, name):
    if not SHARED_SCENES.is_dir():
        pytest.skip(f"shared scenes folder {SHARED_SCENES} is absent")
    scene = shared_scene(name)
    camera = frame_points(scene.positions, 64, 48)
    for k in (0, 4):
        settings = RenderSettings(order="per-pixel", order_k=k)
        reference = render_reference(scene, camera, settings)
        assert reference[..., 3].max() > 0.01, "the view must show the scene"
        assert_matches_per_ray(gl_render(scene, camera, settings), reference)


def test_random_scene_every_pixel_order(gl_render):
    scene = random_scene(n=300, seed=1, log_scale=(-4.0, -1.0), anisotropy=2.0)
    for settings in (EXACT, replace(EXACT, order_k=2)):
        assert_matches_per_ray(gl_render(scene, CAMERA, settings), render_reference(scene, CAMERA, settings))


class _Limits:
    """A context whose GL limits are ``info`` (only what the check reads)."""

    def __init__(self, **info):
        self.info = info
        self.extensions = set()


def test_a_gpu_with_too_few_storage_blocks_is_told_why_in_one_line():
    roomy = _Limits(GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS=16, GL_MAX_COMBINED_SHADER_STORAGE_BLOCKS=80,
                    GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS=16)
    assert storage_block_problem(roomy, "lists", 8) is None and storage_block_problem(roomy, "fetch", 8) is None
    # OpenGL 4.3's minimum: 8 per stage and 8 in all.
    minimum = _Limits()
    assert storage_block_problem(minimum, "lists", 1) is None  # 1 + 1 + 6 blocks in all, 7 in the resolve
    problem = storage_block_problem(minimum, "lists", 2)
    assert "needs 9 storage blocks where this GPU offers 8" in problem and "\n" not in problem
    assert storage_block_problem(minimum, "fetch", 3) is None
    assert "COMPUTE" in storage_block_problem(replace_info(roomy, GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS=13), "lists", 8)


def replace_info(limits, **info):
    return _Limits(**{**limits.info, **info})
