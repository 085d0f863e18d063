"""What a GL measured of itself, remembered per renderer and driver: the choices of
``--sort auto`` and ``--precision auto``.

A :class:`GlProfile` holds what :mod:`raygs_viewer.render.gl.probe` measured on one GL:
the CPU and the GPU sort side by side at a few scene sizes (and whether the GPU's order
equalled the CPU's to the element), and one frame blended at each precision (its time
and its largest difference from the float32 image). The choices follow from those
numbers alone, so the same file gives the same choices on every start:

- the sort: the GPU's where its order was identical at every size measured and its time,
  interpolated to the scene's size, is below the CPU's; else the CPU's;
- the blend: the narrowest precision whose difference from float32 stays within the
  accuracy study's bound (:data:`BLEND_ERROR_BOUNDS`) and that is at least 10 % faster
  (:data:`BLEND_GAIN`); else float32.

The file (``$XDG_CONFIG_HOME/raygs-viewer/gl-profile.json``) keeps one entry per
renderer string; an entry whose driver string (``GL_VERSION``) differs is measured
again. It is a convenience, never a reason to fail: one that cannot be read is ignored
with one warning (the caller prints it) and written anew.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import moderngl

from raygs_viewer.errors import UserError, one_line
from raygs_viewer.files import config_file, write_atomically
from raygs_viewer.jsonfile import JsonFields, json_text, read_json_file

PROFILE_NAME = "gl-profile.json"
PROFILE_VERSION = 1
#: The most a narrower blend may differ from float32 per channel: the bounds the
#: accuracy study states and the tests hold (docs/accuracy-vs-time.md; measured at most
#: 5.5e-3 and 2.0e-2 on the test scenes).
BLEND_ERROR_BOUNDS = {"float16": 1e-2, "8bit": 4e-2}
#: Narrowest first: the order the blend choice tries them in.
NARROW_BLENDS = ("8bit", "float16")
#: A narrower blend is chosen only at this fraction of float32's time or less (10 %
#: faster): a smaller gain is within the noise of one short probe and not worth its error.
BLEND_GAIN = 0.9
BLEND_WORDS = {"float32": "float32", "float16": "float16", "8bit": "8-bit"}


@dataclass(frozen=True)
class Choice:
    """What an automatic default chose (``value``: "cpu"/"gpu", or a precision) and why,
    in one line for the panel and the terminal."""

    value: str
    why: str


@dataclass(frozen=True)
class SortTiming:
    """The CPU and the GPU sort of one generated scene of ``count`` gaussians, best of a
    few (ms); ``gpu_ms`` None where the GPU sort cannot run; ``identical``: the GPU's
    order equalled the CPU's, index for index."""

    count: int
    cpu_ms: float
    gpu_ms: float | None
    identical: bool


@dataclass(frozen=True)
class BlendTiming:
    """One frame blended at ``precision``: its time (ms, best of a few, measured beside
    float32's) and its largest per-channel difference from the float32 image."""

    precision: str
    ms: float
    max_error: float


@dataclass(frozen=True)
class GlProfile:
    """What one GL measured (``renderer``: GL_RENDERER, ``version``: GL_VERSION, which
    names the driver; ``measured``: the date, YYYY-MM-DD)."""

    renderer: str
    version: str
    measured: str
    sorts: tuple[SortTiming, ...]
    blends: tuple[BlendTiming, ...]
    gpu_sort_problem: str | None = None

    def sort_choice(self, count: int) -> Choice:
        """The sort ``--sort auto`` takes for a scene of ``count`` gaussians."""
        when = f"measured {self.measured}"
        if self.gpu_sort_problem is not None:
            return Choice("cpu", f"sort: CPU, the GPU sort cannot run here ({self.gpu_sort_problem})")
        measured = sorted((s for s in self.sorts if s.gpu_ms is not None), key=lambda s: s.count)
        if not measured:
            return Choice("cpu", "sort: CPU, the GPU sort was not measured here")
        wrong = [s.count for s in measured if not s.identical]
        if wrong:
            return Choice("cpu", f"sort: CPU, the GPU sort's order differed from the CPU's at {wrong[0]:,} "
                                 f"gaussians here, {when}")
        cpu = estimate(count, [(s.count, s.cpu_ms) for s in measured], fixed=False)
        gpu = estimate(count, [(s.count, s.gpu_ms) for s in measured], fixed=True)
        at = "" if any(s.count == count for s in measured) else " (est.)"
        kind = "gpu" if gpu < cpu else "cpu"
        first, second = (("GPU", gpu), ("CPU", cpu)) if kind == "gpu" else (("CPU", cpu), ("GPU", gpu))
        return Choice(kind, f"sort: {first[0]}, {_ms(first[1])} against {_ms(second[1])} on the {second[0]} "
                            f"at {count:,} gaussians{at}, {when}")

    def precision_choice(self) -> Choice:
        """The blend ``--precision auto`` takes (see the module's docstring)."""
        times = {b.precision: b for b in self.blends}
        base = times.get("float32")
        when = f"measured {self.measured}"
        if base is None or not base.ms > 0:
            return Choice("float32", "blend: float32, the blends were not measured here")
        for precision in NARROW_BLENDS:
            blend = times.get(precision)
            if (blend is not None and blend.max_error <= BLEND_ERROR_BOUNDS[precision]
                    and blend.ms <= BLEND_GAIN * base.ms):
                return Choice(precision, f"blend: {BLEND_WORDS[precision]}, {blend.ms / base.ms:.2f}x float32's "
                                         f"time, largest difference {blend.max_error:.2g} (at most "
                                         f"{BLEND_ERROR_BOUNDS[precision]:g}), {when}")
        others = ", ".join(_blend_verdict(times[p], base) for p in NARROW_BLENDS if p in times)
        return Choice("float32", f"blend: float32; {others or 'no narrower blend measured'}, {when}")

    def to_json(self) -> dict:
        return asdict(self)


