"""The GL geometry outputs (render/gl/geometry.py) against the float64 reference's
(render_reference_channels): every output, in every mode, order and accuracy switch,
through both ways (the fragment lists, and the blend beside colour where no median is
asked for), on a generated scene and the shared real scenes; negative controls break
the shaders the way the issue names (a wrong z convention, an unflipped normal, a
median at the wrong crossing) and show the comparison fails."""

from dataclasses import replace

import numpy as np
import pytest
from testkit import (
    shared_scene,
    SHARED_SCENES,
    assert_channels_differ,
    assert_channels_match,
    make_scene,
    patched_glsl,
    random_scene,
    rendered,
    sorted_channels,
    sorted_render,
)

from raygs_viewer.camera.pinhole import frame_points, look_at
from raygs_viewer.camera.stereo import StereoRig, eye_cameras
from raygs_viewer.errors import UserError
from raygs_viewer.render.channel_pictures import ALPHA_THRESHOLD, ChannelView, channel_picture
from raygs_viewer.render.gl.geometry import takes_lists
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.reference import render_reference, render_reference_channels
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

CAMERA = look_at((0.4, -0.3, -3.2), (0.0, 0.0, 0.0), width=64, height=48)
SETTINGS = {
    "raygs": RenderSettings(),
    "distance order": RenderSettings(order="distance"),
    "mip, a background": RenderSettings(mip=True, background=(0.2, 0.3, 0.5)),
    "mip, no modulation": RenderSettings(mip=True, mip_modulation=False),
    "exact mip": RenderSettings(mode="raygs-exact-mip"),
    "gs": RenderSettings(mode="gs"),
    "gs compensation": RenderSettings(mode="gs", gs_compensation=True),
    "clamp and cut-off": RenderSettings(alpha_clamp=True, transmittance_cutoff=True),
    "supersample 2, a background": RenderSettings(supersample=2, background=(0.9, 0.1, 0.4)),
    "per-pixel": RenderSettings(order="per-pixel"),
    "per-pixel K=2": RenderSettings(order="per-pixel", order_k=2),
    "per-pixel exact mip, cut-off": RenderSettings(order="per-pixel", mode="raygs-exact-mip",
                                                   transmittance_cutoff=True),
}


@pytest.fixture(scope="module")
def scene():
    # Opaque enough that most covered pixels pass alpha 0.5 and the cut-off fires.
    base = random_scene(n=250, seed=5, log_scale=(-3.5, -1.2), anisotropy=2.0)
    opacities = np.random.default_rng(5).uniform(0.3, 1.0, base.count).astype(np.float32)
    return replace(base, opacities=opacities)


@pytest.fixture(scope="module")
def renderer(gl_session_ctx, scene):
    made = GLRenderer(gl_session_ctx, scene)
    yield made
    made.release()


@pytest.mark.parametrize("name", SETTINGS)
def test_every_output_matches_the_reference(renderer, scene, name):
    settings = SETTINGS[name]
    reference = render_reference_channels(scene, CAMERA, settings)
    assert (reference.median_depth > 0).mean() > 0.2, "the view must hold pixels with a median"
    assert_channels_match(sorted_channels(renderer, CAMERA, settings), reference)
    # Without the median, a global order without the cut-off blends beside colour instead.
    blended = sorted_channels(renderer, CAMERA, settings, median=False)
    assert blended.median_depth is None
    assert takes_lists(settings, median=False) == (settings.per_pixel or settings.transmittance_cutoff)
    assert_channels_match(blended, reference)


def test_the_cut_off_fires_in_the_scene(scene):
    # Without this the cut-off rows above would compare nothing the default rows do not.
    on, off = (render_reference(scene, CAMERA, RenderSettings(transmittance_cutoff=cut)) for cut in (True, False))
    assert np.abs(on - off).max() > 1e-3


