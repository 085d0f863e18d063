"""How a render is planned (:class:`Planner`): from its settings, what is asked for, the
scene's storage layout and what the GPU offers, the :class:`~raygs_viewer.render.gl.plan.RenderPlan`
every pass then follows.

The GPU enters only through its extensions and limits (:class:`GLCapabilities`), which a
``moderngl.Context`` has and a :class:`GpuDescription` states without opening one: the
renderer plans with its context (``GLRenderer.planner``, made once); the shader variants
(:mod:`raygs_viewer.render.gl.variants`) plan with described GPUs, through this same
code, every render the renderer can make.
"""

from __future__ import annotations

from collections.abc import Mapping, Set
from dataclasses import KW_ONLY, dataclass, field
from typing import Callable, Protocol

from raygs_viewer.errors import UserError
from raygs_viewer.render.channels import Outputs
from raygs_viewer.render.gl.geometry import takes_lists
from raygs_viewer.render.gl.kbuffer import FRAMEBUFFER_FETCH
from raygs_viewer.render.gl.per_pixel import choose_path, storage_block_problem
from raygs_viewer.render.gl.plan import DEFAULT_DRAW_LAYOUT, DrawLayout, RenderPlan
from raygs_viewer.render.gl.storage import EXACT_MIP_SPLAT_BYTES, GEOMETRY_BYTES, SPLAT_BYTES, StorageLayout
from raygs_viewer.render.settings import RenderSettings


class GLCapabilities(Protocol):
    """What planning reads of a GL context: its extension names and ``ctx.info``'s limits."""

    @property
    def extensions(self) -> Set[str]: ...

    @property
    def info(self) -> Mapping[str, object]: ...


@dataclass(frozen=True, eq=False)
class GpuDescription:
    """A GPU's extensions and limits, stated rather than read from a driver."""

    extensions: frozenset[str] = frozenset()
    info: Mapping[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class Planner:
    """What a render's plan is decided from besides what the render asks (its settings,
    outputs and draw layout: :meth:`plan`'s arguments); made once per renderer.

    gpu:         the GPU's extensions and limits (the renderer's context).
    layout_for:  the storage layout of records of so many bytes (``SceneBuffers.layout_for``;
                 UserError where this GPU cannot bind them).
    scene_count, sh_degree: the scene's gaussians and stored SH degree.
    general, order_path: the renderer's options (``GLRenderer``).
    """

    gpu: GLCapabilities
    layout_for: Callable[[int], StorageLayout]
    scene_count: int
    sh_degree: int
    _: KW_ONLY
    general: bool = False
    order_path: str = "auto"

    def plan(self, settings: RenderSettings, outputs: Outputs = "color",
             draw_layout: DrawLayout = DEFAULT_DRAW_LAYOUT) -> RenderPlan:
        """The plan of a render of ``settings`` that draws ``outputs`` (colour, or the
        geometry outputs too, with or without the median depth, which only the fragment
        lists give) in ``draw_layout``."""
        geometry = outputs != "color"
        lists_geometry = geometry and takes_lists(settings, outputs == "median")
        record = EXACT_MIP_SPLAT_BYTES if settings.mode == "raygs-exact-mip" else SPLAT_BYTES
        layout = self.layout_for(record + (GEOMETRY_BYTES if geometry else 0))
        path, problem = None, None
        if settings.per_pixel or lists_geometry:  # composites in its own passes, the cut-off included
            try:
                path = choose_path(self.gpu, settings, self.scene_count, self.order_path, lists_geometry)
                problem = storage_block_problem(self.gpu, path, layout.splat_blocks)
            except UserError as error:  # a forced k-buffer that cannot run
                path, problem = "fetch", str(error)
        elif settings.transmittance_cutoff and FRAMEBUFFER_FETCH not in self.gpu.extensions:
            # The blend cannot stop a pixel without reading it (NVIDIA's desktop drivers
            # have no fetch): the fragment lists composite the global order with the
            # cut-off in their own pass, as they do for the geometry outputs.
            path = "lists"
            problem = storage_block_problem(self.gpu, path, layout.splat_blocks)
        return RenderPlan(settings, layout, outputs=outputs, path=path, sh_degree=self.sh_degree,
                          general=self.general, problem=problem, draw=draw_layout)
