"""Pieces shared by every subcommand: the ``--set`` option, number parsing, UsageError."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

from physics import NumericsConfig, SwimmerParams, configure, preset_names
from physics.presets import DEFAULT_PRESET, PRESETS, RETIRED_PRESETS, retired_preset_message


class UsageError(Exception):
    """Bad command-line input; the CLI prints it on one line and exits with status 2."""


#: ``--preset`` help when a command's default is the parameter defaults.
PARAMETER_DEFAULTS = "the parameter defaults: the paper's model at h = 1 ms, as 'paper'"
#: ``--preset`` default of every command that runs the swimmer, and what it means.
DEFAULT_PRESET_ARG = (DEFAULT_PRESET, f"{DEFAULT_PRESET} (the paper's grid with error-controlled "
                                      f"{PRESETS[DEFAULT_PRESET]['numerics']['integrator'].upper()} steps; "
                                      "its accuracy against 'reference': docs/bench_quick.md)")


def preset_argument(value: str) -> str:
    """``--preset``'s type: a retired preset is refused with its own one-line message (argparse's choices, the
    live presets only, refuse the rest)."""
    if value in RETIRED_PRESETS:
        raise argparse.ArgumentTypeError(retired_preset_message(value))
    return value


def add_common_arguments(parser: argparse.ArgumentParser, accepts_set: bool = True,
                         preset: tuple[str | None, str] | None = (None, PARAMETER_DEFAULTS)) -> None:
    """The options a subcommand shares: ``--set`` (if ``accepts_set``) and ``--preset`` (unless ``preset`` is
    None; else ``(default, what the default means)``). A command without them gets ``set=[]`` and
    ``preset=None``, so its help lists only what it uses."""
    if accepts_set:
        parser.add_argument("--set", metavar="NAME=VALUE", action="append", default=[], dest="set",
                            help="override a physical or numerical parameter (repeatable; "
                                 "see 'flagellum params' for names, units and ranges)")
    else:
        parser.set_defaults(set=[])
    if preset is None:
        parser.set_defaults(preset=None)
        return
    default, meaning = preset
    parser.add_argument("--preset", type=preset_argument, choices=preset_names(), default=default,
                        help="speed/accuracy preset" + (", applied before --set" if accepts_set else "")
                             + f" (reference = the converged yardstick, paper = the paper's 1 ms implicit Euler; errors of each: docs/bench_quick.md); default: {meaning}")


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
        return configure(preset, overrides)
    except (ValueError, TypeError) as exc:
        raise UsageError(str(exc)) from None


def parse_int(option: str, raw: str, minimum: int, maximum: int | None = None) -> int:
    """Parse a whole number >= ``minimum`` (and <= ``maximum``) given to ``option`` ("1.5" and "-1" are refused,
    not rounded)."""
    try:
        value = int(str(raw).strip(), 10)
    except ValueError:
        value = None
    if value is None or value < minimum or (maximum is not None and value > maximum):
        allowed = f"an integer >= {minimum}" + (f" and <= {maximum}" if maximum is not None else "")
        raise UsageError(f"{option} {raw!r} is not allowed; allowed: {allowed}")
    return value


SCHEDULER_HELP = ("run the tasks on the Dask cluster at ADDR (tcp://HOST:PORT) instead of local processes; "
                  "needs pip install 'dask[distributed]'")


def parse_workers(args: argparse.Namespace) -> tuple[int | None, str | None]:
    """``(--workers, --scheduler)``: an integer >= 1 or None, and a well-formed Dask address or None."""
    from batch.backends import BackendError, check_scheduler_address

    scheduler = getattr(args, "scheduler", None)
    if args.workers is not None and scheduler is not None:
        raise UsageError("--workers and --scheduler both given; --workers counts local processes, "
                         "a cluster uses its own workers")
    from batch.backends import MAX_WORKERS

    workers = None if args.workers is None else parse_int("--workers", args.workers, 1, maximum=MAX_WORKERS)
    if scheduler is not None:
        try:
            check_scheduler_address(scheduler)
        except BackendError as exc:
            raise UsageError(str(exc)) from None
    return workers, scheduler


def ensure_dir(option: str, path: Path) -> Path:
    """Create the output folder ``path`` given to ``option`` (and its parents); UsageError if it cannot be."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{option} {str(path)!r}: cannot create the directory ({exc.strerror or exc}); allowed: a "
                         "folder that exists or can be created") from None
    return path


def parse_number(option: str, raw: str, allowed: str, positive: bool = False) -> float:
    """Parse a finite float given to ``option``; ``allowed`` describes the valid range in messages."""
    try:
        value = float(raw)
    except (TypeError, ValueError):
        raise UsageError(f"{option} {raw!r} is not a number; allowed: {allowed}") from None
    if not math.isfinite(value) or (positive and value <= 0.0):
        raise UsageError(f"{option} {raw!r} is not allowed; allowed: {allowed}")
    return value


RANDOMIZE_HELP = ("model error: the swimmer has E, mu and b drawn within +-F (a fraction, e.g. 0.05) and the helix "
                  "pitch and radius within +-G (--randomize-geometry, default 0.4 F), while the controllers keep the "
                  "nominal turn map")
RANDOMIZE_GEOMETRY_HELP = "with --randomize: the helix pitch and radius within +-G (a fraction in [0, 0.5]; default 0.4 F)"


def add_randomize_arguments(parser: argparse.ArgumentParser, help_suffix: str = "") -> None:
    """``--randomize F`` and ``--randomize-geometry G`` (``parse_randomize``)."""
    parser.add_argument("--randomize", metavar="F", help=RANDOMIZE_HELP + help_suffix)
    parser.add_argument("--randomize-geometry", metavar="G", help=RANDOMIZE_GEOMETRY_HELP)


def parse_randomize(args: argparse.Namespace) -> dict | None:
    """The env's ``randomize`` setting from ``--randomize`` / ``--randomize-geometry`` (None without them);
    UsageError naming a bad value."""
    if args.randomize is None:
        if args.randomize_geometry is not None:
            raise UsageError("--randomize-geometry needs --randomize")
        return None
    f = parse_number("--randomize", args.randomize, "a fraction in (0, 0.5]", positive=True)
    if f > 0.5:
        raise UsageError(f"--randomize {args.randomize!r} is not allowed; allowed: a fraction in (0, 0.5]")
    g = 0.4 * f
    if args.randomize_geometry is not None:
        g = parse_number("--randomize-geometry", args.randomize_geometry, "a fraction in [0, 0.5]")
        if not 0.0 <= g <= 0.5:
            raise UsageError(f"--randomize-geometry {args.randomize_geometry!r} is not allowed; allowed: a "
                             "fraction in [0, 0.5]")
    return {"youngs_modulus": f, "viscosity": f, "head_radius": f, "geometry": g, "obs_noise_std": 0.0}