def test_colour_and_alpha_agree_with_the_colour_render(renderer):
    for settings in (SETTINGS["raygs"], SETTINGS["per-pixel"], SETTINGS["gs"]):
        image = sorted_render(renderer, CAMERA, settings)
        channels = sorted_channels(renderer, CAMERA, settings)
        # The geometry pass composites front to back through the lists, colour alone blends
        # back to front: the same sums in another float32 order.
        np.testing.assert_allclose(channels.rgb, image[..., :3], atol=2e-6)
        np.testing.assert_allclose(channels.alpha, image[..., 3], atol=2e-6)


def test_stereo_eyes_match_the_reference(renderer, scene):
    rig = StereoRig(ipd=0.3, convergence=3.0, scene_scale=1.0)
    for eye in eye_cameras(CAMERA, rig):
        assert_channels_match(sorted_channels(renderer, eye, RenderSettings()),
                              render_reference_channels(scene, eye, RenderSettings()))


def test_view_pictures_show_the_channels(renderer, gl_session_ctx):
    """render_into draws a channel's picture and returns the depth range it used (the
    range given, or the one found in the image)."""
    with DepthSorter(renderer.scene) as sorter:
        order = exact_order(sorter, CAMERA, RenderSettings())
    target = FloatTarget(gl_session_ctx, CAMERA.width, CAMERA.height)
    try:
        for view in (ChannelView("depth"), ChannelView("median_depth", (2.0, 4.0)),
                     ChannelView("normal", normal_space="world"), ChannelView("alpha")):
            result = renderer.render_into(target, CAMERA, RenderSettings(), order, view=view)
            # The view asks for the median only where it shows it (the blend serves the rest).
            channels = renderer.render_channels(CAMERA, RenderSettings(), order, median=view.channel == "median_depth")
            expected, used = channel_picture(channels.in_space(view.normal_space, CAMERA), view)
            np.testing.assert_allclose(target.read()[..., :3], expected, atol=1e-6)
            assert result.view_range == used and result.order_stats is None
            assert (used is not None) == (view.channel in ("depth", "median_depth"))
            if view.depth_range is not None:
                assert used == view.depth_range
        result = renderer.render_into(target, CAMERA, RenderSettings(), order)
        assert result.view_range is None and result.order_stats is None
        np.testing.assert_array_equal(target.read(), renderer.render(CAMERA, RenderSettings(), order))
    finally:
        target.release()


# --- the pictures' alpha threshold ---------------------------------------------------------------

HALO_CAMERA = look_at((0.0, 0.0, -3.0), (0.0, 0.0, 0.0), width=48, height=36)


@pytest.fixture(scope="module")
def halo(gl_session_ctx):
    """An opaque gaussian at z = 3 behind a wide, faint one at z = 2 (alpha about 0.03,
    under the default threshold): haze the colour view barely shows."""
    scene = make_scene([(0.0, 0.0, 0.0), (0.0, 0.0, -1.0)], [(0.6, 0.6, 0.1), (2.0, 2.0, 0.05)],
                       opacities=[0.99, 0.03])
    made = GLRenderer(gl_session_ctx, scene)
    yield made
    made.release()


def gl_and_twin_pictures(renderer, view: ChannelView):
    """((GPU picture, its range), (CPU twin's picture, its range)) of ``view``."""
    with DepthSorter(renderer.scene) as sorter:
        order = exact_order(sorter, HALO_CAMERA, RenderSettings())
    image, result = rendered(renderer, HALO_CAMERA, RenderSettings(), order, view=view)
    channels = renderer.render_channels(HALO_CAMERA, RenderSettings(), order, median=view.channel == "median_depth")
    return (image[..., :3], result.view_range), channel_picture(channels.in_space(view.normal_space, HALO_CAMERA), view)


@pytest.mark.parametrize("channel", ["depth", "median_depth", "normal"])
@pytest.mark.parametrize("threshold", [0.0, ALPHA_THRESHOLD, 0.6])
def test_the_gpu_picture_masks_as_its_cpu_twin(halo, channel, threshold):
    (gpu, gpu_range), (cpu, cpu_range) = gl_and_twin_pictures(halo, ChannelView(channel, alpha_threshold=threshold))
    np.testing.assert_allclose(gpu, cpu, atol=1e-6)
    assert gpu_range == cpu_range


