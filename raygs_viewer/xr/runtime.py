"""The OpenXR runtime as this viewer meets it: pyopenxr loaded when a headset is asked
for, the active runtime's manifest checked before the loader reads it, an instance with
the extensions this GL context needs, and the headset ("system") with its two views.

Every way this can fail on a user's machine is one line (a :class:`UserError`): pyopenxr
missing (the line names the ``[xr]`` extra), no runtime active, a manifest naming a
library that is not there, no headset, a runtime without OpenGL (Windows Mixed Reality
has only Direct3D), a context the runtime cannot bind. The loader's own diagnostics
on stderr are turned off (``XR_LOADER_DEBUG``): the line says it once.
"""

from __future__ import annotations

import ctypes
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from raygs_viewer.errors import UserError

INSTALL_HINT = "pip install 'raygs-viewer[xr]'"
OPENGL_EXTENSION = "XR_KHR_opengl_enable"
EGL_EXTENSION = "XR_MNDX_egl_enable"
DEPTH_EXTENSION = "XR_KHR_composition_layer_depth"
#: What the session's binding needs from the runtime, beyond OpenGL itself.
BINDING_EXTENSIONS = {"glx": (), "win32": (), "egl": (EGL_EXTENSION,)}
APPLICATION = "raygs-viewer"


def load_openxr() -> ModuleType:
    """pyopenxr's ``xr`` module, or a UserError naming the extra that installs it."""
    os.environ.setdefault("XR_LOADER_DEBUG", "none")  # the loader's stderr lines: ours says it once
    try:
        import xr  # an optional extra: only a headset session needs it
    except ImportError as exc:
        raise UserError(f"the headset needs pyopenxr, which is not installed ({exc.name or 'xr'}): "
                        f"{INSTALL_HINT}") from None
    return xr


def active_manifest(environ: dict[str, str] | None = None) -> Path | None:
    """The manifest of the runtime the Khronos loader will load on Linux: ``XR_RUNTIME_JSON``,
    else ``active_runtime.json`` in the user's then the system's XDG config folders
    (None: none there; on Windows the registry names it and the loader reads it)."""
    environ = os.environ if environ is None else environ
    if environ.get("XR_RUNTIME_JSON"):
        return Path(environ["XR_RUNTIME_JSON"])
    if not sys.platform.startswith("linux"):
        return None
    home = environ.get("XDG_CONFIG_HOME") or str(Path(environ.get("HOME", "~")).expanduser() / ".config")
    folders = [home, *(environ.get("XDG_CONFIG_DIRS") or "/etc/xdg").split(":"), "/etc"]
    for folder in folders:
        candidate = Path(folder) / "openxr" / "1" / "active_runtime.json"
        if candidate.is_file():
            return candidate
    return None


def manifest_problem(manifest: Path | None) -> str | None:
    """Why the loader cannot load the runtime ``manifest`` names (one line), or None.
    A bare library name is left to the dynamic loader's search."""
    if manifest is None:
        return ("no OpenXR runtime is active: start SteamVR, Monado or WiVRn (or set XR_RUNTIME_JSON to a "
                "runtime's manifest); docs/xr.md says how")
    try:
        text = manifest.read_text(encoding="utf-8")
    except OSError as exc:
        return f"the OpenXR runtime manifest {manifest} cannot be read: {exc.strerror or exc}"
    try:
        library = json.loads(text)["runtime"]["library_path"]
    except (ValueError, KeyError, TypeError):
        return f"the OpenXR runtime manifest {manifest} is not a runtime manifest (no runtime.library_path)"
    if not isinstance(library, str) or not library:
        return f"the OpenXR runtime manifest {manifest} names no library"
    if "/" not in library and "\\" not in library:
        return None
    path = Path(library) if Path(library).is_absolute() else manifest.resolve().parent / library
    if not path.exists():
        where = "" if str(path) == library else f" ({path})"
        return f"the OpenXR runtime manifest {manifest} names {library}, which is missing{where}"
    return None


def check_runtime() -> None:
    """UserError (one line) when no headset session can start here for want of pyopenxr
    or of a loadable runtime: asked before a scene is read, so a large scene's load is
    not waited through for nothing."""
    load_openxr()
    manifest = active_manifest()
    if manifest is None and not sys.platform.startswith("linux"):
        return  # the loader reads the registry there: what it finds, it says at the instance
    problem = manifest_problem(manifest)
    if problem is not None:
        raise UserError(problem)


@dataclass(frozen=True)
class ViewSize:
    """One view's sizes, as the runtime recommends and allows them (pixels)."""

    recommended: tuple[int, int]
    maximum: tuple[int, int]


@dataclass(frozen=True)
class RuntimeInfo:
    """What the runtime and its headset are, for the CLI's line, the panel and doctor."""

    runtime: str
    version: str
    system: str
    views: tuple[ViewSize, ...]
    extensions: tuple[str, ...]

    def describe(self) -> str:
        """e.g. "Monado 25.1.0, Monado: Simulated HMD"."""
        return f"{self.runtime} {self.version}, {self.system}"


