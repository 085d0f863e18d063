"""The work the renderer saves, and that saving it changes no pixel: specialised shader
variants against the general one (and the float64 reference), colours computed at
load, the skipped preprocessing pass and order upload, the window's hot path (no
redundant passes, no GL objects made per frame), the reused sorter's scratch arrays
under threads, and ``--general`` on the command line.

Every equality here is exact or near it: a stale record, an unset uniform or a
skipped upload that should have run shows up as a visible difference, and each test
also checks that the change it makes does move the image or the records, so an
equality cannot pass by the change doing nothing."""

from __future__ import annotations

import dataclasses
import functools
import threading

import moderngl
import numpy as np
import pytest
from testkit import assert_matches, random_scene, sorted_render

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.camera.stereo import StereoRig, eye_cameras
from raygs_viewer.capture.screenshot import tile_camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.renderer import GL_EXT_FRAMEBUFFER_FETCH, GLRenderer
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.sh import C0 as SH_C0
from raygs_viewer.sort.cull import Cull
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.keys import key_values, sort_back_to_front
from raygs_viewer.sort.request import Order, SortRequest

S = RenderSettings
FRONT = look_at([0.3, -0.2, -3.0], [0, 0, 0], width=80, height=60)
INSIDE = look_at([0.1, 0.05, -0.6], [0.2, 0.0, 1.0], width=64, height=48, fov_y_degrees=90)
# Measured: the general and the specialised variants differ by at most 2.4e-7 on
# these scenes and views (float32 rounding of reordered arithmetic); 8x that.
GENERAL_TOLERANCE = 2e-6


def _scene(degree: int, n: int = 300, seed: int = 1) -> Scene:
    """Small, thin and large gaussians with SH of ``degree``; a third of them fully
    opaque, so that the alpha clamp changes the image."""
    scene = random_scene(n=n, seed=seed + degree, degree=degree, log_scale=(-6.0, -1.5), anisotropy=2.0)
    opacities = scene.opacities.copy()
    opacities[::3] = 1.0
    return dataclasses.replace(scene, opacities=opacities)


@functools.lru_cache(maxsize=None)
def scene_of(degree: int) -> Scene:
    return _scene(degree)


def render(ctx, scene, camera, settings=S(), order=None, *, frame=None, color_origin=None,
           **options) -> np.ndarray:
    """One image from a fresh renderer (``options``: GLRenderer's, e.g. general=True);
    ``order`` None: the exact order, sorted now."""
    ctx.__enter__()
    renderer = GLRenderer(ctx, scene, **options)
    try:
        if order is None:
            order = exact(scene, camera, settings)
        return renderer.render(camera, settings, order, frame=frame, color_origin=color_origin)
    finally:
        renderer.release()


def exact(scene, camera, settings=S(), **options) -> Order:
    """``camera``'s exact order for ``settings`` (``options``: exact_order's)."""
    with DepthSorter(scene) as sorter:
        return exact_order(sorter, camera, settings, **options)


@pytest.fixture
def make_renderer(gl_ctx):
    """make_renderer(scene, **options) -> a GLRenderer released after the test."""
    made = []

    def make(scene, **options):
        gl_ctx.__enter__()
        made.append(GLRenderer(gl_ctx, scene, **options))
        return made[-1]

    yield make
    gl_ctx.__enter__()
    for renderer in made:
        renderer.release()


def _needs_fetch(ctx, settings):
    if settings.transmittance_cutoff and GL_EXT_FRAMEBUFFER_FETCH not in ctx.extensions:
        pytest.skip(f"{GL_EXT_FRAMEBUFFER_FETCH} is not offered by this driver")


