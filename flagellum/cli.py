"""``flagellum`` command line: builds the parser from ``flagellum.commands`` and dispatches.

Exit status: 0 success, 1 simulation error, 2 bad input (one line ``flagellum: error: ...``),
130 interrupted by Ctrl-C.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from flagellum import __version__
from flagellum.commands import COMMANDS
from flagellum.commands.common import UsageError, add_common_arguments

PROG = "flagellum"


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line ``flagellum: error: ...``, status 2."""

    def error(self, message: str) -> NoReturn:
        one_line = " ".join(message.split())
        hint = f" (see '{self.prog} --help')"
        self.exit(2, f"{PROG}: error: {one_line}{hint}\n")


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with one subparser per module in ``COMMANDS``."""
    parser = _Parser(prog=PROG, description="Simulate a bacterium-like swimmer: a spherical head driven by a "
                                            "rotating helical flagellum in a viscous fluid.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        module = importlib.import_module(f"flagellum.commands.{name}")
        cmd = sub.add_parser(module.NAME, help=module.HELP, description=module.DESCRIPTION)
        module.add_arguments(cmd)
        add_common_arguments(cmd)
        cmd.set_defaults(_run=module.run, _parser=cmd)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``flagellum`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status.

    Bad input raises ``SystemExit(2)`` after printing one line to stderr.
    """
    from physics.errors import SimulationError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args))
    except UsageError as exc:
        args._parser.error(str(exc))
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except SimulationError as exc:
        print(f"{PROG}: simulation failed: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
