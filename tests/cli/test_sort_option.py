"""``--sort gpu`` in ``render``, ``render-path`` and the window: the same pictures as the
CPU sort, to the bit, through every path that draws an order; a GL that cannot run the
GPU sort is refused in one line; the inline sorter the window uses with it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from PIL import Image
from testkit import assert_one_line_error, run_cli

from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.sort.request import SortRequest
from raygs_viewer.sort.worker import InlineSorter


def png(path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image)


@pytest.mark.parametrize("options", [
    (), ("--order", "per-pixel"), ("--order", "distance"), ("--mode", "gs"), ("--mip", "--supersample", "2"),
    ("--stereo", "--layout", "sbs"), ("--channels", "depth"),
], ids=["raygs", "per-pixel", "distance", "gs", "mip-2x2", "stereo", "depth-picture"])
def test_render_draws_the_same_picture_with_either_sort(capsys, tmp_path, options):
    shots = {}
    for sort in ("cpu", "gpu"):
        out = tmp_path / f"{sort}.png"
        code, _, err = run_cli(capsys, "render", "--width", "64", "--height", "48", *options, "--sort", sort,
                               "--out", out)
        assert code == 0, err
        shots[sort] = png(out)
    np.testing.assert_array_equal(shots["gpu"], shots["cpu"])
    assert shots["cpu"].max() > 0


def test_render_path_draws_the_same_frames_with_either_sort(capsys, tmp_path):
    for sort in ("cpu", "gpu"):
        code, _, err = run_cli(capsys, "render-path", "demo", "orbit", "--size", "48x32", "--duration", "0.5",
                               "--fps", "6", "--sort", sort, "--out", tmp_path / sort)
        assert code == 0, err
    frames = sorted(path.name for path in (tmp_path / "cpu").iterdir())
    assert len(frames) == 3
    for name in frames:
        np.testing.assert_array_equal(png(tmp_path / "gpu" / name), png(tmp_path / "cpu" / name))


def test_a_gl_without_what_the_gpu_sort_needs_is_refused_in_one_line(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(GpuSorter, "problem", staticmethod(lambda ctx: "OpenGL 4.1 has no compute shaders"))
    out = tmp_path / "shot.png"
    code, _, err = run_cli(capsys, "render", "--width", "32", "--height", "24", "--sort", "gpu", "--out", out)
    assert_one_line_error(code, err)
    assert "the GPU sort cannot run here: OpenGL 4.1 has no compute shaders" in err and not out.exists()
    code, _, err = run_cli(capsys, "render", "--width", "32", "--height", "24", "--sort", "cpu", "--out", out)
    assert code == 0 and out.exists()  # the CPU sort needs none of it


def test_the_window_sorts_on_the_gpu_in_its_own_frame(open_viewer):
    """The frame draws the order of its own view, kept on the GPU, and the scene target
    holds to the bit what the CPU sort's order draws."""
    from raygs_viewer.render.sorting import exact_order
    from raygs_viewer.sort.depth import DepthSorter

    viewer, drive = open_viewer(sort="gpu", hide_panel=True)
    drive.frames(3)
    drive.settle()
    assert isinstance(viewer.scene.sorter, InlineSorter) and isinstance(viewer.scene.direct_sorter, GpuSorter)
    assert viewer.scene.sorter.finished >= 1 and viewer.scene.sorter.error is None
    order = viewer.drawer.orders["depth"]
    assert order.on_device and order.answers(viewer.shown.sort)
    with DepthSorter(viewer.loaded.scene) as cpu:
        expected = viewer.scene.renderer.render(viewer.camera, viewer.settings,
                                                exact_order(cpu, viewer.camera, viewer.settings))
    np.testing.assert_array_equal(viewer.drawer.mono.left.read(), expected)
    viewer.split.on, viewer.split.preset = True, "RayGS, distance order"
    drive.frames(2)
    assert set(viewer.drawer.orders) == {"depth", "distance"}
    assert all(order.answers(viewer.shown.sort) for order in viewer.drawer.orders.values())


def test_the_window_refuses_the_gpu_sort_where_it_cannot_run(open_viewer, monkeypatch):
    from raygs_viewer.errors import UserError

    monkeypatch.setattr(GpuSorter, "problem", staticmethod(lambda ctx: "no compute shaders"))
    with pytest.raises(UserError, match="--sort gpu: the GPU sort cannot run here: no compute shaders"):
        open_viewer(sort="gpu")