# ---------------------------------------------------------------------------- 1. variants
# name: (scene SH degree, settings, settings that differ only by the feature or None).
# The second must give a visibly different image, so a general variant that ignored
# the feature's uniform could not match the specialised one.
VARIANTS = {
    "SH 0 scene": (0, S(), None),
    "SH 1 scene": (1, S(), S(sh_degree=0)),
    "SH 3 scene": (3, S(), S(sh_degree=1)),
    "SH 1 scene, sh_degree 0": (1, S(sh_degree=0), S()),
    "SH 3 scene, sh_degree 0": (3, S(sh_degree=0), S()),
    "SH 3 scene, sh_degree 1": (3, S(sh_degree=1), S()),
    "MIP": (3, S(mip=True, mip_sigma2=0.5), S()),
    "MIP, no modulation": (3, S(mip=True, mip_sigma2=0.5, mip_modulation=False), S(mip=True, mip_sigma2=0.5)),
    "MIP 2x2, sh_degree 0": (3, S(mip=True, supersample=2, sh_degree=0), S(supersample=2, sh_degree=0)),
    "exact MIP": (3, S(mode="raygs-exact-mip", mip_sigma2=0.5), S()),
    "exact MIP, no modulation": (3, S(mode="raygs-exact-mip", mip_sigma2=0.5, mip_modulation=False),
                                 S(mode="raygs-exact-mip", mip_sigma2=0.5)),
    "GS": (3, S(mode="gs"), S()),
    "GS + compensation": (3, S(mode="gs", gs_compensation=True), S(mode="gs")),
    "GS ignores mip": (3, S(mode="gs", mip=True, mip_sigma2=0.5), None),
    "GS on an SH 0 scene": (0, S(mode="gs", gs_compensation=True), S(mode="gs")),
    "alpha clamp": (3, S(alpha_clamp=True), S()),
    "alpha clamp, cut-off": (3, S(alpha_clamp=True, transmittance_cutoff=True), S(transmittance_cutoff=True)),
    "2x2": (3, S(supersample=2), S()),
}


@pytest.mark.parametrize("camera", [FRONT, INSIDE], ids=["front", "inside"])
@pytest.mark.parametrize("name", list(VARIANTS))
def test_general_variant_draws_what_the_specialised_one_draws(gl_ctx, name, camera):
    degree, settings, without = VARIANTS[name]
    _needs_fetch(gl_ctx, settings)
    scene = scene_of(degree)
    specialised = render(gl_ctx, scene, camera, settings)
    general = render(gl_ctx, scene, camera, settings, general=True)
    assert np.all(np.isfinite(general))
    difference = float(np.abs(general - specialised).max())
    assert difference <= GENERAL_TOLERANCE, f"{name}: general vs specialised differ by {difference:.3g}"
    reference = render_reference(scene, camera, settings)
    assert reference[..., 3].max() > 0.5  # the view shows something
    assert_matches(specialised, reference)
    if without is not None:  # the feature shows: an ignored switch could not pass
        moved = float(np.abs(render(gl_ctx, scene, camera, without) - specialised).max())
        assert moved > 100 * GENERAL_TOLERANCE, f"{name}: the feature changes the image by only {moved:.3g}"


def test_gs_ignores_mip_like_the_specialised_variant(gl_ctx):
    """mip is a RayGS option: in GS mode both variants draw plain GS."""
    scene = scene_of(3)
    plain = render(gl_ctx, scene, FRONT, S(mode="gs"))
    for general in (False, True):
        image = render(gl_ctx, scene, FRONT, S(mode="gs", mip=True, mip_sigma2=0.5), general=general)
        assert np.abs(image - plain).max() <= GENERAL_TOLERANCE


def test_one_general_renderer_switches_features_between_frames(gl_ctx, make_renderer):
    """One general renderer (one variant per mode) drawing many settings in turn:
    every uniform is set for the frame it draws, none sticks from the frame before."""
    scene = scene_of(3)
    renderer = make_renderer(scene, general=True)
    sequence = [S(mip=True, mip_sigma2=0.5), S(), S(sh_degree=0), S(alpha_clamp=True), S(sh_degree=1),
                S(mip=True, mip_sigma2=0.5, mip_modulation=False), S(mode="gs", gs_compensation=True),
                S(mode="gs"), S(mode="raygs-exact-mip", mip_sigma2=0.5, mip_modulation=False), S()]
    for settings in sequence:
        image = sorted_render(renderer, FRONT, settings)
        expected = render(gl_ctx, scene, FRONT, settings)
        assert np.abs(image - expected).max() <= GENERAL_TOLERANCE, settings


# ------------------------------------------------------------------ 2. colours at load
GARBAGE_SEED = 99


def _spoil_harmonics(renderer: GLRenderer) -> None:
    """Overwrites the SH coefficients on the GPU with large random numbers."""
    size = renderer.storage.harmonics.size // 4
    garbage = np.random.default_rng(GARBAGE_SEED).normal(0.0, 5.0, size).astype(np.float32)
    renderer.storage.harmonics.write(garbage.tobytes())


