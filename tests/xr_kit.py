"""The real OpenXR runtime the headset tests run against: Monado, built with its null
compositor and a simulated headset, in ``../shared/openxr`` (its README).

Every session runs in a child process: this Monado closes file descriptor 0 when a
swapchain is destroyed, so the child's standard input is /dev/null and the test
runner's own descriptors are never touched. :func:`skip_reason` says why the tests
cannot run here (no runtime, no pyopenxr, a runtime that does not load); the tests
skip with it.
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from testkit import SHARED_SCENES

OPENXR = SHARED_SCENES.parent / "openxr"
MONADO_MANIFEST = OPENXR / "monado" / "openxr_monado.json"
ROOT = Path(__file__).resolve().parents[1]
#: A child that has not finished by then is hung, not slow (a session of 40 frames takes
#: about 3 s here); the bound only keeps a hang from stalling the suite.
HANG_SECONDS = 300


def runtime_env(*, compositor: str = "null", display: str | None = None, **extra: str) -> dict[str, str]:
    """The environment of a child that runs against Monado: the runtime's manifest, the
    simulated headset, the null compositor ("null") or the main one in an X window
    ("xcb", with ``display``), and a private runtime folder (mode 700) for its socket.
    ``display`` None: no X server (the EGL binding)."""
    env = {key: value for key, value in os.environ.items()
           if not key.startswith(("XRT_", "XR_", "DISPLAY", "WAYLAND_DISPLAY"))}
    env.update(XR_RUNTIME_JSON=str(MONADO_MANIFEST), SIMULATED_ENABLE="1", XRT_LOG="error",
               XDG_RUNTIME_DIR=tempfile.mkdtemp(prefix="raygs-xr-"))
    if compositor == "null":
        env["XRT_COMPOSITOR_NULL"] = "1"
    else:
        env["XRT_COMPOSITOR_FORCE_XCB"] = "1"
    if display is not None:
        env["DISPLAY"] = display
    env.update(extra)
    return env


def run_child(args: list[str], env: dict[str, str], *, cwd: str | Path | None = None) -> subprocess.CompletedProcess:
    """``python args...`` in a child with standard input from /dev/null (see the module
    docstring), its output captured as text."""
    return subprocess.run([sys.executable, *args], env=env, cwd=cwd or ROOT, stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=HANG_SECONDS, check=False)


def run_cli(args: list[str], env: dict[str, str], **options) -> subprocess.CompletedProcess:
    """``raygs-viewer args...`` from the working tree, in a child (:func:`run_child`)."""
    return run_child(["-m", "raygs_viewer", *args], env, **options)


_PROBE = """
import xr
instance = xr.create_instance(xr.InstanceCreateInfo(enabled_extension_names=[]))
xr.get_system(instance, xr.SystemGetInfo(form_factor=xr.FormFactor.HEAD_MOUNTED_DISPLAY))
xr.destroy_instance(instance)
print("ok")
"""


@functools.cache
def skip_reason() -> str | None:
    """None when a session can run here, else why not (one line)."""
    if not MONADO_MANIFEST.is_file():
        return f"the OpenXR runtime for tests is not here ({MONADO_MANIFEST})"
    try:
        import xr  # noqa: F401
    except ImportError:
        return "pyopenxr is not installed (pip install '.[xr]')"
    done = run_child(["-c", _PROBE], runtime_env())
    if done.returncode != 0 or "ok" not in done.stdout:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return f"the OpenXR runtime in {OPENXR} does not start here: {tail}"
    return None
