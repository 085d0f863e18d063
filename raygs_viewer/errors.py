"""The one exception type that reaches the user as a one-line message."""


class UserError(Exception):
    """Bad input or an unusable environment, described in one line.

    The CLI prints ``error: <message>`` and exits with status 2; the window shows
    the message in its panel. Anything else escaping is a bug.
    """