@pytest.mark.parametrize("degree, settings, general, uses_harmonics", [
    (0, S(), False, False),
    (3, S(sh_degree=0), False, False),
    (0, S(mode="gs"), False, False),
    (0, S(mode="raygs-exact-mip"), False, False),
    (3, S(sh_degree=0, supersample=2, mip=True), False, False),
    (0, S(), True, True),
    (3, S(sh_degree=0), True, True),
    (3, S(sh_degree=1), False, True),
    (3, S(), False, True),
], ids=["sh0-scene", "sh0-override", "sh0-gs", "sh0-exact-mip", "sh0-mip-2x2", "general-sh0-scene",
        "general-sh0-override", "sh1-override", "sh3"])
def test_colours_at_load_replace_the_harmonics(gl_ctx, make_renderer, degree, settings, general, uses_harmonics):
    """Specialised SH-0 variants read the colours computed at load, never the SH
    buffer: spoiling it changes nothing. Variants that evaluate SH (the general one,
    degree >= 1) read it, and change."""
    scene = scene_of(degree)
    clean = render(gl_ctx, scene, FRONT, settings, general=general)
    renderer = make_renderer(scene, general=general)
    _spoil_harmonics(renderer)
    spoiled = sorted_render(renderer, FRONT, settings)
    if uses_harmonics:
        assert np.abs(spoiled - clean).max() > 0.05
    else:
        np.testing.assert_array_equal(spoiled, clean)


def test_colour_buffer_is_computed_once(gl_ctx, make_renderer, monkeypatch):
    scene = scene_of(3)
    renderer = make_renderer(scene)
    sorted_render(renderer, FRONT, S())
    assert renderer.storage.colors is None  # SH degree 3 evaluates SH: no colours needed
    sorted_render(renderer, FRONT, S(sh_degree=0))
    colors = renderer.storage.colors
    assert colors is not None
    expected = np.maximum(SH_C0 * scene.sh[:, 0, :].astype(np.float64) + 0.5, 0.0).astype(np.float32)
    stored = np.frombuffer(colors.read(), np.float32).reshape(-1, 4)  # RGB and a zero pad (16-byte records)
    np.testing.assert_array_equal(stored[:, :3], expected)
    assert not stored[:, 3].any()
    made = []
    original = moderngl.Context.buffer
    monkeypatch.setattr(moderngl.Context, "buffer", lambda self, *a, **k: made.append(k) or original(self, *a, **k))
    for camera, settings in ((INSIDE, S(sh_degree=0)), (FRONT, S()), (FRONT, S(sh_degree=0, mode="gs")),
                             (INSIDE, S(sh_degree=0, supersample=2))):
        sorted_render(renderer, camera, settings)
        assert renderer.storage.colors is colors
    assert made == []
    # The general variant never reads them.
    general = make_renderer(scene, general=True)
    sorted_render(general, FRONT, S(sh_degree=0))
    assert general.storage.colors is None


# -------------------------------------------------------------- 3. preprocess skipping
def preprocess(renderer, camera, settings, frame=None, color_origin=None) -> None:
    """The renderer's preprocessing pass for ``settings``' plan."""
    renderer.preprocess(camera, renderer.plan(settings), frame=frame, color_origin=color_origin)


def _records(gl_ctx, scene, camera, settings, frame=None, color_origin=None) -> np.ndarray:
    """The splat records a fresh renderer's preprocessing pass writes."""
    gl_ctx.__enter__()
    renderer = GLRenderer(gl_ctx, scene)
    try:
        preprocess(renderer, camera, settings, frame, color_origin)
        return renderer.read_splats()
    finally:
        renderer.release()


def test_same_view_twice_preprocesses_once(make_renderer):
    renderer = make_renderer(scene_of(3))
    first = sorted_render(renderer, FRONT, S())
    second = sorted_render(renderer, FRONT, S())
    assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (1, 1)
    np.testing.assert_array_equal(first, second)
    # An equal camera made anew is the same view.
    again = Camera(FRONT.width, FRONT.height, FRONT.fx, FRONT.fy, FRONT.cx, FRONT.cy, FRONT.R.copy(), FRONT.t.copy())
    preprocess(renderer, again, S(), None, FRONT.center.copy())
    assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (1, 2)


