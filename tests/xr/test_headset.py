"""The headset against a real OpenXR runtime (Monado, simulated headset, null compositor;
tests/xr_kit.py): a scripted session's line, its eyes as submitted against a headless
render of each eye's camera to the bit and against the float64 reference, the depth
layer against the median-depth channel, both GL bindings, and the bad cases' one line.

Every session runs in a child process (xr_kit's module docstring says why)."""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
import xr_kit
from PIL import Image
from testkit import assert_matches, assert_one_line_error, listing, run_cli

from raygs_viewer.capture.sidecar import load_sidecar

#: The tests that run a session; the bad cases that fail before one need only pyopenxr,
#: and some not even that.
needs_runtime = pytest.mark.skipif(xr_kit.skip_reason() is not None, reason=str(xr_kit.skip_reason()))
needs_pyopenxr = pytest.mark.skipif(importlib.util.find_spec("xr") is None,
                                    reason="pyopenxr is not installed (pip install '.[xr]')")

#: Small windows: the eyes are the runtime's recommended 320 x 240 whatever the window.
WINDOW = ["--width", "160", "--height", "120"]
LINE = re.compile(r"^xr: Monado [\d.]+, Monado: Simulated HMD, (\d+)x(\d+) per eye \((EGL|GLX), GL_SRGB8_ALPHA8, "
                  r"(with depth|no depth)\), (\d+) frames submitted", re.MULTILINE)


def xr_line(done: subprocess.CompletedProcess) -> re.Match:
    assert done.returncode == 0, done.stderr[-3000:]
    match = LINE.search(done.stdout)
    assert match, done.stdout
    return match


@pytest.fixture(scope="module")
def scripted(tmp_path_factory):
    """One scripted session on the EGL binding (no X server): 3 headset frames, the last
    one's eyes saved, with --scene-scale 0.5 (two scene units a metre)."""
    folder = tmp_path_factory.mktemp("xr")
    done = xr_kit.run_cli(["view", "--xr", "--xr-depth", "--frames", "3", "--scene-scale", "0.5", "--screenshot",
                           str(folder / "shot.png"), *WINDOW], xr_kit.runtime_env())
    return folder, done


@needs_runtime
def test_a_scripted_session_says_its_runtime_headset_size_and_frames_in_one_line(scripted):
    _, done = scripted
    match = xr_line(done)
    assert match.group(1, 2, 3, 4, 5) == ("320", "240", "EGL", "with depth", "3")
    assert len([line for line in done.stdout.splitlines() if line.startswith("xr:")]) == 1


@needs_runtime
def test_each_eye_as_submitted_is_its_sidecar_rendered_again_to_the_bit_and_the_float64_reference(
        scripted, capsys):
    folder, done = scripted
    xr_line(done)
    cameras = []
    for side in ("left", "right"):
        png, sidecar = folder / f"shot-{side}.png", folder / f"shot-{side}.json"
        submitted = np.asarray(Image.open(png))
        assert submitted.shape == (240, 320, 3) and submitted.std() > 5  # a picture, not a blank
        code, _, err = run_cli(capsys, "render", "--sidecar", sidecar, "--out", folder / f"again-{side}.png")
        assert code == 0, err
        assert np.array_equal(np.asarray(Image.open(folder / f"again-{side}.png")), submitted)
        for name, extra in (("gl", ()), ("ref", ("--reference",))):
            code, _, err = run_cli(capsys, "render", "--sidecar", sidecar, *extra,
                                   "--out", folder / f"{name}-{side}.npy")
            assert code == 0, err
        image, reference = np.load(folder / f"gl-{side}.npy"), np.load(folder / f"ref-{side}.npy")
        assert_matches(image, reference)
        # The PNG is the float32 render rounded as every screenshot is: no second gamma.
        assert np.array_equal(np.round(np.clip(image[..., :3], 0, 1) * 255).astype(np.uint8), submitted)
        shot = load_sidecar(sidecar)
        assert shot.viewpoint is not None and len(shot.viewpoint.cull_cameras) == 2
        cameras.append(shot.camera)
    left, right = cameras
    # The eyes stand the simulated headset's 63 mm apart: 0.126 units at 0.5 m a unit.
    assert np.linalg.norm(left.center - right.center) == pytest.approx(0.063 / 0.5, rel=1e-3)
    assert not np.allclose(left.center, right.center)


