"""Named scenes where float32 is delicate (maths page, section 8), for the stability
tests and ``docs/robustness.md``.

Each :class:`HardCase` is a small generated scene and a camera looking at its hard
part. The GL renderer (float32) and the float64 reference must both render it
without NaN or Inf and agree within the case's ``bound``; the docs justify each bound.
Most cameras sit at the origin looking along +z (camera space = world space), so
positions below read directly as camera-space offsets.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from raygs_viewer.bench.common import scene_renderer
from raygs_viewer.camera.pinhole import Camera, look_at
from raygs_viewer.render.gl.context import context_description, create_headless_context
from raygs_viewer.render.reference import render_reference
from raygs_viewer.render.settings import DEFAULT_P_MIN, RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.scene.model import Scene, sh_coefficient_count

WIDTH, HEIGHT = 96, 72
#: The default cut-off's support at opacity OPACITY: kappa = 2 ln(o / p_min).
OPACITY = 0.8
KAPPA = 2.0 * math.log(OPACITY / DEFAULT_P_MIN)


@dataclass(frozen=True)
class HardCase:
    """scene and camera: what is rendered. risk: what can go wrong in float32; remedy:
    what the code does about it. bound: the largest per-channel difference allowed
    between GL and the float64 reference (see docs/robustness.md for each).
    ambiguous: indices of gaussians whose drawn-or-skipped decision lies within float32
    rounding of its threshold; ``drawn`` is then the same scene with those gaussians
    moved to where they are drawn for certain (a hair farther out), and the test
    compares each with the reference of the decision GL took."""

    name: str
    scene: Scene
    camera: Camera
    risk: str
    remedy: str
    bound: float
    settings: RenderSettings = RenderSettings()
    ambiguous: tuple[int, ...] = ()
    drawn: Scene | None = None


def _scene(positions, scales, rotations=None, opacities=OPACITY, colors=None) -> Scene:
    positions = np.asarray(positions, np.float64).reshape(-1, 3)
    n = positions.shape[0]
    scales = np.broadcast_to(np.asarray(scales, np.float64), (n, 3))
    rotations = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if rotations is None else np.asarray(rotations, np.float64)
    rotations = rotations / np.linalg.norm(rotations, axis=1, keepdims=True)
    opacities = np.broadcast_to(np.asarray(opacities, np.float64), (n,))
    if colors is None:
        hues = np.linspace(0.0, 1.0, n, endpoint=False)
        colors = 0.5 + 0.4 * np.stack([np.cos(2 * np.pi * (hues + k / 3)) for k in range(3)], axis=1)
    sh = np.zeros((n, sh_coefficient_count(0), 3), np.float32)
    sh[:, 0] = (np.asarray(colors, np.float64) - 0.5) / 0.28209479177387814
    return Scene(positions.astype(np.float32), rotations.astype(np.float32), scales.astype(np.float32),
                 opacities.astype(np.float32), sh, 0)


def _forward_camera(fov_y_degrees: float = 60.0, eye=(0.0, 0.0, 0.0)) -> Camera:
    eye = np.asarray(eye, np.float64)
    return look_at(eye, eye + [0.0, 0.0, 1.0], width=WIDTH, height=HEIGHT, fov_y_degrees=fov_y_degrees)


def _looking_ahead(name: str, scene: Scene, risk: str, remedy: str, bound: float = 2 * DEFAULT_P_MIN) -> HardCase:
    """A case seen by :func:`_forward_camera`, with the usual bound of twice the default cut-off."""
    return HardCase(name, scene, _forward_camera(), risk, remedy, bound)


def _quaternion(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, np.float64)
    axis = axis / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])


def _background_blobs() -> tuple[list, list]:
    """A few ordinary gaussians in front, so every image has content besides the hard part."""
    return [[-0.6, 0.3, 4.0], [0.7, -0.2, 5.0], [0.0, 0.5, 3.0]], [[0.15, 0.1, 0.12]] * 3


def camera_at_centre() -> HardCase:
    positions, scales = _background_blobs()
    return _looking_ahead(
        "camera at a centre", _scene([[0.0, 0.0, 0.0]] + positions, [[0.5, 0.3, 0.4]] + scales),
        "c = 0: the whitened direction w/|w| is 0/0",
        "c^2 <= kappa (the camera inside the support) skips the gaussian before any division, as the "
        "maths page's section 3 says; the reference does the same")


def camera_just_inside() -> HardCase:
    positions, scales = _background_blobs()
    # c^2 = 0.999 kappa: just inside the support.
    d = 0.4 * math.sqrt(0.999 * KAPPA)
    return _looking_ahead(
        "camera just inside a support", _scene([[0.0, 0.0, d]] + positions, [[0.4, 0.4, 0.4]] + scales),
        "b = sqrt(1 - kappa/c^2) of a negative number",
        "skipped by the same c^2 <= kappa test")


def _just_above(epsilon: float, ambiguous_below: float = 1e-6) -> HardCase:
    positions, scales = _background_blobs()
    # An isotropic gaussian straight ahead and an elongated one off-axis, both with
    # c^2 = kappa (1 + epsilon): their supports almost reach the camera, so their
    # footprints cover most of the image and the quads' half-size sqrt(kappa)/b grows
    # like 1/sqrt(epsilon).
    s = 0.3
    d = s * math.sqrt(KAPPA * (1.0 + epsilon))
    tilted = _quaternion([0.3, 1.0, 0.2], 0.7)
    R = _rotation_matrix(tilted)
    elongated_centre = R @ [0.0, 0.0, d]  # along the gaussian's own z axis, whose scale is s
    hard = [[0.0, 0.0, d], list(elongated_centre)]
    return HardCase(
        f"c^2 = kappa (1 + {epsilon:g})",
        _scene(hard + positions, [[s, s, s], [1.5, 0.6, s]] + scales,
               rotations=[[1, 0, 0, 0], tilted] + [[1, 0, 0, 0]] * 3),
        _forward_camera(),
        "b -> 0: the quad's half-size sqrt(kappa)/b explodes; with 1 - kappa/c^2 it is infinite (or "
        "NaN) once an approximate GPU division takes kappa/c^2 to 1 or beyond",
        "b = sqrt((c^2 - kappa)/c^2): the difference is exact when the two are close, so b > 0; the "
        "half-size is capped at 1e4 (a size that still covers the screen: beyond it D is within "
        "float32 rounding of c^2 > kappa, so only fragments at the p_min threshold are lost)",
        2 * DEFAULT_P_MIN,
        ambiguous=(0, 1) if epsilon < ambiguous_below else (),
        drawn=_just_above(1e-6).scene if epsilon < ambiguous_below else None)


def _rotation_matrix(q) -> np.ndarray:
    w, x, y, z = np.asarray(q, np.float64) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def behind_camera() -> HardCase:
    positions, scales = _background_blobs()
    # Straight behind the camera: in the whitened frame w points exactly along -z (the
    # Householder branch's sign), and a long tilted axis carries the support in front.
    tilted = _quaternion([1.0, 0.0, 0.0], 0.9)
    return _looking_ahead(
        "straight behind the camera", _scene([[0.0, 0.0, -2.0], [0.0, 0.0, -1.5]] + positions,
                                             [[0.4, 0.4, 0.4], [0.25, 4.0, 0.25]] + scales,
                                             rotations=[[1, 0, 0, 0], tilted] + [[1, 0, 0, 0]] * 3),
        "mu-hat = -e_z: the rotation taking e_z to mu-hat is singular in the naive form",
        "the Householder form with the sign of mu-hat_z (|h|^2 >= 2); behind-the-camera peaks are "
        "clipped by the side planes, as the reference skips peaks with x^T Sigma^-1 mu <= 0")


def straddling() -> HardCase:
    positions, scales = _background_blobs()
    return _looking_ahead(
        "straddling the camera plane", _scene([[0.8, 0.0, 0.0], [-0.5, 0.4, 0.3]] + positions,
                                              [[0.15, 2.0, 2.5], [0.1, 1.5, 3.0]] + scales),
        "quad corners with w <= 0: near-plane clipping would cut a seam, the projection divides by ~0",
        "depth clamp instead of near clipping; the side planes still clip what is behind")


def isotropic() -> HardCase:
    ones = [1.0, 1.0, 1.0]
    return _looking_ahead(
        "isotropic and nearly isotropic", _scene(
            [[-0.8, 0.0, 4.0], [0.0, 0.0, 4.0], [0.8, 0.0, 4.0], [0.0, 0.7, 3.0]],
            [np.multiply(ones, 0.2), [0.2, 0.2 * (1 + 1e-7), 0.2 * (1 - 1e-7)], [0.2, 0.2, 0.2 * (1 + 1e-5)],
             [0.15, 0.15, 0.15]],
            rotations=[[1, 0, 0, 0], _quaternion([1, 2, 3], 1.0), _quaternion([3, 1, 2], 2.0), [1, 0, 0, 0]]),
        "B = s^2 I: the eigenvector of the quad's orientation is undefined (atan2(0, 0))",
        "any unit vector is fine for B = s^2 I: angle 0 when b01 = 0 and b00 = b11, and atan2 is "
        "continuous enough near it that the square still bounds the (near-)circle")


def needles_and_pancakes() -> HardCase:
    rotations = [_quaternion([1, 1, 0], 0.5), _quaternion([0, 1, 1], 1.1), _quaternion([1, 0, 1], 0.3),
                 _quaternion([1, 2, 0], 2.0), [1, 0, 0, 0], _quaternion([2, 1, 1], 0.8)]
    return _looking_ahead(
        "needles and pancakes (ratios to 1e6, scales to 1e-10)", _scene(
            [[-0.6, -0.3, 4.0], [0.6, -0.3, 4.0], [0.0, 0.4, 4.0], [-0.5, 0.5, 3.0], [0.5, 0.5, 3.0],
             [0.0, 0.0, 5.0]],
            [[1.0, 1e-6, 1e-6], [1e-6, 1.0, 1.0], [1.0, 1.0, 1e-6], [0.3, 3e-7, 0.3], [1e-10, 1e-10, 1e-10],
             [2e-4, 2e-10, 1e-3]],
            rotations=rotations),
        "w = S^-1 R^T mu overflows and B = Q2^T Q2 loses the thin axis (1e-12 next to 1)",
        "the whitened frame works with s (never s^-2): c^2 = |mu/s|^2 stays below 1e25; sub-pixel "
        "needles are hit at pixel centres only, like the reference samples them")


def far_centres() -> HardCase:
    rng = np.random.default_rng(7)
    centre = np.array([0.0, 0.0, 1.0e4])
    positions = centre + rng.uniform(-1500.0, 1500.0, (12, 3)) * [1, 1, 0.3]
    return _looking_ahead(
        "centres 1e4 away", _scene(positions, rng.uniform(100.0, 400.0, (12, 3)),
                                   rotations=rng.normal(size=(12, 4))),
        "|mu| ~ 1e4: c^2 ~ 1e3..1e4 and the quad corners ~1e4 in float32 (ulp 1e-3)",
        "nothing special: every quantity is relative to the gaussian's own size and distance, so "
        "float32 keeps about 1e-7 of each")


def far_camera() -> HardCase:
    rng = np.random.default_rng(8)
    positions = rng.uniform(-0.5, 0.5, (10, 3)) + [0.1234567, -0.0765432, 0.0321]
    scene = _scene(positions, rng.uniform(0.05, 0.15, (10, 3)), rotations=rng.normal(size=(10, 4)))
    eye = np.array([1.0e4 + 0.37, 1234.5678, -2345.6789])
    # A long lens: the object (about 1 unit) fills the image from 1e4 units away.
    distance = float(np.linalg.norm(eye))
    fov = math.degrees(2 * math.atan(1.2 / distance))
    camera = look_at(eye, [0.1234567, -0.0765432, 0.0321], width=WIDTH, height=HEIGHT, fov_y_degrees=fov)
    return HardCase(
        "camera 1e4 from the origin", scene, camera,
        "mu = R (p - C) in float32 rounds every coordinate to the ulp of |C| (1e-3 here, 1/1000 of "
        "the object): edges jitter by 0.02 px and 0.3 % of pixels were off by up to p_min",
        "mu = R p + t: the object's lateral offsets keep full float32 precision and only the large "
        "depth rounds, relatively; the gaussian's frame is then taken from mu. Exact MIP's per-fragment "
        "D = |y x w|^2/|y|^2 takes y x w as (offset/s) x w, since y and w are nearly parallel there",
        2 * DEFAULT_P_MIN)


def grazing() -> HardCase:
    # Pancakes seen almost edge-on: the support's image is a long thin sliver, and for
    # the one whose plane nearly contains the camera a half-hyperbola.
    edge = _quaternion([1.0, 0.0, 0.0], math.pi / 2 - 0.01)
    return _looking_ahead(
        "grazing views", _scene([[0.0, 0.3, 4.0], [0.0, -0.05, 2.0], [0.5, 0.0, 3.0]],
                                [[1.5, 2.0, 0.002], [3.0, 6.0, 0.01], [0.4, 0.4, 0.004]],
                                rotations=[edge, _quaternion([1.0, 0.0, 0.0], math.pi / 2 - 0.002),
                                           _quaternion([0.0, 1.0, 0.0], math.pi / 2 - 0.05)]),
        "the quad is seen edge-on: its interpolated plane coordinate varies fast and far",
        "the plane coordinate is a perspective-correct varying of the 3D quad, exact up to float32")


def opacity_extremes() -> HardCase:
    return _looking_ahead(
        "opacity exactly 0 and 1", _scene([[-0.5, 0.0, 4.0], [0.5, 0.0, 4.0], [0.0, 0.0, 5.0]],
                                          [[0.3, 0.3, 0.3]] * 3, opacities=[1.0, 0.0, 1.0]),
        "ln 0 = -inf in kappa; o = 1 exactly saturates",
        "kappa = 2 (ln o - ln p_min) is -inf for o = 0, so kappa <= 0 skips it; o = 1 is ordinary")


def coincident() -> HardCase:
    n = 2000
    rng = np.random.default_rng(9)
    positions = np.tile([[0.1, -0.05, 3.0]], (n, 1))
    return _looking_ahead(
        "2,000 coincident gaussians", _scene(positions, rng.uniform(0.05, 0.6, (n, 3)),
                                             rotations=rng.normal(size=(n, 4)),
                                             opacities=rng.uniform(0.02, 0.3, n), colors=rng.uniform(0, 1, (n, 3))),
        "equal depths: an unstable sort would composite them in another order each frame",
        "both sorts are stable: equal depths keep scene order in GL and the reference")


#: name -> factory, in the order of docs/robustness.md.
HARD_CASES: dict[str, Callable[[], HardCase]] = {
    "camera-at-centre": camera_at_centre,
    "camera-just-inside": camera_just_inside,
    "c2-above-kappa-1e-2": lambda: _just_above(1e-2),
    "c2-above-kappa-1e-4": lambda: _just_above(1e-4),
    "c2-above-kappa-1e-6": lambda: _just_above(1e-6),
    "c2-above-kappa-1e-9": lambda: _just_above(1e-9),
    "behind-camera": behind_camera,
    "straddling-camera-plane": straddling,
    "isotropic": isotropic,
    "needles-and-pancakes": needles_and_pancakes,
    "far-centres": far_centres,
    "far-camera": far_camera,
    "grazing": grazing,
    "opacity-extremes": opacity_extremes,
    "coincident": coincident,
}


MODES: dict[str, RenderSettings] = {
    "RayGS": RenderSettings(),
    "RayGS + MIP": RenderSettings(mip=True),
    "exact MIP": RenderSettings(mode="raygs-exact-mip"),
    "GS": RenderSettings(mode="gs"),
}


def render_gl(ctx, case: HardCase, settings: RenderSettings) -> tuple[np.ndarray, np.ndarray]:
    """(the GL image of ``case`` in ``settings``, (N,) bool: which gaussians GL drew)."""
    with scene_renderer(ctx, case.scene) as (renderer, sorter):
        image = renderer.render(case.camera, settings, exact_order(sorter, case.camera, settings))
        # A record's c^2 (its fourth float; glsl/splat.glsl) is 0 when it is not drawn.
        drawn = renderer.read_splats()[:, 3] != 0 if settings.mode != "gs" else np.ones(case.scene.count, bool)
    return image, drawn


def as_gl_decided(case: HardCase, drawn: np.ndarray) -> Scene:
    """The case's scene as GL decided it: an ambiguous gaussian GL skipped is left out,
    one it drew comes from ``case.drawn`` (where it is drawn for certain); every other
    gaussian stays, and its decision must match the reference's."""
    if not case.ambiguous:
        return case.scene
    scene, ambiguous = case.scene, list(case.ambiguous)
    positions = scene.positions.copy()
    positions[ambiguous] = case.drawn.positions[ambiguous]
    keep = np.array([i for i in range(scene.count) if i not in case.ambiguous or drawn[i]], int)
    return replace(scene, positions=positions[keep], rotations=scene.rotations[keep], scales=scene.scales[keep],
                   opacities=scene.opacities[keep], sh=scene.sh[keep])


