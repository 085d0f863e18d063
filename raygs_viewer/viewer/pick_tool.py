"""What a click or a double-click on the view does: the point under the mouse, picked in
the last frame's view (:mod:`.picking`), aims the view at it, sets the stereo
convergence, or becomes a measured point; a click on a training camera's frustum flies
there.

Double-click (not while measuring): in orbit mode the point becomes the orbit centre,
the view keeping its direction and gliding sideways so that the point sits on the image
centre at the distance it has (what SuperSplat's double-click and Blender's "center view
to mouse" do); in fly mode the view turns in place to face it. In the stereo preview,
with "double-click sets convergence" on, it sets the rig's convergence to the point's
depth instead (the plane of zero disparity is a depth, not a distance). A pixel
without a median depth changes nothing and says so.

Click: while measuring, the point is the measurement's next end; else, on a training
camera's frustum (:mod:`.training_frustums`), the view flies to that camera.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Protocol

from imgui_bundle import imgui

from raygs_viewer.camera.stereo import rig_quantities
from raygs_viewer.capture.measure_file import MeasureScale
from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.viewer.drawing import SceneDrawer
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.measure import MeasureWidget, format_distance
from raygs_viewer.viewer.picking import Picked, mono_pixel, pick, pixel_camera, stereo_pixel
from raygs_viewer.viewer.shown_scene import ShownScene
from raygs_viewer.viewer.state import PanelState, SplitView, StereoPreview
from raygs_viewer.viewer.training_frustums import TrainingFrustums
from raygs_viewer.viewer.view_control import ViewControl

NOTHING_THERE = ("nothing to pick there: that pixel's alpha never reaches 0.5, so it has no median depth "
                 "(the view is unchanged)")
CONVERGENCE = rig_quantities()["convergence"]


class PickHost(Protocol):
    """The window as the pick tool sees it: the last frame (None before the first) and how
    it was drawn, the settings now."""

    scene: ShownScene
    view: ViewControl
    shown: Frame | None
    settings: RenderSettings
    split: SplitView
    stereo: StereoPreview
    panel: PanelState
    drawer: SceneDrawer

    def right_settings(self) -> RenderSettings | None:
        """The split view's right side, None when it is off."""


class PickTool:
    """``last``: the point of the last double-click (the panel shows it); ``frustums``: the
    training cameras drawn in the scene, which a click flies to."""

    def __init__(self, host: PickHost, measure: MeasureWidget, frustums: TrainingFrustums):
        self.host, self.measure, self.frustums = host, measure, frustums
        self.last: Picked | None = None
        self._flew = False  # the last click flew to a training camera

    def point_at(self, x: float, y: float) -> Picked | None | bool:
        """The point under screen position (x, y) in the last frame's view: False outside
        the image (or before the first frame), None where the pixel has no median depth."""
        host, frame = self.host, self.host.shown
        if frame is None:
            return False
        camera = frame.camera
        scale = imgui.get_io().display_framebuffer_scale
        scale = (scale.x or 1.0, scale.y or 1.0)
        origin = None
        if frame.stereo is not None:
            found = stereo_pixel(x, y, frame.viewport, scale, camera, frame.eyes, frame.stereo.layout)
            if found is None:
                return False
            eye, u, v = found
            settings, origin = host.settings, camera.center  # the eyes' colour is the midpoint's
        else:
            pixel = mono_pixel(x, y, frame.viewport, scale, camera)
            if pixel is None:
                return False
            (u, v), eye = pixel, camera
            right = host.right_settings()
            settings = right if right is not None and u >= host.split.column(camera.width) else host.settings
        try:
            order = host.drawer.orders.get(settings.sort_key)
            if order is None:  # none drawn in this key yet: the pixel's own, of the levels drawn
                drawn = next(iter(host.drawer.orders.values()), None)
                order = exact_order(host.scene.direct_sorter, pixel_camera(eye, u, v), settings,
                                    levels=None if drawn is None else drawn.choice, deleted=host.edit_tool.deleted)
            return pick(host.scene.renderer, eye, u, v, settings, order, origin)
        except UserError as exc:  # settings this GPU cannot render (the frame says so too)
            host.panel.error = f"error: nothing picked: {one_line(exc)}"
            return False

    def double_click(self, x: float, y: float) -> None:
        if self.measure.on:
            return  # its two clicks are the measure tool's
        if self._flew and self.host.view.navigator.animating:
            return  # the second press of a double-click on a frustum: its first flies there
        picked = self.point_at(x, y)
        if picked is False:
            return
        panel = self.host.panel
        if picked is None:
            panel.message = NOTHING_THERE
            return
        self.last = picked
        stereo = self.host.stereo
        if self.host.shown.stereo is not None and stereo.converge_on_pick:
            rig = stereo.rig
            stereo.rig = replace(rig, convergence=CONVERGENCE.clamp(picked.depth * rig.scene_scale))
            panel.message = (f"convergence set to {stereo.rig.convergence:.4g} m "
                             f"(the picked point's depth, {picked.depth:.4g} units)")
            return
        navigator = self.host.view.navigator
        navigator.aim_at(picked.point)
        panel.message = f"{describe(picked, self.measure.scale)}: {'orbiting around it' if navigator.mode == 'orbit' else 'facing it'}"

    def click(self, x: float, y: float) -> None:
        if not self.measure.on:
            index = self.frustums.camera_at(x, y)
            self._flew = index is not None
            if self._flew:
                self.host.view.select_training_camera(index)
            return
        picked = self.point_at(x, y)
        if picked is None:
            self.host.panel.message = NOTHING_THERE.replace("the view is unchanged", "no point taken")
        elif picked is not False:
            self.measure.add_point(picked)


def describe(picked: Picked, scale: MeasureScale | None = None) -> str:
    """"point (x, y, z), d from the camera" of a pick, d in ``scale``'s unit when set."""
    x, y, z = picked.point
    return f"point ({x:.4g}, {y:.4g}, {z:.4g}), {format_distance(picked.distance, scale)} from the camera"
