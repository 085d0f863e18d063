"""The stereo preview's post passes on the GPU (render/gl/stereo_frame): the lens warp,
checked together with its float64 reference, and the layout pass."""

import math

import numpy as np
import pytest

from raygs_viewer.camera.lens_model import (
    DEFAULT_LENS,
    LensModel,
    lens_warp_reference,
    source_point,
)
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.camera.stereo import LAYOUTS, compose, composed_size
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl.stereo_frame import StereoPasses

IDENTITY = LensModel(k1=0.0, k2=0.0, chroma_red=1.0, chroma_blue=1.0)
STRONG = LensModel(k1=0.5, k2=0.0, chroma_red=0.98, chroma_blue=1.03)


def _camera(width, height, cx, cy):
    return Camera(width, height, 0.8 * width, 0.8 * width, cx, cy, np.eye(3), np.zeros(3))


def _texture(ctx, image):
    image = np.ascontiguousarray(image, np.float32)
    return ctx.texture((image.shape[1], image.shape[0]), 4, image[::-1].tobytes(), dtype="f4")


def _target(ctx, width, height):
    return ctx.framebuffer(color_attachments=[ctx.texture((width, height), 4, dtype="f4")])


def _read(fbo):
    width, height = fbo.size
    return np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(height, width, 4)[::-1].copy()


def _release(*objects):
    for obj in objects:
        for attachment in getattr(obj, "color_attachments", ()):
            attachment.release()
        obj.release()


@pytest.fixture
def passes(gl_ctx):
    p = StereoPasses(gl_ctx)
    yield p
    p.release()


@pytest.fixture
def gl_lens(gl_ctx, passes):
    def warp(image, camera, model):
        source, target = _texture(gl_ctx, image), _target(gl_ctx, camera.width, camera.height)
        try:
            passes.lens(source, target, camera, model)
            return _read(target)
        finally:
            _release(source, target)
    return warp


@pytest.fixture(params=["reference", "gl"])
def warp(request):
    """Each independent check runs on the reference and on the GL pass."""
    if request.param == "reference":
        return lens_warp_reference
    return request.getfixturevalue("gl_lens")


def _output_radius(model, source_radius, scale):
    """Solves t D(t^2) / F s = source_radius (all normalised by R) for t by bisection:
    the panel radius at which a channel of ``scale`` shows the source radius."""
    def forward(t):
        return t * (1.0 + model.k1 * t * t + model.k2 * t ** 4) / (1.0 + model.k1 + model.k2) * scale
    low, high = 0.0, 4.0
    for _ in range(200):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if forward(mid) < source_radius else (low, mid)
    return 0.5 * (low + high)


def _near_an_edge(camera, model, margin):
    """Pixels where some channel samples within ``margin`` px of the image border: there
    float32 and float64 may disagree on inside/outside."""
    x = np.arange(camera.width) + 0.5
    y = (np.arange(camera.height) + 0.5)[:, None]
    near = np.zeros((camera.height, camera.width), bool)
    for scale in model.channel_scales:
        qx, qy = source_point(camera, model, x, y, scale)
        near |= (np.minimum(np.abs(qx), np.abs(qx - camera.width)) < margin) \
            | (np.minimum(np.abs(qy), np.abs(qy - camera.height)) < margin)
    return near


@pytest.mark.parametrize("model", [DEFAULT_LENS, STRONG], ids=["default", "k1-only"])
@pytest.mark.parametrize("cx, cy", [(29.3, 23.7), (40.6, 15.2)], ids=["farther-edge-right", "farther-edge-left"])
def test_gl_lens_pass_matches_the_reference(gl_lens, model, cx, cy):
    camera = _camera(67, 41, cx, cy)
    rng = np.random.default_rng(7)
    image = rng.random((41, 67, 4)).astype(np.float32)
    reference = lens_warp_reference(image, camera, model)
    out = gl_lens(image, camera, model)
    near = _near_an_edge(camera, model, 1e-3)
    assert near.mean() < 0.01
    # float32 positions: a few ulp of ~64 px times a texel-to-texel step of up to 1
    np.testing.assert_allclose(out[~near], reference[~near], rtol=0, atol=2e-5)
    # the comparison means something: the warp moved content and blacked out some pixels
    assert np.abs(reference[..., :3] - image[..., :3]).max() > 0.3
    assert (reference[..., 3] == 0).sum() > 5 and (reference[..., 3] == 1).mean() > 0.5


def test_identity_lens_copies_the_image(warp):
    # A dyadic lens centre keeps c + (P - c) exact in float32 too.
    camera = _camera(67, 41, 29.25, 23.75)
    image = np.random.default_rng(1).random((41, 67, 4)).astype(np.float32)
    out = warp(image, camera, IDENTITY)
    np.testing.assert_array_equal(out[..., :3], image[..., :3])
    np.testing.assert_array_equal(out[..., 3], 1.0)


