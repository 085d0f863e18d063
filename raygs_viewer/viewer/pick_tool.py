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

from imgui_bundle import imgui

from raygs_viewer.camera.stereo import rig_quantities
from raygs_viewer.capture.measure_file import MeasureScale
from raygs_viewer.errors import UserError
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.viewer.measure import format_distance
from raygs_viewer.viewer.part import AimAt, Converge, FlyTo, MeasurePoint, Pointing, Reply, Shown
from raygs_viewer.viewer.picking import Picked, mono_pixel, pick, pixel_camera, stereo_pixel
from raygs_viewer.viewer.state import failed, note

NOTHING_THERE = ("nothing to pick there: that pixel's alpha never reaches 0.5, so it has no median depth "
                 "(the view is unchanged)")
CONVERGENCE = rig_quantities()["convergence"]


class PickTool:
    """``last``: the point of the last double-click (the panel shows it)."""

    def __init__(self) -> None:
        self.last: Picked | None = None
        self._flew = False  # the last click flew to a training camera

    @staticmethod
    def point_at(x: float, y: float, shown: Shown, divider: int | None = None) -> Picked | None | bool:
        """The point under screen position (x, y) in the last frame's view (``shown``):
        False outside the image (or before the first frame), None where the pixel has no
        median depth. ``divider``: the split view's first column of the right side. A
        UserError where the GPU cannot draw the view's settings (the frame says so too)."""
        frame, scene = shown.frame, shown.scene
        if frame is None:
            return False
        camera = frame.camera
        scale = imgui.get_io().display_framebuffer_scale
        scale = (scale.x or 1.0, scale.y or 1.0)
        origin = None
        if frame.stereo is not None:
            found = stereo_pixel(x, y, frame.viewport, scale, camera, eyes=frame.eyes, layout=frame.stereo.layout)
            if found is None:
                return False
            eye, u, v = found
            settings, origin = frame.settings, camera.center  # the eyes' colour is the midpoint's
        else:
            pixel = mono_pixel(x, y, frame.viewport, scale, camera)
            if pixel is None:
                return False
            (u, v), eye = pixel, camera
            right = frame.right
            settings = right if right is not None and divider is not None and u >= divider else frame.settings
        order = scene.orders.get(settings.sort_key)
        if order is None:  # none drawn in this key yet: the pixel's own, of the levels drawn
            drawn = next(iter(scene.orders.values()), None)
            order = exact_order(scene.sorter, pixel_camera(eye, u, v), settings,
                                levels=None if drawn is None else drawn.choice, deleted=scene.deleted)
        return pick(scene.renderer, eye, u, v, settings=settings, order=order, color_origin=origin)

    def double_click(self, x: float, y: float, shown: Shown, pointing: Pointing) -> Reply:
        """The point under (x, y) aims the view at it, or sets the stereo convergence to
        its depth."""
        if pointing.measuring:
            return Reply()  # its two clicks are the measure tool's
        if self._flew and pointing.flying:
            return Reply()  # the second press of a double-click on a frustum: its first flies there
        picked = self._point(x, y, shown, pointing)
        if isinstance(picked, Reply):
            return picked
        self.last = picked
        if shown.frame.stereo is not None and pointing.converge:
            metres = CONVERGENCE.clamp(picked.depth * pointing.rig.scene_scale)
            return Reply.of(Converge(metres), note(f"convergence set to {metres:.4g} m "
                                                   f"(the picked point's depth, {picked.depth:.4g} units)"))
        aimed = "orbiting around it" if pointing.orbiting else "facing it"
        return Reply.of(AimAt(picked.point), note(f"{describe(picked, pointing.scale)}: {aimed}"))

    def click(self, x: float, y: float, shown: Shown, pointing: Pointing, frustum: int | None = None) -> Reply:
        """While measuring, the point under (x, y) is the measurement's next end; else a
        click on a training camera's frustum (``frustum``: the one under (x, y), None:
        none) flies there."""
        if not pointing.measuring:
            self._flew = frustum is not None
            return Reply.of(FlyTo(frustum)) if self._flew else Reply()
        picked = self._point(x, y, shown, pointing, NOTHING_THERE.replace("the view is unchanged", "no point taken"))
        return picked if isinstance(picked, Reply) else Reply.of(MeasurePoint(picked))

    def _point(self, x: float, y: float, shown: Shown, pointing: Pointing, nothing: str = NOTHING_THERE
               ) -> Picked | Reply:
        """The point under (x, y), or what the panel says where there is none."""
        try:
            picked = self.point_at(x, y, shown, pointing.divider)
        except UserError as exc:  # settings this GPU cannot render (the frame says so too)
            return Reply.of(failed(exc, "nothing picked"))
        if picked is False:
            return Reply()
        return Reply.of(note(nothing)) if picked is None else picked


def describe(picked: Picked, scale: MeasureScale | None = None) -> str:
    """"point (x, y, z), d from the camera" of a pick, d in ``scale``'s unit when set."""
    x, y, z = picked.point
    return f"point ({x:.4g}, {y:.4g}, {z:.4g}), {format_distance(picked.distance, scale)} from the camera"
