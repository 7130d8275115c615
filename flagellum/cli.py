"""``flagellum`` command line: builds the parser from ``flagellum.commands`` and dispatches.

Exit status: 0 success, 1 simulation error, 2 bad input (one line ``flagellum: error: ...``),
130 interrupted by Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import NoReturn

from flagellum import __version__
from flagellum.commands import COMMANDS
from flagellum.commands.common import DEFAULT_PRESET_ARG, UsageError, add_common_arguments

PROG = "flagellum"
#: Optional dependencies (top-level module -> (the package's extra that installs it, what it is)).
OPTIONAL_MODULES = {"stable_baselines3": ("rl", "stable-baselines3"), "torch": ("rl", "PyTorch"),
                    "tensorboard": ("rl", "tensorboard"), "moviepy": ("video", "moviepy"), "rich": ("rl", "rich"),
                    "distributed": ("cluster", "dask.distributed"), "dask": ("cluster", "dask"),
                    "ray": ("ray", "Ray RLlib")}


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line ``flagellum: error: ...``, status 2."""

    def error(self, message: str) -> NoReturn:
        one_line = " ".join(message.split())
        hint = f" (see '{self.prog} --help')"
        self.exit(2, f"{PROG}: error: {one_line}{hint}\n")


class _TopParser(_Parser):
    """The top-level parser: an unknown option before the command is named (argparse would only say that
    COMMAND is missing, or complain about the command's own options)."""

    commands: list[str]  # the command names, in ``COMMANDS`` order (``build_parser``)

    def parse_args(self, args=None, namespace=None):  # type: ignore[override]
        argv = list(sys.argv[1:] if args is None else args)
        known = {"-h", "--help", "--version"}
        for token in argv:
            if not token.startswith("-") or token == "-":
                break  # the command: what follows is its own
            if token not in known:
                self.error(f"unrecognized argument {token!r} before the command; allowed: COMMAND (one of "
                           f"{', '.join(self.commands)}) or {', '.join(sorted(known))}")
        return super().parse_args(argv, namespace)


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with one subparser per module in ``COMMANDS``."""
    parser = _TopParser(prog=PROG, description="Simulate a bacterium-like swimmer: a spherical head driven by a "
                                            "rotating helical flagellum in a viscous fluid.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    parser.commands = []
    for name in COMMANDS:
        module = importlib.import_module(f"flagellum.commands.{name}")
        parser.commands.append(module.NAME)
        cmd = sub.add_parser(module.NAME, help=module.HELP, description=module.DESCRIPTION)
        module.add_arguments(cmd)
        add_common_arguments(cmd, accepts_set=getattr(module, "ACCEPTS_SET", True),
                             preset=getattr(module, "PRESET", DEFAULT_PRESET_ARG))
        cmd.set_defaults(_run=module.run, _parser=cmd)
    return parser


@contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Treat SIGTERM (kill, job schedulers) like Ctrl-C while a command runs: what was computed is written,
    worker processes are stopped, the exit status is 130."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``flagellum`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status.

    Bad input raises ``SystemExit(2)`` after printing one line to stderr.
    """
    from physics.errors import SimulationError, is_interrupt

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with sigterm_as_interrupt():
            return int(args._run(args))
    except UsageError as exc:
        args._parser.error(str(exc))
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except SystemError as exc:  # Ctrl-C or SIGTERM that landed inside a compiled (Numba) kernel
        if not is_interrupt(exc):
            raise
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except SimulationError as exc:
        print(f"{PROG}: simulation failed: {exc}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as exc:  # an optional dependency of this command is not installed
        root = (exc.name or "").split(".")[0]
        if root not in OPTIONAL_MODULES:
            raise
        extra, package = OPTIONAL_MODULES[root]
        args._parser.error(f"'{PROG} {args.command}' needs {package}, which is not installed; allowed: install the "
                           f"package's [{extra}] extra: pip install 'flagellum-swimmer[{extra}]'")
    except BrokenPipeError:  # output piped into e.g. `head`, which closed early
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