TILE = tile_camera(FRONT, 24, 18, 24, 18)  # GS clamps rays to the whole frame's borders
CHANGES = {
    # name: (base (camera, settings, frame, colour origin), changed)
    "camera moved": ((FRONT, S(), None, None),
                     (dataclasses.replace(FRONT, t=FRONT.t + np.array([1e-3, 0.0, 0.0])), S(), None, None)),
    "camera turned": ((FRONT, S(), None, None), (look_at([0.3, -0.2, -3.0], [0.01, 0, 0], width=80, height=60),
                                                 S(), None, None)),
    "intrinsics (MIP)": ((FRONT, S(mip=True), None, None),
                         (dataclasses.replace(FRONT, fx=FRONT.fx * 1.5), S(mip=True), None, None)),
    "intrinsics (GS)": ((FRONT, S(mode="gs"), None, None),
                        (dataclasses.replace(FRONT, cx=FRONT.cx + 3.0), S(mode="gs"), None, None)),
    "sh_degree": ((FRONT, S(), None, None), (FRONT, S(sh_degree=1), None, None)),
    "sh_degree 0": ((FRONT, S(), None, None), (FRONT, S(sh_degree=0), None, None)),
    "mip": ((FRONT, S(), None, None), (FRONT, S(mip=True, mip_sigma2=0.5), None, None)),
    "mip_sigma2": ((FRONT, S(mip=True), None, None), (FRONT, S(mip=True, mip_sigma2=0.5), None, None)),
    "p_min": ((FRONT, S(), None, None), (FRONT, S(p_min=0.05), None, None)),
    "mode": ((FRONT, S(), None, None), (FRONT, S(mode="gs"), None, None)),
    "gs_compensation": ((FRONT, S(mode="gs"), None, None), (FRONT, S(mode="gs", gs_compensation=True), None, None)),
    "frame": ((TILE, S(mode="gs"), None, None), (TILE, S(mode="gs"), FRONT, None)),
    "colour origin": ((FRONT, S(), None, None), (FRONT, S(), None, FRONT.center + np.array([0.5, 0.0, 0.0]))),
}


#: Settings that only the draw or the picture sees, or that choose what is drawn: the
#: records stay the view's.
UNSEEN = {
    "background": S(background=(0.2, 0.4, 0.6)),
    "level-of-detail budget and distance": S(lod_budget=1000, lod_distance=2.0),
    "order": S(order="distance"),
    "per-pixel order": S(order="per-pixel", order_k=4),
}


@pytest.mark.parametrize("name", list(UNSEEN))
def test_what_the_pass_does_not_read_does_not_run_it_again(make_renderer, name):
    renderer = make_renderer(scene_of(3))
    preprocess(renderer, FRONT, S())
    before = renderer.read_splats()
    preprocess(renderer, FRONT, UNSEEN[name])
    assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (1, 1)
    np.testing.assert_array_equal(renderer.read_splats(), before)


def test_dragging_the_background_redraws_without_the_pass(make_renderer):
    renderer = make_renderer(scene_of(3))
    first = sorted_render(renderer, FRONT, S())
    grey = sorted_render(renderer, FRONT, S(background=(0.5, 0.5, 0.5)))
    assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (1, 1)
    assert not np.array_equal(first, grey)
    np.testing.assert_array_equal(grey, sorted_render(make_renderer(scene_of(3)), FRONT, S(background=(0.5,) * 3)))


@pytest.mark.parametrize("name", list(CHANGES))
def test_every_change_of_view_preprocesses_again(gl_ctx, make_renderer, name):
    base, changed = CHANGES[name]
    scene = scene_of(3)
    renderer = make_renderer(scene)
    preprocess(renderer, *base)
    before = renderer.read_splats()
    preprocess(renderer, *changed)
    assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (2, 0)
    after = renderer.read_splats()
    if after.shape == before.shape:
        assert not np.array_equal(after, before), "the change must change the records"
    np.testing.assert_array_equal(after, _records(gl_ctx, scene, *changed))
    # ... and back: the first view again is not the last one either.
    preprocess(renderer, *base)
    assert renderer.counters.preprocessed == 3
    np.testing.assert_array_equal(renderer.read_splats(), before)


def test_frame_reaches_the_image(gl_ctx, make_renderer):
    """A GS tile drawn with and without its whole frame, on one renderer: each image is
    a fresh renderer's."""
    scene, settings = scene_of(3), S(mode="gs")
    renderer = make_renderer(scene)
    order = exact(scene, TILE, settings)
    alone = renderer.render(TILE, settings, order)
    framed = renderer.render(TILE, settings, order, frame=FRONT)
    assert np.abs(alone - framed).max() > 1e-3
    np.testing.assert_array_equal(framed, render(gl_ctx, scene, TILE, settings, order, frame=FRONT))
    np.testing.assert_array_equal(renderer.render(TILE, settings, order), alone)
    assert renderer.counters.preprocessed == 3