def runtime_name(raw: bytes | str) -> str:
    """The runtime's name without what some runtimes append (Monado: "(XRT) by ...")."""
    name = raw.decode("utf-8", "replace") if isinstance(raw, bytes) else str(raw)
    return name.split("(XRT)")[0].strip() or name


def error_line(exc: BaseException, xr: ModuleType, doing: str) -> str:
    """One line for an OpenXR failure while ``doing`` (e.g. "starting the session")."""
    known = {
        "RuntimeUnavailableError": "the OpenXR runtime could not be loaded",
        "RuntimeFailureError": "the OpenXR runtime failed",
        "FormFactorUnavailableError": "the OpenXR runtime sees no headset: connect it (and switch it on), then "
                                      "try again",
        "FormFactorUnsupportedError": "this OpenXR runtime does not drive head-mounted displays",
        "GraphicsDeviceInvalidError": "the OpenXR runtime refused this OpenGL context",
        "InitializationFailedError": "the OpenXR runtime could not start its side of the session",
        "InstanceLostError": "the OpenXR runtime went away: Enter headset tries again",
        "SessionLostError": "the headset session was lost (the runtime quit or the headset was unplugged): Enter "
                            "headset tries again",
    }
    text = known.get(type(exc).__name__)
    if text is None:
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return f"{text} ({doing})"


class XrRuntime:
    """An instance of the active runtime and its head-mounted display.

    ``binding``: "glx", "egl" or "win32" (``xr.binding.context_binding``), which
    decides the instance's extensions. ``depth``: also enable depth layers where the
    runtime offers them (:attr:`has_depth`). :meth:`destroy` ends the instance."""

    def __init__(self, binding: str, *, depth: bool = True):
        check_runtime()
        xr = self.xr = load_openxr()
        try:
            offered = {p.extension_name.decode() for p in xr.enumerate_instance_extension_properties()}
        except xr.ResultException as exc:
            raise UserError(error_line(exc, xr, "listing the runtime's extensions")) from None
        if OPENGL_EXTENSION not in offered:
            raise UserError("the active OpenXR runtime has no OpenGL support (XR_KHR_opengl_enable); this viewer "
                            "draws with OpenGL (Windows Mixed Reality offers only Direct3D: use SteamVR instead)")
        missing = [name for name in BINDING_EXTENSIONS[binding] if name not in offered]
        if missing:
            raise UserError(f"this window's OpenGL context is an EGL one and the OpenXR runtime does not offer "
                            f"{missing[0]} to bind it: run under X11 (a GLX context) or use Monado")
        wanted = [OPENGL_EXTENSION, *BINDING_EXTENSIONS[binding]]
        self.has_depth = depth and DEPTH_EXTENSION in offered
        if self.has_depth:
            wanted.append(DEPTH_EXTENSION)
        try:
            self.instance = xr.create_instance(xr.InstanceCreateInfo(
                application_info=xr.ApplicationInfo(application_name=APPLICATION, application_version=1,
                                                    engine_name=APPLICATION, engine_version=1,
                                                    api_version=xr.Version(1, 0, 0)),
                enabled_extension_names=wanted))
        except xr.ResultException as exc:
            raise UserError(error_line(exc, xr, "creating the OpenXR instance")) from None
        try:
            self.system = xr.get_system(self.instance, xr.SystemGetInfo(
                form_factor=xr.FormFactor.HEAD_MOUNTED_DISPLAY))
            properties = xr.get_instance_properties(self.instance)
            system = xr.get_system_properties(self.instance, self.system)
            views = xr.enumerate_view_configuration_views(self.instance, self.system,
                                                          xr.ViewConfigurationType.PRIMARY_STEREO)
        except xr.ResultException as exc:
            self.destroy()
            raise UserError(error_line(exc, xr, "finding the headset")) from None
        self.info = RuntimeInfo(
            runtime_name(properties.runtime_name), str(xr.Version(properties.runtime_version)),
            system.system_name.decode("utf-8", "replace") if isinstance(system.system_name, bytes)
            else str(system.system_name),
            tuple(ViewSize((v.recommended_image_rect_width, v.recommended_image_rect_height),
                           (v.max_image_rect_width, v.max_image_rect_height)) for v in views),
            tuple(wanted))

    def opengl_requirements(self) -> None:
        """Asks for the runtime's OpenGL requirements, which the specification requires
        before a session (a runtime may refuse the session otherwise)."""
        xr = self.xr
        function = ctypes.cast(xr.get_instance_proc_addr(self.instance, "xrGetOpenGLGraphicsRequirementsKHR"),
                               xr.PFN_xrGetOpenGLGraphicsRequirementsKHR)
        requirements = xr.GraphicsRequirementsOpenGLKHR()
        result = function(self.instance, self.system, ctypes.byref(requirements))
        if result < 0:
            raise UserError(f"the OpenXR runtime gave no OpenGL requirements (result {result})")

    def destroy(self) -> None:
        instance, self.instance = getattr(self, "instance", None), None
        if instance is not None:
            try:
                self.xr.destroy_instance(instance)
            except self.xr.ResultException:
                pass  # a runtime already gone has nothing left to free
