"""Blend precision (settings.PRECISIONS): float16 and 8-bit accumulate the blended colour
(and float16 the geometry outputs) in narrower pixels, within a stated error of the
float64 reference; float32 is today's image to the bit; the per-pixel order and the
transmittance cut-off composite in their own passes and keep float32."""

import json

import numpy as np
import pytest
from PIL import Image
from testkit import (
    assert_differs,
    assert_matches,
    demo_sidecar,
    random_scene,
    rendered,
    run_cli,
    sorted_channels,
)

from raygs_viewer.camera.pinhole import look_at
from raygs_viewer.render.gl.renderer import GLRenderer
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import ACCURACY_PRESETS, PRECISIONS, RenderSettings
from raygs_viewer.render.tolerance import BLENDS
from raygs_viewer.scene.demo import demo_scene
from raygs_viewer.scene.model import Scene

CAMERA = look_at([0.3, -0.2, -3.0], [0, 0, 0], width=80, height=60)
#: The largest and the mean error per channel against the float64 reference that each
#: blend precision may add, for colours within 0..1 (docs/accuracy-vs-time.md measures it
#: on real scenes): a float16 blend rounds every step to 11 significant bits (about 5e-4
#: at 1), an 8-bit one to 1/255; the steps' errors add up over the layers a pixel blends.
#: Measured on these scenes: float16 at most 5.5e-3 (mean 1.3e-3), 8-bit 2.0e-2 (mean 2.7e-3).
#: One home with doctor's rows: render.tolerance.BLENDS.
MAX_ERROR = {precision: bound.max_error for precision, bound in BLENDS.items()}
MEAN_ERROR = {precision: bound.mean for precision, bound in BLENDS.items()}


def in_range(scene: Scene) -> Scene:
    """``scene`` with colours within 0..1 from every side: 8 bits cannot hold more, and
    clamp each fragment's colour where float blends it as it is."""
    sh = scene.sh.copy()
    sh[:, 0] = np.clip(sh[:, 0], -0.45 / 0.28209479, 0.45 / 0.28209479)
    sh[:, 1:] *= 0.1
    return Scene(scene.positions, scene.rotations, scene.scales, scene.opacities, sh, scene.sh_degree)


SCENES = {
    "random": lambda: in_range(random_scene(n=400, seed=1)),
    "dense": lambda: in_range(random_scene(n=2000, seed=2, log_scale=(-3.0, -1.5))),
    "demo": demo_scene,
}


def _render(gl_ctx, scene, settings, camera=CAMERA):
    renderer = GLRenderer(gl_ctx, scene)
    try:
        return rendered(renderer, camera, settings)[0]
    finally:
        renderer.release()


@pytest.mark.parametrize("precision", ["float16", "8bit"])
@pytest.mark.parametrize("name", sorted(SCENES))
def test_narrow_blends_stay_within_their_stated_error(gl_ctx, name, precision):
    scene = SCENES[name]()
    reference = render_reference(scene, CAMERA)
    assert reference[..., 3].max() > 0.9
    image = _render(gl_ctx, scene, RenderSettings(precision=precision))
    error = np.abs(np.clip(image, 0, 1) - np.clip(reference, 0, 1))
    assert error.max() <= MAX_ERROR[precision] and error.mean() <= MEAN_ERROR[precision], (error.max(), error.mean())
    # The precision is applied: the float32 comparison's tolerances would catch the difference.
    assert_differs(image, reference)


@pytest.mark.parametrize("settings", [RenderSettings(), RenderSettings(mode="gs"), RenderSettings(supersample=2),
                                      RenderSettings(mode="raygs-exact-mip", background=(0.2, 0.3, 0.4))],
                         ids=["raygs", "gs", "2x2", "exact mip"])
def test_every_mode_blends_at_each_precision(gl_ctx, settings):
    scene = in_range(random_scene(n=300, seed=3))
    reference = render_reference(scene, CAMERA, settings)
    float32 = _render(gl_ctx, scene, settings)
    assert_matches(float32, reference)
    for precision in ("float16", "8bit"):
        image = _render(gl_ctx, scene, RenderSettings(**{**settings.__dict__, "precision": precision}))
        assert np.abs(np.clip(image, 0, 1) - np.clip(reference, 0, 1)).max() <= MAX_ERROR[precision]
        assert not np.array_equal(image, float32)


def test_8bit_blends_in_8_bits(gl_ctx):
    """Every blend step rounds to 1/255 and clamps to 0..1: one layer's colour is a
    multiple of 1/255, and a colour above 1 does not get through."""
    scene = in_range(random_scene(n=1, seed=4, log_scale=(-1.0, -1.0)))
    image = _render(gl_ctx, scene, RenderSettings(precision="8bit"))
    levels = image * 255
    np.testing.assert_allclose(levels, np.round(levels), atol=1e-3)


