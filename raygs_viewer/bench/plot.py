"""The benchmarks' scatter plots, drawn with matplotlib (Agg, no window).

:func:`scatter_png` draws rows of side-by-side panels, each row with its title and its
legend on the right; x is logarithmic, y linear or logarithmic. Each series (a
configuration of ``bench accuracy``, a footprint of ``bench perf``) gets a colour and a
marker of its own (:func:`series_styles`), and each group (a scene, a renderer) a fill
of its own (:func:`group_fills`), so that a greyscale print still tells them apart.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from typing import Sequence

#: Colours of the series, in order: Okabe-Ito's colour-blind-safe eight, then seven more of
#: other lightness, so that neighbours differ in grey too.
COLORS = ("#0072B2", "#D55E00", "#000000", "#009E73", "#E69F00", "#56B4E9", "#CC79A7", "#F0E442",
          "#7F7F7F", "#8C2D04", "#6A3D9A", "#9E9A2F", "#B2182B", "#1B7837", "#4D4D9F")
#: Marker shapes of the series, in order (all fillable, so that the groups' fills show).
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", "p", ">", "h", "d", "H", "8")
#: Fills of the groups, in order (matplotlib fill styles).
FILLS = ("full", "none", "left", "bottom", "right", "top")


@dataclass(frozen=True)
class Style:
    color: str      # "#rrggbb"
    marker: str     # a matplotlib marker


#: How the legend shows a group: its fill on a grey circle.
GROUP_STYLE = Style("#666666", "o")
PANEL_INCHES = (4.2, 4.0)
LEGEND_INCHES = 2.8
DPI = 100


@dataclass
class Point:
    x: float
    y: float
    series: str           # the label of its series: its colour and marker
    group: str = ""       # the label of its group: its fill ("" for none: filled)


@dataclass
class Panel:
    title: str
    points: list[Point] = field(default_factory=list)
    #: x positions of dashed vertical guide lines (e.g. the baseline's ratio 1).
    guides_x: tuple[float, ...] = ()


@dataclass
class ScatterRow:
    """One row of panels with its title, axes labels and legend."""
    title: str
    panels: list[Panel]
    x_label: str
    y_label: str
    series: list[str]                                   # legend order
    groups: list[str] = field(default_factory=list)     # legend order, after the series
    log_y: bool = False


def series_styles(labels: Sequence[str]) -> dict[str, Style]:
    """A (colour, marker) per label, no two alike: the i-th colour with the i-th marker,
    past the lists' length the markers shifted by one more each round."""
    styles = {}
    for index, label in enumerate(dict.fromkeys(labels)):
        turn = index // len(COLORS)
        styles[label] = Style(COLORS[index % len(COLORS)], MARKERS[(index + turn) % len(MARKERS)])
    return styles


def group_fills(labels: Sequence[str]) -> dict[str, str]:
    """A fill per group label (in turn: full, hollow, half filled on each side)."""
    return {label: FILLS[index % len(FILLS)] for index, label in enumerate(dict.fromkeys(labels))}


def _marker(style: Style, fill: str = "full") -> dict[str, object]:
    """A point's look: its series' colour and marker, its group's fill, a black edge (which
    keeps a light colour and a hollow marker visible)."""
    return {"linestyle": "none", "marker": style.marker, "markersize": 8, "color": style.color,
            "markeredgecolor": "black", "markeredgewidth": 0.7, "fillstyle": fill}


def _log_subs(low: float, high: float) -> tuple[float, ...]:
    """The mantissas labelled on a log axis from ``low`` to ``high``: finer over a short
    span, so that a panel of ratios between 0.8 and 4 still reads 1, 1.5, 2, 3."""
    decades = math.log10(high / low)
    return (1.0,) if decades > 3 else (1.0, 2.0, 5.0) if decades > 1.2 else (1.0, 1.5, 2.0, 3.0, 5.0, 7.0)


def _tick_label(value: float) -> str:
    """1.5, 20, 5000, then 10k, 200k, 1M: counts of gaussians stay short enough not to run
    into each other."""
    if value >= 1e6:
        return f"{value / 1e6:g}M"
    return f"{value / 1e3:g}k" if value >= 1e4 else f"{value:g}"


def _shown(point: Point, log_y: bool) -> bool:
    return math.isfinite(point.x) and math.isfinite(point.y) and point.x > 0 and (point.y > 0 or not log_y)


def scatter_png(rows: Sequence[ScatterRow]) -> bytes:
    """A PNG of ``rows`` one below the other. Points with a non-finite coordinate, x <= 0
    or (log_y) y <= 0 are left out."""
    # matplotlib only when a plot is drawn: it takes a second to import, and the
    # benchmarks' other work and the viewer never need it. Agg draws without a display.
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib import figure, lines, ticker  # late, as the line above says

    columns = max((len(row.panels) for row in rows), default=1) or 1
    width = PANEL_INCHES[0] * columns + LEGEND_INCHES
    fig = figure.Figure(figsize=(width, PANEL_INCHES[1] * len(rows)), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    labels = ticker.FuncFormatter(lambda value, _: _tick_label(value))
    for row, sub in zip(rows, fig.subfigures(len(rows), 1, squeeze=False)[:, 0]):
        styles, fills = series_styles(row.series), group_fills(row.groups)
        sub.suptitle(row.title, fontsize=13)
        axes = sub.subplots(1, columns, squeeze=False)[0]
        for index, (ax, panel) in enumerate(zip(axes, row.panels)):
            ax.set_title(panel.title, fontsize=11)
            ax.set_xscale("log")
            if row.log_y:
                ax.set_yscale("log")
            for guide in panel.guides_x:
                if guide > 0:
                    ax.axvline(guide, color="0.35", linestyle="--", linewidth=1)
            for point in (p for p in panel.points if _shown(p, row.log_y)):
                ax.plot([point.x], [point.y], **_marker(styles[point.series], fills.get(point.group, "full")))
            ax.margins(0.08)
            for axis, limits in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim()))[:2 if row.log_y else 1]:
                axis.set_major_locator(ticker.LogLocator(subs=_log_subs(*limits)))
                axis.set_major_formatter(labels)
                axis.set_minor_formatter(ticker.NullFormatter())
            ax.grid(True, color="0.9", linewidth=0.8)
            ax.set_axisbelow(True)
            ax.set_xlabel(row.x_label, fontsize=9)
            if index == 0:
                ax.set_ylabel(row.y_label, fontsize=9)
        for ax in axes[len(row.panels):]:
            ax.set_visible(False)
        handles = [lines.Line2D([], [], label=label, **_marker(styles[label])) for label in row.series]
        handles += [lines.Line2D([], [], label=label, **_marker(GROUP_STYLE, fills[label])) for label in row.groups]
        sub.legend(handles=handles, loc="outside right center", fontsize=8, frameon=False)  # below the title
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, facecolor="white")
    return buffer.getvalue()
