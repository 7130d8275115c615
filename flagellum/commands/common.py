"""Pieces shared by every subcommand: the ``--set`` option, number parsing, UsageError."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

from physics.params import NumericsConfig, SwimmerParams, apply_overrides
from physics.presets import apply_preset, preset_names


class UsageError(Exception):
    """Bad command-line input; the CLI prints it on one line and exits with status 2."""


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    """Options every subcommand accepts."""
    parser.add_argument("--set", metavar="NAME=VALUE", action="append", default=[], dest="set",
                        help="override a physical or numerical parameter (repeatable; "
                             "see 'flagellum params' for names, units and ranges)")
    parser.add_argument("--preset", choices=preset_names(), default=None,
                        help="speed/accuracy preset applied before --set (paper = the reference; "
                             "see docs/fidelity.md); default: the parameter defaults (paper's model, h = 1 ms)")


def parse_overrides(items: Sequence[str]) -> dict[str, str]:
    """``["name=value", ...]`` -> ``{"name": "value"}``; UsageError on malformed items or repeats."""
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        if not sep or not name or not value:
            raise UsageError(f"--set {item!r} is not allowed; expected NAME=VALUE, e.g. --set head_radius=0.01")
        if name in out:
            raise UsageError(f"--set {name} given twice ({out[name]!r} and {value!r}); give it once")
        out[name] = value
    return out


def build_config(overrides: dict[str, str], preset: str | None = None) -> tuple[SwimmerParams, NumericsConfig]:
    """Default parameters, then the preset (if any), then ``overrides``; UsageError names bad values."""
    try:
        params, numerics = apply_preset(preset) if preset else (SwimmerParams(), NumericsConfig())
        return apply_overrides(params, numerics, overrides)
    except (ValueError, TypeError) as exc:
        raise UsageError(str(exc)) from None


def parse_number(option: str, raw: str, allowed: str, positive: bool = False) -> float:
    """Parse a finite float given to ``option``; ``allowed`` describes the valid range in messages."""
    try:
        value = float(raw)
    except (TypeError, ValueError):
        raise UsageError(f"{option} {raw!r} is not a number; allowed: {allowed}") from None
    if not math.isfinite(value) or (positive and value <= 0.0):
        raise UsageError(f"{option} {raw!r} is not allowed; allowed: {allowed}")
    return value
