"""What the tests share: generated scenes, the image comparison, the one-line-error check."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.capture.sidecar import build_sidecar, demo_sha256
from raygs_viewer.cli.main import main
from raygs_viewer.errors import UserError
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.render.tolerance import MATCH, OVER, PER_RAY_TIE_ERROR
from raygs_viewer.scene.demo import demo_scene
from raygs_viewer.scene.model import Scene, sh_coefficient_count
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import LodChoice
from raygs_viewer.sort.request import SortRequest

SHARED_SCENES = Path(__file__).resolve().parents[2] / "shared" / "scenes"


def random_rotation(rng):
    """A uniformly random proper rotation (det +1), float64."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def unit_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    return (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)


def point_on_pixel_ray(camera, u, v, depth):
    """World point on the ray of pixel (u, v) at camera-space depth ``depth``."""
    ray = np.array([(u + 0.5 - camera.cx) / camera.fx, (v + 0.5 - camera.cy) / camera.fy, 1.0])
    return camera.R.T @ (ray * depth - camera.t)


def independent_eye(camera: Camera, rig, side: float) -> Camera:
    """A stereo eye built from first principles: centre moved along the camera's right
    axis (R's first row, in world space), t = -R c, principal point shifted so the
    midline point at the convergence distance keeps its pixel."""
    baseline = rig.ipd / rig.scene_scale / 2
    center = camera.center + side * baseline * camera.R[0]
    shift = camera.fx * baseline / (rig.convergence / rig.scene_scale)
    return Camera(camera.width, camera.height, camera.fx, camera.fy, camera.cx + side * shift, camera.cy,
                  camera.R, -camera.R @ center)


def make_scene(positions, scales, rotations=None, opacities=None, colors=None, sh=None, degree=0):
    """A Scene from plain arrays; colours are RGB (SH DC chosen to give them head-on)."""
    positions = np.asarray(positions, np.float32).reshape(-1, 3)
    n = positions.shape[0]
    scales = np.broadcast_to(np.asarray(scales, np.float32), (n, 3)).copy()
    rotations = (np.tile(np.float32([1, 0, 0, 0]), (n, 1)) if rotations is None
                 else np.asarray(rotations, np.float32).reshape(n, 4))
    opacities = np.broadcast_to(np.asarray(0.8 if opacities is None else opacities, np.float32), (n,)).copy()
    if sh is None:
        sh = np.zeros((n, sh_coefficient_count(degree), 3), np.float32)
        rgb = np.broadcast_to(np.asarray((0.8, 0.6, 0.4) if colors is None else colors, np.float32), (n, 3))
        sh[:, 0] = (rgb - 0.5) / 0.28209479177387814
    return Scene(positions, rotations, scales, opacities, np.asarray(sh, np.float32), degree)


#: The most gaussians a shared scene keeps in the tests that compare it with the float64
#: reference, whose cost is per gaussian (about 0.1 ms each): the 45k donut took 5 s a render.
SHARED_PART = 12_000


def shared_scene(name: str, most: int = SHARED_PART) -> Scene:
    """The shared scene ``name`` as the viewer loads it; where it has more than ``most``
    gaussians, the ``most`` nearest one point of it (the gaussian nearest its per-axis
    quartiles), in file order. A region at its full density rather than a thinned whole:
    each pixel of a view framing it still sees as many layers as in the whole scene,
    which is what the per-ray order and the blend are tested against."""
    from raygs_viewer.scene.io import load_scene  # only where the scenes exist
    scene = load_scene(SHARED_SCENES / name)
    if scene.count <= most:
        return scene
    positions = scene.positions.astype(np.float64)
    quartiles = np.percentile(positions, 25, axis=0)
    anchor = positions[np.argmin(np.linalg.norm(positions - quartiles, axis=1))]
    nearest = np.argpartition(np.linalg.norm(positions - anchor, axis=1), most - 1)[:most]
    return scene.rows(np.sort(nearest))


