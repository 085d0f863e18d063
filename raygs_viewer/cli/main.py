"""The ``raygs-viewer`` command line: ``view`` (the window), ``info``, ``render``,
``render-path`` (a camera path to a video), ``verify``, ``convert`` (a scene to
another format), ``evaluate`` (renders against the photos) and ``bench``.

Without a command the window opens: ``raygs-viewer`` shows the demo, and
``raygs-viewer SCENE.ply [view options]`` or ``raygs-viewer --frames 3`` mean
``raygs-viewer view ...``. ``render --sidecar SHOT.json`` renders a screenshot of the
window again from the JSON sidecar saved beside it.

Bad input ends in one line, ``error: <what and where>``, and exit status 2.

The commands live beside this module: :mod:`cli.view`, :mod:`cli.commands` (info,
render, verify), :mod:`cli.path` (render-path), :mod:`cli.convert`, :mod:`cli.evaluate` and :mod:`cli.bench`;
:mod:`cli.argtypes` and :mod:`cli.options` hold what their parsers share.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from raygs_viewer import __version__
from raygs_viewer.cli import bench, commands, convert, doctor, evaluate, path, view
from raygs_viewer.cli.argtypes import Parser, join_dash_values
from raygs_viewer.errors import UserError
from raygs_viewer.scene.io import SCENE_SUFFIXES
from raygs_viewer.scene.source import is_demo

#: The modules of the commands, in the order --help lists them: each one's
#: ``add_parsers`` adds its commands, and each command's parser names the function that
#: runs it (``set_defaults(run=...)``), so a new command is a module and its entry here.
COMMAND_MODULES = (view, commands, path, convert, evaluate, bench, doctor)
#: The options whose value may start with '-', and what such a value looks like.
DASH_VALUES = {**view.DASH_VALUES, **convert.DASH_VALUES}
# Arguments that keep their meaning at the top level instead of starting the window.
TOP_LEVEL_OPTIONS = ("-h", "--help", "--version")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="raygs-viewer",
        description="Ray-based Gaussian splatting (RayGS) viewer. Without a command it opens the window: "
                    "'raygs-viewer [SCENE] [view options]' is short for 'raygs-viewer view [SCENE] [view options]', "
                    "and plain 'raygs-viewer' shows the built-in demo.")
    parser.add_argument("--version", action="version", version=f"raygs-viewer {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in COMMAND_MODULES:
        module.add_parsers(subparsers)
    parser.set_defaults(command_names=tuple(subparsers.choices))
    return parser


#: Every command's name, in the order --help lists them.
COMMANDS = build_parser().get_default("command_names")


def route(argv: list[str]) -> list[str]:
    """The argument list with the implied ``view`` made explicit: no arguments, a scene
    as the first argument, or an option other than -h/--help/--version first."""
    if not argv:
        return ["view"]
    first = argv[0]
    if first in COMMANDS or first in TOP_LEVEL_OPTIONS:
        return argv
    if first.startswith("-") or is_demo(first) or os.path.exists(first) \
            or Path(first).suffix.lower() in SCENE_SUFFIXES:
        return ["view", *argv]
    raise UserError(f"'{first}' is neither a command ({', '.join(COMMANDS)}) nor a scene file "
                    f"(see 'raygs-viewer --help')")


#: The exit status of a command whose reader went away: a shell's for a process that
#: SIGPIPE ended (128 + 13), which is what the command would have got without Python.
BROKEN_PIPE_STATUS = 141


def main(argv: list[str] | None = None) -> int:
    try:
        argv = join_dash_values(route(list(sys.argv[1:] if argv is None else argv)), DASH_VALUES)
        args = build_parser().parse_args(argv)
        status = args.run(args)
        sys.stdout.flush()  # here, where a closed pipe is caught, not at exit where it is not
        return status
    except BrokenPipeError:
        return quiet_broken_pipe()
    except UserError as exc:
        print(f"error: {str(exc).splitlines()[0] if str(exc) else 'failed'}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


def quiet_broken_pipe() -> int:
    """The reader of stdout closed it (``raygs-viewer info X | head -1``): not an error
    to report. stdout is pointed at /dev/null so that the interpreter's last flush at
    exit, which would fail the same way and print a traceback, has nowhere to fail."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # no real stdout (a test's capture): nothing is flushed at exit either
        pass
    return BROKEN_PIPE_STATUS


if __name__ == "__main__":
    sys.exit(main())
