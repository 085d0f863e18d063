"""The window's measured defaults: ``--sort auto`` and ``--precision auto``.

The choices come from this GL's profile (``render.gl.profile``): remembered from an
earlier run on the same renderer and driver, or measured now by a
:class:`~raygs_viewer.render.gl.probe.Probe`, one small step after each of the first
frames, so the window opens at once and stays responsive while it measures. Until the
profile is there the window uses the CPU sort and the float32 blend, the choices that
are right everywhere; when it arrives the viewer applies it (a GPU sort takes the next
frame's order, a narrower blend the next draw). A scripted run (``--frames``) never
measures: it uses what is remembered, else those safe choices, so its images and its
time do not depend on a measurement taking place.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Callable

import moderngl

from raygs_viewer.errors import UserError, one_line
from raygs_viewer.render.gl.probe import Probe
from raygs_viewer.render.gl.profile import Choice, GlProfile, gl_identity, load_profile, remember_profile
from raygs_viewer.render.gl.gpu_sort import GpuSorter
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import measured_sort

#: What a sort or blend is until the profile says otherwise.
SAFE_SORT, SAFE_PRECISION = "cpu", "float32"


class AutoDefaults:
    """``sort``: "auto", "cpu" or "gpu" (the command line's); ``precision``: True for
    ``--precision auto``. ``measure``: whether a missing profile may be measured now
    (not in a scripted run); ``probe_factory(ctx)`` makes the probe (tests make a small
    one). ``profile``: the GL's, once known; ``measuring``: the probe's last step while
    it runs; ``warning``: a line the panel shows (an unreadable or unwritable file)."""

    def __init__(self, ctx: moderngl.Context, sort: str, precision: bool, measure: bool,
                 probe_factory: Callable[[moderngl.Context], Probe] = Probe):
        self.ctx, self.sort, self.precision = ctx, sort, precision
        self.profile: GlProfile | None = None
        self.warning = ""
        self.measuring = ""
        self.steps_done = 0
        self.probe: Probe | None = None
        if not self.automatic:
            return
        self.profile, warning = load_profile(*gl_identity(ctx))
        self._warn(warning)
        if self.profile is None and measure:
            self.probe = probe_factory(ctx)
            self.measuring = "starting"

    @property
    def automatic(self) -> bool:
        return self.sort == "auto" or self.precision

    def sort_choice(self, count: int) -> Choice:
        """The sort for a scene of ``count`` gaussians: the command line's, or the
        profile's choice, or the CPU's until there is one."""
        if self.sort != "auto":
            return Choice(self.sort, f"sort: {self.sort.upper()} (--sort {self.sort})")
        if self.profile is None:
            return Choice(SAFE_SORT, f"sort: CPU, until this GL is measured{self._until()}")
        return measured_sort(self.profile, self.ctx, count)

    def sort_for(self, count: int) -> str:
        """The sort ("cpu", "gpu") for a scene of ``count`` gaussians (:meth:`sort_choice`)."""
        return self.sort_choice(count).value

    def precision_choice(self) -> Choice | None:
        """The blend ``--precision auto`` takes now; None where the command line named one."""
        if not self.precision:
            return None
        if self.profile is None:
            return Choice(SAFE_PRECISION, f"blend: float32, until this GL is measured{self._until()}")
        return self.profile.precision_choice()

    def check(self, ctx: moderngl.Context) -> None:
        """UserError in one line where ``--sort gpu`` was asked of a GL that cannot run it."""
        if self.sort == "gpu" and GpuSorter.problem(ctx):
            raise UserError(f"--sort gpu: the GPU sort cannot run here: {GpuSorter.problem(ctx)}")

    def settings(self, settings: RenderSettings, start: RenderSettings) -> RenderSettings:
        """``settings`` with the blend ``--precision auto`` takes now, unless the panel
        chose another since the start (``start``: the command line's settings)."""
        choice = self.precision_choice()
        if choice is None or settings.precision != start.precision:
            return settings
        return replace(settings, precision=choice.value)

    def lines(self, count: int) -> list[str]:
        """What the panel says of the automatic choices for a scene of ``count``
        gaussians: each choice and why, and a warning about the profile's file."""
        if not self.automatic:
            return []
        lines = [self.sort_choice(count).why] if self.sort == "auto" else []
        blend = self.precision_choice()
        return lines + ([blend.why] if blend is not None else []) + ([self.warning] if self.warning else [])

    def step(self) -> bool:
        """One probe step (after a frame); True when this step finished the profile."""
        if self.probe is None:
            return False
        try:
            self.measuring = next(self.probe.steps)
            self.steps_done += 1
            return False
        except StopIteration:
            pass
        except (UserError, MemoryError, moderngl.Error) as exc:  # never a reason to stop the window
            self.probe = None
            self.measuring = ""
            self._warn(f"warning: measuring this GL failed, the safe defaults stay: {one_line(exc)}")
            return False
        self.profile, self.probe, self.measuring = self.probe.profile, None, ""
        self._warn(remember_profile(self.profile))
        return True

    def close(self) -> None:
        """Ends a probe under way (its scenes, sorters and GL objects); call with the
        window's context current."""
        if self.probe is not None:
            self.probe.steps.close()
            self.probe = None

    def _until(self) -> str:
        if self.probe is not None:
            return f" (measuring: {self.measuring}, step {self.steps_done})"
        return " (a scripted run measures nothing: `raygs-viewer doctor` or a window measures it)"

    def _warn(self, warning: str | None) -> None:
        if warning:
            self.warning = warning
            print(warning, file=sys.stderr, flush=True)
