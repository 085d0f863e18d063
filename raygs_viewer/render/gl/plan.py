"""The plan of one render: which variant each pass runs, decided once from the render
settings and what is asked for (colour, or the geometry outputs with or without the
median), before any pass runs.

A :class:`RenderPlan` carries everything a pass needs to know about its variant: the
mode, exact MIP, whether the records and targets carry the geometry outputs, the
per-pixel path (none: blending; "lists"; "fetch"), front to back, the storage layout of
the records, and, where this GPU cannot draw it, the one-line reason. Every pass takes
the plan, so none works its variant out again.

The accuracy options and the scene's SH degree become ``#define`` literals, so a frame
pays only for what is on; the all-features build (``general``) switches the same
features by uniforms instead. :data:`FEATURES` is the one table of those switches: it
gives both the literals and the uniforms.
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from typing import Callable, NamedTuple, Protocol

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.channels import Outputs
from raygs_viewer.render.gl.shaders import Programs
from raygs_viewer.render.gl.storage import StorageLayout
from raygs_viewer.render.settings import (
    ALPHA_CLAMP,
    GS_DILATION,
    GS_NEAR,
    MAX_ORDER_K,
    TRANSMITTANCE_CUTOFF,
    RenderSettings,
)
from raygs_viewer.sort.request import Order

#: The draw's PER_PIXEL define for each per-pixel path (render/gl/per_pixel.py): none,
#: fragment lists (glsl/fragment_lists.glsl), a k-buffer (glsl/kbuffer.glsl).
PER_PIXEL_PATHS = {None: 0, "lists": 1, "fetch": 2}

#: The texture kind (moderngl dtype) the blended colour, and the geometry attachments,
#: accumulate in at each precision (settings.PRECISIONS). The geometry sums are signed
#: and unbounded (depth times alpha), which 8 bits cannot hold: they take float16 there.
COLOR_DTYPES = {"float32": "f4", "float16": "f2", "8bit": "f1"}
GEOMETRY_DTYPES = {"float32": "f4", "float16": "f2", "8bit": "f2"}

#: How the quads reach the vertex stage (splat_blocks.glsl's DRAW_VERTICES): one
#: instance of a 4-vertex strip per splat, the splat from gl_InstanceID; or no instances,
#: the splat from gl_VertexID: an index buffer of 6 indices over 4 vertices per splat
#: ("indexed", as vkgs and vkraygs draw), or 6 vertices per splat and no buffer.
DRAW_VERTICES = {"instanced": 0, "indexed": 1, "triangles": 2}
#: Where a splat's record is: at its scene index, the vertex stage reading it through
#: the order ("scene"); or at its place in the draw, written there by a preprocessing
#: pass that runs over the order, so the vertex stage reads records in sequence and the
#: culled gaussians cost no work ("draw", as vkgs and vkraygs do).
RECORDS = ("scene", "draw")


@dataclass(frozen=True)
class DrawLayout:
    """How a draw lays out its quads and records (:data:`DRAW_VERTICES`, :data:`RECORDS`).
    Every layout draws the same triangles in the same order, so in float32 the image is
    the same to the bit; they differ only in what the GPU does to get there."""

    vertices: str = "instanced"
    records: str = "scene"

    def __post_init__(self) -> None:
        if self.vertices not in DRAW_VERTICES:
            raise ValueError(f"unknown draw vertices '{self.vertices}': use one of {', '.join(DRAW_VERTICES)}")
        if self.records not in RECORDS:
            raise ValueError(f"unknown records '{self.records}': use one of {', '.join(RECORDS)}")

    @property
    def name(self) -> str:
        return self.vertices if self.records == "scene" else f"{self.vertices}, draw-order records"


#: Today's layout, and the default until a GPU has measured the others (docs/performance.md).
DEFAULT_DRAW_LAYOUT = DrawLayout()


class Feature(NamedTuple):
    """One switch of glsl/features.glsl: its literal's name, its uniform's name, and its
    value for some settings and the scene's stored SH degree."""

    define: str
    uniform: str
    value: Callable[[RenderSettings, int], object]


