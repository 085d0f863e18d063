"""Keys and mouse, read from imgui once a frame: shortcuts, camera movement, and the
A/B split view's divider drag.

imgui has already decided whether the panel wants the keyboard or the mouse; what it
wants is left alone. Positions are in screen coordinates (imgui's), the viewport in
framebuffer pixels: ``io.display_framebuffer_scale`` converts.
"""

from __future__ import annotations

import math
from typing import Callable, Mapping

from imgui_bundle import imgui

from raygs_viewer.camera.navigation import Navigator
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.viewer.state import SplitView

#: The divider's position, as a fraction of the viewport's width, stays in this range.
SPLIT_RANGE = (0.02, 0.98)
#: The divider can be grabbed this many screen pixels either side of it.
SPLIT_GRAB = 6.0

Key = imgui.Key
#: The shortcuts, in the order they are handled: action name -> the keys that trigger it.
SHORTCUTS: dict[str, tuple] = {
    "quit": (Key.escape,),
    "screenshot": (Key.f12,),
    "add_keyframe": (Key.k,),
    "switch_navigation": (Key.tab,),
    "next_camera": (Key.n, Key.page_down),
    "previous_camera": (Key.p, Key.page_up),
    "reset_view": (Key.r, Key.home),
    "toggle_panel": (Key.h, Key.f1),
}


class InputHandler:
    """``actions`` maps each SHORTCUTS name to what it does."""

    def __init__(self, actions: Mapping[str, Callable[[], None]]):
        self.actions = dict(actions)
        self.dragging_divider = False   # the left button holds the split view's divider

    def handle(self, dt: float, navigator: Navigator, camera: Camera | None,
               viewport: tuple[int, int, int, int], split: SplitView | None) -> None:
        """One frame's input. ``camera`` and ``viewport``: the last frame's view;
        ``split``: the split view while it is shown (its divider can be dragged)."""
        io = imgui.get_io()
        if not io.want_capture_keyboard:
            self._keys(io, dt, navigator)
        if self._divider(io, viewport, split):
            return  # the mouse drags the split view's divider, not the camera
        if not io.want_capture_mouse:
            self._mouse(io, navigator, camera, viewport)

    def _keys(self, io, dt: float, navigator: Navigator) -> None:
        for action, keys in SHORTCUTS.items():
            if any(imgui.is_key_pressed(k, False) for k in keys):
                self.actions[action]()
        def down(k) -> float:
            return 1.0 if imgui.is_key_down(k) else 0.0
        right = down(Key.d) - down(Key.a)
        upward = down(Key.e) - down(Key.q)
        forward = down(Key.w) - down(Key.s)
        if right or upward or forward:
            navigator.move(dt, right, upward, forward, fast=io.key_shift, slow=io.key_ctrl)

    @staticmethod
    def _mouse(io, navigator: Navigator, camera: Camera | None, viewport: tuple[int, int, int, int]) -> None:
        dx, dy = io.mouse_delta.x, io.mouse_delta.y
        if not (math.isfinite(dx) and math.isfinite(dy)):
            dx = dy = 0.0
        left, right, middle = (imgui.is_mouse_down(b) for b in (0, 1, 2))
        wheel = io.mouse_wheel
        if navigator.mode == "fly":
            if (left or right) and (dx or dy):
                navigator.look(dx, dy)
            if wheel:
                navigator.scale(wheel)
            return
        panning = right or middle or (left and io.key_shift)
        if panning and (dx or dy):
            scale = io.display_framebuffer_scale
            # The image's focal length in window pixels (the stereo preview is scaled).
            focal = camera.fy * viewport[3] / camera.height if camera is not None else 1000.0
            navigator.pan(dx * scale.x, dy * scale.y, focal)
        elif left and (dx or dy):
            navigator.rotate(dx, dy)
        if wheel:
            navigator.zoom(wheel)

    def _divider(self, io, viewport: tuple[int, int, int, int], split: SplitView | None) -> bool:
        """A left press within SPLIT_GRAB screen pixels of the divider (not on the panel)
        grabs it, and it follows the mouse until the button is released. True while the
        mouse belongs to the divider (the camera ignores it)."""
        if split is None:
            self.dragging_divider = False
            return False
        scale = io.display_framebuffer_scale
        sx, sy = (scale.x or 1.0), (scale.y or 1.0)
        vx, vy, vw, vh = viewport
        mx, my = io.mouse_pos.x, io.mouse_pos.y
        finite = math.isfinite(mx) and math.isfinite(my) and abs(mx) < 1e30 and abs(my) < 1e30
        if self.dragging_divider:
            if not imgui.is_mouse_down(0):
                self.dragging_divider = False
            elif finite and vw > 0:
                low, high = SPLIT_RANGE
                split.fraction = min(max((mx * sx - vx) / vw, low), high)
            imgui.set_mouse_cursor(imgui.MouseCursor_.resize_ew.value)
            return True
        if io.want_capture_mouse or not finite:
            return False
        divider = (vx + split.column(vw)) / sx
        if abs(mx - divider) <= SPLIT_GRAB and vy / sy <= my <= (vy + vh) / sy:
            imgui.set_mouse_cursor(imgui.MouseCursor_.resize_ew.value)
            if imgui.is_mouse_clicked(0):
                self.dragging_divider = True
                return True
        return False
