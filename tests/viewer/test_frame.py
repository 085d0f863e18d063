"""One frame's inputs as one value (viewer.frame.Frame): made once a frame, the same value
handed to the sort, the drawer and the overlays and kept as ``viewer.shown``; in stereo
the eye cameras in it, made once with the frame, are the ones its sort culls for and
the stereo frame draws."""

from __future__ import annotations

from dataclasses import replace

from raygs_viewer.camera.pinhole import camera_key
from raygs_viewer.camera.stereo import StereoRig, custom_preset, eye_cameras
from raygs_viewer.render.gl import stereo_frame
from raygs_viewer.viewer import view_control
from raygs_viewer.viewer.frame import Frame
from raygs_viewer.viewer.state import StereoPreview

EYE = custom_preset(40, 30, 90.0, 72.0)


def recording(monkeypatch, owner, name: str, record):
    """Wraps ``owner.name``: ``record(args)`` before each call."""
    original = getattr(owner, name)

    def wrapper(*args, **kwargs):
        record(args)
        return original(*args, **kwargs)

    monkeypatch.setattr(owner, name, wrapper)


def stereo(open_viewer, rig=StereoRig()):
    preview = StereoPreview.of(EYE, on=True, layout="sbs", rig=rig)
    return open_viewer(hide_panel=True, width=2 * EYE.width, height=EYE.height, stereo=preview)


def test_each_frame_is_made_once_and_handed_to_the_sort_the_drawer_and_the_overlays(open_viewer, monkeypatch):
    viewer, drive = open_viewer(hide_panel=True)
    made, asked, drawn, overlaid = [], [], [], []
    make = Frame.make.__func__
    monkeypatch.setattr(Frame, "make", classmethod(lambda cls, *args, **kwargs: made.append(make(cls, *args, **kwargs))
                                                   or made[-1]))
    recording(monkeypatch, viewer.scene.sorter, "request", lambda args: asked.append(args[0]))
    recording(monkeypatch, viewer.drawer, "draw", lambda args: drawn.append(args[1]))
    recording(monkeypatch, viewer.measure, "overlay", lambda args: overlaid.append(args[0]))
    drive.frames(3)
    assert len(made) == len(asked) == len(drawn) == len(overlaid) == 3
    for frame, request, draw, overlay in zip(made, asked, drawn, overlaid):
        assert request is frame.sort and overlay is frame  # the frame's own request, not one made again
        assert draw.sort is frame.sort and draw.camera is frame.camera and draw.index == frame.index
    assert [frame.index for frame in made] == [1, 2, 3] and all(frame.eyes is None for frame in made)
    assert viewer.shown is drawn[-1] and viewer.camera is made[-1].camera and viewer.viewport == made[-1].viewport


def test_the_channel_views_are_read_after_the_panel_and_drawn_with_the_frame(open_viewer, monkeypatch):
    viewer, drive = open_viewer(hide_panel=True)
    drive.frames(1)
    viewer.view_mode.channel = "depth"
    drawn = []
    recording(monkeypatch, viewer.drawer, "draw", lambda args: drawn.append(args[1]))
    drive.frames(1)
    assert drawn[0].view == drawn[0].right_view == viewer.view_mode.view() and viewer.shown is drawn[0]


def test_the_stereo_eyes_are_made_once_a_frame_and_are_the_ones_sorted_for_and_drawn(open_viewer, monkeypatch):
    viewer, drive = stereo(open_viewer)
    made = []
    recording(monkeypatch, view_control, "eye_cameras", lambda args: made.append("view"))
    recording(monkeypatch, stereo_frame, "eye_cameras", lambda args: made.append("stereo frame"))
    drawing, rendered = [], []  # each eye rendered is filed under the frame being drawn
    recording(monkeypatch, viewer.drawer, "draw", lambda args: drawing.append(args[1]))
    recording(monkeypatch, viewer.scene.renderer, "render_into", lambda args: rendered.append((drawing[-1], args[1])))
    drive.frames(3)
    assert made == ["view"] * 3  # never again by the stereo frame
    # A frame whose sort is not back yet draws the last image again and renders nothing,
    # so only the frames that rendered are looked at (how many depends on the machine's load).
    eyes_drawn = [(frame, [eye for drawn, eye in rendered if drawn is frame]) for frame in drawing]
    eyes_drawn = [(frame, eyes) for frame, eyes in eyes_drawn if eyes]
    assert eyes_drawn  # the first frame draws
    for frame, eyes in eyes_drawn:
        assert len(eyes) == 2 and eyes[0] is frame.eyes[0] and eyes[1] is frame.eyes[1]
        assert [camera_key(c) for c in frame.sort.cull_cameras] == [camera_key(e) for e in frame.eyes]


def test_the_stereo_frame_draws_the_frame_s_eyes_not_its_own_of_the_rig(open_viewer, monkeypatch):
    """Eyes handed in that differ from the rig's are what is drawn: the stereo frame does not
    make the eyes again from the rig."""
    viewer, drive = stereo(open_viewer)
    other = StereoRig(ipd=0.25, scene_scale=0.5)
    camera_of = viewer.view.camera

    def framing(width, height, view):
        shot = camera_of(width, height, view)
        return shot._replace(eyes=eye_cameras(shot.camera, other))

    monkeypatch.setattr(viewer.view, "camera", framing)
    rendered = []
    recording(monkeypatch, viewer.scene.renderer, "render_into", lambda args: rendered.append(args[1]))
    viewer.settings = replace(viewer.settings, p_min=viewer.settings.p_min * 1.01)  # something to draw
    drive.frames(2)
    assert rendered
    frame = viewer.shown
    theirs = eye_cameras(frame.camera, other)
    rigs = eye_cameras(frame.camera, frame.stereo.rig)
    assert [camera_key(c) for c in rendered[-2:]] == [camera_key(c) for c in theirs]
    assert [camera_key(c) for c in rendered[-2:]] != [camera_key(c) for c in rigs]
