"""Render settings shared by the GL renderer, the reference renderer and the CLI.

The accuracy options of the maths page, sections 6, 7 and 10, live here so that the
GL path, the float64 reference, the sidecar and the benchmark read one definition.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.setting_info import Setting, Shown, checked, setting, settings_table
from raygs_viewer.scene.lod_meta import MAX_LEVELS

DEFAULT_P_MIN = 1.0 / 255.0
DEFAULT_BACKGROUND = (0.0, 0.0, 0.0)
#: The spherical-harmonics degrees a scene may store.
SH_DEGREES = (0, 1, 2, 3)

#: "raygs": RayGS, with the pixel-invariant MIP filter of Eq. 17 when ``mip`` is on.
#: "raygs-exact-mip": RayGS with the pixel-dependent MIP filter (Appendix A.5),
#: evaluated per fragment; MIP is on by definition in this mode.
#: "gs": EWA splatting, the linearised projection with a 0.3 px^2 dilation.
RENDER_MODES = ("raygs", "raygs-exact-mip", "gs")
MODE_LABELS = {"raygs": "RayGS", "raygs-exact-mip": "RayGS exact MIP", "gs": "GS (EWA)"}

#: How each pixel orders its gaussians (maths page, section 11).
#: "depth": one global order by the camera-space depth z of the centres (the paper's).
#: "distance": one global order by the distance |mu| from the camera centre; it does
#: not change when the camera turns in place, so a turn needs no new sort.
#: "per-pixel": each pixel composites its gaussians front to back by t*, the ray
#: parameter of the gaussian's peak on that pixel's ray; exactly (order_k 0), or
#: through a re-ordering window of order_k entries fed in the depth order (which feeds
#: it better than distance on the shared scenes: docs/ordering.md).
ORDERS = ("depth", "distance", "per-pixel")
ORDER_LABELS = {"depth": "depth", "distance": "distance", "per-pixel": "per pixel"}
#: Largest re-ordering window (k-buffer entries per pixel) of the bounded per-pixel order.
MAX_ORDER_K = 16

#: What the blended colour accumulates in (docs/performance.md, "On a GPU"): float32
#: (exact to float32 rounding), float16 (RGBA16F, as nvpro's viewer and Unity's blend) or
#: 8bit (RGBA8, as vkgs and vkraygs blend: every blend step rounds to 1/255 and clamps
#: to 0..1). Narrower pixels cost less fill. The per-pixel order and the transmittance
#: cut-off composite in their own passes and keep float32.
PRECISIONS = ("float32", "float16", "8bit")
PRECISION_LABELS = {"float32": "float32", "float16": "float16", "8bit": "8-bit"}

#: Variance (px^2) added to every projected 2D covariance in GS mode, as INRIA training does.
GS_DILATION = 0.3
#: GS skips gaussians whose centre is nearer than this (camera-space z, scene units):
#: the linearised projection is undefined at z = 0.
GS_NEAR = 0.01
#: INRIA and GOF clamp a splat's alpha to this (section 10).
ALPHA_CLAMP = 0.99
#: ... and stop compositing a pixel front to back before its transmittance falls below this.
TRANSMITTANCE_CUTOFF = 1e-4
#: The levels a streamed SOG may have, and the largest budget of gaussians taken.
MAX_LOD_LEVELS = MAX_LEVELS
MAX_LOD_BUDGET = 1 << 40
#: Supersampling factors per axis the renderers accept (k x k samples per pixel).
MAX_SUPERSAMPLE = 4
#: Largest MIP filter variance accepted, px^2 (a filter 10 px wide is no longer anti-aliasing).
MAX_MIP_SIGMA2 = 100.0
#: The exact MIP quad widens the filter for the farthest peak, tau_max = |mu| + sqrt(kappa)
#: max(s_mip) (see preprocess.comp); culling widens the approximate filter's margin by
#: this factor. It is conservative: tau_max <= 2|mu| unless sqrt(kappa) max(s_mip) > |mu|,
#: and then the cull sphere already holds the camera centre, so nothing is culled.
EXACT_MIP_CULL_FACTOR = 2.0


@dataclass(frozen=True)
class RenderSettings:
    """How to render.

    p_min: opacity below which a fragment is discarded; it sets the support
    kappa = -2 ln(p_min / o) of every gaussian (Eq. 3). background: linear RGB the
    image is composited over. sh_degree: highest spherical-harmonics band
    evaluated, capped at the scene's; None uses all the scene has.

    mode: one of RENDER_MODES. mip: the pixel-invariant MIP filter in "raygs" mode
    (ignored by the other modes). mip_sigma2: the pixel filter's variance in px^2
    of the rendered (supersampled) image, for both MIP forms. mip_modulation: scale
    opacity so the total opacity matches the unfiltered gaussian's (Eq. 17's root;
    in exact MIP mode the per-pixel root). gs_compensation: in "gs" mode, scale
    opacity by sqrt(det(Sigma2) / det(Sigma2 + dilation)) as Mip-Splatting does.

    supersample: render k x k samples per pixel and average them (box filter).
    alpha_clamp: clamp each splat's alpha to ALPHA_CLAMP. transmittance_cutoff:
    composite front to back and stop a pixel before its transmittance falls below
    TRANSMITTANCE_CUTOFF, as INRIA and GOF do (section 10).

    order: one of ORDERS, how each pixel orders its gaussians. order_k: with order
    "per-pixel", 0 sorts every pixel's fragments exactly; K in 1..MAX_ORDER_K
    re-orders them through a window of K entries (a k-buffer) fed in the global
    depth order. Per-pixel order needs a RayGS mode (EWA splats have no ray key).

    Each field carries its Setting (:mod:`raygs_viewer.render.setting_info`): its
    limits, where it applies, its command-line help and how verify's line and the
    split view's label show it. The checks below, the command line, those describers
    and the sidecar reader read nothing else, so a field added with its Setting
    reaches all of them (the GL and reference renderers and the panel are its own).
    """

    p_min: float = setting(DEFAULT_P_MIN, Setting(
        "opacity cut-off, sets kappa = -2 ln(P/o) (default 1/255)", "P", limits=(0.0, 1.0), open=True,
        accuracy=False, label=Shown("p_min {:.3g}")))
    background: tuple[float, float, float] = setting(DEFAULT_BACKGROUND, Setting(
        "background colour, 0..1 each (default 0,0,0)", "R,G,B", limits=(0.0, 1.0), accuracy=False))
    sh_degree: int | None = setting(None, Setting(
        f"highest spherical-harmonics band to evaluate, {SH_DEGREES[0]}..{SH_DEGREES[-1]}, capped at the scene's "
        "(default: all the scene has)", "D", choices=SH_DEGREES, accuracy=False))
    mode: str = setting("raygs", Setting(
        "raygs: RayGS (default); raygs-exact-mip: RayGS with the exact, per-pixel MIP filter; gs: EWA splatting "
        "as INRIA 3DGS renders (0.3 px^2 dilation)", choices=RENDER_MODES, words=MODE_LABELS, what="render mode",
        line=Shown("mode {}"), label=Shown("{}", worded="{}", always=True)))
    mip: bool = setting(False, Setting(
        "RayGS mode: the pixel-invariant MIP filter (Eq. 17) (default off)", modes=("raygs",),
        line=Shown("MIP {}")))
    mip_sigma2: float = setting(0.1, Setting(
        "the MIP filter's variance in px^2 of the rendered image (default 0.1); implies --mip unless --no-mip "
        "is given", "S", limits=(0.0, MAX_MIP_SIGMA2), unit="px^2", what="MIP sigma^2", needs="mip_active",
        implies=("mip", True), line=Shown("sigma^2 {:g} px^2"), label=Shown("MIP {:g} px²", always=True)))
    mip_modulation: bool = setting(True, Setting(
        "scale opacity so a filtered gaussian keeps its total opacity (default on); either form implies --mip "
        "unless --no-mip is given", needs="mip_active", implies=("mip", True),
        line=Shown("modulation {}"), label=Shown(" no mod.", joined=True)))
    gs_compensation: bool = setting(False, Setting(
        "gs mode: scale opacity by sqrt(det(S) / det(S + dilation)), as Mip-Splatting does", modes=("gs",),
        line=Shown("compensation {}"), label=Shown("comp.")))
    supersample: int = setting(1, Setting(
        f"render K x K samples per pixel and average them, K = 1..{MAX_SUPERSAMPLE} (default 1)", "K",
        limits=(1, MAX_SUPERSAMPLE), line=Shown("supersample {0}x{0}"), label=Shown("{0}×{0}")))
    alpha_clamp: bool = setting(False, Setting(
        "clamp every splat's alpha to 0.99, as INRIA and GOF do",
        line=Shown("alpha clamp {}"), label=Shown("alpha clamp")))
    transmittance_cutoff: bool = setting(False, Setting(
        "stop compositing a pixel before its transmittance falls below 1e-4, as INRIA and GOF do",
        line=Shown("transmittance cut-off {}"), label=Shown("T cut-off")))
    order: str = setting("depth", Setting(
        "how each pixel orders its gaussians: depth (one global sort by the centres' view depth, the default), "
        "distance (by their distance from the camera), per-pixel (each pixel sorts its own by where its ray meets "
        "them; RayGS modes)", choices=ORDERS, words=ORDER_LABELS, line=Shown("order {}")))
    order_k: int = setting(0, Setting(
        "per-pixel order: 0 sorts every fragment exactly (default); K re-orders them through a window of K per "
        "pixel (a k-buffer), for speed; implies --order per-pixel", "K", limits=(0, MAX_ORDER_K),
        words={0: "exact"}, what="order K", needs="per_pixel", implies=("order", "per-pixel"),
        line=Shown(" (K={})", worded=" ({})", joined=True)))
    precision: str = setting("float32", Setting(
        "what the blended colour accumulates in: float32 (exact, the default), float16 or 8bit (less fill on a "
        "GPU, at the error bench accuracy states); the per-pixel order and the cut-off keep float32",
        choices=PRECISIONS, words=PRECISION_LABELS, line=Shown("blend {}", worded="blend {}"),
        label=Shown("{}", worded="{} blend")))
    lod: int | None = setting(None, Setting(
        "a streamed SOG (lod-meta.json): draw level N everywhere, 0 the finest (default: choose each part's "
        "level per view)", "N", limits=(0, MAX_LOD_LEVELS - 1), what="level of detail", accuracy=False,
        line=Shown("level {}"), label=Shown("level {}")))
    lod_budget: int | None = setting(None, Setting(
        "a streamed SOG: the most gaussians the per-view choice of levels draws; what is largest on screen "
        "is refined first (default: no limit)", "COUNT", limits=(1, MAX_LOD_BUDGET), what="LOD budget",
        accuracy=False, line=Shown("budget {:,}"), label=Shown("budget {:,}")))
    lod_distance: float | None = setting(None, Setting(
        "a streamed SOG: the distance (scene units) from which level 1 is drawn; level l from 2^(l-1) times it "
        "(default: four half-diagonals of the median part)", "D", limits=(0.0, 1e30), open=True,
        what="LOD distance", accuracy=False, line=Shown("LOD distance {:g}")))

    def effective_sh_degree(self, scene_degree: int) -> int:
        return scene_degree if self.sh_degree is None else min(self.sh_degree, scene_degree)

    @property
    def sort_key(self) -> str:
        """The key of the global CPU sort: "distance" for the distance order, else
        "depth" (per-pixel order's window is fed in the depth order)."""
        return "distance" if self.order == "distance" else "depth"

    @property
    def per_pixel(self) -> bool:
        return self.order == "per-pixel"

    @property
    def mip_active(self) -> bool:
        """Whether a RayGS MIP filter (either form) is applied."""
        return self.mode == "raygs-exact-mip" or (self.mode == "raygs" and self.mip)

    def pixel_variance(self, camera: Camera) -> float:
        """sigma_x^2: the MIP filter's variance at unit distance along a ray, for
        ``camera`` as rendered (already supersampled); 0 when no MIP filter is applied."""
        return self.mip_sigma2 / (camera.fx * camera.fy) if self.mip_active else 0.0

    def cull_dilation(self, camera: Camera) -> float | None:
        """Extra world-space standard deviation per unit of distance that the support
        may gain from filtering (for conservative culling); None where the support is
        not bounded by a dilated 3D ellipsoid (GS: its linearised footprint), so only
        gaussians behind the camera may be culled."""
        if self.mode == "gs":
            return None
        sigma = math.sqrt(self.pixel_variance(camera))
        return sigma * EXACT_MIP_CULL_FACTOR if self.mode == "raygs-exact-mip" else sigma

    def __post_init__(self) -> None:
        for name, info, hint in settings_table(type(self)):
            if name == "background":  # a shape the table does not describe
                object.__setattr__(self, "background", checked_colour(info, self.background))
            else:
                object.__setattr__(self, name, checked(name, info, hint, getattr(self, name)))
        if self.per_pixel and self.mode == "gs":
            raise UserError("per-pixel order needs a RayGS mode: EWA splats have no ray parameter to sort by")


def checked_colour(info: Setting, colour) -> tuple[float, float, float]:
    """``colour`` as three floats, or UserError unless it is three finite numbers within
    ``info``'s limits: a colour beyond 0..1 is no colour the image can show, and the
    blend would carry it into every pixel a gaussian leaves uncovered."""
    if len(colour) != 3 or not all(math.isfinite(c) for c in colour):
        raise UserError(f"background must be three finite numbers, got {colour!r}")
    if not all(info.within(c) for c in colour):
        raise UserError(f"background must be three numbers in {info.interval()}, got {colour!r}")
    return tuple(float(c) for c in colour)


#: The accuracy options: the RenderSettings fields beyond p_min, background and SH degree
#: (what a preset sets, and what the command line's render-settings options carry).
ACCURACY_FIELDS = tuple(name for name, info, _ in settings_table(RenderSettings) if info.accuracy)

#: Named accuracy configurations, as overrides of RenderSettings: the A/B split view's
#: choices for its right side and the rows of ``raygs-viewer bench accuracy``.
#: "RayGS" (the default settings) is the baseline every ratio is taken against.
ACCURACY_PRESETS: dict[str, dict[str, object]] = {
    "GS": {"mode": "gs"},
    "GS + compensation": {"mode": "gs", "gs_compensation": True},
    "RayGS": {},
    "RayGS + MIP": {"mip": True, "mip_modulation": True},
    "RayGS + MIP, no modulation": {"mip": True, "mip_modulation": False},
    "RayGS exact MIP": {"mode": "raygs-exact-mip", "mip_modulation": True},
    "RayGS p_min e^-4": {"p_min": math.exp(-4.0)},
    "RayGS p_min 1e-3": {"p_min": 1e-3},
    "RayGS 2x2 supersampling": {"supersample": 2},
    "RayGS, distance order": {"order": "distance"},
    "RayGS, per-pixel order": {"order": "per-pixel"},
    "RayGS, per-pixel order K=4": {"order": "per-pixel", "order_k": 4},
    "RayGS + MIP, per-pixel order": {"mip": True, "mip_modulation": True, "order": "per-pixel"},
    "RayGS, float16 blend": {"precision": "float16"},
    "RayGS, 8-bit blend": {"precision": "8bit"},
}


def apply_preset(settings: RenderSettings, name: str) -> RenderSettings:
    """``settings`` with the accuracy options of preset ``name`` (the options a preset
    does not name are reset to their defaults; p_min, background and SH degree are kept
    unless the preset sets them)."""
    defaults = RenderSettings()
    reset = {name_: getattr(defaults, name_) for name_ in ACCURACY_FIELDS}
    return replace(settings, **{**reset, **ACCURACY_PRESETS[name]})
