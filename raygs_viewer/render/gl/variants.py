"""The renderer's shader variants: which ``#define`` each pass gets for a scene and its
settings, compiled on first use and kept by those defines.

The accuracy options of :class:`~raygs_viewer.render.settings.RenderSettings` and the
scene's SH degree become literals, so a frame pays only for what is on; ``general=True``
compiles the one variant that switches every feature by uniforms instead
(:meth:`ShaderVariants.set_features`), to measure what specialising saves.
"""

from __future__ import annotations

import moderngl

from raygs_viewer.render.gl.shaders import ProgramAndArray, Programs, set_uniform
from raygs_viewer.render.gl.storage import StorageLayout
from raygs_viewer.render.settings import (
    ALPHA_CLAMP,
    GS_DILATION,
    GS_NEAR,
    MAX_ORDER_K,
    TRANSMITTANCE_CUTOFF,
    RenderSettings,
)

#: The draw's PER_PIXEL define for each per-pixel path (render/gl/per_pixel.py): none,
#: fragment lists (glsl/fragment_lists.glsl), a k-buffer (glsl/kbuffer.glsl).
PER_PIXEL_PATHS = {None: 0, "lists": 1, "fetch": 2}


def _glsl_bool(value: bool) -> str:
    return "true" if value else "false"


def _glsl_float(value: float) -> str:
    return repr(float(value))


class ShaderVariants:
    """The programs of one renderer: ``sh_degree`` is its scene's stored degree,
    ``general`` selects the all-features variant. ``programs`` builds and keeps them
    (the per-pixel order's passes ask it too). Release with :meth:`release`."""

    def __init__(self, ctx: moderngl.Context, sh_degree: int, general: bool = False):
        self.sh_degree = sh_degree
        self.general = bool(general)
        self.programs = Programs(ctx)

    def colors_at_load(self, settings: RenderSettings) -> bool:
        """Whether this variant reads colours computed at load instead of evaluating SH."""
        return not self.general and settings.effective_sh_degree(self.sh_degree) == 0

    def feature_defines(self, settings: RenderSettings) -> dict[str, object]:
        """The feature switches of features.glsl: literals for this scene and these
        settings, or GENERAL (uniforms, set by :meth:`set_features`)."""
        if self.general:
            return {"GENERAL": 1}
        return {"GENERAL": 0,
                "SH_DEGREE": settings.effective_sh_degree(self.sh_degree),
                "MIP": _glsl_bool(settings.mode == "raygs" and settings.mip),
                "MIP_MODULATION": _glsl_bool(settings.mip_modulation),
                "GS_COMPENSATION": _glsl_bool(settings.mode == "gs" and settings.gs_compensation),
                "ALPHA_CLAMP": _glsl_bool(settings.alpha_clamp)}

    def set_features(self, program, settings: RenderSettings) -> None:
        """The general variant's feature uniforms (features.glsl), from ``settings``;
        nothing for a specialised variant, which has them as literals."""
        if not self.general:
            return
        set_uniform(program, "u_sh_degree", settings.effective_sh_degree(self.sh_degree))
        set_uniform(program, "u_mip", settings.mode == "raygs" and settings.mip)
        set_uniform(program, "u_mip_modulation", settings.mip_modulation)
        set_uniform(program, "u_gs_compensation", settings.mode == "gs" and settings.gs_compensation)
        set_uniform(program, "u_alpha_clamp", settings.alpha_clamp)

    def preprocess(self, settings: RenderSettings, geometry: bool = False) -> moderngl.ComputeShader:
        """preprocess.comp for ``settings``; ``geometry``: records with the normal."""
        defines = {"SH_STORED_DEGREE": self.sh_degree,
                   "MODE_GS": int(settings.mode == "gs"),
                   "GEOMETRY": int(geometry),
                   "GS_DILATION": _glsl_float(GS_DILATION),
                   "GS_NEAR": _glsl_float(GS_NEAR),
                   "EXACT_MIP": int(settings.mode == "raygs-exact-mip"),
                   **self.feature_defines(settings)}
        if not self.general:
            defines["COLOR_AT_LOAD"] = _glsl_bool(self.colors_at_load(settings))
        return self.programs.compute("preprocess.comp", defines)

    def order_defines(self, settings: RenderSettings, layout: StorageLayout, path: str | None = None,
                      window: int = 0, geometry: bool = False) -> dict[str, object]:
        """What the per-pixel order's programs share with the draw: the splat blocks of
        ``layout``, the cut-off, the path (PER_PIXEL), the k-buffer's ``window`` and
        whether the records and passes carry the geometry outputs."""
        return {"SPLAT_BLOCKS": layout.splat_blocks, "SPLATS_PER_BLOCK": layout.splats_per_block,
                "EXACT_MIP": int(settings.mode == "raygs-exact-mip"),  # the record's layout
                "GEOMETRY": int(geometry),
                "MODE_GS": int(settings.mode == "gs"),
                "MIN_TRANSMITTANCE": _glsl_float(TRANSMITTANCE_CUTOFF),
                "PER_PIXEL": PER_PIXEL_PATHS[path],
                "CUTOFF": _glsl_bool(settings.transmittance_cutoff),
                "FRONT_TO_BACK": int(settings.transmittance_cutoff and path is None),
                "MAX_ORDER_K": MAX_ORDER_K,
                "ORDER_K": max(1, window)}

    def draw(self, settings: RenderSettings, layout: StorageLayout, floor: bool = False,
             path: str | None = None, geometry: bool = False) -> ProgramAndArray:
        """The quad stages for ``settings`` reading the splat blocks of ``layout``;
        ``floor``: glsl/quads.*, the same quads with a constant fragment. ``path``: the
        per-pixel order's draw ("lists": count and fill; "fetch": the k-buffer of
        ``settings.order_k`` entries), None for blending. ``geometry``: records with
        the normal (the lists feeding the geometry outputs)."""
        gs = settings.mode == "gs"
        if floor and gs:
            raise ValueError("the floor pass draws RayGS quads; EWA's records are not quads in space")
        defines = {"ALPHA_MAX": _glsl_float(ALPHA_CLAMP),
                   **self.order_defines(settings, layout, path, settings.order_k if path == "fetch" else 0,
                                        geometry),
                   **self.feature_defines(settings)}
        stage = "quads" if floor else "gs" if gs else "raygs"
        return self.programs.draw(f"{stage}.vert", f"{stage}.frag", defines)

    def resolve(self, front_to_back: bool, geometry: bool = False) -> ProgramAndArray:
        """The full-screen pass that averages a sample target down (resolve.frag); with
        ``geometry``, its two geometry attachments too."""
        return self.programs.fullscreen("resolve.frag", {"FRONT_TO_BACK": int(front_to_back),
                                                         "GEOMETRY": int(geometry)})

    def release(self) -> None:
        self.programs.release()
