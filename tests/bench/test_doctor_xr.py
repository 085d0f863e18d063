"""doctor's XR section (raygs_viewer.bench.doctor_xr): against the real runtime (Monado, its
simulated headset, the null compositor: tests/xr_kit.py), ``doctor --xr-only`` in a child
describes the runtime, the headset, its sizes and formats, the controller bindings and a
run of headset frames; without a runtime, or without pyopenxr, the section is one line;
a child process that dies, hangs or reports nonsense is a line of the section, and
doctor goes on (exit status 0)."""

from __future__ import annotations

import io
import json
import math
import re
import subprocess
import sys

import pytest
import xr_kit

from raygs_viewer.bench import doctor_xr
from raygs_viewer.bench.doctor import DoctorOptions, format_report, run_doctor
from raygs_viewer.xr.actions import binding_lines

needs_runtime = pytest.mark.skipif(xr_kit.skip_reason() is not None, reason=str(xr_kit.skip_reason()))
HEADING = "## XR: the headset runtime (OpenXR)"
XR_ONLY_LINE = "doctor: the XR section only (--xr-only): no correctness rows checked"


def section(stdout: str) -> list[str]:
    """The XR section's lines of a printed report (the last line, doctor's summary, left out)."""
    lines = stdout.rstrip().splitlines()
    assert lines[-1] == XR_ONLY_LINE, lines[-1]
    start = lines.index(HEADING)
    return [line for line in lines[start + 1:-1] if line]


def manifest_naming(tmp_path, library: str):
    path = tmp_path / "runtime.json"
    path.write_text(json.dumps({"file_format_version": "1.0.0", "runtime": {"library_path": library}}))
    return path


@needs_runtime
def test_the_section_describes_monado_its_headset_and_two_headset_frames():
    """Run from the manifest's folder with XR_RUNTIME_JSON relative to it: the child (which
    runs in the package's folder) is handed the same manifest."""
    env = {**xr_kit.runtime_env(), "XR_RUNTIME_JSON": xr_kit.MONADO_MANIFEST.name}
    done = xr_kit.run_cli(["doctor", "--xr-only", "--xr-frames", "2"], env, cwd=xr_kit.MONADO_MANIFEST.parent)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = section(done.stdout)
    rows = dict(re.fullmatch(r"\| (.+?) \| (.*) \|", line).groups() for line in lines
                if line.startswith("| ") and not line.startswith("| |"))
    # Monado's simulated headset, as ../shared/openxr/README.md measured it: 320x240 per eye, sRGB swapchains.
    assert re.fullmatch(r"Monado \d+\.\d+\.\d+ \(manifest `/.*/openxr_monado\.json`\)", rows["runtime"])
    assert rows["system"] == "Monado: Simulated HMD"
    assert rows["view configuration"] == "primary stereo, 2 views"
    assert rows["per eye, recommended"] == "320x240, 320x240"
    offered = rows["swapchain formats offered"].split(", ")
    assert "GL_SRGB8_ALPHA8" in offered and "GL_DEPTH_COMPONENT32F" in offered
    assert rows["colour swapchains"] == "GL_SRGB8_ALPHA8, 320x240 per eye"
    assert rows["depth swapchains"].startswith("GL_DEPTH_COMPONENT32F")
    assert rows["extensions used"].split(", ")[:2] == ["XR_KHR_opengl_enable (OpenGL)",
                                                       "XR_MNDX_egl_enable (the EGL binding)"]
    assert rows["OpenGL binding"].startswith("EGL: ")
    assert "Controller bindings, as suggested to the runtime (all 4 profiles taken):" in lines
    listed = [line[2:] for line in lines if line.startswith("- ")]
    assert "valve/index_controller  grab: left squeeze/value, right squeeze/value" in listed
    assert listed == binding_lines() and len(listed) == 15
    assert any(line.startswith("2 headset frames of the demo (3,914 gaussians) at 320x240 per eye, without depth")
               for line in lines)
    counts = next(line for line in lines if "submitted with the eyes' layer" in line)
    assert re.match(r"2 of 2 submitted with the eyes' layer, 0 skipped, [0-2] late; the work ", counts), counts
    work = re.fullmatch(r"\| work a frame, outside xrWaitFrame \| ([\d.]+) ms \|", next(
        line for line in lines if line.startswith("| work a frame")))
    assert work and math.isfinite(float(work.group(1))) and float(work.group(1)) > 0
    assert not any(line.startswith("stopped:") for line in lines)
    header = r"^`raygs-viewer doctor --xr-only --xr-frames 2` on .*\(XR \d+\.\d s\)\.$"
    assert re.search(header, done.stdout, re.MULTILINE)


