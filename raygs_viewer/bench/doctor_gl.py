"""``doctor``'s first two tables: which GL this is (vendor, renderer, version, driver, the
kind of context, the machine around it), and the limits and extensions the viewer relies
on, each with what it is needed for and the fallback a missing or smaller one selects.
"""

from __future__ import annotations

import os
import platform
import re
from dataclasses import dataclass

import moderngl
import numpy as np

from raygs_viewer import __version__
from raygs_viewer.bench.common import software_renderer
from raygs_viewer.render.gl.context import REQUIRE, context_backend, context_description
from raygs_viewer.render.gl.gpu_sort import STORAGE_BLOCKS, TILE, WORKGROUP, GpuSorter
from raygs_viewer.render.gl.kbuffer import FRAMEBUFFER_FETCH, max_window
from raygs_viewer.render.gl.memory import MEMORY_VARIABLE, available_memory
from raygs_viewer.render.gl.per_pixel import LIST_BLOCKS
from raygs_viewer.render.gl.storage import MAX_SPLAT_BLOCKS, SPLAT_BYTES, gpu_limit
from raygs_viewer.render.settings import MAX_ORDER_K

CONTEXT_KINDS = {"egl": "headless EGL", "osmesa": "headless OSMesa", "other": "a window's (or the caller's)"}
SUBGROUPS = ("GL_KHR_shader_subgroup", "GL_ARB_shader_ballot", "GL_NV_shader_thread_group")
INTERLOCKS = ("GL_ARB_fragment_shader_interlock", "GL_NV_fragment_shader_interlock",
              "GL_INTEL_fragment_shader_ordering")
TIMER_QUERY = "GL_ARB_timer_query"
DOUBLES = "GL_ARB_gpu_shader_fp64"


@dataclass(frozen=True)
class Limit:
    """One row of the limits table: what, its value here, what the viewer needs it for,
    and ``fallback``: what it does where the value is missing or too small; ``short``:
    whether it is so here (the fallback is taken)."""

    what: str
    here: str
    needs: str
    fallback: str
    short: bool = False


def driver_of(version: str) -> str:
    """The driver in a GL_VERSION string: "Mesa 22.3.6" of "4.5 (Core Profile) Mesa 22.3.6"."""
    rest = re.sub(r"^\s*\d+(\.\d+)*\s*", "", version)
    rest = re.sub(r"^\((Core|Compatibility) Profile\)\s*", "", rest)
    return rest.strip() or "not named"


def _mib(size: int) -> str:
    return f"{size / (1 << 20):,.0f} MiB"


def gl_rows(ctx: moderngl.Context) -> list[tuple[str, str]]:
    """(what, value) of the GL and the machine it runs on."""
    info = ctx.info
    version = str(info.get("GL_VERSION", "unknown"))
    major, minor = divmod(ctx.version_code, 100)
    renderer = str(info.get("GL_RENDERER", "unknown"))
    clock = ("a software renderer: times are the CPU's, the GL drained around the work"
             if software_renderer(renderer) else "timer queries")
    return [("vendor", str(info.get("GL_VENDOR", "unknown"))), ("renderer", renderer),
            ("version", f"OpenGL {major}.{minor // 10} (GL_VERSION: {version})"), ("driver", driver_of(version)),
            ("context", CONTEXT_KINDS[context_backend(ctx)]), ("clock", clock),
            ("raygs-viewer", __version__),
            ("Python, numpy, moderngl", f"{platform.python_version()}, {np.__version__}, {moderngl.__version__}"),
            ("system", f"{platform.platform()}, {os.cpu_count()} CPU cores"),
            ("described as", context_description(ctx))]


def _present(ctx: moderngl.Context, names: tuple[str, ...]) -> str:
    found = [name for name in names if name in ctx.extensions]
    return ", ".join(found) if found else "none"