@pytest.mark.parametrize("settings", [S(), S(mode="gs"), S(supersample=2, mip=True)], ids=["raygs", "gs", "mip-2x2"])
def test_alternating_stereo_eyes_are_never_stale(gl_ctx, make_renderer, settings):
    """Left, right, left, right on one renderer (the window's stereo frame): every
    image is a fresh renderer's image of that eye."""
    scene = scene_of(3)
    rig = StereoRig(ipd=0.3, scene_scale=1.0)
    eyes = eye_cameras(FRONT, rig)
    order = exact(scene, FRONT, settings, cull_cameras=eyes)
    fresh = [render(gl_ctx, scene, eye, settings, order, color_origin=FRONT.center) for eye in eyes]
    assert np.abs(fresh[0] - fresh[1]).max() > 0.05
    renderer = make_renderer(scene)
    for _ in range(2):
        for eye, expected in zip(eyes, fresh):
            np.testing.assert_array_equal(renderer.render(eye, settings, order, color_origin=FRONT.center), expected)
    assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (4, 0)


class _FailingProgram:
    """A compute program whose ``run`` fails after ``runs`` chunks (a pass cut short)."""

    def __init__(self, program, runs: int):
        self.program, self.runs = program, runs

    def __getitem__(self, name):
        return self.program[name]

    def __contains__(self, name):
        return name in self.program

    def run(self, **groups):
        if self.runs == 0:
            raise RuntimeError("simulated failure in the middle of the pass")
        self.runs -= 1
        self.program.run(**groups)


def test_a_pass_cut_short_leaves_no_stale_records(gl_ctx, make_renderer, monkeypatch):
    """A pass that fails after writing some chunks: the records are neither the old
    view's nor the new one's, so the next frame of the old view preprocesses again."""
    scene = scene_of(3)
    renderer = make_renderer(scene, block_limit=4096)  # 19 chunks of 16 gaussians
    assert renderer.layout.chunk < scene.count // 4
    other = look_at([2.5, 0.5, 1.0], [0, 0, 0], width=80, height=60)
    image = sorted_render(renderer, FRONT, S())
    original = renderer.programs.compute
    monkeypatch.setattr(renderer.programs, "compute", lambda name, defines=None: _FailingProgram(
        original(name, defines), runs=3) if name == "preprocess.comp" else original(name, defines))
    with pytest.raises(RuntimeError, match="simulated"):
        preprocess(renderer, other, S())
    monkeypatch.undo()
    assert not np.array_equal(renderer.read_splats(), _records(gl_ctx, scene, FRONT, S()))  # partly overwritten
    np.testing.assert_array_equal(sorted_render(renderer, FRONT, S()), image)
    assert (renderer.counters.preprocessed, renderer.counters.preprocess_skipped) == (2, 0)


def test_a_pass_refused_with_user_error_leaves_the_renderer_usable(gl_ctx, make_renderer):
    """Exact MIP's larger records need more storage blocks than a 4 KiB limit allows:
    the pass is refused with a one-line UserError, and the next frame still draws
    the right image."""
    scene = scene_of(3)
    renderer = make_renderer(scene, block_limit=4096)
    image = sorted_render(renderer, FRONT, S())
    with pytest.raises(UserError, match="storage blocks") as info:
        sorted_render(renderer, FRONT, S(mode="raygs-exact-mip"))
    assert "\n" not in str(info.value)
    np.testing.assert_array_equal(sorted_render(renderer, FRONT, S()), image)
    other = look_at([2.5, 0.5, 1.0], [0, 0, 0], width=80, height=60)
    np.testing.assert_array_equal(sorted_render(renderer, other, S()),
                                  render(gl_ctx, scene, other, S(), block_limit=4096))


# ------------------------------------------------------------------ 4. upload skipping
def _uploaded(renderer: GLRenderer, size: int) -> np.ndarray:
    return np.frombuffer(renderer.storage.order.read(size=size * 4), np.uint32)


def test_same_order_array_is_uploaded_once(make_renderer):
    renderer = make_renderer(scene_of(3))
    order = exact(renderer.scene, FRONT)
    counters = renderer.counters
    renderer.upload_order(order)
    renderer.upload_order(order)
    assert (counters.uploads, counters.upload_skipped) == (1, 1)
    renderer.upload_order(order.with_indices(order.indices))  # another order of the very array: not again
    assert (counters.uploads, counters.upload_skipped) == (1, 2)
    equal = Order(order.indices.copy())  # equal content, another array: uploaded (identity is the contract)
    renderer.upload_order(equal)
    assert (counters.uploads, counters.upload_skipped) == (2, 2)
    renderer.upload_order(order)  # not the last one uploaded any more
    assert (counters.uploads, counters.upload_skipped) == (3, 2)
    renderer.render(FRONT, S(), order)  # draw() goes through upload_order
    renderer.render(FRONT, S(), order)
    assert (counters.uploads, counters.upload_skipped) == (3, 4)
    renderer.render(FRONT, S(), order.indices)  # the very array, given by hand
    assert (counters.uploads, counters.upload_skipped) == (3, 5)
    np.testing.assert_array_equal(_uploaded(renderer, order.count), order.indices)