def test_a_manifest_naming_a_missing_library_is_the_sections_one_line(tmp_path):
    env = {**xr_kit.runtime_env(), "XR_RUNTIME_JSON": str(manifest_naming(tmp_path, "./libgone_openxr.so"))}
    done = xr_kit.run_cli(["doctor", "--xr-only"], env)
    assert done.returncode == 0 and done.stderr == "", done.stderr[-2000:]
    (line,) = section(done.stdout)
    assert line.startswith("no OpenXR runtime active: ") and "libgone_openxr.so" in line and "missing" in line


def test_no_runtime_at_all_is_one_line(monkeypatch, tmp_path):
    monkeypatch.delenv("XR_RUNTIME_JSON", raising=False)
    for name in ("XDG_CONFIG_HOME", "XDG_CONFIG_DIRS", "HOME"):
        monkeypatch.setenv(name, str(tmp_path / name))
    said = []
    found = doctor_xr.xr_section(3, said.append)
    expected = "no OpenXR runtime active (XR_RUNTIME_JSON is not set and no active_runtime.json was found): nothing"
    assert found.lines == [expected + " to check"]
    assert not found.ran and said == []


def test_pyopenxr_missing_is_one_line_naming_the_extra(monkeypatch, tmp_path):
    monkeypatch.setenv("XR_RUNTIME_JSON", str(manifest_naming(tmp_path, "libsome_openxr.so")))  # a bare name: found
    monkeypatch.setitem(sys.modules, "xr", None)                                                # on the search path
    (line,) = doctor_xr.xr_section(3, print).lines
    assert "pyopenxr is not installed" in line and "pip install 'raygs-viewer[xr]'" in line


@pytest.mark.parametrize("outcome, expected", [
    (subprocess.CompletedProcess([], -11, stdout="half a line\n", stderr="noise\nSegmentation fault\n"),
     "stopped: the XR check's process ended without its report (exit status -11): Segmentation fault"),
    (subprocess.CompletedProcess([], 0, stdout=doctor_xr.MARK + "{not json\n", stderr=""),
     "stopped: the XR check's process ended without its report (exit status 0): no output"),
    (subprocess.TimeoutExpired(["python"], 1.0), "stopped: the XR check did not finish within"),
])
def test_a_child_that_dies_hangs_or_says_nonsense_is_a_line_and_doctor_goes_on(monkeypatch, tmp_path, outcome,
                                                                                expected):
    monkeypatch.setenv("XR_RUNTIME_JSON", str(manifest_naming(tmp_path, "libsome_openxr.so")))
    monkeypatch.setattr(doctor_xr, "pyopenxr_installed", lambda: True)

    def child(*args, **kwargs):
        assert kwargs["stdin"] == subprocess.DEVNULL  # the runtime may close descriptor 0
        if isinstance(outcome, BaseException):
            raise outcome
        return outcome

    monkeypatch.setattr(doctor_xr.subprocess, "run", child)
    result = run_doctor(DoctorOptions(xr_only=True, xr_frames=1), out=io.StringIO())
    assert result.status == 0 and len(result.xr) == 1 and result.xr[0].startswith(expected), result.xr
    assert format_report(result).rstrip().endswith(HEADING + "\n\n" + result.xr[0])


def test_the_childs_report_is_read_from_its_marked_line(monkeypatch, tmp_path):
    monkeypatch.setenv("XR_RUNTIME_JSON", str(manifest_naming(tmp_path, "libsome_openxr.so")))
    monkeypatch.setattr(doctor_xr, "pyopenxr_installed", lambda: True)
    said = doctor_xr.MARK + json.dumps({"lines": ["| runtime | X 1.0 |", "done"]})
    monkeypatch.setattr(doctor_xr.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(
        [], 0, stdout=f"a runtime's chatter\n{said}\n", stderr=""))
    found = doctor_xr.xr_section(2, lambda line: None)
    assert found.ran and found.lines == ["| runtime | X 1.0 |", "done"]


def test_an_error_anywhere_in_the_section_is_a_line(monkeypatch):
    def broken():
        raise RuntimeError("the loader exploded")

    monkeypatch.setattr(doctor_xr, "active_manifest", broken)
    assert doctor_xr.xr_section(2, print).lines == ["stopped: RuntimeError: the loader exploded"]