@pytest.fixture(scope="module")
def windowed():
    """One child drives a Viewer through two sessions' worth of cases (one window and
    one runtime start for all): :data:`DEPTH_PART`, then :data:`LOSS_PART`; returns
    what each printed."""
    done = xr_kit.run_child(["-c", WINDOWED], xr_kit.runtime_env())
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@needs_runtime
def test_the_depth_layer_is_chained_and_holds_each_eyes_median_depth_and_the_mirror_the_eyes(windowed):
    """A Viewer in the headset draws a frame with depth; the layer's views each chain a
    depth info naming that eye's depth swapchain, and the depth image read back equals
    1 - near / z of the median-depth channel of the same eye, order and colour origin
    (xr.eyes.depth_values, the shader's twin)."""
    result = windowed["depth"]
    assert result["chained"] == [True, True]
    assert result["found"] > 0.2 and result["max_error"] <= 1e-6, result
    assert result["far_where_none"], result
    # The desktop's mirror shows both eyes as submitted: the same bytes, not decoded from sRGB.
    assert result["mirrored"], result
    # The session ran focused and ended cleanly on the exit it asked for.
    states = result["states"]
    assert states[:5] == ["IDLE", "READY", "SYNCHRONIZED", "VISIBLE", "FOCUSED"], states
    assert states[-2:] == ["IDLE", "EXITING"] and "STOPPING" in states and result["over"], states


#: The child's window, for both parts.
WINDOW_PRELUDE = r"""
import ctypes, json
import numpy as np
import xr
from raygs_viewer.viewer.app import Viewer, load_start_scene
from raygs_viewer.viewer.state import HeadsetChoices, ViewerOptions
from raygs_viewer.xr.eyes import depth_values

# A screenshot path makes the frames waited for capture their eyes; nothing is saved here.
options = ViewerOptions(width=160, height=120, platform="null", frames=100, screenshot="unsaved.png",
                        headset=HeadsetChoices(enter=True, depth=True))
viewer = Viewer(options, load_start_scene(options))
results = {}
"""

DEPTH_PART = r"""
if True:
    assert viewer.headset.enter().kind == "done"
    while viewer.headset.stats.layered < 2:
        viewer.wait_for_sort = True  # each frame draws the order of its own view, and captures
        viewer.frame()
    shot, session = viewer.headset.last_shot, viewer.headset.session
    layer = session.last_layer
    chained = []
    for side in range(2):
        view = layer.views[side]
        info = ctypes.cast(view.next, ctypes.POINTER(type(session.last_depth_infos[side]))).contents
        chained.append(bool(view.next) and info.sub_image.swapchain == session.depth[side].handle
                       and info.min_depth == 0.0 and info.max_depth == 1.0)
    errors, found, far = [], [], []
    for side, eye in enumerate(shot.eyes.cameras):
        channels = viewer.scene.renderer.render_channels(eye, shot.settings, shot.order,
                                                         color_origin=shot.eyes.midpoint.center)
        expected = depth_values(channels.median_depth, viewer.headset.room.units_per_metre)
        got = shot.images.depth[side]
        errors.append(float(np.abs(got - expected).max()))
        found.append(float((channels.median_depth > 0).mean()))
        far.append(bool(np.all(got[channels.median_depth <= 0] == 1.0)))
    mirror = viewer.drawer.mono.stereo_image.read(components=3, as_bytes=True)
    mirrored = bool(np.array_equal(mirror, np.concatenate(shot.images.colour, axis=1)))
    viewer.leave_headset()
    viewer.wait_for_sort = False
    results["depth"] = {"chained": chained, "max_error": max(errors), "found": min(found),
                        "far_where_none": all(far), "mirrored": mirrored, "states": session.states_seen,
                        "over": session.over}
"""


@needs_runtime
def test_a_lost_session_leaves_the_window_drawing_says_so_and_enter_tries_again(windowed):
    """The runtime answers a frame with XR_ERROR_SESSION_LOST (what an unplugged headset
    or a runtime that quit gives): the window goes on drawing its own view, the panel
    says so, and entering again runs a new session, which a minimised window keeps
    running."""
    result = windowed["loss"]
    assert result["error"].startswith("error: the headset session was lost"), result
    assert "Enter headset tries again" in result["error"], result
    # The window drew its own view again, and shows it (not the last mirror).
    assert result["active_after_loss"] is False and result["desktop_frames_after_loss"] >= 1, result
    assert result["shows_mirror"] is False, result
    assert result["submitted_again"] >= 2, result
    assert result["acquire_lost"]["active"] is False, result
    assert result["acquire_lost"]["error"].startswith("error: the headset session was lost"), result
    assert result["minimised"] == {"submitted": 3, "desktop": 0}, result