def test_the_mask_removes_the_haze_and_its_depths_from_the_range(halo):
    channels = sorted_channels(halo, HALO_CAMERA, RenderSettings())
    haze = (channels.alpha > 0) & (channels.alpha < ALPHA_THRESHOLD)
    core = channels.alpha > 0.5
    assert haze.mean() > 0.3 and core.mean() > 0.05  # both are in the view
    (off, off_range), _ = gl_and_twin_pictures(halo, ChannelView("depth", alpha_threshold=0.0))
    (on, on_range), _ = gl_and_twin_pictures(halo, ChannelView("depth"))
    assert off[haze].any(axis=-1).all()    # unmasked, the haze paints a depth
    assert not on[haze].any()              # masked, it shows none
    assert on[core].any(axis=-1).all()     # the object stays
    # The haze at z = 2 starts the unmasked range; masked, the object near z = 3 spans it
    # (from its fringe, whose expected depth the haze in front still pulls nearer).
    assert off_range[0] < 2.1 and on_range[0] > 2.4
    (normal, _), _ = gl_and_twin_pictures(halo, ChannelView("normal"))
    assert not normal[haze].any() and normal[core].any(axis=-1).all()


@pytest.mark.parametrize("fault", ["depth", "normal"])
def test_an_unmasked_gpu_picture_fails_the_comparison(monkeypatch, halo, fault):
    # Negative control: the GPU pass without its mask no longer matches the CPU twin.
    if fault == "depth":
        patched_glsl(monkeypatch, "channel_picture.frag", "alpha < u_alpha_threshold", "false")
    else:
        patched_glsl(monkeypatch, "channel_picture.frag", "alpha >= u_alpha_threshold", "true")
    renderer = GLRenderer(halo.ctx, halo.scene)
    try:
        (gpu, _), (cpu, _) = gl_and_twin_pictures(renderer, ChannelView(fault))
        assert np.abs(gpu - cpu).max() > 0.1
    finally:
        renderer.release()


# --- hard cases ---------------------------------------------------------------------------------

def test_hard_cases_stay_finite_and_match(gl_session_ctx):
    """A gaussian straddling the camera plane, needles, and depths from 1e-3 to 1e4 in one image."""
    camera = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width=48, height=32, fov_y_degrees=90.0)
    positions = [(0.0, 0.0, 0.004), (0.3, 0.1, 0.0), (-0.2, 0.05, 1.0), (0.0, -0.2, 2.0),
                 (0.5, 0.3, 1e4), (-0.5, -0.3, 3e3), (0.01, 0.01, 2e-3)]
    scales = [(0.05, 0.05, 0.02), (0.4, 0.4, 0.3), (1e-4, 1e-4, 0.6), (0.5, 1e-4, 1e-4),
              (3e3, 2e3, 1e3), (200.0, 300.0, 100.0), (1e-4, 2e-4, 1e-4)]
    rng = np.random.default_rng(0)
    rotations = rng.normal(size=(len(positions), 4))
    scene = make_scene(positions, scales, rotations=rotations / np.linalg.norm(rotations, axis=1, keepdims=True),
                       opacities=0.9)
    renderer = GLRenderer(gl_session_ctx, scene)
    try:
        for settings in (RenderSettings(), RenderSettings(order="per-pixel"), RenderSettings(mode="raygs-exact-mip"),
                         RenderSettings(mode="gs")):
            reference = render_reference_channels(scene, camera, settings)
            assert reference.alpha.max() > 0.5
            assert_channels_match(sorted_channels(renderer, camera, settings), reference)
    finally:
        renderer.release()


# --- negative controls ----------------------------------------------------------------------------