def test_lens_centre_keeps_its_value(warp):
    camera = _camera(67, 41, 30.5, 17.5)  # the centre of pixel (30, 17)
    image = np.random.default_rng(2).random((41, 67, 4)).astype(np.float32)
    patch = np.float32([0.3, 0.6, 0.9, 0.5])
    image[15:20, 28:33] = patch
    out = warp(image, camera, STRONG)
    np.testing.assert_allclose(out[16:19, 29:32, :3], np.broadcast_to(patch[:3], (3, 3, 3)), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(out[16:19, 29:32, 3], 1.0)
    assert np.abs(out[..., :3] - image[..., :3]).max() > 0.3  # elsewhere the warp moves things


@pytest.mark.parametrize("model", [DEFAULT_LENS, STRONG], ids=["default", "k1-only"])
def test_a_dot_lands_at_the_predicted_radius_per_channel(warp, model):
    """A white blob off the lens centre: each channel's centroid on the panel sits where
    t D(t^2) / F s_c equals the blob's normalised radius. With F = D(1) the centre is
    magnified, so inside the lens circle content moves outward, red (s < 1) farthest."""
    width, height, cx, cy = 161, 121, 70.5, 64.25
    camera = _camera(width, height, cx, cy)
    radius = max(cx, width - cx)
    dot = np.array([cx + 40.0, cy - 25.0])
    x, y = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    blob = np.exp(-((x - dot[0]) ** 2 + (y - dot[1]) ** 2) / (2 * 1.2 ** 2))
    image = np.repeat(blob[..., None], 4, axis=2).astype(np.float32)
    out = warp(image, camera, model).astype(np.float64)
    direction = (dot - (cx, cy)) / np.linalg.norm(dot - (cx, cy))
    source_radius = np.linalg.norm(dot - (cx, cy)) / radius
    radii = []
    for c, scale in enumerate(model.channel_scales):
        weight = out[..., c]
        centroid = np.array([(weight * x).sum(), (weight * y).sum()]) / weight.sum()
        predicted = np.array([cx, cy]) + direction * _output_radius(model, source_radius, scale) * radius
        assert np.linalg.norm(centroid - predicted) < 0.1, (c, centroid, predicted)
        radii.append(np.linalg.norm(centroid - (cx, cy)))
    assert radii[1] - np.linalg.norm(dot - (cx, cy)) > 3.0  # moved outward by pixels, not rounding
    assert radii[0] - radii[1] > 0.15 and radii[1] - radii[2] > 0.4  # red outermost, blue innermost


def test_outside_the_image_is_black(warp):
    """A centred lens on a square image: along the diagonal the image corner (normalised
    radius sqrt 2) is reached at the panel radius the formula gives; beyond it the
    panel is black, corners included."""
    size = 101
    camera = _camera(size, size, 50.5, 50.5)
    out = warp(np.ones((size, size, 4), np.float32), camera, DEFAULT_LENS)
    for row, col in ((0, 0), (0, size - 1), (size - 1, 0), (size - 1, size - 1)):
        np.testing.assert_array_equal(out[row, col], 0.0)
    k = np.arange(size)
    t = math.sqrt(2) * np.abs(k + 0.5 - 50.5) / 50.5
    for c, scale in enumerate(DEFAULT_LENS.channel_scales):
        edge = _output_radius(DEFAULT_LENS, math.sqrt(2), scale)
        diagonal = out[k, k, c]
        assert np.all(diagonal[t < edge - 0.02] > 0.99) and np.all(diagonal[t > edge + 0.02] == 0.0), c
        assert (t > edge + 0.02).sum() >= 10 and (t < edge - 0.02).sum() >= 50
    edge = _output_radius(DEFAULT_LENS, math.sqrt(2), 1.0)
    clear = np.abs(t - edge) > 0.02
    np.testing.assert_array_equal(out[k, k, 3][clear], np.where(t < edge, 1.0, 0.0)[clear])


def test_farther_horizontal_edge_maps_to_itself(warp):
    """The midpoint of the edge farther from the lens centre maps to itself; a ramp
    image shows where the last column on the centre row samples."""
    width, height, cx, cy = 67, 41, 30.5, 20.5
    model = LensModel(k1=0.22, k2=0.24, chroma_red=1.0, chroma_blue=1.0)
    camera = _camera(width, height, cx, cy)
    assert source_point(camera, model, width, cy) == pytest.approx((width, cy), abs=1e-12)
    mirrored = _camera(width, height, width - cx, cy)
    assert source_point(mirrored, model, 0.0, cy) == pytest.approx((0.0, cy), abs=1e-12)
    # the nearer edge is inside the lens circle, so it samples nearer the centre
    assert source_point(camera, model, 0.0, cy)[0] > 0.5

    ramp = np.zeros((height, width, 4), np.float32)
    ramp[..., 1] = np.arange(width) + 0.5  # bilinear sampling reproduces it exactly
    out = warp(ramp, camera, model)
    radius = width - cx
    t = (width - 0.5 - cx) / radius
    expected = cx + t * radius * (1 + 0.22 * t * t + 0.24 * t ** 4) / (1 + 0.22 + 0.24)
    assert out[20, width - 1, 1] == pytest.approx(expected, abs=2e-5)
    assert width - 1.0 < expected < width - 0.5


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("width, height", [(37, 23), (16, 29)])
def test_gl_compose_matches_stereo_compose(gl_ctx, passes, layout, width, height):
    rng = np.random.default_rng(3)
    left = rng.normal(size=(height, width, 4)).astype(np.float32)
    right = rng.normal(size=(height, width, 4)).astype(np.float32) + 10.0
    left[0, 0, 0], right[-1, -1, 2], right[1, 2, 0] = np.inf, np.nan, -0.0
    textures = _texture(gl_ctx, left), _texture(gl_ctx, right)
    target = _target(gl_ctx, *composed_size(width, height, layout))
    try:
        passes.compose(*textures, target, layout)
        out = _read(target)
    finally:
        _release(*textures, target)
    expected = compose(left, right, layout)
    assert out.shape == expected.shape
    np.testing.assert_array_equal(out.view(np.uint32), expected.view(np.uint32))


def test_unknown_layout_is_a_user_error(gl_ctx, passes):
    with pytest.raises(UserError, match="stereo layout"):
        composed_size(37, 23, "over-under")
    texture, target = _texture(gl_ctx, np.zeros((3, 5, 4))), _target(gl_ctx, 5, 3)
    try:
        with pytest.raises(UserError, match="over-under"):
            passes.compose(texture, texture, target, "over-under")
    finally:
        _release(texture, target)