LOSS_PART = r"""
if True:
    assert viewer.headset.enter().kind == "done"
    while viewer.headset.stats.ended < 2:
        viewer.frame()
    real_wait = xr.wait_frame
    def lost(*args, **kwargs):
        raise xr.SessionLostError()
    xr.wait_frame = lost
    viewer.frame()
    xr.wait_frame = real_wait
    drawn_before = viewer.stats.draws
    for _ in range(3):
        viewer.frame()
    result = {"error": viewer.panel.error, "active_after_loss": viewer.headset.active,
              "desktop_frames_after_loss": viewer.stats.draws - drawn_before,
              "shows_mirror": viewer.drawer.mono.stereo_image is not None}
    assert viewer.headset.enter().kind == "done"
    while viewer.headset.stats.ended < 2:
        viewer.frame()
    result["submitted_again"] = viewer.headset.stats.ended
    # Lost while acquiring a swapchain image, in the middle of drawing the eyes.
    real_acquire = xr.acquire_swapchain_image
    xr.acquire_swapchain_image = lost
    viewer.frame()
    xr.acquire_swapchain_image = real_acquire
    viewer.frame()
    result["acquire_lost"] = {"error": viewer.panel.error, "active": viewer.headset.active}
    assert viewer.headset.enter().kind == "done"
    while viewer.headset.stats.ended < 2:
        viewer.frame()
    # Minimised (GLFW's null platform cannot iconify: its framebuffer is made empty), the
    # headset goes on and the desktop draws nothing.
    viewer.window.framebuffer_size = lambda: (0, 0)
    ended, draws = viewer.headset.stats.ended, viewer.stats.draws
    for _ in range(3):
        viewer.frame()
    result["minimised"] = {"submitted": viewer.headset.stats.ended - ended, "desktop": viewer.stats.draws - draws}
    results["loss"] = result
"""

WINDOWED = (WINDOW_PRELUDE + "try:\n" + "\n".join("    " + line for line in (DEPTH_PART + LOSS_PART).splitlines())
            + "\n    print(json.dumps(results))\nfinally:\n    viewer.close()\n")


@needs_runtime
def test_the_glx_binding_under_an_x_server(tmp_path):
    """Under Xvfb the window's context is a GLX one: the session binds it (with the
    FBConfig and visual the runtime needs) and submits its frames."""
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb)")
    with xvfb() as display:
        done = xr_kit.run_cli(["view", "--xr", "--frames", "3", *WINDOW],
                              xr_kit.runtime_env(display=display))
    match = xr_line(done)
    assert match.group(3, 4, 5) == ("GLX", "no depth", "3")


class xvfb:
    """An Xvfb server for the test's duration; its display number read from -displayfd
    (a blocking read: ready when it answers, no sleep)."""

    def __enter__(self) -> str:
        import os
        read, write = os.pipe()
        self.server = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "640x480x24", "-nolisten",
                                        "tcp"], pass_fds=(write,), stdin=subprocess.DEVNULL,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(write)
        with os.fdopen(read) as answer:
            number = answer.readline().strip()
        if not number:
            self.server.kill()
            pytest.skip("Xvfb did not start")
        return f":{number}"

    def __exit__(self, *exc) -> None:
        self.server.terminate()
        self.server.wait(timeout=xr_kit.HANG_SECONDS)


# --------------------------------------------------------------------------- bad cases


def bad_case(capsys, tmp_path) -> str:
    """Runs ``view --xr --frames 2 --screenshot`` in this process (each case here fails
    before any session or swapchain is made, so file descriptor 0 is safe); asserts exit
    2, one ``error:`` line, nothing written; returns the line."""
    before = listing(tmp_path)
    code, _, err = run_cli(capsys, "view", "--xr", "--frames", "2", "--screenshot", tmp_path / "shot.png", *WINDOW)
    assert listing(tmp_path) == before
    return assert_one_line_error(code, err)


@needs_pyopenxr
def test_a_manifest_naming_a_missing_library(capsys, tmp_path, monkeypatch):
    manifest = tmp_path / "runtime.json"
    manifest.write_text(json.dumps({"file_format_version": "1.0.0",
                                    "runtime": {"name": "gone", "library_path": "./libgone_openxr.so"}}))
    monkeypatch.setenv("XR_RUNTIME_JSON", str(manifest))
    line = bad_case(capsys, tmp_path)
    assert "libgone_openxr.so" in line and "missing" in line


