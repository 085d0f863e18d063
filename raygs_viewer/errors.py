"""The one exception type that reaches the user as a one-line message, and the number
checks that word its most common messages."""

import math


class UserError(Exception):
    """Bad input or an unusable environment, described in one line.

    The CLI prints ``error: <message>`` and exits with status 2; the window shows
    the message in its panel. Anything else escaping is a bug.
    """


def is_number(value) -> bool:
    """An int or a float, not a bool: Python's bools are ints, but JSON files and
    callers mean true/false, never 1/0."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def finite_number(value) -> float | None:
    """``value`` as a float when it is a finite :func:`is_number`, else None; an integer
    beyond float range (JSON numbers have no limit) is None too, not an OverflowError."""
    if not is_number(value):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def checked_number(value, low: float, high: float, what: str) -> float:
    """``value`` as a float if it is a finite number (not a bool) in [low, high];
    otherwise UserError "<what> must be a number in [low, high], got <value>"."""
    number = finite_number(value)
    if number is None or not low <= number <= high:
        raise UserError(f"{what} must be a number in [{low:g}, {high:g}], got {value!r}")
    return number


def one_line(exc: BaseException, limit: int | None = None) -> str:
    """``exc``'s message on one line (its type's name when it has none), cut to
    ``limit`` characters with "..." when given."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if limit is None or len(text) <= limit else text[:limit - 3] + "..."
