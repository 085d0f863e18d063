"""The preprocessing pass (glsl/preprocess.comp): the per-view splat records of a scene
(colour, opacity, c^2, quad axes), of every gaussian at its scene index, of an order's
level-of-detail rows only, or of an order's gaussians at their places in it.

It runs only when something it reads changed: its variant, its uniforms, the rows (and,
in draw order, the order itself). A change only the draw or the picture sees (the
background, a level-of-detail budget that chooses the same rows) costs no pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.gl.plan import RenderPlan
from raygs_viewer.render.gl.shaders import Programs, set_uniform
from raygs_viewer.render.gl.storage import SceneBuffers, place_runs, spread_runs
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import Order

WORKGROUP = 128  # local_size_x of preprocess.comp


@dataclass
class WorkCounters:
    """What the renderer did and skipped since it was made (for tests and the panel)."""

    preprocessed: int = 0       # preprocessing passes run
    preprocess_skipped: int = 0  # ... skipped: the records were already this view's
    uploads: int = 0            # order uploads
    upload_skipped: int = 0     # ... skipped: that order was already on the GPU


class PreprocessPass:
    """One scene's preprocessing into ``storage``'s record buffers, with ``programs``;
    ``upload(order)`` puts an order on the GPU (the renderer's one door for orders);
    ``counters`` counts the passes run and skipped."""

    def __init__(self, ctx: moderngl.Context, storage: SceneBuffers, programs: Programs,
                 upload: Callable[[Order], None], counters: WorkCounters):
        self.ctx, self.storage, self.programs, self.upload, self.counters = ctx, storage, programs, upload, counters
        self._key: tuple | None = None          # what the records in storage.splats were made for
        self._order: np.ndarray | None = None  # ... the order, for records in draw order
        self._last_layout = storage.layout

    def run(self, camera: Camera, plan: RenderPlan, order: Order | None = None, *, frame: Camera | None = None,
            color_origin: np.ndarray | None = None) -> None:
        """Writes the per-view splat records for ``camera`` (the camera actually
        rasterized: already supersampled) in ``plan``'s variant: of every gaussian at its
        scene index, or only of ``order``'s level-of-detail rows (``Order.spans``); or,
        with records in draw order, of ``order``'s gaussians at their places in it
        (``order`` required). ``frame``: the whole image's camera when ``camera`` renders
        one tile of it (GS clamps rays to the whole image). ``color_origin``: the world
        point SH colour is seen from (default: the camera's centre; stereo shares the
        eyes' midpoint)."""
        origin = camera.center if color_origin is None else np.asarray(color_origin, np.float64)
        in_draw_order = plan.records_in_draw_order
        if in_draw_order and order is None:
            raise ValueError("records in draw order are preprocessed for an order")
        spans = None if order is None or in_draw_order or order.spans is None else order.spans
        selection = self.storage.selection_key
        defines = plan.preprocess_defines(selection is not None)
        uniforms = {**view_uniforms(camera, plan.settings, frame, origin), **plan.feature_uniforms()}
        key = (tuple(defines.items()), tuple(uniforms.items()), plan.layout, plan.colors_at_load,
               None if spans is None else spans.tobytes(), selection)
        if key == self._key and (not in_draw_order or order.indices is self._order):
            self.counters.preprocess_skipped += 1
            return
        self._key = self._order = None  # until this pass has written every record
        self.storage.hold_records(plan.layout, plan.settings.mode)
        self._last_layout = plan.layout
        program = self.programs.compute("preprocess.comp", defines)
        for name, value in uniforms.items():
            set_uniform(program, name, value)
        if selection is not None:
            self.storage.bind_selection()
        if in_draw_order:
            self._places(program, plan, order)
        else:
            for chunk in self.storage.preprocess_chunks(plan.layout, plan.colors_at_load):
                program["u_out_offset"].value = chunk.offset
                set_uniform(program, "u_chunk_start", chunk.start)  # read by the selection's tint only
                for first, count in chunk_runs(chunk.start, chunk.count, spans):
                    set_uniform(program, "u_first", first)  # gone where a negative control breaks the shader
                    program["u_count"].value = count
                    program.run(group_x=-(-count // WORKGROUP))
        self.ctx.memory_barrier()
        self.counters.preprocessed += 1
        self._key = key
        self._order = order.indices if in_draw_order else None

    def _places(self, program: moderngl.ComputeShader, plan: RenderPlan, order: Order) -> None:
        """The draw-order preprocessing's dispatches: one per (chunk, splat block) the
        order's places fall in (storage.place_runs); for an order on the GPU, one per
        chunk and block (storage.spread_runs)."""
        self.upload(order)
        layout = plan.layout
        if order.on_device:
            # Grouping the places by chunk on the host would read the order back: a stall
            # until the sort is done and 4 bytes a place over the bus, every frame. Each
            # block's places run once per chunk instead, each place not in the chunk
            # costing one read of the order; where one chunk holds the scene (up to 2M
            # gaussians at SH degree 0, 131k at degree 3, with 128 MiB blocks) that is
            # one dispatch per block, no more than the grouped ones.
            ranks, runs = None, spread_runs(order.count, layout)
        else:
            ranks, runs = place_runs(order.host_indices(), layout)
        self.storage.bind_places(order.count, ranks)
        set_uniform(program, "u_ranked", ranks is not None)
        for run in runs:
            self.storage.bind_chunk(layout, plan.colors_at_load, run.chunk_start)
            self.storage.bind_records(layout, run.block_start)
            set_uniform(program, "u_chunk_start", run.chunk_start)
            set_uniform(program, "u_chunk_rows", min(layout.chunk, layout.count - run.chunk_start))
            set_uniform(program, "u_block_start", run.block_start)
            set_uniform(program, "u_first", run.first)
            program["u_count"].value = run.count
            program.run(group_x=-(-run.count // WORKGROUP))

    def forget(self) -> None:
        """The next :meth:`run` runs whatever it last wrote (a benchmark times it)."""
        self._key = self._order = None

    def read(self) -> np.ndarray:
        """(N, F) float32 copy of the per-view records of the last :meth:`preprocess`
        (the ``Splat`` struct, row by row; F = 16, or 28 in exact MIP mode; with records
        in draw order, the first rows are the order's places), for tests and diagnostics."""
        return self.storage.read_records(self._last_layout)


def view_uniforms(camera: Camera, settings: RenderSettings, frame: Camera | None, origin: np.ndarray) -> dict:
    """The preprocessing pass's uniforms of the view (see ``PreprocessPass.run``), by
    name: everything it reads of the camera and the settings."""
    return {"u_world_to_camera": camera.R.astype(np.float32).tobytes(order="F"),
            "u_translation": tuple(np.asarray(camera.t, np.float64).astype(np.float32).tolist()),
            "u_color_origin": tuple(origin.astype(np.float32).tolist()),  # gone at SH degree 0
            "u_log_p_min": math.log(settings.p_min),
            "u_pixel_variance": settings.pixel_variance(camera),
            "u_intrinsics": (camera.fx, camera.fy, camera.cx, camera.cy),
            "u_ray_bounds": gs_ray_bounds(frame or camera)}


def chunk_runs(start: int, count: int, spans: np.ndarray | None) -> list[tuple[int, int]]:
    """(first, count) runs, relative to the chunk, of the chunk's rows ``start ..
    start + count`` that ``spans`` cover (all of them for None)."""
    if spans is None:
        return [(0, count)]
    lo = np.maximum(spans[:, 0], start)
    hi = np.minimum(spans[:, 1], start + count)
    keep = hi > lo
    return [(int(a) - start, int(b - a)) for a, b in zip(lo[keep], hi[keep])]


def gs_ray_bounds(camera: Camera) -> tuple[float, float, float, float]:
    """INRIA's clamp box for the ray x/z, y/z of GS's Jacobian: the image's borders
    widened by 15 % of its size on each side (lower x, lower y, upper x, upper y)."""
    margin_x, margin_y = 0.15 * camera.width / camera.fx, 0.15 * camera.height / camera.fy
    return (-camera.cx / camera.fx - margin_x, -camera.cy / camera.fy - margin_y,
            (camera.width - camera.cx) / camera.fx + margin_x, (camera.height - camera.cy) / camera.fy + margin_y)
