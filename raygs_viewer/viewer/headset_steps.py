"""The steps of the desktop loop (``app.Viewer``) that a headset adds: following the
session (its news, the window's vsync), waiting for the runtime's frame and placing its
eyes, drawing and submitting them, and a scripted run's count of headset frames and its
end. The headset's own state and work are ``headset.HeadsetMode``'s; this is where the
window's state meets it.
"""

from __future__ import annotations

import time

import numpy as np

from raygs_viewer.camera.navigation import UP_AXES
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.sort.request import SortResult
from raygs_viewer.viewer.drawing import SortAsked, order_for
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.state import failed, mended
from raygs_viewer.viewer.window_state import WindowState
from raygs_viewer.xr.eyes import HeadsetEyes

#: Window frames a scripted headset run waits for the session to start (and to end):
#: the runtime takes a few; this many is a runtime that is not going to.
MAX_FRAMES_TO_START = 600


class HeadsetSteps(WindowState):
    """The headset's steps of ``app.Viewer``'s loop, on the state ``WindowState`` holds."""

    def follow_headset(self) -> None:
        """The headset's news (a session that began, ended or was lost), and the window's
        vsync: off while the runtime paces the loop, as asked otherwise."""
        said = self.headset.poll()
        self.panel.say(*said)
        if said and not self.headset.active:
            self.drawer.forget()  # the desktop draws its own view again
        vsync = self.options.vsync and not self.headset.running
        if self.window.vsync != vsync:
            self.window.vsync = vsync

    def wait_for_headset(self, dt: float) -> HeadsetEyes | None:
        """A running headset's next frame (its wait paces the loop) and its eyes, placed
        by the desktop view, the stereo rig's scale and the controllers (None: no
        headset frame to draw this time)."""
        if not self.headset.running:
            return None
        area = self.view_area()
        # A minimised window has no view: the room stays where the last one put it.
        desktop = self.view.camera(area, None).camera if min(area[2:]) > 0 else self.headset.desktop
        up = np.asarray(UP_AXES[self.view.navigator.up], np.float64)
        # A scripted run's screenshot: its last frame's eyes, and the first drawn until then
        # (a last frame the runtime does not show leaves the one before it).
        scripted = self.options.screenshot is not None and self.options.frames is not None and (
            self.wait_for_sort or self.headset.last_shot is None)
        self.headset.capture_asked = self.captures.requested or scripted
        return self.headset.wait(desktop or self.view.camera((0, 0, 64, 64), None).camera, up,
                                 self.stereo.rig.scene_scale, dt)

    def draw_headset(self, frame: Frame, result: SortResult | None, asked: SortAsked) -> None:
        """Step 7 of ``Viewer.frame`` in the headset: both eyes drawn and submitted, the
        desktop shows them as submitted."""
        order = order_for({} if result is None else result.orders, self.settings.sort_key)
        age = asked.serial - (0 if result is None else result.serial)
        # The headset shows the scene (as its screenshots and their sidecars do): the
        # selection's tint is an editing aid of the desktop view, which sets it again.
        self.scene.renderer.set_selection(None)
        try:
            mirror = self.headset.draw(self.scene.renderer, self.settings, order, order_age=age)
        except UserError as exc:
            self.panel.say(failed(one_line(exc), source="draw"))
            return
        self.panel.say(mended("draw"))
        if mirror is not None:
            self.drawer.mono.drawn(("headset", self.frame_index), mirror)

    def frames_done(self) -> int:
        """The frames a scripted run has drawn: the window's, or with ``--xr`` the headset
        frames submitted (a session that is over, or never runs, is an error)."""
        if not self.options.headset.enter:
            return self.frame_index
        if not self.headset.active:
            said = self.panel.error or "the headset session ended"
            raise UserError(f"{said} after {self.headset.stats.ended} of {self.options.frames} headset frames")
        if not self.headset.running and self.frame_index > MAX_FRAMES_TO_START:
            raise UserError(f"the headset session did not start within {MAX_FRAMES_TO_START} frames "
                            f"(it is {self.headset.session.state})")
        return self.headset.stats.ended

    def leave_headset(self) -> None:
        """Ends the session and follows it until it is over (a scripted run's end); one
        the runtime does not end in time is abandoned. The window then draws its own
        view again."""
        self.headset.leave()
        for _ in range(MAX_FRAMES_TO_START):
            if not self.headset.active:
                break
            self.panel.say(*self.headset.poll())
            time.sleep(0.01)
        self.headset.abandon()
        self.drawer.forget()