def random_scene(n=300, seed=0, degree=3, spread=1.0, log_scale=(-4.0, -1.5), anisotropy=1.0):
    """Random blobs of every shape and colour around the origin, SH of ``degree``."""
    rng = np.random.default_rng(seed)
    coeffs = sh_coefficient_count(degree)
    sh = np.zeros((n, coeffs, 3), np.float32)
    sh[:, 0] = rng.normal(size=(n, 3))
    sh[:, 1:] = rng.normal(size=(n, coeffs - 1, 3)) * 0.3
    log_scales = rng.uniform(*log_scale, size=(n, 3))
    log_scales[:, 0] += rng.uniform(-anisotropy, anisotropy, n)
    return Scene(
        rng.uniform(-spread, spread, (n, 3)).astype(np.float32),
        unit_quaternions(rng, n),
        np.exp(log_scales).astype(np.float32),
        rng.uniform(0.05, 1.0, n).astype(np.float32),
        sh, degree,
    )


# ------------------------------------------------ sorting for a render, as the tools do


def sorted_render(renderer, camera, settings=RenderSettings(), *, levels=None, cull_cameras=None, **options):
    """``renderer.render`` of ``camera``'s exact order for ``settings``, sorted now by a
    DepthSorter of the renderer's scene (what ``render``, screenshots and render-path
    draw). ``levels``, ``cull_cameras``: see ``render.sorting.exact_order``; ``options``:
    ``render``'s (frame, color_origin)."""
    with DepthSorter(renderer.scene) as sorter:
        order = exact_order(sorter, camera, settings, cull_cameras=cull_cameras, levels=levels)
    return renderer.render(camera, settings, order, **options)


def sorted_channels(renderer, camera, settings=RenderSettings(), *, levels=None, **options):
    """``renderer.render_channels`` of the exact order, as :func:`sorted_render`."""
    with DepthSorter(renderer.scene) as sorter:
        order = exact_order(sorter, camera, settings, levels=levels)
    return renderer.render_channels(camera, settings, order, **options)


def rendered(renderer, camera, settings=RenderSettings(), order=None, *, levels=None, **options):
    """(image, RenderResult): ``renderer.render_into`` a float target of ``camera``'s size,
    read back as ``render`` reads it; ``order`` None: the exact order, sorted now (see
    :func:`sorted_render`); ``options``: ``render_into``'s (frame, color_origin, view)."""
    from raygs_viewer.render.gl.targets import FloatTarget  # late: only the GL tests need it

    if order is None:
        with DepthSorter(renderer.scene) as sorter:
            order = exact_order(sorter, camera, settings, levels=levels)
    target = FloatTarget(renderer.ctx, camera.width, camera.height)
    try:
        result = renderer.render_into(target, camera, settings, order, **options)
        return target.read(), result
    finally:
        target.release()


def sort_indices(sorter, camera, p_min=1 / 255, method="auto", *, key="depth", **request):
    """(M,) uint32: ``sorter``'s order by ``key`` for ``SortRequest(camera, p_min, ...)``
    (``request``: its dilation, cull_cameras, levels)."""
    return sorter.sort(SortRequest(camera, p_min, keys=(key,), method=method, **request)).order.indices


def spans_choice(spans, leaves=0):
    """A level-of-detail choice of exactly ``spans`` ((S, 2) ascending [start, stop)
    rows), for orders and sorts limited to given rows without a LodScene."""
    spans = np.asarray(spans, np.int64).reshape(-1, 2)
    levels = np.zeros(leaves, np.int64)
    return LodChoice(levels, levels.copy(), spans, int((spans[:, 1] - spans[:, 0]).sum()))


def compare(image, reference):
    """Error statistics of a float image against the float64 reference, all channels."""
    error = np.abs(np.asarray(image, np.float64) - reference)
    return {
        "max": float(error.max()),
        "p999": float(np.quantile(error, 0.999)),
        "mean": float(error.mean()),
        "over_1e-3": float((error.max(axis=-1) > OVER).mean()),  # fraction of pixels
    }


def assert_matches(image, reference, max_error=MATCH.max_error, pixel_fraction=MATCH.pixel_fraction, p999=MATCH.p999):
    """GL-vs-reference agreement. Float32 and float64 agree to ~1e-5 per pixel, but a
    pixel where some gaussian's opacity lies within float32 rounding of p_min keeps or
    drops that fragment (seen: 1.1e-5 relative from p_min on a shared scene), which moves
    it by up to p_min * colour; so a few pixels may reach ``max_error`` (2 p_min by
    default), while at most ``pixel_fraction`` of pixels may differ by over 1e-3."""
    stats = compare(image, reference)
    assert np.all(np.isfinite(image)), "NaN or Inf in the image"
    assert stats["max"] <= max_error and stats["over_1e-3"] <= pixel_fraction and stats["p999"] <= p999, stats
    return stats


