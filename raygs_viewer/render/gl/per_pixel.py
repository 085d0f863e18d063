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
import numpy as np

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.errors import UserError
from raygs_viewer.render.gl import kbuffer
from raygs_viewer.render.gl.fragment_lists import FragmentLists
from raygs_viewer.render.gl.order_stats import OrderStats
from raygs_viewer.render.gl.targets import FloatTarget
from raygs_viewer.render.settings import RenderSettings

ORDER_PATHS = ("auto", "lists", "fetch")


class PerPixelOrder:
    """The per-pixel order of one renderer: its paths' buffers, made on first use.
    ``block_limit``: bytes one storage block may hold; ``pool_fragments``: the lists'
    pool (default :data:`~raygs_viewer.render.gl.fragment_lists.DEFAULT_POOL_FRAGMENTS`)."""

    def __init__(self, ctx: moderngl.Context, scene_count: int, block_limit: int,
                 pool_fragments: int | None = None, order_path: str = "auto"):
        if order_path not in ORDER_PATHS:
            raise UserError(f"order path must be one of {', '.join(ORDER_PATHS)}, got {order_path!r}")
        self.ctx = ctx
        self.scene_count = scene_count
        self.order_path = order_path
        self.lists = FragmentLists(ctx, block_limit, pool_fragments)
        self._kbuffer: kbuffer.KBuffer | None = None

    def path_for(self, settings: RenderSettings) -> str:
        """"lists" or "fetch" for ``settings`` (UserError: forced "fetch" cannot run)."""
        problem = kbuffer.why_not(self.ctx, settings, self.scene_count)
        if self.order_path == "fetch" and problem:
            raise UserError(problem)
        if self.order_path == "lists" or problem:
            return "lists"
        return "fetch"

    def problem(self, settings: RenderSettings) -> str | None:
        """None when ``settings``' per-pixel order can be rendered, else why not."""
        try:
            self.path_for(settings)
        except UserError as error:
            return str(error)
        return None

    def render(self, renderer, target: FloatTarget, camera: Camera, settings: RenderSettings,
               order: np.ndarray) -> OrderStats:
        """Draws ``order`` into ``target`` (float32, camera-sized) by the per-pixel order;
        the renderer has preprocessed ``camera``."""
        if self.path_for(settings) == "lists":
            return self.lists.render(renderer, target, camera, settings, order)
        if self._kbuffer is None:
            self._kbuffer = kbuffer.KBuffer(self.ctx)
        return self._kbuffer.render(renderer, target, camera, settings, order)

    def release(self) -> None:
        self.lists.release()
        if self._kbuffer is not None:
            self._kbuffer.release()
            self._kbuffer = None