def measure(ctx, case: HardCase, settings: RenderSettings) -> tuple[float, int]:
    """(largest |GL - reference| over pixels and channels, non-finite GL pixels) of
    ``case`` in ``settings``' mode."""
    image, drawn = render_gl(ctx, case, settings)
    reference = render_reference(as_gl_decided(case, drawn), case.camera, settings)
    bad = int((~np.isfinite(image)).any(axis=-1).sum())
    return float(np.abs(np.nan_to_num(image, nan=9.0).astype(np.float64) - reference).max()), bad


def main() -> None:
    """``python -m raygs_viewer.bench.hard_cases``: the largest GL-vs-reference difference of
    every case in every mode, as the markdown table docs/robustness.md quotes."""
    ctx = create_headless_context()
    print(f"GL: {context_description(ctx)}; {WIDTH}x{HEIGHT}, p_min 1/255\n")
    print("| case | " + " | ".join(MODES) + " |")
    print("|---|" + "---:|" * len(MODES))
    for name, factory in HARD_CASES.items():
        case = factory()
        cells = []
        for settings in MODES.values():
            error, bad = measure(ctx, case, settings)
            cells.append(f"{error:.1e}" + (f" ({bad} non-finite)" if bad else ""))
        print(f"| {name} | " + " | ".join(cells) + " |")
    ctx.release()


if __name__ == "__main__":
    main()
