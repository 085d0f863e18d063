"""Keys and mouse, read from imgui once a frame: shortcuts, camera movement, the A/B
split view's divider drag, and clicks and double-clicks on the view (picking a point).

A click is a left press and release with the mouse moved at most CLICK_SLOP screen
units between them (a drag turns the camera instead); a double-click is imgui's (two
presses within its io.mouse_double_click_time). Shortcuts and clicks come back as
requests (``part.Press``, ``part.Click``) for the window to carry out.
:meth:`InputHandler.inject` queues a double-click directly, through the same handling,
for what cannot wait on real time (tests, scripts).

imgui has already decided whether the panel wants the keyboard or the mouse; what it
wants is left alone. Positions are in screen coordinates (imgui's), the viewport in
framebuffer pixels: ``io.display_framebuffer_scale`` converts.
"""

from __future__ import annotations

import math
from typing import get_args

from imgui_bundle import imgui

from raygs_viewer.camera.navigation import Navigator
from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.viewer.part import Click, Press, Request, Shortcut
from raygs_viewer.viewer.state import SplitView

#: The divider's position, as a fraction of the viewport's width, stays in this range.
SPLIT_RANGE = (0.02, 0.98)
#: The divider can be grabbed this many screen pixels either side of it.
SPLIT_GRAB = 6.0
#: A press and release this close (screen units) are a click, not a drag.
CLICK_SLOP = 3.0

Key = imgui.Key
#: The shortcuts, in the order they are handled: each request -> the keys that make it.
SHORTCUTS: dict[Shortcut, tuple] = {
    "quit": (Key.escape,),
    "screenshot": (Key.f12,),
    "add_keyframe": (Key.k,),
    "switch_navigation": (Key.tab,),
    "next_camera": (Key.n, Key.page_down),
    "previous_camera": (Key.p, Key.page_up),
    "reset_view": (Key.r, Key.home),
    "toggle_panel": (Key.h, Key.f1),
}


#: The keys that type text: shortcuts and movement on them wait for the pointer to leave the panel.
LETTERS = frozenset(getattr(Key, letter) for letter in "abcdefghijklmnopqrstuvwxyz")


assert set(SHORTCUTS) == set(get_args(Shortcut))


class InputHandler:
    """The keys and the mouse of the view, each frame: they move the camera, drag the
    split view's divider, and come back as requests (shortcuts, clicks)."""

    def __init__(self) -> None:
        self.dragging_divider = False   # the left button holds the split view's divider
        self._press: tuple[float, float] | None = None   # where the left button went down on the view
        self._injected: list[tuple[float, float]] = []

    def inject(self, x: float, y: float) -> None:
        """A double-click at screen position (x, y), handled in the next frame as a real
        one is (unless the panel has the mouse there)."""
        self._injected.append((float(x), float(y)))

    def handle(self, dt: float, navigator: Navigator, *, camera: Camera | None, viewport: tuple[int, int, int, int],
               split: SplitView | None, mouse_taken: bool = False, keys_taken: tuple = ()) -> list[Request]:
        """One frame's input: moves ``navigator``; returns the shortcuts pressed and the
        clicks on the view, in order. ``camera`` and ``viewport``: the last frame's view;
        ``split``: the split view while it is shown (its divider can be dragged);
        ``mouse_taken``: an edit tool draws with the mouse this frame (keys only);
        ``keys_taken``: keys a part answered this frame, whose shortcuts do nothing."""
        io = imgui.get_io()
        requests: list[Request] = []
        if not io.want_capture_keyboard and not self._panel_clicked(io):
            # Letters act on the view only while the pointer is not over the panel: a
            # person typing a path has the pointer there, and a field that lost the keys
            # (Enter, a click beside it) must not turn the next letters into shortcuts.
            requests += self._keys(io, dt, navigator, letters=not io.want_capture_mouse, taken=keys_taken)
        injected, self._injected = self._injected, []
        if mouse_taken:
            self._press = None
        elif self._divider(io, viewport, split):
            self._press = None  # the mouse drags the split view's divider, not the camera
        elif not io.want_capture_mouse:
            requests += self._clicks(io, injected)
            self._mouse(io, navigator, camera, viewport)
        else:
            self._press = None
        return requests

    @staticmethod
    def _panel_clicked(io) -> bool:
        """Whether a button went down on the panel this frame. imgui's keyboard capture
        is last frame's: a click into a text field and the first letters typed into it
        can arrive in one frame (a fast typist, xdotool), and those letters are the
        field's, not shortcuts."""
        return io.want_capture_mouse and any(imgui.is_mouse_clicked(b) for b in range(3))

    def _clicks(self, io, injected: list[tuple[float, float]]) -> list[Click]:
        x, y = io.mouse_pos.x, io.mouse_pos.y
        if not (math.isfinite(x) and math.isfinite(y)):
            self._press = None
            return []
        clicks = []
        if imgui.is_mouse_clicked(0):
            self._press = (x, y)
        elif self._press is not None and imgui.is_mouse_released(0):
            press, self._press = self._press, None
            if abs(x - press[0]) <= CLICK_SLOP and abs(y - press[1]) <= CLICK_SLOP:
                clicks.append(Click(x, y))
        if imgui.is_mouse_double_clicked(0):
            injected.append((x, y))
        return clicks + [Click(*position, double=True) for position in injected]

    def _keys(self, io, dt: float, navigator: Navigator, letters: bool = True, taken: tuple = ()) -> list[Press]:
        """The shortcuts pressed, and the movement keys; with ``letters`` False only the
        keys that type no text (F12, Escape, Tab, Page Up/Down, Home, F1)."""
        pressed = [Press(shortcut) for shortcut, keys in SHORTCUTS.items()
                   if any(imgui.is_key_pressed(k, False) for k in keys
                          if (letters or k not in LETTERS) and k not in taken)]
        if not letters:
            return pressed

        def down(k) -> float:
            return 1.0 if imgui.is_key_down(k) else 0.0
        right = down(Key.d) - down(Key.a)
        upward = down(Key.e) - down(Key.q)
        forward = down(Key.w) - down(Key.s)
        if right or upward or forward:
            navigator.move(dt, right, upward, forward, fast=io.key_shift, slow=io.key_ctrl)
        return pressed

    @staticmethod
    def _mouse(io, navigator: Navigator, camera: Camera | None, viewport: tuple[int, int, int, int]) -> None:
        dx, dy = io.mouse_delta.x, io.mouse_delta.y
        if not (math.isfinite(dx) and math.isfinite(dy)):
            dx = dy = 0.0
        # A button that went down this frame starts its drag here: the frame's delta is
        # the pointer's move before the press (a quick move then a click arrive in one
        # frame at a few frames a second), not a drag.
        left, right, middle = (imgui.is_mouse_down(b) and not imgui.is_mouse_clicked(b) for b in (0, 1, 2))
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
