"""The per-pixel order (``RenderSettings.order == "per-pixel"``, maths page section 11):
which path renders it, and the figures it reports.

Two paths: "lists" (render/gl/fragment_lists.py: per-pixel fragment lists in a bounded
pool, exact or with a window of K; any OpenGL 4.3 driver) and "fetch"
(render/gl/kbuffer.py: a k-buffer through framebuffer fetch, the bounded order only, K
up to the colour attachments less one). ``order_path`` "auto" takes fetch where it can
run and lists elsewhere; forcing a path that cannot run is a UserError.
"""

from __future__ import annotations

import moderngl

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl import kbuffer
from raygs_viewer.render.gl.fragment_lists import FragmentLists
from raygs_viewer.render.gl.plan import Passes, RenderPlan
from raygs_viewer.render.gl.results import OrderStats
from raygs_viewer.render.gl.storage import gpu_limit
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import Order

ORDER_PATHS = ("auto", "lists", "fetch")


#: Storage blocks the lists path binds besides the records (fragment_lists.glsl: counts,
#: row offsets, cursors, pool, row bases, status); its resolve pass also reads the records.
LIST_BLOCKS = 6


def storage_block_problem(ctx: moderngl.Context, path: str, splat_blocks: int) -> str | None:
    """Why ``path`` cannot bind its storage blocks on this GPU with records in
    ``splat_blocks`` blocks, or None. OpenGL 4.3 guarantees only 8 per stage and 8 in
    all; desktop drivers offer 16 per stage or more."""
    fragment = LIST_BLOCKS if path == "lists" else splat_blocks  # the k-buffer reads evicted colours
    needs = {"GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS": fragment,
             "GL_MAX_COMBINED_SHADER_STORAGE_BLOCKS": 1 + splat_blocks + fragment,  # with the vertex stage's
             "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS": splat_blocks + (LIST_BLOCKS if path == "lists" else 0)}
    for limit, needed in needs.items():
        offered = gpu_limit(ctx, limit, 8)
        if needed > offered:
            return (f"the per-pixel order needs {needed} storage blocks where this GPU offers {offered} "
                    f"({limit}) for a scene of this size")
    return None


def choose_path(ctx: moderngl.Context, settings: RenderSettings, scene_count: int, order_path: str = "auto",
                lists_only: bool = False) -> str:
    """"lists" or "fetch" for ``settings`` on a GPU of ``ctx``'s extensions and limits
    (UserError: ``order_path`` "fetch" cannot run); ``lists_only``: the geometry outputs,
    which only the lists give (the k-buffer's attachments are full)."""
    problem = kbuffer.why_not(ctx, settings, scene_count)
    if lists_only:
        problem = problem or "the geometry outputs need the fragment lists"
    if order_path == "fetch" and problem:
        raise UserError(problem)
    if order_path == "lists" or problem:
        return "lists"
    return "fetch"


class PerPixelOrder:
    """The per-pixel order of one renderer: its paths' buffers, made on first use.
    ``block_limit``: bytes one storage block may hold; ``pool_fragments``: the lists'
    pool (default :data:`~raygs_viewer.render.gl.fragment_lists.DEFAULT_POOL_FRAGMENTS`)."""

    def __init__(self, ctx: moderngl.Context, block_limit: int, pool_fragments: int | None = None,
                 order_path: str = "auto"):
        if order_path not in ORDER_PATHS:
            raise UserError(f"order path must be one of {', '.join(ORDER_PATHS)}, got {order_path!r}")
        self.ctx = ctx
        self.order_path = order_path
        self.lists = FragmentLists(ctx, block_limit, pool_fragments)
        self._kbuffer: kbuffer.KBuffer | None = None

    def render(self, passes: Passes, target: FloatTarget, camera: Camera, plan: RenderPlan,
               order: Order) -> OrderStats:
        """Draws ``order`` into ``target`` (float32, camera-sized) by ``plan``'s per-pixel
        path; ``passes`` has preprocessed ``camera``. With ``plan.geometry`` the target has
        the geometry attachments (render/gl/fragment_lists.py)."""
        if plan.path == "lists":
            return self.lists.render(passes, target, camera, plan, order)
        if self._kbuffer is None:
            self._kbuffer = kbuffer.KBuffer(self.ctx)
        return self._kbuffer.render(passes, target, camera, plan, order)

    def release(self) -> None:
        self.lists.release()
        if self._kbuffer is not None:
            self._kbuffer.release()
            self._kbuffer = None