def limit_rows(ctx: moderngl.Context) -> list[Limit]:
    """The limits and extensions the viewer relies on (module docstring)."""
    major, minor = divmod(ctx.version_code, 100)
    block = gpu_limit(ctx, "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 1 << 27)
    compute = gpu_limit(ctx, "GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS", 8)
    fragment = gpu_limit(ctx, "GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS", 8)
    vertex = gpu_limit(ctx, "GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS", 8)
    invocations = gpu_limit(ctx, "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS", 1024)
    groups = ctx.info.get("GL_MAX_COMPUTE_WORK_GROUP_COUNT")
    groups_x = int(groups[0]) if isinstance(groups, tuple) and groups else 65535
    window = max_window(ctx)
    memory, how = available_memory(ctx)
    fetch = FRAMEBUFFER_FETCH in ctx.extensions
    return [
        Limit("OpenGL version", f"{major}.{minor // 10}", f"{REQUIRE // 100}.{REQUIRE % 100 // 10}: compute "
              "shaders and storage buffers (the preprocessing pass, the sort, the per-pixel passes)",
              "none: the viewer does not start (`error: no headless OpenGL 4.3 context`)", ctx.version_code < REQUIRE),
        Limit("storage block size", _mib(block), f"the records and the scene are cut into blocks of it: records "
              f"for up to {MAX_SPLAT_BLOCKS * block // SPLAT_BYTES:,} gaussians in {MAX_SPLAT_BLOCKS} blocks; the "
              f"GPU sort holds a scene's positions in one: up to {GpuSorter.capacity(ctx):,} gaussians",
              "a larger scene is refused in one line; `--sort auto` takes the CPU sort over the GPU sort's size"),
        Limit("storage blocks a compute shader", str(compute), f"{STORAGE_BLOCKS} for the GPU sort",
              "the CPU sort (`--sort gpu` is refused in one line, `--sort auto` takes the CPU's)",
              compute < STORAGE_BLOCKS),
        Limit("storage blocks a vertex / fragment shader", f"{vertex} / {fragment}",
              f"the records' blocks in the vertex stage; {LIST_BLOCKS} for the per-pixel order's fragment lists",
              "a scene whose records need more blocks is refused; the per-pixel order is not supported",
              fragment < LIST_BLOCKS),
        Limit("compute work group: invocations; groups in x", f"{invocations}; {groups_x:,}",
              f"{WORKGROUP} invocations (GL 4.3 guarantees 1024); the sort culls {TILE:,} rows a group",
              f"none needed: GL 4.3 guarantees both (65,535 groups: {65535 * TILE:,} rows a sort)",
              invocations < WORKGROUP),
        Limit("colour attachments (k-buffer window)", f"K up to {window}",
              f"the per-pixel order's k-buffer: one attachment for the state, one per entry (K up to {MAX_ORDER_K})",
              "a larger K takes the fragment lists", window < MAX_ORDER_K),
        Limit(FRAMEBUFFER_FETCH, "present" if fetch else "missing",
              "the per-pixel order through a k-buffer (K > 0) and the transmittance cut-off",
              "the bounded per-pixel order and the transmittance cut-off take the fragment lists (the same image)",
              not fetch),
        Limit("double precision (GL 4.0, " + DOUBLES + ")", "core" if ctx.version_code >= 400 else "missing",
              "the GPU sort's correctly rounded square roots", "the CPU sort", ctx.version_code < 400),
        Limit("timer queries (GL 3.3, " + TIMER_QUERY + ")", "core" if ctx.version_code >= 330 else "missing",
              "the GPU times of the window's statistics and the benchmarks",
              "none needed: a software renderer (whose passes run after a query closes) is timed on the CPU"),
        Limit("subgroup operations", _present(ctx, SUBGROUPS), "not used: the sort's scans use shared memory "
              "(core GL 4.3)", "none needed"),
        Limit("fragment shader interlock", _present(ctx, INTERLOCKS), "not used: the per-pixel order uses "
              "fragment lists (atomics) or framebuffer fetch", "none needed"),
        Limit("GPU memory for buffers", "unknown" if memory is None else f"{_mib(memory)} ({how})",
              "refusing a scene that would not fit, before it is uploaded; a streamed SOG's levels that fit",
              f"where unknown nothing is refused on its account (`{MEMORY_VARIABLE}=MiB` sets a cap); the driver's "
              "out-of-memory error still ends a load in one line", memory is None),
    ]


def gl_tables(ctx: moderngl.Context) -> list[str]:
    """Both tables, in markdown."""
    lines = ["| | |", "|---|---|"] + [f"| {what} | {value} |" for what, value in gl_rows(ctx)]
    lines += ["", "| limit or extension | here | the viewer needs it for | where missing or smaller |",
              "|---|---|---|---|"]
    for limit in limit_rows(ctx):
        lines.append(f"| {limit.what} | {limit.here} | {limit.needs} | "
                     f"{'**taken here:** ' if limit.short else ''}{limit.fallback} |")
    return lines
