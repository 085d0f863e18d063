"""--sort auto and --precision auto in the window: measured in the first frames without
holding them up, remembered, applied, shown in the panel."""

from __future__ import annotations

from dataclasses import replace

import pytest
from appkit import headless, window_image
from testkit import assert_matches

from raygs_viewer.render.gl.probe import Probe
from raygs_viewer.render.gl.profile import BlendTiming, GlProfile, SortTiming, gl_identity, load_profile, remember_profile

STEPS = 4


def measured(ctx, sort_faster="gpu", blend="8bit") -> GlProfile:
    renderer, version = gl_identity(ctx)
    cpu, gpu = (5.0, 1.0) if sort_faster == "gpu" else (1.0, 5.0)
    narrow = {"8bit": (10.0, 9.0, 5.0), "float32": (10.0, 9.8, 9.7)}[blend]
    return GlProfile(renderer, version, "2026-12-06", (SortTiming(1000, cpu, gpu, True), SortTiming(100_000, cpu * 10,
                                                                                                  gpu, True)),
                     (BlendTiming("float32", narrow[0], 0.0), BlendTiming("float16", narrow[1], 0.002),
                      BlendTiming("8bit", narrow[2], 0.01)))


class ScriptedProbe:
    """A probe of STEPS steps that ends in a given profile: the window's handling of a
    measurement, without the measurement's time."""

    made = 0

    def __init__(self, ctx, **kinds):
        ScriptedProbe.made += 1
        self.profile = None
        self.steps = self._steps(measured(ctx, **kinds))

    def _steps(self, result):
        for step in range(STEPS):
            yield f"step {step}"
        self.profile = result


def no_probe(ctx):
    raise AssertionError("a remembered profile is measured again")


@pytest.fixture(autouse=True)
def count_probes():
    ScriptedProbe.made = 0


def test_the_window_measures_a_new_gl_in_its_first_frames_and_applies_it(open_viewer):
    viewer, drive = open_viewer(sort="auto", auto_precision=True, probe_factory=ScriptedProbe)
    assert viewer.scene.sort == "cpu" and viewer.settings.precision == "float32"  # safe until measured
    draws = viewer.stats.draws
    drive.frames(STEPS)
    assert viewer.stats.draws > draws  # drawn while measuring: one step a frame, never the whole probe
    assert viewer.auto.steps_done == STEPS and viewer.scene.sort == "cpu"
    assert any("until this GL is measured (measuring: step" in label for label in drive.panel.labels())
    drive.frames(1)
    assert ScriptedProbe.made == 1
    assert viewer.scene.sort == "gpu" and viewer.settings.precision == "8bit"
    assert load_profile(*gl_identity(viewer.ctx))[0] == measured(viewer.ctx)
    drive.settle()
    labels = drive.panel.labels()
    assert any(label.startswith("sort: GPU, 1 ms against 6.3 ms on the CPU at 3,914 gaussians (est.)")
               for label in labels)
    assert any(label.startswith("blend: 8-bit, 0.50x float32's time") for label in labels)
    assert_matches(window_image(viewer), headless(viewer))  # the GPU order, the 8-bit blend


def test_a_remembered_profile_is_applied_at_the_start_without_measuring(open_viewer, gl_ctx):
    remember_profile(measured(gl_ctx, sort_faster="cpu", blend="float32"))
    viewer, drive = open_viewer(sort="auto", auto_precision=True, probe_factory=no_probe)
    drive.frames(2)
    assert viewer.scene.sort == "cpu" and viewer.settings.precision == "float32"
    assert viewer.auto.sort_choice(3914).why.startswith("sort: CPU, 1.3 ms against 5 ms on the GPU")


def test_a_new_driver_is_measured_again(open_viewer, gl_ctx):
    old = measured(gl_ctx)
    remember_profile(GlProfile(old.renderer, old.version + " (older)", old.measured, old.sorts, old.blends))
    viewer, drive = open_viewer(sort="auto", auto_precision=True, probe_factory=ScriptedProbe)
    drive.frames(STEPS + 1)
    assert ScriptedProbe.made == 1 and viewer.scene.sort == "gpu"


def test_a_choice_made_in_the_panel_stands_when_the_profile_arrives(open_viewer):
    viewer, drive = open_viewer(sort="auto", auto_precision=True, probe_factory=ScriptedProbe)
    viewer.settings = replace(viewer.settings, precision="float16")
    drive.frames(STEPS + 1)
    assert viewer.settings.precision == "float16"


def test_named_choices_measure_nothing(open_viewer):
    viewer, drive = open_viewer(sort="cpu", probe_factory=no_probe)
    drive.frames(2)
    assert viewer.auto.lines(10) == []


def test_a_scripted_run_measures_nothing(open_viewer):
    viewer, drive = open_viewer(sort="auto", auto_precision=True, frames=3, probe_factory=no_probe)
    drive.frames(2)
    assert viewer.scene.sort == "cpu" and viewer.settings.precision == "float32"
    assert "a scripted run measures nothing" in viewer.auto.sort_choice(10).why


def test_a_failing_probe_keeps_the_safe_defaults_with_one_warning(open_viewer, capsys):
    def failing(ctx):
        probe = Probe(ctx, sort_counts=(1000,), blend_count=1000, blend_size=(32, 18), repeats=1)

        def steps():
            yield "first"
            raise MemoryError("out of memory")
        probe.steps = steps()
        return probe

    viewer, drive = open_viewer(sort="auto", auto_precision=True, probe_factory=failing)
    drive.frames(4)
    assert viewer.scene.sort == "cpu" and viewer.settings.precision == "float32"
    assert viewer.auto.warning == "warning: measuring this GL failed, the safe defaults stay: out of memory"
    assert capsys.readouterr().err.count("measuring this GL failed") == 1


def test_the_real_probe_runs_in_the_window(open_viewer):
    def small(ctx):
        return Probe(ctx, sort_counts=(2000,), blend_count=2000, blend_size=(32, 18), repeats=1)

    viewer, drive = open_viewer(sort="auto", auto_precision=True, probe_factory=small)
    for _ in range(500):  # the probe takes a fixed number of steps, one a frame; the bound only stops a hang
        if viewer.auto.probe is None:
            break
        drive.frames(1)
    profile = viewer.auto.profile
    assert profile is not None, viewer.auto.warning
    assert profile.sorts[0].identical
    assert viewer.scene.sort == profile.sort_choice(3914).value
    assert viewer.settings.precision == profile.precision_choice().value
    # The choice is made after the frame the probe's last step followed: the window shows
    # it from the next frame on (under load the probe may choose a narrow blend).
    drive.settle()
    drive.frames(1)
    assert_matches(window_image(viewer), headless(viewer))