#: (shader, its text, the broken form, the settings, whether the median is asked for):
#: the lists' resolve in the order where each fault is least obvious, and the blend.
FAULTS = {
    "lists: z as the distance along the ray": (
        "lists_resolve.comp", "float z = uintBitsToFloat(entry.x) * g_ray.z;", "float z = uintBitsToFloat(entry.x);",
        RenderSettings(order="per-pixel"), True),
    "lists: an unflipped normal": (
        "lists_resolve.comp", "vec3 n = dot(s.normal.xyz, g_ray) > 0.0 ? -s.normal.xyz : s.normal.xyz;",
        "vec3 n = s.normal.xyz;", RenderSettings(), True),
    "lists: the median after the crossing": (
        "lists_resolve.comp", "state.a >= 0.5) g_median", "state.a - weight >= 0.5) g_median", RenderSettings(), True),
    "lists: the median at the last fragment past 0.5": (
        "lists_resolve.comp", "g_median.y == 0.0 && state.a >= 0.5", "state.a >= 0.5",
        RenderSettings(order="per-pixel"), True),
    "blend: z as the distance along the ray": (
        "raygs.frag", "t_star * ray.z, normal", "t_star, normal", RenderSettings(), False),
    "blend: an unflipped normal": (
        "raygs.frag", "dot(v_normal, ray) > 0.0 ? -v_normal : v_normal", "v_normal", RenderSettings(), False),
    "blend, GS: an unflipped normal": (
        "gs.frag", "dot(v_normal_depth.xyz, ray) > 0.0 ? -v_normal_depth.xyz : v_normal_depth.xyz",
        "v_normal_depth.xyz", RenderSettings(mode="gs"), False),
}


@pytest.mark.parametrize("fault", FAULTS)
def test_a_broken_output_fails_the_comparison(monkeypatch, gl_session_ctx, scene, fault):
    shader, old, new, settings, median = FAULTS[fault]
    reference = render_reference_channels(scene, CAMERA, settings)
    patched_glsl(monkeypatch, shader, old, new)
    renderer = GLRenderer(gl_session_ctx, scene)
    try:
        assert_channels_differ(sorted_channels(renderer, CAMERA, settings, median=median), reference)
    finally:
        renderer.release()


def test_forcing_the_k_buffer_with_geometry_is_a_clear_error(gl_session_ctx, scene):
    renderer = GLRenderer(gl_session_ctx, scene, order_path="fetch")
    try:
        with pytest.raises(UserError, match="geometry outputs need the fragment lists"):
            sorted_channels(renderer, CAMERA, RenderSettings(order="per-pixel", order_k=2))
    finally:
        renderer.release()


# --- the shared real scenes -------------------------------------------------------------------------

def _shared_scene_names():
    if not SHARED_SCENES.is_dir():
        return ["(absent)"]
    return sorted(p.name for p in SHARED_SCENES.iterdir() if p.suffix in (".ply", ".splat"))


#: Image sizes that show each scene at a bounded reference cost (default 48 x 36): the
#: three-gaussian scene needs more pixels to be seen, the 45k-gaussian one fewer to be quick.
SHARED_SIZES = {"metalsplatter-train3.ply": (64, 48)}


@pytest.mark.parametrize("name", _shared_scene_names())
def test_shared_scenes_match_the_reference(gl_session_ctx, name):
    if not SHARED_SCENES.is_dir():
        pytest.skip(f"shared scenes folder {SHARED_SCENES} is absent")
    scene = shared_scene(name)
    camera = frame_points(scene.positions, *SHARED_SIZES.get(name, (48, 36)))
    renderer = GLRenderer(gl_session_ctx, scene)
    try:
        for settings in (RenderSettings(order=order) for order in ("depth", "per-pixel")):
            reference = render_reference_channels(scene, camera, settings)
            assert reference.alpha.max() > 0.01, "the view must show the scene"
            assert_channels_match(sorted_channels(renderer, camera, settings), reference)
    finally:
        renderer.release()