def _blend_verdict(blend: BlendTiming, base: BlendTiming) -> str:
    word = BLEND_WORDS[blend.precision]
    if blend.max_error > BLEND_ERROR_BOUNDS[blend.precision]:
        return f"{word} differs by {blend.max_error:.2g} (over {BLEND_ERROR_BOUNDS[blend.precision]:g})"
    return f"{word} {blend.ms / base.ms:.2f}x its time (not 10 % faster)"


def _ms(value: float) -> str:
    return f"{value:.2g} ms" if value < 10 else f"{value:.0f} ms"


def estimate(count: int, points: list[tuple[int, float]], fixed: bool) -> float:
    """A time at ``count`` from times measured at other sizes: linear between the two
    measured sizes around it; beyond the largest, proportional to the count; below the
    smallest, proportional too, or (``fixed``: a GPU sort, whose passes and one read-back
    cost the same for a small scene) the smallest's time."""
    points = sorted(points)
    if count <= points[0][0]:
        low, ms = points[0]
        return ms if fixed else ms * count / max(low, 1)
    for (low, low_ms), (high, high_ms) in zip(points, points[1:]):
        if count <= high:
            return low_ms + (high_ms - low_ms) * (count - low) / (high - low)
    high, ms = points[-1]
    return ms * count / high


def gl_identity(ctx: moderngl.Context) -> tuple[str, str]:
    """(renderer, driver) as the GL names them: what a profile is remembered by."""
    return str(ctx.info.get("GL_RENDERER", "unknown")), str(ctx.info.get("GL_VERSION", "unknown"))


def profile_path():
    return config_file(PROFILE_NAME)


def _read_entries(path) -> list[dict]:
    """The file's entries; UserError naming the file where it is not ours."""
    data = read_json_file(path, "a GL profile (JSON)")
    if not isinstance(data, dict):
        raise UserError(f"{path}: not a GL profile")
    fields = JsonFields(path, data)
    fields.version(PROFILE_VERSION, "GL profile")
    entries = fields.get("profiles", list)
    if not all(isinstance(entry, dict) for entry in entries):
        raise UserError(f"{path}: profiles: each entry must be an object")
    return entries


def _profile(path, entry: dict) -> GlProfile:
    fields = JsonFields(path, entry)

    def time(item: JsonFields, name: str) -> float:
        value = item.get(name, float)
        if value < 0:
            raise UserError(f"{path}: '{name}' must be >= 0, got {value!r}")
        return value

    sorts = []
    for index, item in enumerate(fields.get("sorts", list)):
        item = JsonFields.entry(path, f"sorts[{index}]", item)
        where = f"sorts[{index}]."
        gpu = item.optional(where + "gpu_ms", float)
        sorts.append(SortTiming(item.get(where + "count", int), time(item, where + "cpu_ms"),
                                None if gpu is None else time(item, where + "gpu_ms"),
                                item.get(where + "identical", bool)))
    blends = []
    for index, item in enumerate(fields.get("blends", list)):
        item = JsonFields.entry(path, f"blends[{index}]", item)
        where = f"blends[{index}]."
        blends.append(BlendTiming(item.choice(where + "precision", ("float32", *NARROW_BLENDS), "float32"),
                                  time(item, where + "ms"), time(item, where + "max_error")))
    return GlProfile(fields.get("renderer", str), fields.get("version", str), fields.get("measured", str),
                     tuple(sorts), tuple(blends), fields.optional("gpu_sort_problem", str))


def load_profile(renderer: str, version: str) -> tuple[GlProfile | None, str | None]:
    """(the profile remembered for this renderer and driver, or None: never measured, or
    measured with another driver; a warning where the file could not be read)."""
    path = profile_path()
    if not path.exists():
        return None, None
    try:
        for entry in _read_entries(path):
            if entry.get("renderer") == renderer:
                profile = _profile(path, entry)
                return (profile if profile.version == version else None), None
    except (UserError, TypeError, ValueError) as exc:
        return None, f"warning: the GL profile is not used (measuring again): {one_line(exc)}"
    return None, None


def remember_profile(profile: GlProfile) -> str | None:
    """Writes ``profile`` into the file atomically, in place of its renderer's entry and
    beside the others (an unreadable file is replaced); a warning where it cannot be
    written."""
    path = profile_path()
    try:
        entries = _read_entries(path) if path.exists() else []
    except (UserError, TypeError, ValueError):
        entries = []
    entries = [e for e in entries if e.get("renderer") != profile.renderer] + [profile.to_json()]
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomically(path, json_text({"version": PROFILE_VERSION, "profiles": entries}).encode(), overwrite=True)
    except OSError as exc:
        return f"warning: the GL profile is not remembered: {path.parent}: {exc.strerror or exc}"
    except UserError as exc:
        return f"warning: the GL profile is not remembered: {one_line(exc)}"
    return None