def assert_matches_per_ray(image, reference):
    """:func:`assert_matches` for the per-pixel order on scenes that may hold near-ties
    of t* (real and random scenes): a few pixels may swap such a pair; the share of
    pixels over 1e-3 and the 99.9th percentile stay as tight as ever."""
    return assert_matches(image, reference, max_error=PER_RAY_TIE_ERROR)


def assert_differs(image, reference, **tolerances):
    """The negative control: ``image`` must fail :func:`assert_matches`."""
    try:
        assert_matches(image, reference, **tolerances)
    except AssertionError:
        return
    raise AssertionError(f"expected a visible difference, got {compare(image, reference)}")


def assert_user_error(call, path, *fragments):
    """``call()`` raises UserError with a one-line message naming ``path`` and every fragment."""
    with pytest.raises(UserError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message and "\r" not in message, message
    assert Path(path).name in message, message
    for fragment in fragments:
        assert fragment in message, message
    return message


def _field_parent(data, dotted: str):
    """The container holding the field at ``dotted`` and its key (list entries by index)."""
    *parents, last = dotted.split(".")
    for key in parents:
        data = data[int(key)] if isinstance(data, list) else data[key]
    return data, int(last) if isinstance(data, list) else last


def set_field(dotted: str, value):
    """A mutation of parsed JSON: the field at ``dotted`` ("a.b", "keyframes.2.fov") set to ``value``."""
    def mutate(data):
        parent, key = _field_parent(data, dotted)
        parent[key] = value
    return mutate


def delete_field(dotted: str):
    """A mutation of parsed JSON: the field at ``dotted`` removed."""
    def mutate(data):
        parent, key = _field_parent(data, dotted)
        del parent[key]
    return mutate


def write_case(path, change, valid):
    """The file of a malformed-file case at ``path``: ``change`` None (no file), bytes or
    str (the file's content), or a mutation of a fresh ``valid()`` dict. Returns ``path``."""
    path = Path(path)
    if isinstance(change, bytes):
        path.write_bytes(change)
    elif isinstance(change, str):
        path.write_text(change)
    elif change is not None:
        data = valid()
        change(data)
        path.write_text(json.dumps(data))  # NaN/Infinity written as JSON's common extension
    return path


# ------------------------------------------------ files, CLI runs and sidecars the tests share


_NP_TYPES = {"float": "f4", "double": "f8", "uchar": "u1", "char": "i1", "short": "i2",
             "ushort": "u2", "int": "i4", "uint": "u4"}


def gaussian_columns(n=4, degree=0, seed=0, normals=False, filter_3d=None):
    """Ordered {name: float64 values} for n valid gaussians in the INRIA layout."""
    rng = np.random.default_rng(seed)
    cols = {}
    for name in ("x", "y", "z"):
        cols[name] = rng.uniform(-5, 5, n)
    if normals:
        for name in ("nx", "ny", "nz"):
            cols[name] = np.zeros(n)
    for c in range(3):
        cols[f"f_dc_{c}"] = rng.uniform(-1, 1, n)
    k = (degree + 1) ** 2 - 1
    for j in range(3 * k):
        cols[f"f_rest_{j}"] = 1000.0 * np.arange(n) + j  # distinct per (gaussian, channel, coefficient)
    cols["opacity"] = rng.uniform(-4, 4, n)
    for a in range(3):
        cols[f"scale_{a}"] = rng.uniform(-6, 0, n)
    for a in range(4):
        cols[f"rot_{a}"] = rng.uniform(-2, 2, n)
    if filter_3d is not None:
        cols["filter_3D"] = np.broadcast_to(np.asarray(filter_3d, np.float64), (n,)).copy()
    return cols


def ply_bytes(columns, *, types=None, count=None, fmt="binary_little_endian", nl="\n",
              elements_before=(), elements_after=(), header_lines=None):
    """Raw PLY bytes. columns: ordered {name: values}; types: {name: ply type} (default float).

    elements_before / elements_after: (header text, raw data bytes) pairs.
    header_lines: replace the whole header (a list of lines, without 'ply').
    """
    types = types or {}
    names = list(columns)
    n = len(next(iter(columns.values()))) if columns else 0
    endian = ">" if fmt == "binary_big_endian" else "<"
    dtype = np.dtype([(name, endian + _NP_TYPES[types.get(name, "float")]) for name in names])
    rows = np.zeros(n, dtype)
    for name in names:
        rows[name] = columns[name]
    if header_lines is None:
        header_lines = [f"format {fmt} 1.0", "comment written by test_scene_io"]
        header_lines += [h for h, _ in elements_before]
        header_lines.append(f"element vertex {n if count is None else count}")
        header_lines += [f"property {types.get(name, 'float')} {name}" for name in names]
        header_lines += [h for h, _ in elements_after]
        header_lines.append("end_header")
    header = nl.join(["ply"] + header_lines) + nl
    return (header.encode("ascii") + b"".join(d for _, d in elements_before) + rows.tobytes()
            + b"".join(d for _, d in elements_after))


def write_ply(path, columns, **kwargs):
    path.write_bytes(ply_bytes(columns, **kwargs))
    return path


def splat_bytes(positions, scales, rgba, quat_bytes):
    dtype = np.dtype([("p", "<f4", (3,)), ("s", "<f4", (3,)), ("c", "u1", (4,)), ("q", "u1", (4,))])
    rows = np.zeros(len(positions), dtype)
    rows["p"], rows["s"], rows["c"], rows["q"] = positions, scales, rgba, quat_bytes
    assert dtype.itemsize == 32
    return rows.tobytes()


INRIA_PROPERTIES = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                    "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]


def write_inria_ply(path, n=5, seed=0, spread=0.5):
    """A small INRIA PLY (SH degree 0, float32 properties) written with plyfile: gaussians
    of 0.03..0.08 around the origin, opaque-ish."""
    rng = np.random.default_rng(seed)
    rows = np.zeros(n, dtype=[(name, "<f4") for name in INRIA_PROPERTIES])
    for axis, name in enumerate("xyz"):
        rows[name] = rng.uniform(-spread, spread, n)
    for c in range(3):
        rows[f"f_dc_{c}"] = rng.uniform(-1, 1, n)
    rows["opacity"] = rng.uniform(1.0, 3.0, n)            # sigmoid: 0.73..0.95
    for a in range(3):
        rows[f"scale_{a}"] = np.log(rng.uniform(0.03, 0.08, n))
    q = rng.normal(size=(n, 4))
    for a in range(4):
        rows[f"rot_{a}"] = q[:, a]
    PlyData([PlyElement.describe(rows, "vertex")], text=False, byte_order="<").write(str(path))
    return path


def run_cli(capsys, *argv):
    """main(argv) -> (return code, stdout, stderr)."""
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line_error(code, err):
    assert code == 2, err
    assert "Traceback" not in err
    assert err.startswith("error: "), err
    assert err.endswith("\n") and err.count("\n") == 1, repr(err)
    return err


def listing(folder):
    return sorted(p.name for p in Path(folder).iterdir())


SETTINGS = RenderSettings(p_min=0.02, background=(0.1, 0.2, 0.3), sh_degree=1)


def window_camera(width=64, height=48):
    """Like a camera the window produces after some navigation: an arbitrary float64
    pose (digits that JSON must not lose), fx != fy, off-centre principal point."""
    pose = look_at([0.6123456789012345, -1.1 / 3, -4.2 - 1e-13], [0.2, 0.1 + 1e-9, 1.0 / 7])
    return Camera(width, height, 70.0 / 3 * width / 21, 55.0 * height / 48 + 1e-11, width / 2 - 1.0 / 3,
                  height / 2 + 0.125, pose.R, pose.t)


def demo_sidecar(camera=None, settings=SETTINGS, scale=1.0, **kwargs):
    camera = camera or window_camera()
    return build_sidecar(scene_path="demo", scene_sha256=demo_sha256(), scene=demo_scene(), camera=camera,
                         settings=settings, scale=scale, **kwargs)




DEMO_ARRAYS_SHA256 = "681ba16b73b4b817a049a853be122a212abe52c7cd0cf34d9f0bb0c41c312ef4"



def channel_errors(image, reference):
    """Per-output error figures of a GL ChannelImage against the reference's: rgb and
    alpha absolute; depth and median depth relative to the reference's value; normal as
    the length of the difference; ``median_found`` the share of pixels where only one
    of the two has a median. The median's figures are left out where ``image`` has none
    (a render not asked for it)."""
    covered = reference.alpha > 0

    def relative(a, b, where):
        return np.where(where, np.abs(a.astype(np.float64) - b) / np.maximum(np.abs(b), 1e-30), 0.0)

    errors = {
        "rgb": np.abs(image.rgb.astype(np.float64) - reference.rgb).max(axis=-1),
        "alpha": np.abs(image.alpha.astype(np.float64) - reference.alpha),
        "depth": relative(image.depth, reference.depth, covered),
        "normal": np.where(covered, np.linalg.norm(image.normal.astype(np.float64) - reference.normal, axis=-1), 0.0),
    }
    if image.median_depth is not None:
        both = (reference.median_depth > 0) & (image.median_depth > 0)
        errors["median_depth"] = relative(image.median_depth, reference.median_depth, both)
        errors["median_found"] = ((reference.median_depth > 0) != (image.median_depth > 0)).astype(np.float64)
    return errors


#: Per output: the error most pixels stay under, and the share of pixels allowed over it.
#: The share covers a fragment within float32 rounding of p_min kept by one renderer and
#: dropped by the other (see assert_matches), which moves the depth of a faint pixel, or
#: its median across 0.5, by up to that fragment's own weight.
CHANNEL_TOLERANCES = {"rgb": 1e-3, "alpha": 1e-3, "depth": 1e-4, "median_depth": 1e-5, "normal": 1e-3,
                      "median_found": 0.5}
CHANNEL_PIXEL_FRACTION = 0.003


def assert_channels_match(image, reference, pixel_fraction=CHANNEL_PIXEL_FRACTION):
    """Every output of a GL ChannelImage agrees with the reference's: at most
    ``pixel_fraction`` of pixels over each tolerance; all outputs finite. Returns the
    largest error of each output (for the closing figures)."""
    for name in ("rgb", "alpha", "depth", "median_depth", "normal"):
        if getattr(image, name) is not None:
            assert np.all(np.isfinite(getattr(image, name))), f"NaN or Inf in {name}"
    errors = channel_errors(image, reference)
    for name, error in errors.items():
        over = float((error > CHANNEL_TOLERANCES[name]).mean())
        assert over <= pixel_fraction, f"{name}: {over:.4f} of pixels over {CHANNEL_TOLERANCES[name]} " \
                                       f"(max {error.max():.3g}, p99.9 {np.quantile(error, 0.999):.3g})"
    return {name: float(error.max()) for name, error in errors.items()}


def assert_channels_differ(image, reference):
    """The negative control: ``image`` must fail :func:`assert_channels_match`."""
    try:
        assert_channels_match(image, reference)
    except AssertionError:
        return
    raise AssertionError("expected the outputs to differ from the reference")


def patched_glsl(monkeypatch, name, old, new):
    """Breaks one shader on purpose for a negative control: ``glsl/<name>`` is read with
    ``old`` (which must occur) replaced by ``new`` until the test ends."""
    from raygs_viewer.render.gl import shaders  # late: only the GL tests that patch need it
    read = shaders._read

    def patched(file):
        text = read(file)
        if file == name:
            assert old in text, f"{old!r} not in {name}"
            text = text.replace(old, new)
        return text

    monkeypatch.setattr(shaders, "_read", patched)


class LineSink:
    """A text stream that keeps what is written, as a list of strings (``sink``)."""

    def __init__(self, sink: list):
        self.sink = sink

    def write(self, text):
        self.sink.append(text)

    def flush(self):
        pass


#: Every way a pixel's fragments are composited: modes, the MIP filter, the cut-off, and
#: the per-pixel orders (exact, a window of K, with the cut-off).
COMPOSITING_SETUPS = {
    "global": RenderSettings(),
    "mip": RenderSettings(mip=True),
    "exact mip": RenderSettings(mode="raygs-exact-mip"),
    "ewa": RenderSettings(mode="gs"),
    "cut-off": RenderSettings(transmittance_cutoff=True, alpha_clamp=True),
    "per pixel": RenderSettings(order="per-pixel"),
    "per pixel k=2": RenderSettings(order="per-pixel", order_k=2),
    "per pixel cut-off": RenderSettings(order="per-pixel", transmittance_cutoff=True),
}
