"""The interactive viewer: a GLFW window, the RayGS renderer, and an imgui panel on top.

:class:`Viewer` is the desktop window's loop over what ``window_state.WindowState``
holds: each frame it takes the input, draws the panel, makes the frame once
(``frame.Frame``), lets the parts draw over the view, draws the scene and shows it.
The last frame stays as ``Viewer.shown``. Screenshots re-render the same view offscreen
with an exact sort, so they reproduce headlessly from their sidecar
(``raygs-viewer render --sidecar``); the window's own image (panel included) is kept
for ``--window-screenshot``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from imgui_bundle import imgui

from raygs_viewer.camera.pinhole import Camera
from raygs_viewer.capture.image_io import check_output_path, save_image
from raygs_viewer.capture.screenshot import check_screenshot_path
from raygs_viewer.capture.sidecar import load_camera_source
from raygs_viewer.errors import UserError
from raygs_viewer.photos.evaluate import evaluation_settings, render_view
from raygs_viewer.render.gl.context import context_description
from raygs_viewer.render.lod_view import lod_settings_given
from raygs_viewer.scene.loader import LoadedScene, load_now
from raygs_viewer.scene.progress import ProgressCallback
from raygs_viewer.sort.request import SortResult
from raygs_viewer.viewer.drawing import SortAsked, request_sort
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.headset import mirror_framing
from raygs_viewer.viewer.headset_steps import HeadsetSteps
from raygs_viewer.viewer.lod_window import first_levels, lod_request, reading
from raygs_viewer.viewer.overlay import draw_split_overlay
from raygs_viewer.viewer.panel_sections import Draft, panel_sections
from raygs_viewer.viewer.part import Click, Shown
from raygs_viewer.viewer.photo_view import Drawn, blocked_reason, standing_at
from raygs_viewer.viewer.screenshots import (
    Saved,
    Shot,
    ShownView,
    levels_read,
    screenshot_said,
    sidecar_extra,
)
from raygs_viewer.viewer.state import ViewerOptions, failed, mended
from raygs_viewer.viewer.stats import summary
from raygs_viewer.viewer.window import choose_platform
from raygs_viewer.xr.eyes import HeadsetEyes
from raygs_viewer.xr.runtime import check_runtime


class Viewer(HeadsetSteps):
    """The desktop window: ``frame()`` runs one iteration of the loop; ``run()`` loops
    until the window closes or ``options.frames`` are drawn (see ``WindowState`` for
    what it holds and its factories)."""

    def frame(self) -> None:
        """One iteration of the loop. Its steps, in this order, and why:

        1. The clock, the window's events, and what finished in the background: a loaded
           scene is shown before anything reads the scene shown; the headset's news (a
           session that began or ended: the window's vsync follows it).
        2. The parts act (``Part.act``, in the order of :attr:`parts`), on the last
           frame's view (what the pointer is over): the edit tool's handles and shapes
           take the left button before the camera can.
        3. The camera: the keys and the mouse move it and come back as shortcuts and
           clicks (a pick reads the last frame's view); the view flies on; the path plays
           last, so that it yields to what the user did.
        4. The panel draws, from the last frame, and returns what it changed: the render
           settings (a draft), messages and requests, carried out before the frame is made.
        5. In the headset, the runtime's wait paces the loop here, as late as it can be:
           its eyes are located just before they are drawn. The frame is made, once, from
           the camera (or the headset's eyes) and everything the panel set; its sort is
           asked for (never waited on but on a scripted run's last frame).
        6. The parts draw over the view (``Part.overlay``, the same order: back to front;
           not over the headset's mirror), then the notes.
        7. The draw returns a report: the statistics record it, the photo view follows it.
           In the headset, both eyes are drawn and submitted instead, and the window
           shows them as submitted.
        8. Present, keep the window's image, swap; a screenshot asked for (it re-renders
           offscreen); one step of a probe under way.
        """
        dt = self.stats.tick(self.clock())
        self.frame_index += 1
        self.window.poll_events()
        self.take_loaded()
        self.follow_headset()
        width, height = self.window.framebuffer_size()
        if width <= 0 or height <= 0:  # minimised: nothing to show
            if self.headset.running:  # the headset goes on: the runtime paces the loop
                self._headset_unseen(dt)
            elif self.options.frames is None:  # do not spin
                self.window.wait_events(0.1)
            return
        self.window.begin_frame()
        imgui.new_frame()
        self.feedback.watch(self.panel)  # what the last frame's actions said
        if imgui.is_mouse_clicked(0):
            self.feedback.clicked()
        self._act(dt)
        draft = Draft(self.settings)
        reply = self.side_panel.draw(panel_sections(self, draft))
        self.settings = draft.settings
        self.answer(reply)
        eyes = self.wait_for_headset(dt)
        frame, result, asked = self._make_frame(eyes)
        scene, pointing = self.scene_view(), self.pointing()
        self.overlay_rects = {} if not frame.split else draw_split_overlay(
            frame.viewport, self.split, self.settings, self.input.dragging_divider)
        for part in self.parts if eyes is None else ():  # the mirror shows the eyes as submitted
            self.answer(part.overlay(frame, scene, pointing))
        width_shown = imgui.get_io().display_size.x
        left = self.side_panel.notes_left(width_shown)
        self.feedback.draw(left, 10.0, width_shown - left - 10.0)
        imgui.render()
        if eyes is not None:
            self.draw_headset(frame, result, asked)
        else:
            self.headset.submit_empty()  # a headset frame waited for with no eyes located: ended, empty
            self._draw(frame, result, asked)
        self.drawer.mono.present(self.ctx.screen, (width, height), frame.viewport,
                                 self.split.column(frame.viewport[2]))
        if self.captures.window_due():
            self.captures.window = self.capture_window()
        self.window.end_frame()
        if self.captures.due():
            self.panel.say(screenshot_said(self._save_shots))
        if self.auto.step():  # this GL's profile is measured: its sort for the scene shown, its blend
            self.panel.say(self.swap_said(self.scene.resort(), "sort"))
            self.settings = self.auto.settings(self.settings, self.options.settings)

    def _act(self, dt: float) -> None:
        """Steps 2 and 3 of :meth:`frame`: the parts act, then the camera moves."""
        shown, mouse_free, keys_taken = Shown(self.shown, self.scene_view(), self.pointing().divider,
                                             self.stats.last_frame_time), True, ()
        for part in self.parts:
            reply = part.act(shown, mouse_free)
            mouse_free = mouse_free and not reply.took_mouse
            keys_taken += reply.took_keys
            self.answer(reply)
        for request in self.input.handle(dt, self.view.navigator, camera=self.camera, viewport=self.viewport,
                                         split=self.split if self.right_settings() is not None else None,
                                         mouse_taken=not mouse_free, keys_taken=keys_taken):
            if isinstance(request, Click) and self.headset.running:
                continue  # a click on the mirror picks nothing: it shows the eyes, not the view it would pick in
            self.carry_out(request)
        self.view.advance(dt, self.options.navigation.turntable)
        self.camera_path.follow(self.view, self.stats.last_frame_time)

    def _headset_unseen(self, dt: float) -> None:
        """A headset frame while the window is minimised: waited for, drawn and submitted,
        with nothing shown on the desktop."""
        eyes = self.wait_for_headset(dt)
        if eyes is None:
            self.headset.submit_empty()
            return
        self.draw_headset(*self._make_frame(eyes))

    def _make_frame(self, eyes: HeadsetEyes | None = None) -> tuple[Frame, SortResult | None, SortAsked]:
        """Step 5 of :meth:`frame`: the frame, and its sort asked for (the newest result
        to draw, after a streamed SOG's level arrived the last order until its first).
        ``eyes``: a headset frame's, which it is made for (mono, culled for both eyes,
        sorted from their midpoint; the desktop mirrors them)."""
        stereo, said = self.stereo.frame_view(self.shown_stereo)
        self.panel.say(said)
        right = self.right_settings()
        views = self.view_mode.side_views(split=right is not None)
        self.panel.say(views[2])
        if eyes is not None:
            stereo, views = None, (None, None, None)
            framing = mirror_framing(eyes, self.view_area(), self.headset.choices.mirror)
        else:
            framing = self.view.camera(self.view_area(), stereo, self.stereo.headset_size)
        frame = self.shown = Frame.make(self.frame_index, framing, stereo=stereo, settings=self.settings, right=right,
                                        lod=self.frame_lod(), deleted=self.edit_tool.deleted, views=views[:2])
        # wait_for_sort: only the last frame of a scripted run, whose capture must show the finished view.
        result, asked = request_sort(self.scene.sorter, frame, self.wait_for_sort)
        return frame, self.scene.shown(result), asked

    def _draw(self, frame: Frame, result: SortResult | None, asked: SortAsked) -> None:
        """Step 7 of :meth:`frame`."""
        report = self.drawer.draw(self.scene.renderer, frame, result, asked, self.scene.sort_timer)
        self.stats.record(report)
        # Settings this GPU cannot render (the panel greys those out) stand until they mend.
        self.panel.say(mended("draw") if report.problem is None else failed(report.problem, source="draw"))
        view, mono = self.view, self.drawer.mono
        index = standing_at(view.cameras, view.training_index, view.lens, view.navigator.pose)
        self.panel.say(self.photo.frame(Drawn(
            self.loaded, None if mono.left is None else index, frame.camera,
            blocked_reason(frame.stereo is not None, frame.split, self.view_mode.channel), report.drew, mono,
            # At a training camera's own size the Photo view renders as ``evaluate`` does, with the
            # panel's settings over the dataset's background, so the two measure one PSNR.
            lambda photo_view, dataset: render_view(self.scene.renderer, self.scene.direct_sorter, photo_view,
                                                    evaluation_settings(self.settings, dataset)))))

    def capture_window(self, overlay: bool = True) -> np.ndarray:
        """(H, W, 3) uint8, top row first: the window as shown, panel included;
        ``overlay=False``: without anything imgui draws (panel, divider, labels)."""
        return self.drawer.mono.capture(self.window.framebuffer_size(), self.viewport,
                                        self.split.column(self.viewport[2]),
                                        self.window.draw_imgui if overlay else None)

    def save_screenshot(self, path: str | Path | None = None) -> Saved:
        """Re-renders the last frame's view offscreen (:mod:`.screenshots`) and saves it;
        returns the (png, json) pair, the left side's or the stereo pair's."""
        frame = self.shown
        if frame is None:
            raise UserError("nothing has been drawn yet")
        if self.headset.active:
            self.captures.saved = self.headset.save_shot(
                self.loaded, extra=sidecar_extra(self.view.navigator, self.loaded, self.view.training_index,
                                                 context_description(self.ctx)),
                edits=self.edit_tool.sidecar_entry(self.loaded), levels=levels_read(self.loaded, self.settings),
                path=path, folder=self.captures.options.folder)
            return self.captures.last
        self.photo.check_screenshot()
        self.scene.lod.check_screenshot()
        # The settings now: what the frame drew, or what a script set since.
        shown = ShownView(frame.full_camera, self.settings, frame.stereo, self.drawer.shown_view,
                          self.split if self.right_settings() is not None else None, self.drawer.shown_right_view)
        extra = sidecar_extra(self.view.navigator, self.loaded, self.view.training_index,
                              context_description(self.ctx))
        shot = Shot(shown, self.loaded, lod_request(self.loaded, self.settings), self.stereo.save_eyes, extra,
                    self.edit_tool.deleted, self.edit_tool.sidecar_entry(self.loaded))
        self.scene.renderer.set_selection(None)  # a screenshot shows the scene, not the selection's tint
        return self.captures.take(self.scene.renderer, self.scene.direct_sorter, shot, path)

    def _save_shots(self) -> list[Saved]:
        """Every (png, json) pair a screenshot of the last frame writes."""
        self.save_screenshot()
        return self.captures.saved

    # -- loop ------------------------------------------------------------------------
    def run(self) -> None:
        """Frames until the window closes or ``options.frames`` are drawn (in the
        headset: headset frames submitted); the last keeps the window's image for
        ``--window-screenshot``."""
        options = self.options
        while not (self.window.should_close and self.may_close()):
            if options.headset.enter and options.frames is None and self.window.platform == "null" \
                    and not self.headset.active:
                break  # an invisible window whose headset session ended has nothing left to show
            last = options.frames is not None and self.frames_done() + 1 >= options.frames
            self.captures.keep_next |= last and options.window_screenshot is not None
            self.wait_for_sort = last
            if last:  # a scripted run ends on every level of a streamed SOG its settings want
                self.frame_lod()
                if reading(self.loaded, self.scenes.loader):
                    self.scenes.loader.wait_done()
            self.frame()
            if last:
                break

    def may_close(self) -> bool:
        """Whether the window, asked to close, may: not at the first ask while deletions
        are not exported (the panel says so, and the same ask again closes)."""
        problem = self.edit_tool.exporter.may_close(self.edit_tool.edits)
        if problem is None:
            return True
        self.window.keep_open()
        self.panel.say(problem)
        return False

    def summary(self) -> str:
        """One line of the frame statistics, printed after a scripted run."""
        gpu_times, post_times = self.drawer.gpu_times()
        return summary(self.stats, self.frame_index, camera=self.camera, stereo=self.shown_stereo, gpu_times=gpu_times,
                       post_times=post_times, scene_count=self.loaded.scene.count,
                       general=self.scene.renderer.general)


def load_start_scene(options: ViewerOptions, progress: ProgressCallback | None = None) -> LoadedScene:
    """The scene the window opens with, read before it opens so that a bad file fails on
    the command line: a streamed SOG up to its coarsest level (or --lod N's), the window
    reads the rest."""
    source = options.source
    loaded = load_now(source.with_levels(first_levels(source, options.settings)), progress)
    given = lod_settings_given(options.settings)
    if loaded.lod is None and given:  # start values of the panel: kept for a streamed SOG opened later
        loaded.warnings.append(f"{', '.join(given)}: not for this scene, which is not a streamed SOG "
                               "(lod-meta.json); kept for one opened later")
    return loaded


def start_camera(options: ViewerOptions) -> Camera | None:
    """The start view of ``--camera``: a cameras.json's camera, or a screenshot sidecar's
    (the view of a screenshot, to go on from)."""
    return None if options.camera is None else load_camera_source(options.camera, options.camera_index)


def run_viewer(options: ViewerOptions, progress: ProgressCallback | None = None) -> int:
    """Opens the window and runs until it is closed (or ``options.frames`` have been
    drawn); returns the exit status. Bad input found before the window opens (scene,
    cameras, screenshot path) raises UserError, so the CLI exits with status 2.
    ``progress`` follows the scene's load, before the window opens."""
    if choose_platform(options.platform) == "null" and options.frames is None and options.platform == "auto" \
            and not options.headset.enter:
        # An invisible window that runs until killed would look like a hang (not so in a
        # headset: it shows the scene, e.g. a headless machine streaming through WiVRn).
        raise UserError("no display (DISPLAY and WAYLAND_DISPLAY are unset): run on a desktop, or add "
                        "--frames N --screenshot shot.png for a headless capture")
    if options.screenshot is not None:
        check_screenshot_path(options.screenshot)
    if options.window_screenshot is not None:
        if not options.window_screenshot.lower().endswith(".png"):
            raise UserError(f"{options.window_screenshot}: the window screenshot must be a .png")
        check_output_path(options.window_screenshot)
    if options.headset.enter:
        check_runtime()  # before a large scene's load
    loaded = load_start_scene(options, progress)
    for warning in loaded.warnings:
        print(f"warning: {warning}", flush=True)
    viewer = Viewer(options, loaded, start_camera(options))
    try:
        if options.headset.enter:
            entered = viewer.headset.enter()
            if entered.kind == "error":  # the CLI says it once, with its own "error: "
                raise UserError(entered.text.removeprefix("error: "))
            viewer.panel.say(entered)
        viewer.run()
        captures = viewer.captures
        if options.screenshot is not None:
            viewer.save_screenshot(options.screenshot)
        if options.window_screenshot is not None and captures.window is not None:
            save_image(options.window_screenshot, captures.window.astype(np.float32) / 255.0)
        if options.headset.enter and viewer.headset.session is not None:
            line = viewer.headset.summary()  # the scripted headset run's one line
            viewer.leave_headset()
            print(line, flush=True)
        elif options.frames is not None:
            print(viewer.summary(), flush=True)
        if captures.last is not None and options.screenshot is not None:
            for png, sidecar in captures.saved:
                print(f"{png} (+ {sidecar.name})")
    finally:
        viewer.close()
    return 0


__all__ = ["Viewer", "load_start_scene", "run_viewer", "start_camera"]