@needs_pyopenxr
def test_no_runtime_active(capsys, tmp_path, monkeypatch):
    from raygs_viewer.xr.runtime import active_manifest

    monkeypatch.delenv("XR_RUNTIME_JSON", raising=False)
    for key, value in (("XDG_CONFIG_HOME", tmp_path / "config"), ("XDG_CONFIG_DIRS", tmp_path / "etc"),
                       ("HOME", tmp_path)):
        monkeypatch.setenv(key, str(value))
    if active_manifest() is not None:
        pytest.skip("this machine has a system-wide OpenXR runtime")
    line = bad_case(capsys, tmp_path)
    assert "no OpenXR runtime is active" in line


def test_pyopenxr_missing_names_the_extra(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "xr", None)  # what an import of a missing package meets
    line = bad_case(capsys, tmp_path)
    assert "pip install 'raygs-viewer[xr]'" in line


@needs_runtime
def test_a_gl_without_what_the_runtime_shares_images_through(tmp_path):
    """Mesa hides GL_EXT_memory_object_fd: Monado cannot import the swapchain images. In
    a child (the runtime starts its side of a session before refusing it)."""
    before = listing(tmp_path)
    done = xr_kit.run_cli(["view", "--xr", "--frames", "2", "--screenshot", str(tmp_path / "shot.png"), *WINDOW],
                          {**xr_kit.runtime_env(), "MESA_EXTENSION_OVERRIDE": "-GL_EXT_memory_object_fd"})
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert done.returncode == 2 and len(errors) == 1 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert "GL_EXT_memory_object_fd" in errors[0]
    assert listing(tmp_path) == before


def bare_manifest(folder):
    """A runtime manifest naming a library by its bare name (left to the dynamic loader:
    not checked here); the tests stand in for the runtime's answers before it is loaded."""
    manifest = folder / "runtime.json"
    manifest.write_text(json.dumps({"file_format_version": "1.0.0", "runtime": {"library_path": "libstand_in.so"}}))
    return manifest


@needs_pyopenxr
def test_a_runtime_without_opengl_or_without_a_headset_is_one_line(monkeypatch, tmp_path):
    """Windows Mixed Reality offers no XR_KHR_opengl_enable; a runtime with no headset
    answers xrGetSystem with XR_ERROR_FORM_FACTOR_UNAVAILABLE. Neither is this
    runtime's, so the runtime's answers are stood in for (no instance is made)."""
    import xr

    from raygs_viewer.errors import UserError
    from raygs_viewer.xr import runtime

    monkeypatch.setenv("XR_RUNTIME_JSON", str(bare_manifest(tmp_path)))
    offered = [xr.ExtensionProperties(extension_name="XR_KHR_D3D11_enable")]
    monkeypatch.setattr(xr, "enumerate_instance_extension_properties", lambda *a: offered)
    with pytest.raises(UserError, match=r"^the active OpenXR runtime has no OpenGL support .*Direct3D"):
        runtime.XrRuntime("glx")
    line = runtime.error_line(xr.FormFactorUnavailableError(), xr, "finding the headset")
    assert line.startswith("the OpenXR runtime sees no headset") and "\n" not in line


@needs_pyopenxr
def test_an_egl_context_needs_the_runtimes_egl_extension(monkeypatch, tmp_path):
    import xr

    from raygs_viewer.errors import UserError
    from raygs_viewer.xr import runtime

    monkeypatch.setenv("XR_RUNTIME_JSON", str(bare_manifest(tmp_path)))
    offered = [xr.ExtensionProperties(extension_name="XR_KHR_opengl_enable")]
    monkeypatch.setattr(xr, "enumerate_instance_extension_properties", lambda *a: offered)
    with pytest.raises(UserError, match="XR_MNDX_egl_enable"):
        runtime.XrRuntime("egl")


def test_the_colour_format_is_an_srgb_one_of_the_runtimes_list():
    from raygs_viewer.errors import UserError
    from raygs_viewer.xr.swapchain import (
        GL_RGBA8,
        GL_SRGB8,
        GL_SRGB8_ALPHA8,
        choose_format,
    )

    assert choose_format([0x881A, GL_RGBA8, GL_SRGB8_ALPHA8, GL_SRGB8]) == GL_SRGB8_ALPHA8
    assert choose_format([GL_RGBA8, GL_SRGB8]) == GL_SRGB8
    with pytest.raises(UserError, match="it offers GL_RGBA8"):
        choose_format([GL_RGBA8])


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-n", "0"]))
