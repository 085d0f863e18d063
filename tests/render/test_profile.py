"""The GL profile behind --sort auto and --precision auto: the choices its numbers
give, the file it is remembered in, and the probe that measures it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from raygs_viewer.render.gl.probe import measure_profile, probe_camera, probe_scene
from raygs_viewer.render.gl.profile import (
    BLEND_ERROR_BOUNDS,
    BlendTiming,
    GlProfile,
    SortTiming,
    estimate,
    gl_identity,
    load_profile,
    profile_path,
    remember_profile,
)
from raygs_viewer.render.sorting import chosen_sort


def profile(sorts=(), blends=(), renderer="Some GPU", version="4.6 driver 1", problem=None) -> GlProfile:
    return GlProfile(renderer, version, "2026-12-06", tuple(sorts), tuple(blends), problem)


FAST_GPU = (SortTiming(100_000, 2.0, 0.5, True), SortTiming(1_000_000, 61.0, 0.9, True))
SLOW_GPU = (SortTiming(100_000, 2.2, 52.0, True), SortTiming(1_000_000, 24.0, 507.0, True))


# --------------------------------------------------------------------- the sort's choice

def test_the_gpu_sort_is_chosen_where_it_measured_faster_and_the_same():
    choice = profile(FAST_GPU).sort_choice(1_000_000)
    assert choice.value == "gpu"
    assert choice.why == "sort: GPU, 0.9 ms against 61 ms on the CPU at 1,000,000 gaussians, measured 2026-12-06"


def test_the_cpu_sort_is_chosen_where_it_measured_faster():
    assert profile(SLOW_GPU).sort_choice(1_000_000).value == "cpu"
    assert profile(SLOW_GPU).sort_choice(5_000).value == "cpu"


def test_the_choice_follows_the_scene_size_where_the_two_cross():
    # CPU 0.02 ms per 1k gaussians, GPU 5 ms flat: they cross near 250k.
    crossing = (SortTiming(100_000, 2.0, 5.0, True), SortTiming(1_000_000, 20.0, 5.0, True))
    assert profile(crossing).sort_choice(100_000).value == "cpu"
    assert profile(crossing).sort_choice(400_000).value == "gpu"
    assert profile(crossing).sort_choice(3_000_000).value == "gpu"
    assert "(est.)" in profile(crossing).sort_choice(400_000).why


def test_a_gpu_order_that_differed_once_is_never_chosen():
    wrong = (FAST_GPU[0], SortTiming(1_000_000, 61.0, 0.9, False))
    choice = profile(wrong).sort_choice(100_000)
    assert choice.value == "cpu" and "differed" in choice.why and "1,000,000" in choice.why


def test_a_gl_without_the_gpu_sort_chooses_the_cpu_and_says_why():
    choice = profile((SortTiming(100_000, 2.0, None, False),), problem="OpenGL 4.1 has no compute shaders").sort_choice(10)
    assert choice.value == "cpu" and "OpenGL 4.1 has no compute shaders" in choice.why


def test_estimate_between_beyond_and_below_the_sizes_measured():
    points = [(100, 1.0), (1000, 10.0)]
    assert estimate(550, points, fixed=False) == pytest.approx(5.5)
    assert estimate(3000, points, fixed=True) == pytest.approx(30.0)
    assert estimate(10, points, fixed=False) == pytest.approx(0.1)
    assert estimate(10, points, fixed=True) == pytest.approx(1.0)


# --------------------------------------------------------------------- the blend's choice

def blends(f16_ms, f16_error, b8_ms, b8_error):
    return (BlendTiming("float32", 10.0, 0.0), BlendTiming("float16", f16_ms, f16_error),
            BlendTiming("8bit", b8_ms, b8_error))


def test_the_narrowest_blend_within_its_error_and_ten_percent_faster_is_chosen():
    choice = profile(blends=blends(8.0, 0.003, 6.0, 0.02)).precision_choice()
    assert choice.value == "8bit"
    assert "0.60x float32's time" in choice.why and "0.02" in choice.why


def test_a_blend_over_its_error_bound_is_passed_over():
    over = BLEND_ERROR_BOUNDS["8bit"] * 1.5
    assert profile(blends=blends(8.0, 0.003, 6.0, over)).precision_choice().value == "float16"


def test_a_blend_less_than_ten_percent_faster_is_passed_over():
    choice = profile(blends=blends(9.5, 0.003, 9.2, 0.02)).precision_choice()
    assert choice.value == "float32"
    assert "not 10 % faster" in choice.why
    assert profile(blends=blends(9.0, 0.003, 9.2, 0.02)).precision_choice().value == "float16"


# --------------------------------------------------------------------- the file

def test_a_profile_is_remembered_per_renderer_and_measured_again_for_a_new_driver():
    first, other = profile(FAST_GPU, blends(8, 0.003, 6, 0.02)), profile(SLOW_GPU, renderer="Other GPU")
    assert remember_profile(first) is None
    assert remember_profile(other) is None
    assert load_profile("Some GPU", "4.6 driver 1") == (first, None)
    assert load_profile("Other GPU", "4.6 driver 1") == (other, None)
    assert load_profile("Some GPU", "4.6 driver 2") == (None, None)  # a new driver: measure again
    newer = profile(SLOW_GPU, version="4.6 driver 2")
    remember_profile(newer)
    data = json.loads(profile_path().read_text())
    assert [entry["renderer"] for entry in data["profiles"]] == ["Other GPU", "Some GPU"]
    assert load_profile("Some GPU", "4.6 driver 2") == (newer, None)
    assert [p.name for p in profile_path().parent.iterdir()] == ["gl-profile.json"]  # no temporary left


@pytest.mark.parametrize("text", ["{not json", "[]", '{"version": 9, "profiles": []}',
                                  '{"version": 1, "profiles": [{"renderer": "Some GPU", "version": "4.6 driver 1", '
                                  '"measured": "x", "sorts": [{"count": 1, "cpu_ms": -1, "identical": true}], '
                                  '"blends": []}]}'])
def test_an_unreadable_file_is_ignored_with_one_warning_and_written_anew(text):
    profile_path().parent.mkdir(parents=True)
    profile_path().write_text(text)
    found, warning = load_profile("Some GPU", "4.6 driver 1")
    assert found is None
    assert warning.startswith("warning: the GL profile is not used") and "\n" not in warning
    assert remember_profile(profile(FAST_GPU)) is None
    assert load_profile("Some GPU", "4.6 driver 1")[0] == profile(FAST_GPU)


def test_a_folder_that_cannot_be_written_is_one_warning(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("XDG_CONFIG_HOME", str(blocker))
    warning = remember_profile(profile(FAST_GPU))
    assert warning.startswith("warning: the GL profile is not remembered") and "\n" not in warning


def test_render_path_s_auto_sort_reads_the_remembered_profile(gl_ctx):
    renderer, version = gl_identity(gl_ctx)
    assert chosen_sort("auto", gl_ctx, 1000).value == "cpu"  # not measured: the CPU sort
    remember_profile(profile(FAST_GPU, renderer=renderer, version=version))
    assert chosen_sort("auto", gl_ctx, 1_000_000).value == "gpu"
    assert chosen_sort("cpu", gl_ctx, 1_000_000).value == "cpu"


# --------------------------------------------------------------------- the probe

def test_the_probe_measures_both_sorts_and_every_blend_on_this_gl(gl_ctx):
    steps = []
    measured = measure_profile(gl_ctx, steps.append, sort_counts=(3000, 9000), blend_count=3000,
                               blend_size=(64, 36), repeats=1, today=lambda: "2026-12-06")
    assert (measured.renderer, measured.version) == gl_identity(gl_ctx)
    assert measured.measured == "2026-12-06"
    assert [s.count for s in measured.sorts] == [3000, 9000]
    assert all(s.identical and s.gpu_ms > 0 and s.cpu_ms > 0 for s in measured.sorts)
    assert [b.precision for b in measured.blends] == ["float32", "float16", "8bit"]
    assert measured.blends[0].max_error == 0.0
    assert 0 < measured.blends[1].max_error <= BLEND_ERROR_BOUNDS["float16"]
    assert 0 < measured.blends[2].max_error <= BLEND_ERROR_BOUNDS["8bit"]
    assert len(steps) >= 8  # small steps: the window runs one a frame


def test_the_probe_scene_covers_the_probe_view(gl_render):
    """A blend probe of a view mostly empty would time the clear, not the blend."""
    image = gl_render(probe_scene(2000), probe_camera(64, 36))
    assert np.mean(image[..., 3] > 0.5) > 0.45
    assert np.mean(image[9:27, 20:44, 3]) > 0.9


def test_a_scene_over_what_the_gpu_sort_holds_takes_the_cpu_sort(gl_ctx, monkeypatch):
    from raygs_viewer.render.gl.gpu_sort import GpuSorter

    renderer, version = gl_identity(gl_ctx)
    remember_profile(profile(FAST_GPU, renderer=renderer, version=version))
    monkeypatch.setattr(GpuSorter, "capacity", staticmethod(lambda ctx: 500_000))
    assert chosen_sort("auto", gl_ctx, 400_000).value == "gpu"
    choice = chosen_sort("auto", gl_ctx, 600_000)
    assert (choice.value, choice.why) == ("cpu", "sort: CPU, the GPU sort holds at most 500,000 gaussians here")
