"""Named speed/accuracy presets, selectable everywhere (CLI ``--preset``, API, environment).

``paper`` is the paper's discretisation (N = 122, edges 2 delta, LSBT + Higdon head) and scheme
(implicit Euler, eqn 6) at the paper's h = 1 ms, Newton tolerance 1e-6 (the chord iteration compiled, without
Anderson mixing), with the resistance
refreshed whenever the shape has changed by more than 0.03 r0 (first order in h: 2 % off the
converged turn angle, docs/bench_quick.md); its steps with a rebuilt resistance are solved by
Newton-Krylov (the same solution to the Newton tolerance, 1.4x faster in a burst).

``faithful`` (the default everywhere: ``DEFAULT_PRESET``) is the paper's swimmer on the paper's
grid, integrated by variable-step BDF3 with the local error per step held below ``step_tol``
(``physics.integrate.time_integrator``); steps at which the shape has changed (the resistance is rebuilt:
buckling, relaxation) are solved by Newton-Krylov in the mobility form (``physics.solvers.newton_krylov``),
the others by the chord iteration on the reused dense factorisation; ``dt`` = 0.1 s is the sampling /
control step inside which the adaptive steps are taken. ``fast`` is the same grid and scheme with a
looser error tolerance. ``reference`` is the converged swimmer every preset's error is measured against:
the same model with BDF2 at step_tol 1e-7, Newton 1e-8 and the resistance rebuilt at 0.003 r0 of
deformation (BDF3 stalls below step_tol 1e-6: its steps collapse to microseconds; the convergence of
``reference``: docs/time_integration.md). ``coarse`` (N = 45, h = 10 ms implicit Euler) swims like
``paper`` but buckles later and turns differently: its turns are its own, and so is its turn map.

Measured costs and errors against ``reference``: docs/bench_quick.md (``flagellum bench --quick``); the wider
ladder: docs/fidelity.md (scripts/bench_fidelity.py).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from physics.params import NumericsConfig, SwimmerParams, apply_overrides, check_combination

#: The preset of every command, the environment and the agents unless told otherwise.
DEFAULT_PRESET = "faithful"

#: the error-controlled presets: Newton-Krylov where the shape changes, the plain chord iteration elsewhere (Anderson
#: mixing cost more than it saved there: steady 10 rpm 38x -> 53x real time, same iteration count)
_ADAPTIVE = {"dt": 0.1, "jacobian_refresh": "resistance", "hydro_model": "lsbt", "head_model": "higdon",
             "newton_krylov": True, "anderson_depth": 0}

PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "reference": {"params": {"n_nodes": 122},
                  "numerics": {**_ADAPTIVE, "integrator": "bdf2", "step_tol": 1e-7, "hydro_refresh_tol": 0.003,
                               "newton_tol": 1e-8}},
    # paper: the chord iteration without Anderson mixing runs compiled (chord_iteration.chord_loop): 1.25x steady,
    # 1.18x burst, the end state of a 1.5 s burst 2.7e-10 m from the mixed iteration's
    "paper": {"params": {"n_nodes": 122},
              "numerics": {"dt": 1e-3, "hydro_model": "lsbt", "head_model": "higdon",
                           "hydro_refresh_tol": 0.03, "newton_tol": 1e-6, "newton_krylov": True, "anderson_depth": 0}},
    "faithful": {"params": {"n_nodes": 122},
                 "numerics": {**_ADAPTIVE, "integrator": "bdf3", "step_tol": 1e-4, "hydro_refresh_tol": 0.03,
                              "newton_tol": 1e-5}},
    "fast": {"params": {"n_nodes": 122},
             "numerics": {**_ADAPTIVE, "integrator": "bdf3", "step_tol": 1e-3, "hydro_refresh_tol": 0.03,
                          "newton_tol": 1e-5}},
    "coarse": {"params": {"n_nodes": 45},
               "numerics": {"dt": 1e-2, "hydro_model": "lsbt", "head_model": "higdon",
                            "hydro_refresh_tol": 0.1, "newton_tol": 1e-5}},
}


def preset_names() -> list[str]:
    return list(PRESETS)


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
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose one of {preset_names()}")
    p = (params or SwimmerParams()).replace(**PRESETS[name]["params"])
    n = (numerics or NumericsConfig()).replace(**PRESETS[name]["numerics"])
    return p, n