def test_a_new_order_is_drawn(gl_ctx, make_renderer):
    """A then other orders on one renderer (same view: preprocessing skipped): each
    image is a fresh renderer's image of that order."""
    scene = scene_of(3)
    renderer = make_renderer(scene)
    order = exact(scene, FRONT).indices
    orders = [order, order[::-1].copy(), order[order.size // 2:].copy(), np.roll(order, 7), order]
    images = []
    for drawn in orders:
        images.append(renderer.render(FRONT, S(), drawn))
        np.testing.assert_array_equal(_uploaded(renderer, drawn.size), drawn)
        np.testing.assert_array_equal(images[-1], render(gl_ctx, scene, FRONT, S(), drawn))
    assert all(np.abs(a - b).max() > 1e-3 for a, b in zip(images, images[1:]))  # each change shows
    counters = renderer.counters
    assert (counters.preprocessed, counters.preprocess_skipped, counters.uploads) == (1, 4, 5)


# ------------------------------------------------------------------------- 5. window
CREATORS = [name for name in ("buffer", "texture", "texture3d", "texture_array", "texture_cube", "depth_texture",
                              "depth_texture_cube", "framebuffer", "simple_framebuffer", "empty_framebuffer",
                              "renderbuffer", "depth_renderbuffer", "program", "compute_shader", "vertex_array",
                              "simple_vertex_array", "query", "sampler", "scope", "detect_framebuffer")
            if hasattr(moderngl.Context, name)]


def _count_gl_objects(monkeypatch) -> list[str]:
    """Every moderngl.Context method that makes a GL object, counted: the names called."""
    made: list[str] = []
    for name in CREATORS:
        original = getattr(moderngl.Context, name)

        def counting(self, *args, name_=name, original_=original, **kwargs):
            made.append(name_)
            return original_(self, *args, **kwargs)
        monkeypatch.setattr(moderngl.Context, name, counting)
    return made


def _work(viewer) -> dict:
    return dataclasses.asdict(viewer.scene.renderer.counters)


def test_still_window_runs_no_passes(open_viewer):
    viewer, drive = open_viewer(hide_panel=True)
    drive.settle()
    work = _work(viewer)
    assert work["preprocessed"] >= 1 and work["uploads"] >= 1
    drive.frames(6)
    assert _work(viewer) == work


def test_new_order_for_the_drawn_view_uploads_without_preprocessing(open_viewer):
    from appkit import gated_viewer, window_image

    viewer, drive, gate = gated_viewer(open_viewer, hide_panel=True)
    drive.frames(1)
    assert gate.inside.wait(timeout=30)  # the first sort runs, held at the gate
    drive.frames(2)
    work = _work(viewer)
    assert viewer.scene.sorter.finished == 0 and viewer.stats.visible == 0
    assert work["preprocessed"] == 1 and work["uploads"] == 0  # the view drawn, with no order yet
    gate.release.set()
    result = viewer.scene.sorter.wait(viewer.scene.sorter.requested, timeout=30)
    assert result is not None
    drive.frames(1)
    assert viewer.stats.drawn_serial == result.serial and viewer.stats.order_age == 0
    after = _work(viewer)
    assert after["preprocessed"] == 1 and after["preprocess_skipped"] == work["preprocess_skipped"] + 1
    assert after["uploads"] == 1
    expected = render(viewer.ctx, viewer.loaded.scene, viewer.camera, viewer.settings, result.order)
    np.testing.assert_array_equal(window_image(viewer), expected)
    drive.frames(3)
    assert _work(viewer) == after


@pytest.mark.parametrize("view", ["mono", "stereo", "split"])
def test_turning_camera_makes_no_gl_objects_per_frame(open_viewer, monkeypatch, view):
    """Ten frames of a turning camera, each drawing a new view with a new order: the
    passes run every frame, and not one GL object is made."""
    from raygs_viewer.viewer.state import NavigationChoices
    options = {"navigation": NavigationChoices(turntable=3.0)}
    if view == "stereo":
        from raygs_viewer.camera.stereo import custom_preset
        from raygs_viewer.viewer.state import StereoPreview
        options.update(stereo=StereoPreview.of(custom_preset(96, 72, 90.0, 72.0), on=True), width=192, height=72)
    viewer, drive = open_viewer(**options)
    if view == "split":
        viewer.split.on = True
        assert viewer.right_settings() is not None
    for _ in range(4):  # warm-up: targets, shader variants, the first orders
        drive.frames(1)
        viewer.scene.sorter.wait(viewer.scene.sorter.requested, timeout=30)
    before = _work(viewer)
    made = _count_gl_objects(monkeypatch)
    for _ in range(10):
        drive.frames(1)
        viewer.scene.sorter.wait(viewer.scene.sorter.requested, timeout=30)  # a new order for the next frame
    monkeypatch.undo()
    after = _work(viewer)
    passes = {"mono": 1, "stereo": 2, "split": 2}[view]  # each pass draws the frame's one order
    assert after["preprocessed"] - before["preprocessed"] == 10 * passes
    assert after["uploads"] - before["uploads"] == 10
    assert after["upload_skipped"] - before["upload_skipped"] == 10 * (passes - 1)
    assert made == [], f"GL objects made per frame: {sorted(set(made))} ({len(made)} calls)"


def test_counting_sees_gl_objects_being_made(gl_ctx, monkeypatch):
    """The control for the test above: the counting catches what a frame would make."""
    made = _count_gl_objects(monkeypatch)
    buffer = gl_ctx.buffer(reserve=16)
    texture = gl_ctx.texture((2, 2), 4)
    fbo = gl_ctx.framebuffer(color_attachments=[texture])
    monkeypatch.undo()
    for obj in (fbo, texture, buffer):
        obj.release()
    assert made == ["buffer", "texture", "framebuffer"]


# ----------------------------------------------------------------------------- 6. sorter
SORT_SCENE = random_scene(n=20000, seed=7, degree=0, spread=2.0, log_scale=(-5.0, -1.0))
SORT_CAMERAS = [
    look_at([0.3, -0.2, -6.0], [0, 0, 0], width=96, height=72, fov_y_degrees=30),
    look_at([5.0, -1.0, 1.0], [0.5, 0, 0], width=64, height=64, fov_y_degrees=40),
    look_at([0.1, 0.05, -0.5], [0.2, 0.0, 1.0], width=80, height=48, fov_y_degrees=100),  # inside the cloud
    look_at([0.0, -7.0, 0.5], [0, 0, 0], width=72, height=96, fov_y_degrees=30),
]
# (camera index, p_min, dilation, cull cameras): changes of each kind, and repeats
SORT_CALLS = [
    (0, 1 / 255, 0.0, None), (1, 1 / 255, 0.0, None), (1, 0.2, 0.0, None), (1, 1 / 255, 0.0, None),
    (2, 0.05, 0.002, None), (2, 0.05, None, None), (3, 1 / 255, 0.01, None), (0, 0.2, 0.0, None),
    (0, 0.2, 0.0, "stereo"), (0, 1 / 255, 0.0, None), (3, 0.05, 0.0, "stereo"), (3, 0.05, 0.0, None),
    (2, 0.5, 0.0, None), (2, 1 / 255, 0.0, None),
]


def _request(index: int, p_min: float, dilation, stereo) -> SortRequest:
    """The request of SORT_CALLS' entry."""
    camera = SORT_CAMERAS[index]
    cull = eye_cameras(camera, StereoRig(ipd=1.0, scene_scale=1.0)) if stereo else None
    return SortRequest(camera, p_min, dilation, cull)


def _depth_sorted(request: SortRequest, visible: np.ndarray) -> np.ndarray:
    """(M,) uint32: ``visible`` back to front by their depth keys (the keys' own range)."""
    depths = key_values(SORT_SCENE.positions[visible], request.camera, "depth", Cull(SORT_SCENE).coordinate_scale)
    return visible[sort_back_to_front(depths)].astype(np.uint32)


def _call(sorter: DepthSorter, index: int, p_min: float, dilation, stereo, split: bool = False) -> np.ndarray:
    """The order of SORT_CALLS' entry; ``split``: cull, then sort the kept rows by their
    keys, as two steps."""
    request = _request(index, p_min, dilation, stereo)
    if split:
        return _depth_sorted(request, sorter.cull(request))
    return sorter.sort(request).order.indices


def test_cull_then_sort_is_order():
    sorter = DepthSorter(SORT_SCENE)
    for call in SORT_CALLS:
        request = _request(*call)
        visible = sorter.cull(request)
        assert visible.dtype == np.int64 and np.all(np.diff(visible) > 0)
        assert 0 < visible.size < SORT_SCENE.count
        order = _depth_sorted(request, visible)
        assert order.dtype == np.uint32
        np.testing.assert_array_equal(order, sorter.sort(request).order.indices)
        np.testing.assert_array_equal(np.sort(order), visible)


def test_reused_sorter_gives_what_a_fresh_one_gives():
    """Scratch arrays and the p_min cache carried from call to call never leak into
    the next result."""
    shared, shared_cull = DepthSorter(SORT_SCENE), Cull(SORT_SCENE)
    previous = None
    for call in SORT_CALLS:
        order = _call(shared, *call)
        np.testing.assert_array_equal(order, _call(DepthSorter(SORT_SCENE), *call), err_msg=str(call))
        np.testing.assert_array_equal(shared_cull.support(call[1]).radius, Cull(SORT_SCENE).support(call[1]).radius)
        if previous is not None:  # each step changes the answer: a stale one would show
            assert not np.array_equal(order, previous), call
        previous = order


def test_threads_sharing_a_sorter_each_get_their_own_answer():
    """The window's sort thread and a screenshot share one DepthSorter: two threads
    ordering different views at once, many times, always get their own view's order
    (the culling's scratch arrays are shared: without the lock they mix)."""
    sorter = DepthSorter(SORT_SCENE)
    calls = [(0, 1 / 255, 0.0, None), (2, 0.05, 0.002, "stereo")]
    expected = [_call(DepthSorter(SORT_SCENE), *call) for call in calls]
    assert not np.array_equal(*expected)
    start = threading.Barrier(2)
    wrong, errors, done = [0, 0], [], [0, 0]

    def worker(side: int) -> None:
        try:
            start.wait(timeout=30)
            for i in range(40):  # order, and cull + sort (each locks on its own)
                if not np.array_equal(_call(sorter, *calls[side], split=i % 2 == 1), expected[side]):
                    wrong[side] += 1
                done[side] += 1
        except Exception as exc:  # a race may also raise (shapes of a half-written result)
            errors.append(repr(exc))

    threads = [threading.Thread(target=worker, args=(side,)) for side in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=120)
    assert not any(thread.is_alive() for thread in threads)
    assert errors == [] and wrong == [0, 0] and done == [40, 40], (errors, wrong, done)


# -------------------------------------------------------------------------------- 7. CLI
@pytest.fixture
def made_renderers(monkeypatch):
    """The ``general`` flag of every GLRenderer made during the test, as made."""
    flags: list[bool] = []
    original = GLRenderer.__init__

    def recording(self, *args, **kwargs):
        original(self, *args, **kwargs)
        flags.append(self.general)
    monkeypatch.setattr(GLRenderer, "__init__", recording)
    return flags


def test_render_general_saves_the_same_image(capsys, tmp_path, made_renderers, restore_gl_ctx):
    from PIL import Image

    from raygs_viewer.cli.main import main

    images = {}
    for flag in ([], ["--general"]):
        for suffix in ("png", "npy"):
            out = tmp_path / f"demo{'-general' if flag else ''}.{suffix}"
            assert main(["render", "demo", "--width", "64", "--height", "48", *flag, "--out", str(out)]) == 0, \
                capsys.readouterr().err
            images[(bool(flag), suffix)] = np.asarray(Image.open(out)).astype(int) if suffix == "png" else np.load(out)
    assert made_renderers == [False, False, True, True]
    assert np.abs(images[(True, "png")] - images[(False, "png")]).max() <= 1
    assert images[(False, "png")].std() > 5  # shows something
    assert np.abs(images[(True, "npy")] - images[(False, "npy")]).max() <= GENERAL_TOLERANCE


def test_view_general_reports_general_shaders(capsys, made_renderers, restore_gl_ctx):
    from raygs_viewer.cli.main import main

    for flag in ([], ["--general"]):
        code = main(["view", *flag, "--frames", "3", "--window-platform", "null", "--width", "96", "--height", "72"])
        out, err = capsys.readouterr()
        assert code == 0, err
        assert "3 frames" in out
        assert ("general shaders" in out) == bool(flag), out
    assert made_renderers == [False, True]


def test_verify_accepts_general(capsys, made_renderers, restore_gl_ctx):
    from raygs_viewer.cli.main import main

    code = main(["verify", "--general", "--width", "32", "--repeat", "1", "--mode", "gs"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "max error" in out and "mode gs" in out
    assert made_renderers == [True]
