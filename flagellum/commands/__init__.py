"""Subcommands of ``flagellum``: one module each, a thin layer over library calls.

A command module defines ``NAME`` (str), ``HELP`` (one line), ``DESCRIPTION`` (str),
``add_arguments(parser)`` and ``run(args) -> int`` (exit code). It raises
``flagellum.commands.common.UsageError`` for bad input. To add one (sweep, bench, ...),
write the module and list it in ``COMMANDS``.
"""

from __future__ import annotations

COMMANDS: tuple[str, ...] = ("simulate", "params", "sweep", "bench", "calibrate_turns", "follow", "evaluate",
                             "train")
