"""Small scatter plots drawn with Pillow (the project has no matplotlib).

:func:`scatter_panels` draws side-by-side panels that share a legend: each point
has a colour (one per series) and a marker shape (one per group), the x axis is
logarithmic, the y axis linear. It is what ``raygs-viewer bench accuracy`` needs
for its error-against-time figure, and little more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from PIL import Image, ImageDraw, ImageFont

#: Colours for series, in order (a colour-blind-friendly palette, Okabe-Ito plus greys).
PALETTE = ((0, 114, 178), (213, 94, 0), (0, 0, 0), (0, 158, 115), (86, 180, 233), (204, 121, 167),
           (230, 159, 0), (120, 120, 120), (170, 40, 40), (100, 60, 160), (150, 150, 40))
#: Marker shapes for groups, in order.
SHAPES = ("circle", "square", "triangle", "diamond", "down-triangle", "cross")

PANEL_WIDTH, PANEL_HEIGHT = 420, 400
MARGIN_LEFT, MARGIN_RIGHT, MARGIN_TOP, MARGIN_BOTTOM = 62, 16, 44, 52
LEGEND_WIDTH = 280
TITLE_HEIGHT = 36
MARKER = 6  # marker half-size, px


@dataclass
class Point:
    x: float
    y: float
    color: tuple[int, int, int]
    shape: str = "circle"


@dataclass
class Panel:
    title: str
    points: list[Point] = field(default_factory=list)
    #: x positions of dashed vertical guide lines (e.g. the baseline's ratio 1).
    guides_x: tuple[float, ...] = ()


def _font(size: int):
    try:
        return ImageFont.load_default(size=size)  # Pillow >= 10.1 with FreeType: a scalable font
    except (TypeError, OSError, ImportError):
        return ImageFont.load_default()


def _text_size(draw: ImageDraw.ImageDraw, text: str, font) -> tuple[int, int]:
    left, top, right, bottom = draw.textbbox((0, 0), text, font=font)
    return right - left, bottom - top


def linear_ticks(low: float, high: float, count: int = 6) -> list[float]:
    """Round numbers (1, 2, 2.5 or 5 times a power of ten apart) covering [low, high]."""
    if not high > low:
        return [low]
    raw = (high - low) / max(count - 1, 1)
    power = 10.0 ** math.floor(math.log10(raw))
    # The round step whose number of ticks comes nearest to ``count`` (the coarser on a tie).
    step = min((m * power for m in (10, 5, 2.5, 2, 1)),
               key=lambda step: abs(math.floor(high / step) - math.ceil(low / step) + 1 - count))
    first = math.ceil(low / step - 1e-9) * step
    ticks, value = [], first
    while value <= high + 1e-9 * step:
        ticks.append(round(value, 12))
        value += step
    return ticks


def log_ticks(low: float, high: float, count: int = 7) -> list[float]:
    """Round numbers between low and high (> 0) for a logarithmic axis, at most ``count``
    of them when possible: mantissas from a fine set first, coarser until few enough."""
    for mantissas in ((1, 1.25, 1.5, 2, 2.5, 3, 4, 5, 6, 8), (1, 1.5, 2, 3, 5), (1, 2, 5), (1,)):
        ticks = [m * 10.0 ** k for k in range(math.floor(math.log10(low)) - 1, math.ceil(math.log10(high)) + 1)
                 for m in mantissas]
        ticks = [t for t in ticks if low * (1 - 1e-9) <= t <= high * (1 + 1e-9)]
        if len(ticks) <= count:
            break
    if len(ticks) > count:  # a huge range even with powers of ten: thin them out
        ticks = ticks[::math.ceil(len(ticks) / count)]
    return ticks


def _tick_label(value: float) -> str:
    return f"{value:g}"


def _marker(draw: ImageDraw.ImageDraw, x: float, y: float, shape: str, color, size: int = MARKER) -> None:
    s = size
    outline = (255, 255, 255)
    if shape == "square":
        draw.rectangle((x - s + 1, y - s + 1, x + s - 1, y + s - 1), fill=color, outline=outline)
    elif shape == "triangle":
        draw.polygon([(x, y - s - 1), (x - s - 1, y + s), (x + s + 1, y + s)], fill=color, outline=outline)
    elif shape == "down-triangle":
        draw.polygon([(x, y + s + 1), (x - s - 1, y - s), (x + s + 1, y - s)], fill=color, outline=outline)
    elif shape == "diamond":
        draw.polygon([(x, y - s - 1), (x + s + 1, y), (x, y + s + 1), (x - s - 1, y)], fill=color, outline=outline)
    elif shape == "cross":
        draw.line((x - s, y - s, x + s, y + s), fill=color, width=3)
        draw.line((x - s, y + s, x + s, y - s), fill=color, width=3)
    else:
        draw.ellipse((x - s, y - s, x + s, y + s), fill=color, outline=outline)


def _dashed_vertical(draw: ImageDraw.ImageDraw, x: float, top: float, bottom: float, color) -> None:
    y = top
    while y < bottom:
        draw.line((x, y, x, min(y + 5, bottom)), fill=color, width=1)
        y += 9


def _padded_range(values: list[float], log: bool) -> tuple[float, float]:
    if log:
        values = [math.log10(v) for v in values]
    low, high = min(values), max(values)
    pad = 0.08 * (high - low) if high > low else (0.05 if log else max(abs(low) * 0.05, 0.5))
    low, high = low - pad, high + pad
    return (10.0 ** low, 10.0 ** high) if log else (low, high)


def scatter_panels(panels: list[Panel], *, title: str, x_label: str, y_label: str,
                   series: list[tuple[str, tuple[int, int, int]]],
                   groups: list[tuple[str, str]] = (), log_y: bool = False) -> Image.Image:
    """An RGB image: one panel per entry of ``panels`` side by side (x logarithmic, y
    linear or, with ``log_y``, logarithmic; each panel with its own ranges), a title
    above and a legend on the right listing ``series`` (label, colour) and ``groups``
    (label, marker shape). Points with a non-finite coordinate, x <= 0 or (log_y) y <= 0
    are left out."""
    font, small, big = _font(14), _font(12), _font(17)
    width = PANEL_WIDTH * max(len(panels), 1) + LEGEND_WIDTH
    height = PANEL_HEIGHT + TITLE_HEIGHT
    image = Image.new("RGB", (width, height), (255, 255, 255))
    draw = ImageDraw.Draw(image)
    tw, th = _text_size(draw, title, big)
    draw.text(((width - LEGEND_WIDTH - tw) / 2, (TITLE_HEIGHT - th) / 2), title, fill=(0, 0, 0), font=big)

    for index, panel in enumerate(panels):
        ox, oy = index * PANEL_WIDTH, TITLE_HEIGHT
        left, right = ox + MARGIN_LEFT, ox + PANEL_WIDTH - MARGIN_RIGHT
        top, bottom = oy + MARGIN_TOP, oy + PANEL_HEIGHT - MARGIN_BOTTOM
        points = [p for p in panel.points if math.isfinite(p.x) and math.isfinite(p.y) and p.x > 0
                  and (p.y > 0 or not log_y)]
        xs = [p.x for p in points] + [g for g in panel.guides_x if g > 0]
        ys = [p.y for p in points]
        x_low, x_high = _padded_range(xs or [1.0], log=True)
        y_low, y_high = _padded_range(ys or [1.0 if log_y else 0.0], log=log_y)

        def to_px(x: float, y: float) -> tuple[float, float]:
            fx = (math.log10(x) - math.log10(x_low)) / (math.log10(x_high) - math.log10(x_low))
            if log_y:
                fy = (math.log10(y) - math.log10(y_low)) / (math.log10(y_high) - math.log10(y_low))
            else:
                fy = (y - y_low) / (y_high - y_low)
            return left + fx * (right - left), bottom - fy * (bottom - top)

        tw, th = _text_size(draw, panel.title, font)
        draw.text((left + (right - left - tw) / 2, oy + (MARGIN_TOP - th) / 2), panel.title, fill=(0, 0, 0), font=font)
        for tick in log_ticks(x_low, x_high):
            x, _ = to_px(tick, y_low)
            draw.line((x, top, x, bottom), fill=(232, 232, 232))
            draw.line((x, bottom, x, bottom + 4), fill=(0, 0, 0))
            label = _tick_label(tick)
            lw, _ = _text_size(draw, label, small)
            draw.text((x - lw / 2, bottom + 6), label, fill=(0, 0, 0), font=small)
        for tick in (log_ticks if log_y else linear_ticks)(y_low, y_high):
            _, y = to_px(x_low, tick)
            draw.line((left, y, right, y), fill=(232, 232, 232))
            draw.line((left - 4, y, left, y), fill=(0, 0, 0))
            label = _tick_label(tick)
            lw, lh = _text_size(draw, label, small)
            draw.text((left - 7 - lw, y - lh / 2 - 2), label, fill=(0, 0, 0), font=small)
        for guide in panel.guides_x:
            if guide > 0:
                x, _ = to_px(guide, y_low)
                _dashed_vertical(draw, x, top, bottom, (90, 90, 90))
        draw.rectangle((left, top, right, bottom), outline=(0, 0, 0))
        lw, lh = _text_size(draw, x_label, small)
        draw.text((left + (right - left - lw) / 2, bottom + 26), x_label, fill=(0, 0, 0), font=small)
        if index == 0:  # the y label, rotated, once at the far left
            lw, lh = _text_size(draw, y_label, small)
            label = Image.new("RGBA", (lw + 4, lh + 6), (255, 255, 255, 0))
            ImageDraw.Draw(label).text((2, 0), y_label, fill=(0, 0, 0), font=small)
            label = label.rotate(90, expand=True)
            image.paste(label, (ox + 4, int((top + bottom - label.height) / 2)), label)
        for point in points:
            _marker(draw, *to_px(point.x, point.y), point.shape, point.color)

    x0, y = width - LEGEND_WIDTH + 10, TITLE_HEIGHT + MARGIN_TOP
    for label, color in series:
        _marker(draw, x0 + 8, y + 8, "circle", color)
        draw.text((x0 + 22, y), label, fill=(0, 0, 0), font=small)
        y += 20
    if groups:
        y += 10
        for label, shape in groups:
            _marker(draw, x0 + 8, y + 8, shape, (60, 60, 60))
            draw.text((x0 + 22, y), label, fill=(0, 0, 0), font=small)
            y += 20
    return image


def stacked(images: list[Image.Image]) -> Image.Image:
    """``images`` one below the other on white, as wide as the widest."""
    width = max(image.width for image in images)
    result = Image.new("RGB", (width, sum(image.height for image in images)), (255, 255, 255))
    top = 0
    for image in images:
        result.paste(image, (0, top))
        top += image.height
    return result
