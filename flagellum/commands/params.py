"""``flagellum params``: list every physical and numerical parameter."""

from __future__ import annotations

import argparse
import dataclasses
import json
from typing import Any

from flagellum.commands.common import PARAMETER_DEFAULTS, build_config, parse_overrides
from physics.params import parameter_table

NAME = "params"
HELP = "list every parameter with its default, unit, allowed range and meaning"
DESCRIPTION = ("List the physical (SwimmerParams) and numerical (NumericsConfig) parameters. "
               "Any of them can be changed on every command with --set NAME=VALUE. "
               "With --set, a 'value' column shows the result.")


PRESET = (None, PARAMETER_DEFAULTS)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print a JSON list instead of a table")


def rows_with_values(overrides: dict[str, str], preset: str | None = None) -> list[dict[str, Any]]:
    """``parameter_table()`` rows plus the ``value`` after the preset and ``overrides``."""
    params, numerics = build_config(overrides, preset)
    values = {**dataclasses.asdict(params), **dataclasses.asdict(numerics)}
    return [{**row, "value": values[row["name"]]} for row in parameter_table()]


def format_table(rows: list[dict[str, Any]], show_value: bool) -> str:
    """Plain-text table grouped by physics / numerics."""
    cols = ["name", "default"] + (["value"] if show_value else []) + ["unit", "allowed", "help"]
    cells = [[f"{r[c]:g}" if isinstance(r[c], float) else str(r[c]) for c in cols] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(cols)]

    def line(values: list[str]) -> str:
        return "  ".join(v.ljust(w) for v, w in zip(values[:-1], widths[:-1])) + "  " + values[-1]

    out = [line(cols), line(["-" * w for w in widths])]
    group = None
    for r, row in zip(rows, cells):
        if r["group"] != group:
            group = r["group"]
            out.append(f"[{group}]")
        out.append(line(row))
    return "\n".join(out)


def run(args: argparse.Namespace) -> int:
    overrides = parse_overrides(args.set)
    rows = rows_with_values(overrides, args.preset)
    if args.json:
        print(json.dumps(rows, indent=2))
    else:
        print(format_table(rows, show_value=bool(overrides) or args.preset is not None))
    return 0
