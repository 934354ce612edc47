"""The ``carbody`` command: a thin layer over the library, one subcommand per stage.

Each stage keeps its subcommands in its own ``cli`` module with an ``add_parsers(subparsers)``
function; handlers import their heavy dependencies (OCP, torch, VTK) when they run, so
``carbody --help`` stays instant. Any :class:`~carbody.errors.CarbodyError` becomes one line on
stderr and exit code 2; output piped into a reader that stops early (``| head``) ends quietly;
SIGINT (Ctrl-C), SIGTERM and SIGHUP stop a command in one line, exit code 128 + the signal's
number, after its ``finally`` blocks have removed what it had staged (:mod:`carbody.outputs`).
"""
from __future__ import annotations

import argparse
import importlib
import logging
import os
import signal
import sys

from carbody.errors import CarbodyError
from carbody.signals import Stopped, handlers

#: Modules that register subcommands, in the order they appear in ``--help``.
COMMAND_MODULES = (
    "carbody.reconstruct_cli",
    "carbody.batch_cli",
    "carbody.annotate.cli",
    "carbody.demo",
    "carbody.freecad_cli",
    "carbody.view.cli",
    "carbody.fit.cli",
    "carbody.surface.cli",
    "carbody.templates.cli",
    "carbody.library_cli",
    "carbody.parts_cli",
    "carbody.wireframe_cli",
)


class _Parser(argparse.ArgumentParser):
    """argparse with its mistakes said in one line (a missing option, a word for a number), as
    the commands' own are, instead of the usage block first; exit code 2 as before."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="carbody",
        description="One photo of a car -> an editable CAD car body (Bezier wireframe + Bezier shell) in STEP.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_parsers(sub)
    _add_quiet(parser)
    return parser


def _add_quiet(parser: argparse.ArgumentParser) -> None:
    """``--quiet`` on every command (the ones with actions on each action)."""
    subcommands = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    for action in subcommands:
        for child in action.choices.values():
            _add_quiet(child)
    if not subcommands:
        parser.add_argument("-q", "--quiet", action="store_true",
                            help="no progress display (it shows only on a terminal anyway)")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, or a mistake argparse has said in one line: its exit code
        return exc.code if isinstance(exc.code, int) else 0
    # Libraries' log warnings (ezdxf cannot write its font cache under a read-only home) are not
    # the user's business: what goes wrong is said in carbody's own one line.
    logging.getLogger().addHandler(logging.NullHandler())
    with handlers():  # (a caller in the same process, a test, gets its own back)
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """Run the command ``args`` names; its errors as one line and an exit code."""
    try:
        return int(args.func(args) or 0)
    except CarbodyError as exc:
        print(f"carbody {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, Stopped) as exc:
        signum = exc.signum if isinstance(exc, Stopped) else signal.SIGINT
        print(f"carbody {args.command}: stopped by {signal.Signals(signum).name}", file=sys.stderr)
        return 128 + signum  # as a shell reports a command a signal ended
    except BrokenPipeError:
        # The reader left (``carbody visible-keypoints --view 30 | head``): stop quietly, and
        # keep Python from complaining again when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a shell reports a command its pipe closed on
    except OSError as exc:
        # The file system said no after the checks passed (disk full, a folder removed meanwhile).
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"carbody {args.command}: error: {where}{(exc.strerror or str(exc)).lower()}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