class _Counting:
    def __init__(self, fail=False):
        self.sorts, self.closed, self.fail = 0, False, fail

    def sort(self, request):
        self.sorts += 1
        if self.fail:
            raise RuntimeError("the GPU ran out")
        from raygs_viewer.sort.request import Order, SortResult
        return SortResult(request, {"depth": Order(np.arange(3, dtype=np.uint32), "depth", request)}, None, {})

    def close(self):
        self.closed = True


def test_the_inline_sorter_answers_at_once_and_once_per_view():
    from raygs_viewer.camera.pinhole import look_at

    inner = _Counting()
    sorter = InlineSorter(inner)
    first = SortRequest(look_at((0, 0, -3), (0, 0, 0), width=8, height=8), RenderSettings().p_min)
    serial = sorter.request(first)
    assert sorter.latest().serial == serial and sorter.wait(serial) is sorter.latest()
    assert sorter.request(first) == serial and inner.sorts == 1 and sorter.repeated == 1
    second = replace(first, p_min=0.05)
    assert sorter.request(second) == serial + 1 and inner.sorts == 2 and sorter.finished == 2
    sorter.close()
    assert inner.closed
    with pytest.raises(RuntimeError):
        sorter.request(first)
    failing = InlineSorter(_Counting(fail=True))
    serial = failing.request(first)
    assert failing.error == "RuntimeError: the GPU ran out" and failing.latest() is None
    assert failing.wait(serial) is None and failing.failed == 1
    failing.request(first)
    assert failing._sorter.sorts == 1  # a failed view is not sorted again until another is asked


# -- the measured defaults (--sort auto, --precision auto: viewer.auto_defaults) --------------

def help_of(capsys, command) -> str:
    with pytest.raises(SystemExit):
        run_cli(capsys, command, "--help")
    return " ".join(capsys.readouterr().out.split())


def test_view_and_render_path_default_to_the_measured_sort_and_view_to_the_measured_blend(capsys):
    view = help_of(capsys, "view")
    assert "[--sort {auto,cpu,gpu}]" in view and "(default auto)" in view
    assert "[--precision {float32,float16,8bit,auto}]" in view and "auto (default): the narrowest blend" in view
    assert "(default auto)" in help_of(capsys, "render-path")
    render = help_of(capsys, "render")
    assert "(default cpu)" in render and "{float32,float16,8bit}" in render  # a render records what it used


def test_view_hands_the_window_auto_or_the_named_choice(monkeypatch, capsys):
    import raygs_viewer.viewer.app as app

    seen = []
    monkeypatch.setattr(app, "run_viewer", lambda options, progress=None: seen.append(options) or 0)
    assert run_cli(capsys, "view", "--frames", "1")[0] == 0
    assert run_cli(capsys, "view", "--frames", "1", "--sort", "gpu", "--precision", "float16")[0] == 0
    (auto, named) = seen
    assert (auto.sort, auto.auto_precision, auto.settings.precision) == ("auto", True, "float32")
    assert (named.sort, named.auto_precision, named.settings.precision) == ("gpu", False, "float16")


def test_render_path_s_auto_sort_takes_the_gpu_where_this_gl_measured_it_faster(capsys, tmp_path, gl_ctx,
                                                                               monkeypatch):
    import raygs_viewer.cli.path as path_command
    from raygs_viewer.render.gl.profile import GlProfile, SortTiming, gl_identity, remember_profile

    opened = []
    real = path_command.open_sorter
    monkeypatch.setattr(path_command, "open_sorter", lambda kind, ctx, scene: opened.append(
        type(sorter := real(kind, ctx, scene)).__name__) or sorter)
    remember_profile(GlProfile(*gl_identity(gl_ctx), "2026-12-06", (SortTiming(1000, 9.0, 1.0, True),), ()))
    for out in ("auto", "cpu"):
        code, _, err = run_cli(capsys, "render-path", "demo", "orbit", "--size", "16x12", "--duration", "0.2",
                               "--fps", "5", *(() if out == "auto" else ("--sort", out)), "--out", tmp_path / out)
        assert code == 0, err
    assert opened == ["GpuSorter", "DepthSorter"]