FEATURES = (
    Feature("SH_DEGREE", "u_sh_degree", lambda s, degree: s.effective_sh_degree(degree)),
    Feature("MIP", "u_mip", lambda s, _: bool(s.mode == "raygs" and s.mip)),
    Feature("MIP_MODULATION", "u_mip_modulation", lambda s, _: bool(s.mip_modulation)),
    Feature("GS_COMPENSATION", "u_gs_compensation", lambda s, _: bool(s.mode == "gs" and s.gs_compensation)),
    Feature("ALPHA_CLAMP", "u_alpha_clamp", lambda s, _: bool(s.alpha_clamp)),
)


def glsl_literal(value: object) -> object:
    """A define's value as GLSL reads it: booleans as ``true``/``false``, floats exactly."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return value


@dataclass(frozen=True)
class RenderPlan:
    """One render's variant (see the module docstring).

    settings:  the render settings.
    layout:    the storage layout of the records (exact MIP's are larger, and the
               geometry outputs' hold the normal too).
    outputs:   what the render draws; unless it is colour alone, the records and
               targets carry the geometry outputs (:attr:`geometry`).
    path:      the per-pixel passes that composite (None: blending, or with the cut-off
               the fragment stage composites front to back; "lists"; "fetch").
    sh_degree: the scene's stored SH degree.
    general:   the all-features build (uniforms instead of literals).
    problem:   why this GPU cannot draw the plan (one line), None when it can.
    draw:      the draw layout; the per-pixel passes read records by scene index, so
               with a per-pixel path the records stay in scene order.
    weights:   the passes weigh instead of drawing an image (render/gl/weighing.py): the
               global order front to back (or the lists' resolve) raise each gaussian's
               largest weight T alpha over the pixels weighed.
    """

    settings: RenderSettings
    layout: StorageLayout
    _: KW_ONLY
    outputs: Outputs = "color"
    path: str | None = None
    sh_degree: int = 0
    general: bool = False
    problem: str | None = None
    draw: DrawLayout = DEFAULT_DRAW_LAYOUT
    weights: bool = False

    def __post_init__(self) -> None:
        if self.path is not None and self.draw.records != "scene":
            object.__setattr__(self, "draw", DrawLayout(self.draw.vertices, "scene"))

    @property
    def geometry(self) -> bool:
        """The records and targets carry the geometry outputs."""
        return self.outputs != "color"

    @property
    def records_in_draw_order(self) -> bool:
        return self.draw.records == "draw"

    @property
    def precision(self) -> str:
        """What the blend accumulates in: the settings' precision, or float32 where the
        fragment stage or the per-pixel passes composite (they read the target back, or
        write the image themselves)."""
        return "float32" if self.path is not None or self.front_to_back else self.settings.precision

    def target_dtypes(self, attachments: int) -> tuple[str, ...]:
        """The texture kinds of a target of ``attachments`` this plan draws into: the
        colour's, then the geometry outputs'."""
        return (COLOR_DTYPES[self.precision],) + (GEOMETRY_DTYPES[self.precision],) * (attachments - 1)

    @property
    def direct_dtypes(self) -> tuple[str, ...]:
        """The kind of a colour target this plan draws straight into, with no sample
        target and no resolve pass (``GLRenderer.draw_planned``): the blend precision's,
        unless supersampling or front-to-back compositing resolve into the target
        anyway; then float32, so the resolved image is the one a float32 target gets."""
        if self.settings.supersample > 1 or self.front_to_back:
            return ("f4",)
        return self.target_dtypes(1)

    @property
    def mode_gs(self) -> bool:
        return self.settings.mode == "gs"

    @property
    def exact_mip(self) -> bool:
        return self.settings.mode == "raygs-exact-mip"

    @property
    def front_to_back(self) -> bool:
        """The fragment stage composites front to back (the cut-off, or weights, without a
        per-pixel path)."""
        return (bool(self.settings.transmittance_cutoff) or self.weights) and self.path is None

    @property
    def window(self) -> int:
        """The k-buffer's K (0 elsewhere)."""
        return self.settings.order_k if self.path == "fetch" else 0

    @property
    def colors_at_load(self) -> bool:
        """Whether the preprocessing pass reads the colours computed at load instead of
        evaluating SH (a specialised variant at SH degree 0)."""
        return not self.general and self.settings.effective_sh_degree(self.sh_degree) == 0

    def feature_defines(self) -> dict[str, object]:
        """features.glsl's switches: literals, or GENERAL (then :meth:`feature_uniforms`)."""
        if self.general:
            return {"GENERAL": 1}
        return {"GENERAL": 0, **{f.define: glsl_literal(f.value(self.settings, self.sh_degree)) for f in FEATURES}}

    def feature_uniforms(self) -> dict[str, object]:
        """The all-features build's uniforms; none for a specialised variant."""
        if not self.general:
            return {}
        return {f.uniform: f.value(self.settings, self.sh_degree) for f in FEATURES}

    def preprocess_defines(self, selection: bool = False) -> dict[str, object]:
        """preprocess.comp's; ``selection``: the selected gaussians drawn tinted."""
        defines = {"SH_STORED_DEGREE": self.sh_degree, "MODE_GS": int(self.mode_gs), "GEOMETRY": int(self.geometry),
                   "GS_DILATION": glsl_literal(GS_DILATION), "GS_NEAR": glsl_literal(GS_NEAR),
                   "EXACT_MIP": int(self.exact_mip), "RECORDS_IN_DRAW_ORDER": int(self.records_in_draw_order),
                   "SELECTION": int(selection), **self.feature_defines()}
        if not self.general:
            defines["COLOR_AT_LOAD"] = glsl_literal(self.colors_at_load)
        return defines

    def pass_defines(self) -> dict[str, object]:
        """What the per-pixel passes share with the draw: the splat blocks, the record's
        layout, the cut-off, the path (PER_PIXEL) and the k-buffer's window."""
        return {"SPLAT_BLOCKS": self.layout.splat_blocks, "SPLATS_PER_BLOCK": self.layout.splats_per_block,
                "EXACT_MIP": int(self.exact_mip), "GEOMETRY": int(self.geometry), "MODE_GS": int(self.mode_gs),
                "MIN_TRANSMITTANCE": glsl_literal(TRANSMITTANCE_CUTOFF), "PER_PIXEL": PER_PIXEL_PATHS[self.path],
                "CUTOFF": glsl_literal(bool(self.settings.transmittance_cutoff)),
                "FRONT_TO_BACK": int(self.front_to_back), "MAX_ORDER_K": MAX_ORDER_K, "ORDER_K": max(1, self.window),
                "DRAW_VERTICES": DRAW_VERTICES[self.draw.vertices],
                "RECORDS_IN_DRAW_ORDER": int(self.records_in_draw_order), "WEIGHTS": int(self.weights)}

    def draw_stages(self, floor: bool = False) -> tuple[str, str, dict[str, object]]:
        """(vertex shader, fragment shader, defines) of the quads; ``floor``: glsl/quads.*,
        the same quads with a constant fragment (bench perf)."""
        if floor and self.mode_gs:
            raise ValueError("the floor pass draws RayGS quads; EWA's records are not quads in space")
        stage = "quads" if floor else "gs" if self.mode_gs else "raygs"
        defines = {"ALPHA_MAX": glsl_literal(ALPHA_CLAMP), **self.pass_defines(), **self.feature_defines()}
        return f"{stage}.vert", f"{stage}.frag", defines

    def resolve_defines(self, unorm8_target: bool = False) -> dict[str, object]:
        """resolve.frag's: averaging a sample target down, adding the background after
        front-to-back compositing, the geometry attachments too; rounding as a
        screenshot does into an 8-bit target (``unorm8_target``: a headset's image)."""
        return {"FRONT_TO_BACK": int(self.front_to_back), "GEOMETRY": int(self.geometry),
                "UNORM8_TARGET": int(unorm8_target)}


class Passes(Protocol):
    """What the per-pixel passes need of a renderer: the programs, and the quads' draw of
    a plan with a pass's own uniforms (``GLRenderer.draw``)."""

    programs: Programs

    def draw(self, camera: Camera, plan: RenderPlan, order: Order, *, floor: bool = False,
             uniforms: dict | None = None) -> None: ...