@pytest.mark.parametrize("settings", [RenderSettings(order="per-pixel"), RenderSettings(order="per-pixel", order_k=4),
                                      RenderSettings(transmittance_cutoff=True)],
                         ids=["per-pixel", "per-pixel K=4", "cut-off"])
def test_passes_that_composite_keep_float32(gl_ctx, settings):
    scene = random_scene(n=300, seed=5)
    renderer = GLRenderer(gl_ctx, scene)
    try:
        if renderer.supports(settings):
            pytest.skip("this GL cannot draw these settings")
        float32 = rendered(renderer, CAMERA, settings)[0]
        for precision in ("float16", "8bit"):
            narrow = RenderSettings(**{**settings.__dict__, "precision": precision})
            assert renderer.plan(narrow).precision == "float32"
            np.testing.assert_array_equal(rendered(renderer, CAMERA, narrow)[0], float32)
    finally:
        renderer.release()


def test_float32_is_today_s_image_and_plans_say_what_they_blend_in(gl_ctx):
    scene = random_scene(n=200, seed=6)
    renderer = GLRenderer(gl_ctx, scene)
    try:
        assert renderer.plan(RenderSettings()).target_dtypes(1) == ("f4",)
        assert renderer.plan(RenderSettings(precision="float16"), "geometry").target_dtypes(3) == ("f2",) * 3
        # 8 bits hold no signed, unbounded depth sums: the geometry outputs take float16.
        assert renderer.plan(RenderSettings(precision="8bit"), "geometry").target_dtypes(3) == ("f1", "f2", "f2")
    finally:
        renderer.release()


def test_geometry_outputs_stay_close(gl_ctx):
    """Depth and normal sums blend in float16 at both narrow precisions; at 8 bits they
    are divided by the 8-bit alpha, whose 1/255 steps move the depth of a half-covered
    pixel by up to 2 %."""
    scene = random_scene(n=300, seed=7)
    renderer = GLRenderer(gl_ctx, scene)
    try:
        exact = sorted_channels(renderer, CAMERA, median=False)
        for precision in ("float16", "8bit"):
            narrow = sorted_channels(renderer, CAMERA, RenderSettings(precision=precision), median=False)
            seen = exact.alpha > 0.5
            assert seen.mean() > 0.1
            depth_error = np.abs(narrow.depth[seen] - exact.depth[seen]) / exact.depth[seen]
            assert depth_error.max() < {"float16": 1e-2, "8bit": 3e-2}[precision] and not np.array_equal(narrow.depth, exact.depth)
            cosine = np.sum(narrow.normal[seen] * exact.normal[seen], axis=-1)
            assert cosine.min() > 0.99
    finally:
        renderer.release()


def test_precision_presets_and_settings():
    assert PRECISIONS == ("float32", "float16", "8bit")
    assert RenderSettings().precision == "float32"
    assert {"RayGS, float16 blend", "RayGS, 8-bit blend"} <= set(ACCURACY_PRESETS)
    from raygs_viewer.errors import UserError
    with pytest.raises(UserError, match="precision"):
        RenderSettings(precision="float8")


def read_png(path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image)


def test_sidecars_and_path_files_record_the_precision_and_re_render_to_the_bit(capsys, tmp_path):
    from raygs_viewer.camera.path import path_through_cameras
    from raygs_viewer.camera.pinhole import look_at as camera_at
    from raygs_viewer.capture.path_file import PathDocument, load_path_document, save_path_document
    from raygs_viewer.capture.sidecar import demo_sha256, load_sidecar

    shots = {}
    for precision in ("8bit", "float32"):
        sidecar = tmp_path / f"{precision}.json"
        sidecar.write_text(json.dumps(demo_sidecar(settings=RenderSettings(precision=precision))))
        assert load_sidecar(sidecar).settings.precision == precision
        for copy in ("a", "b"):
            out = tmp_path / f"{precision}-{copy}.png"
            code, _, err = run_cli(capsys, "render", "--sidecar", sidecar, "--out", out)
            assert code == 0, err
            shots[precision, copy] = read_png(out)
    np.testing.assert_array_equal(shots["8bit", "a"], shots["8bit", "b"])
    assert not np.array_equal(shots["8bit", "a"], shots["float32", "a"])

    views = [camera_at([x, 0.0, -3.0], [0, 0, 0], width=48, height=32) for x in (-0.5, 0.0, 0.5)]
    document = PathDocument(path_through_cameras(views, duration=0.5, fps=8), 48, 32,
                            RenderSettings(precision="float16"), None, "demo", demo_sha256())
    saved = save_path_document(document, tmp_path / "fly.json")
    assert json.loads(saved.read_text())["settings"]["precision"] == "float16"
    assert load_path_document(saved).settings.precision == "float16"
