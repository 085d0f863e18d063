import os

import pytest
from hypothesis import settings

# CI replays the same examples every run (a red CI must be reproducible); local runs
# keep exploring new ones.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

# Under pytest-xdist each worker keeps its own example database: workers share no file.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if _WORKER:
    from hypothesis.database import DirectoryBasedExampleDatabase
    # settings(...) starts from the profile loaded above (ci or default).
    settings.register_profile(f"worker-{_WORKER}",
                              settings(database=DirectoryBasedExampleDatabase(f".hypothesis/examples-{_WORKER}")))
    settings.load_profile(f"worker-{_WORKER}")

import timing_kinds
from raygs_viewer.render.gl.context import create_headless_context


def pytest_addoption(parser):
    timing_kinds.add_option(parser)


def pytest_configure(config):
    timing_kinds.configure(config)


@pytest.fixture(autouse=True)
def config_home(tmp_path_factory, monkeypatch):
    """Each test its own empty config folder: what a window remembers between runs
    (viewer.remembered) is never read from, nor written into, the user's home."""
    folder = tmp_path_factory.mktemp("config")
    monkeypatch.setenv("XDG_CONFIG_HOME", str(folder))
    return folder


@pytest.fixture(scope="session")
def gl_session_ctx():
    """One headless GL context for the whole session (creating one costs 50-900 ms)."""
    ctx = create_headless_context()
    yield ctx
    ctx.release()


@pytest.fixture
def gl_ctx(gl_session_ctx):
    """The session's context, made current for this test: a test before may have made
    another one current in this thread (the CLI's, a benchmark's, a viewer's)."""
    gl_session_ctx.__enter__()
    return gl_session_ctx


@pytest.fixture(scope="session")
def gl_render(gl_session_ctx):
    """render(scene, camera, settings=..., order=None, **renderer_options) -> float32
    (H, W, 4); ``order`` None: the exact order for ``settings``, sorted now."""
    from raygs_viewer.render.gl.renderer import GLRenderer
    from raygs_viewer.render.settings import RenderSettings
    from raygs_viewer.render.sorting import exact_order
    from raygs_viewer.sort.depth import DepthSorter

    def render(scene, camera, settings=RenderSettings(), order=None, depth_clamp=True, **options):
        # Current again: a test before may have made another context current (the CLI's,
        # a viewer's) in this thread. Entered, not used as `with`: leaving a nested `with`
        # would unbind the context from a caller's own `with gl_ctx:`.
        gl_session_ctx.__enter__()
        renderer = GLRenderer(gl_session_ctx, scene, **options)
        renderer.depth_clamp = depth_clamp
        try:
            if order is None:
                with DepthSorter(scene) as sorter:
                    order = exact_order(sorter, camera, settings)
            return renderer.render(camera, settings, order)
        finally:
            renderer.release()

    return render


@pytest.fixture
def restore_gl_ctx(gl_ctx):
    """For tests that open a viewer window: its context becomes current in this thread,
    so the session context is made current again afterwards."""
    yield
    gl_ctx.__enter__()


@pytest.fixture(scope="session")
def demo():
    """The built-in demo scene (generating it takes a fraction of a second)."""
    from raygs_viewer.scene.demo import demo_scene
    return demo_scene()


@pytest.fixture(scope="session")
def demo_renderer(gl_session_ctx, demo):
    """A GLRenderer of the demo on the session context. Tests that create and release
    another context in this thread (the CLI's, a viewer's) use it inside ``with gl_ctx:``."""
    from raygs_viewer.render.gl.renderer import GLRenderer
    with gl_session_ctx:
        renderer = GLRenderer(gl_session_ctx, demo)
    yield renderer
    with gl_session_ctx:
        renderer.release()


@pytest.fixture
def open_viewer(restore_gl_ctx, tmp_path):
    """open_viewer(scene="demo", hide_panel=False, **ViewerOptions fields) -> (viewer,
    driver): a real viewer window on GLFW's null platform (tests/appkit.py), closed after
    the test."""
    from appkit import open_viewer_factory
    open_, close_all = open_viewer_factory(tmp_path)
    yield open_
    close_all()
