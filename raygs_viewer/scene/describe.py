"""The ``info`` statistics of a loaded scene and the one-line summary of what was dropped."""

from __future__ import annotations

import numpy as np

from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.spz_format import axes_description, axes_words


def dropped_summary(scene: Scene) -> list[str]:
    """One line per drop reason, e.g. ``dropped 3 gaussians: nan`` (no ``warning:``
    prefix: the caller adds it). Empty when nothing was dropped."""
    lines = []
    for reason, count in scene.dropped.items():
        noun = "gaussian" if count == 1 else "gaussians"
        lines.append(f"dropped {count} {noun}: {reason}")
    return lines


def _stats(values: np.ndarray, *names: str) -> dict[str, float] | None:
    if values.size == 0:
        return None
    v = values.astype(np.float64, copy=False)
    funcs = {"min": np.min, "median": np.median, "mean": np.mean, "max": np.max}
    return {name: float(funcs[name](v)) for name in names}


def describe(scene: Scene) -> dict:
    """JSON-serialisable statistics of a scene (for ``raygs-viewer info``).

    Keys: source, format (Scene.format), axes (for a .spz,
    :func:`~raygs_viewer.scene.spz_format.axes_description`; None for other formats),
    count, sh_degree, filter_fused, bbox ({min, max} of positions,
    or None when empty), opacity ({min, median, mean, max} or None), scale
    ({min, median, max} over all axes, plus median_anisotropy = median of each
    gaussian's max/min scale ratio; None when empty), dropped ({total, by_reason}).
    """
    n = scene.count
    if n:
        bbox = {"min": [float(v) for v in scene.positions.min(axis=0)],
                "max": [float(v) for v in scene.positions.max(axis=0)]}
        s = scene.scales.astype(np.float64)
        scale = _stats(s, "min", "median", "max")
        scale["median_anisotropy"] = float(np.median(s.max(axis=1) / s.min(axis=1)))
    else:
        bbox = None
        scale = None
    return {
        "source": scene.source,
        "format": scene.format,
        "axes": None if scene.axes is None else axes_description(scene.axes),
        "count": n,
        "sh_degree": scene.sh_degree,
        "filter_fused": bool(scene.filter_fused),
        "bbox": bbox,
        "opacity": _stats(scene.opacities, "min", "median", "mean", "max"),
        "scale": scale,
        "dropped": {"total": int(sum(scene.dropped.values())),
                    "by_reason": {k: int(v) for k, v in scene.dropped.items()}},
    }


def format_description(info: dict) -> str:
    """Human-readable multi-line text of :func:`describe`'s dict, with a ``GPU memory`` line
    when the caller added ``gpu_bytes`` (the renderer's figure: the scene layer cannot
    know it)."""

    def g(v: float) -> str:
        return f"{v:.4g}"

    lines = [
        f"source:       {info['source']}",
        f"format:       {info.get('format') or 'in memory'}",
        *([f"axes:         {axes_words(info['axes'])}"] if info.get("axes") else []),
        f"gaussians:    {info['count']}",
        f"SH degree:    {info['sh_degree']}",
        f"3D filter:    {'fused at load' if info['filter_fused'] else 'none'}",
    ]
    bbox = info.get("bbox")
    if bbox:
        lo, hi = bbox["min"], bbox["max"]
        size = [h - l for l, h in zip(lo, hi)]
        lines.append(f"bounds:       min ({', '.join(map(g, lo))})  max ({', '.join(map(g, hi))})"
                     f"  size ({', '.join(map(g, size))})")
    else:
        lines.append("bounds:       (empty scene)")
    o = info.get("opacity")
    if o:
        lines.append(f"opacity:      min {g(o['min'])}  median {g(o['median'])}  "
                     f"mean {g(o['mean'])}  max {g(o['max'])}")
    s = info.get("scale")
    if s:
        lines.append(f"scale:        min {g(s['min'])}  median {g(s['median'])}  max {g(s['max'])}  "
                     f"median max/min ratio {g(s['median_anisotropy'])}")
    lod = info.get("lod")
    if lod:
        counts = ", ".join(f"{level}: {count:,}" for level, count in enumerate(lod["counts"]))
        environment = "none" if lod["environment"] is None else f"{lod['environment']:,} gaussians"
        lines.append(f"levels:       {lod['levels']} (0 the finest; gaussians per level {counts}); "
                     f"{lod['leaves']} parts in {lod['files']} files; environment {environment}")
        if lod.get("gpu_bytes") is not None:
            lines.append(f"every level:  {lod['gpu_bytes'] / (1 << 20):,.1f} MiB of storage buffers, what the window "
                         f"and a render choosing per view hold")
    if info.get("gpu_bytes") is not None:
        lines.append(f"GPU memory:   {info['gpu_bytes'] / (1 << 20):,.1f} MiB of storage buffers "
                     f"(gaussians, SH, splat records, order)")
    d = info.get("dropped") or {"total": 0, "by_reason": {}}
    if d["total"]:
        reasons = ", ".join(f"{r}: {c}" for r, c in d["by_reason"].items())
        lines.append(f"dropped:      {d['total']} invalid ({reasons})")
    else:
        lines.append("dropped:      none")
    return "\n".join(lines)
