"""The one exception type that reaches the user as a one-line message."""

import math


class UserError(Exception):
    """Bad input or an unusable environment, described in one line.

    The CLI prints ``error: <message>`` and exits with status 2; the window shows
    the message in its panel. Anything else escaping is a bug.
    """


def checked_number(value, low: float, high: float, what: str) -> float:
    """``value`` as a float if it is a finite number (not a bool) in [low, high];
    otherwise UserError "<what> must be a number in [low, high], got <value>"."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or not low <= value <= high:
        raise UserError(f"{what} must be a number in [{low:g}, {high:g}], got {value!r}")
    return float(value)


def one_line(exc: BaseException, limit: int | None = None) -> str:
    """``exc``'s message on one line (its type's name when it has none), cut to
    ``limit`` characters with "..." when given."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if limit is None or len(text) <= limit else text[:limit - 3] + "..."
