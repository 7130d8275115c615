"""Named speed/accuracy presets, selectable everywhere (CLI ``--preset``, API, environment).

``paper`` is the paper's discretisation (N = 122, edges 2 delta, LSBT + Higdon head) and scheme
(implicit Euler, eqn 6) at the paper's h = 1 ms, Newton tolerance 1e-6, with the resistance
refreshed whenever the shape has changed by more than 0.03 r0 (first order in h: 2 % off the
converged turn angle, docs/bench_quick.md); its steps with a rebuilt resistance are solved by
Newton-Krylov (the same solution to the Newton tolerance, 1.4x faster in a burst).

``faithful`` (the default everywhere: ``DEFAULT_PRESET``) is the paper's swimmer on the paper's
grid, integrated by variable-step BDF3 with the local error per step held below ``step_tol``
(``physics.integrate.time_integrator``); steps at which the shape has changed (the resistance is rebuilt:
buckling, relaxation) are solved by Newton-Krylov in the mobility form (``physics.solvers.newton_krylov``),
the others by the chord iteration on the reused dense factorisation; ``dt`` = 0.1 s is the sampling /
control step inside which the adaptive steps are taken. ``fast`` is the same grid and scheme with a
looser error tolerance (step_tol 1e-3): the cheaper tier, at a measured price (docs/bench_quick.md: 1.4x
``faithful``'s speed cruising, 1.5x in the burst, 0.6 % off in θ and 7 % in φ). ``reference`` is the converged
swimmer every preset's error is measured against: the same model with BDF2 at step_tol 1e-7, Newton 1e-8 and the resistance rebuilt at
0.003 r0 of deformation (BDF3 stalls below step_tol 1e-6: its steps collapse to microseconds; the convergence of
``reference``: docs/time_integration.md). ``paper`` is the paper's own numerics (1 ms implicit Euler), for
validation only.

Retired (``RETIRED_PRESETS``; asking for it anywhere raises a one-line ValueError naming the replacement,
``check_preset``): ``coarse`` (N = 45, 10 ms implicit Euler: slower than ``faithful`` and wrong, it does not
buckle); docs/presets.md.

Measured costs and errors against ``reference``: docs/bench_quick.md (``flagellum bench --quick``); the wider
ladder: docs/fidelity.md (scripts/bench_fidelity.py).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from physics.params import NumericsConfig, SwimmerParams, apply_overrides, check_combination, refuse_removed

#: The preset of every command, the environment and the agents unless told otherwise.
DEFAULT_PRESET = "faithful"

#: the error-controlled presets: Newton-Krylov where the shape changes, the chord iteration elsewhere
_ADAPTIVE = {"dt": 0.1, "jacobian_refresh": "resistance", "hydro_model": "lsbt", "head_model": "higdon",
             "newton_krylov": True}

PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "reference": {"params": {"n_nodes": 122},
                  "numerics": {**_ADAPTIVE, "integrator": "bdf2", "step_tol": 1e-7, "hydro_refresh_tol": 0.003,
                               "newton_tol": 1e-8}},
    "paper": {"params": {"n_nodes": 122},
              "numerics": {"dt": 1e-3, "hydro_model": "lsbt", "head_model": "higdon",
                           "hydro_refresh_tol": 0.03, "newton_tol": 1e-6, "newton_krylov": True}},
    "faithful": {"params": {"n_nodes": 122},
                 "numerics": {**_ADAPTIVE, "integrator": "bdf3", "step_tol": 1e-4, "hydro_refresh_tol": 0.03,
                              "newton_tol": 1e-5}},
    "fast": {"params": {"n_nodes": 122},
             "numerics": {**_ADAPTIVE, "integrator": "bdf3", "step_tol": 1e-3, "hydro_refresh_tol": 0.03,
                          "newton_tol": 1e-5}},
}

#: One-line description of each preset (CLI help, docs).
PRESET_DESCRIPTIONS = {
    "reference": "the converged yardstick (BDF2 at step_tol 1e-7)",
    "paper": "the paper's own numerics (1 ms implicit Euler), for validation only",
    "faithful": "the default: the paper's grid, error-controlled BDF3 steps",
    "fast": "faithful at a looser step tolerance (step_tol 1e-3): cheaper, at a measured price",
}

#: Presets that were retired, with why (docs/presets.md): asking for one raises ``retired_preset_message``.
RETIRED_PRESETS = {
    "coarse": "slower than 'faithful' and wrong: it does not buckle",
}


def preset_names() -> list[str]:
    """The live presets (never a retired one)."""
    return list(PRESETS)


def retired_preset_message(name: str) -> str:
    """The one-line refusal of the retired preset ``name``, naming the replacement."""
    return (f"preset {name!r} was retired ({RETIRED_PRESETS[name]}; docs/presets.md); use {DEFAULT_PRESET!r} "
            "(the default), or FlagellumTurn-surrogate-v0 / FlagellumBurst-surrogate-v0 for a cheap turn-level swimmer")


def retired_env_message(env_id: str, preset: str, replacement: str) -> str:
    """The one-line refusal of a registered env id that went with the retired ``preset``, naming ``replacement``."""
    return f"{env_id} was retired with its preset (use {replacement}): {retired_preset_message(preset)}"


def check_preset(name: object, label: str = "preset") -> str:
    """``name`` if it is a live preset; else ValueError on one line: the retirement message for a retired preset,
    ``{label}={name!r} is not allowed; choose one of [...]`` for anything else. Every place that takes a preset
    name (``configure``, the environments, the training and sweep configs, the CLI's ``--preset``, the turn maps)
    checks it here."""
    if isinstance(name, str) and name in RETIRED_PRESETS:
        raise ValueError(retired_preset_message(name))
    if not isinstance(name, str) or name not in PRESETS:
        raise ValueError(f"{label}={name!r} is not allowed; choose one of {preset_names()}")
    return name


def configure(preset: str | None = None,
              overrides: Mapping[str, Any] | None = None) -> tuple[SwimmerParams, NumericsConfig]:
    """The parameters and numerics of a run: the defaults (the paper's model at h = 1 ms), then ``preset``
    (None: none), then ``overrides``.

    ``overrides`` maps any ``SwimmerParams`` or ``NumericsConfig`` field name to a value; a string is parsed
    as on the command line (``"0.01"``, ``"true"``, see ``apply_overrides``), anything else is used as it
    is. ValueError names an unknown name or a value out of range.
    """
    p, n = apply_preset(preset) if preset else (SwimmerParams(), NumericsConfig())
    if not overrides:
        check_combination(p, n)
        return p, n
    p, n = apply_overrides(p, n, {k: v for k, v in overrides.items() if isinstance(v, str)})
    typed = {k: v for k, v in overrides.items() if not isinstance(v, str)}
    p_names = {f.name for f in dataclasses.fields(SwimmerParams)}
    n_names = {f.name for f in dataclasses.fields(NumericsConfig)}
    refuse_removed(typed)
    unknown = sorted(set(typed) - p_names - n_names)
    if unknown:
        raise ValueError(f"unknown parameter {unknown[0]!r}; known parameters: {', '.join(sorted(p_names | n_names))}")
    p, n = (p.replace(**{k: v for k, v in typed.items() if k in p_names}),
            n.replace(**{k: v for k, v in typed.items() if k in n_names}))
    check_combination(p, n)
    return p, n


def apply_preset(name: str, params: SwimmerParams | None = None,
                 numerics: NumericsConfig | None = None) -> tuple[SwimmerParams, NumericsConfig]:
    """(params, numerics) with the preset's discretisation and numerics applied on top."""
    check_preset(name)
    p = (params or SwimmerParams()).replace(**PRESETS[name]["params"])
    n = (numerics or NumericsConfig()).replace(**PRESETS[name]["numerics"])
    return p, n
