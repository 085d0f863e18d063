"""The window's level-of-detail decisions as plain values: what to read each frame, how
to show a finer reading, the swap colour by level asks for. No window: WindowLod is
handed the scene, the settings and the loader's state (a stand-in of the LoaderState
protocol) and returns what to do."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest
from lod_kit import random_gaussians, write_streamed_sog

from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.scene.loader import load_now
from raygs_viewer.scene.source import SceneSource
from raygs_viewer.sort.lod_choice import LodRequest
from raygs_viewer.viewer.lod_window import (
    LoaderState,
    LodFrame,
    Refined,
    WindowLod,
    lod_request,
    reading,
    refines,
    tinted_scene,
)

SETTINGS = RenderSettings(lod_budget=1000, lod_distance=4.0)


@dataclass
class Loader:
    """What WindowLod reads of the window's loader (``lod_window.LoaderState``)."""

    busy: bool = False
    path: str = ""


@pytest.fixture(scope="module")
def index(tmp_path_factory) -> str:
    """A streamed SOG of two leaves, three levels and an environment."""
    leaves = [[random_gaussians(n, centre, spread=0.3, scale=scale, seed=10 * k + level)
               for level, (n, scale) in enumerate(((30, 0.06), (10, 0.12), (4, 0.25)))]
              for k, centre in enumerate(((0.0, 0.0, 3.0), (1.0, 0.0, 9.0)))]
    folder = tmp_path_factory.mktemp("lod")
    return str(write_streamed_sog(folder / "scene", leaves, environment=random_gaussians(5, spread=20.0, seed=9)))


def read(index: str, levels=None):
    return load_now(SceneSource(index, levels=levels))


def test_the_loader_protocol_is_what_the_window_s_loader_has():
    from raygs_viewer.scene.loader import SceneLoader

    with SceneLoader() as loader:
        state: LoaderState = loader
        assert (state.busy, state.path) == (False, "")


def test_a_frame_asks_for_the_missing_levels_once_and_gives_the_request(index):
    coarse = read(index, levels=(2,))
    window = WindowLod()
    frame = window.for_frame(coarse, SETTINGS, Loader())
    assert frame.read == SceneSource(index, coarse.cameras_path, levels=None)  # every level
    assert frame.request.key == LodRequest(coarse.lod, None, 1000, 4.0).key == lod_request(coarse, SETTINGS).key
    # Asked once per scene: the next frame reads nothing, nor while a load runs.
    assert window.for_frame(coarse, SETTINGS, Loader(busy=True, path=index)).read is None
    assert window.for_frame(coarse, SETTINGS, Loader(path=index)).read is None
    # Another file's load took the loader over (and failed): read again.
    assert window.for_frame(coarse, SETTINGS, Loader(path="other.ply")).read == SceneSource(index, levels=None)


def test_a_fixed_level_reads_that_level_besides_those_read(index):
    coarse = read(index, levels=(2,))
    frame = WindowLod().for_frame(coarse, RenderSettings(lod=1), Loader())
    assert frame.read == SceneSource(index, levels=(1, 2)) and frame.request.level == 1
    assert WindowLod().for_frame(coarse, RenderSettings(lod=2), Loader()).read is None  # read already


def test_a_scene_that_is_not_streamed_asks_for_nothing(index):
    whole = load_now(SceneSource.demo())
    assert WindowLod().for_frame(whole, SETTINGS, Loader()) == LodFrame(None, None)
    assert lod_request(whole, SETTINGS) is None and not reading(whole, Loader(busy=True, path=whole.path))


def test_a_finer_reading_swaps_the_scene_keeping_the_order_and_the_view(index):
    coarse, whole = read(index, levels=(2,)), read(index)
    whole = replace(whole, refines=True)
    assert refines(coarse, whole) and not refines(None, whole) and not refines(coarse, read(index))
    window = WindowLod()
    refined = window.refine(coarse, whole, SETTINGS, RenderSettings(), Loader())
    assert refined.loaded is whole and refined.settings == SETTINGS
    assert refined.swap.scene is whole.lod.scene and refined.swap.keep  # levels only add rows
    # The load's last word (the same scene, with its hash): nothing to swap.
    last = window.refine(whole, whole, SETTINGS, RenderSettings(), Loader())
    assert isinstance(last, Refined) and (last.loaded, last.settings, last.swap) == (whole, SETTINGS, None)
    # A reading still behind the levels shown: nothing yet.
    assert window.refine(whole, coarse, SETTINGS, RenderSettings(), Loader(busy=True, path=index)) is None


def test_a_finer_reading_follows_the_scene_s_sh_degree_when_it_is_each_scene_s_own(index):
    coarse, whole = read(index, levels=(2,)), read(index)
    degree = coarse.scene.sh_degree
    own = RenderSettings(sh_degree=degree)
    refined = WindowLod().refine(coarse, whole, own, RenderSettings(sh_degree=None), Loader())
    assert refined.settings.sh_degree == whole.scene.sh_degree
    kept = WindowLod().refine(coarse, whole, own, RenderSettings(sh_degree=degree), Loader())
    assert kept.settings is own


def test_colour_by_level_asks_for_the_tinted_copy_and_back(index):
    whole = read(index)
    window = WindowLod()
    swap = window.tint_swap(True, whole.lod)
    assert swap.keep and np.array_equal(swap.scene.sh, tinted_scene(whole.lod).sh)
    assert window.tint is False  # the window sets it once the swap is done
    window.tint = True
    assert window.tint_swap(True, whole.lod) is None and window.tint_swap(False, None) is None
    back = window.tint_swap(False, whole.lod)
    assert back.scene is whole.lod.scene and back.keep
    # While tinted, a finer reading swaps in its tinted copy.
    coarse = read(index, levels=(2,))
    window.installed()
    assert window.tint is False and window.choice is None
    window.tint = True
    refined = window.refine(coarse, whole, SETTINGS, RenderSettings(), Loader())
    assert np.array_equal(refined.swap.scene.sh, tinted_scene(whole.lod).sh)
