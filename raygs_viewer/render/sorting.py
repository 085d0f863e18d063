"""The sort a render asks for: one :class:`~raygs_viewer.sort.request.SortRequest` made
from the render settings of every side shown, and the exact order of a view sorted in
place (what ``render``, ``render-path``, screenshots and the benchmarks draw; the window
sorts the same requests on its sort thread, or with the GPU sort on its own).

Two sorters answer a request with the same orders (docs/performance.md, the sort): the
CPU's (:class:`~raygs_viewer.sort.depth.DepthSorter`, the default) and the GPU's
(:class:`~raygs_viewer.render.gl.gpu_sort.GpuSorter`), which keeps its orders on the GPU;
:func:`open_sorter` makes the one ``--sort`` names."""

from __future__ import annotations

from dataclasses import replace
from typing import Callable, Sequence

import moderngl
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.gl.profile import Choice, GlProfile, gl_identity, load_profile
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.model import Scene
from raygs_viewer.sort.depth import DepthSorter
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest
from raygs_viewer.sort.deleted import DeletedRows
from raygs_viewer.sort.request import Order, SortRequest, keys_of

#: The sorts there are: the CPU's and the GPU's (``--sort`` also takes "auto": :func:`chosen_sort`).
SORTS = ("cpu", "gpu")


def chosen_sort(kind: str, ctx: moderngl.Context, count: int) -> Choice:
    """The sort ``kind`` names for a scene of ``count`` gaussians: "cpu" or "gpu" as
    they are; "auto" the one this GL's remembered profile measured faster
    (``render.gl.profile``), the CPU's where the GL was never measured."""
    if kind != "auto":
        return Choice(kind, f"sort: {kind.upper()} (--sort {kind})")
    profile, _ = load_profile(*gl_identity(ctx))  # an unreadable file: the window and doctor say so
    if profile is None:
        return Choice("cpu", "sort: CPU, this GL is not measured yet (`raygs-viewer doctor` or the window measure it)")
    return measured_sort(profile, ctx, count)


def measured_sort(profile: GlProfile, ctx: moderngl.Context, count: int) -> Choice:
    """``profile``'s sort for ``count`` gaussians, the CPU's where the GPU sort cannot
    hold that many on ``ctx`` (``GpuSorter.capacity``)."""
    choice = profile.sort_choice(count)
    if choice.value == "gpu" and count > GpuSorter.capacity(ctx):
        return Choice("cpu", f"sort: CPU, the GPU sort holds at most {GpuSorter.capacity(ctx):,} gaussians here")
    return choice


def open_sorter(kind: str, ctx: moderngl.Context, scene: Scene) -> DepthSorter | GpuSorter:
    """The sorter ``kind`` (one of :data:`SORTS`, or "auto": :func:`chosen_sort`) of
    ``scene``; a UserError in one line where this GPU cannot run the GPU sort
    (``GpuSorter.problem``). The GPU sort runs on the thread that holds ``ctx``."""
    kind = chosen_sort(kind, ctx, scene.count).value
    if kind not in SORTS:
        raise ValueError(f"unknown sort {kind!r}: use one of {', '.join(SORTS)}")
    return GpuSorter(ctx, scene) if kind == "gpu" else DepthSorter(scene)


def sort_request(camera: Camera, settings: RenderSettings, right: RenderSettings | None = None, *,
                 cull_cameras: Sequence[Camera] | None = None,
                 levels: LodRequest | LodChoice | None = None, deleted: DeletedRows | None = None) -> SortRequest:
    """The one sort that serves every side shown (``right``: the split view's other
    side): the more conservative cull of the two (the smaller p_min; no frustum culling
    if either side needs none, else the larger dilation) and an order per side's key,
    the left's first. ``cull_cameras``: keep what any of them sees (stereo: both eyes,
    which share the midpoint's fx and fy, hence its dilation). ``levels``: a streamed
    SOG's levels to choose for ``camera``, or the choice already made. ``deleted``: the
    gaussians deleted, which no order holds."""
    sides = [settings] if right is None else [settings, right]
    dilations = [side.cull_dilation(camera) for side in sides]
    dilation = None if any(d is None for d in dilations) else max(dilations)
    return SortRequest(camera, min(side.p_min for side in sides), dilation,
                       None if cull_cameras is None else tuple(cull_cameras),
                       keys_of([side.sort_key for side in sides]), levels=levels, deleted=deleted)


def exact_order(sorter: DepthSorter, camera: Camera, settings: RenderSettings, *,
                cull_cameras: Sequence[Camera] | None = None,
                levels: LodRequest | LodChoice | None = None, deleted: DeletedRows | None = None) -> Order:
    """``camera``'s order for ``settings``, sorted now (see :func:`sort_request`)."""
    return sorter.sort(sort_request(camera, settings, cull_cameras=cull_cameras, levels=levels, deleted=deleted)).order


def part_orders(sorter: DepthSorter, camera: Camera, settings: RenderSettings, view: Order, *,
                levels: LodRequest | LodChoice | None = None, deleted: DeletedRows | None = None
                ) -> Callable[[Camera], Order]:
    """For a part of ``camera``'s image (or an eye's, culled from ``camera``'s pose): the
    order ``view`` (what the view draws, sorted from ``camera``) holding only the
    gaussians the cull keeps for that part, in ``view``'s own sequence. Sorting the part
    afresh would not do: the radix sort quantises its keys over the depth range of what
    its cull kept, so near ties fall one way in a part and the other in the whole view."""
    indices = np.asarray(view.indices.read() if view.on_device else view.indices)

    def order_of(part: Camera) -> Order:
        kept = exact_order(sorter, camera, settings, cull_cameras=[part], levels=levels, deleted=deleted)
        rows = np.asarray(kept.indices.read() if kept.on_device else kept.indices)
        member = np.zeros(max(int(indices.max(initial=0)), int(rows.max(initial=0))) + 1, bool)
        member[rows] = True
        return replace(view, indices=indices[member[indices]], request=None)
    return order_of

