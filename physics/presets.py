"""Named speed/accuracy presets, selectable everywhere (CLI ``--preset``, API, environment).

``paper`` is the reference: the paper's discretisation (N = 122, edges 2 delta, LSBT + Higdon
head) at the paper's h = 1 ms, with the resistance refreshed whenever the shape has changed by
more than 0.03 r0 (indistinguishable from refreshing every step, see docs/fidelity.md).
``balanced`` keeps the paper's grid and refresh rule and takes a 20x longer step (h = 20 ms,
Newton tolerance 1e-5): the onset of buckling, and so every turn, needs the paper's grid and
refresh rule; the time step matters little up to 20 ms (docs/node_convergence.md). ``fast`` coarsens the grid to N = 45 and refreshes the resistance
lazily: it swims like ``paper`` (within ~1 %) but buckles later, so its turns are its own and its
turn map must be calibrated on it (the planner does). Measured costs and errors against ``paper``:
docs/fidelity.md (scripts/bench_fidelity.py).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from physics.params import NumericsConfig, SwimmerParams, apply_overrides

PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "paper": {"params": {"n_nodes": 122},
              "numerics": {"dt": 1e-3, "hydro_model": "lsbt", "head_model": "higdon",
                           "hydro_refresh_tol": 0.03, "newton_tol": 1e-6}},
    # the paper's grid (the buckling onset needs it, docs/node_convergence.md) at h = 20 ms
    "balanced": {"params": {"n_nodes": 122},
                 "numerics": {"dt": 2e-2, "hydro_model": "lsbt", "head_model": "higdon",
                              "hydro_refresh_tol": 0.03, "newton_tol": 1e-5}},
    "fast": {"params": {"n_nodes": 45},
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
        return p, n
    p, n = apply_overrides(p, n, {k: v for k, v in overrides.items() if isinstance(v, str)})
    typed = {k: v for k, v in overrides.items() if not isinstance(v, str)}
    p_names = {f.name for f in dataclasses.fields(SwimmerParams)}
    n_names = {f.name for f in dataclasses.fields(NumericsConfig)}
    unknown = sorted(set(typed) - p_names - n_names)
    if unknown:
        raise ValueError(f"unknown parameter {unknown[0]!r}; known parameters: {', '.join(sorted(p_names | n_names))}")
    return (p.replace(**{k: v for k, v in typed.items() if k in p_names}),
            n.replace(**{k: v for k, v in typed.items() if k in n_names}))


def apply_preset(name: str, params: SwimmerParams | None = None,
                 numerics: NumericsConfig | None = None) -> tuple[SwimmerParams, NumericsConfig]:
    """(params, numerics) with the preset's discretisation and numerics applied on top."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose one of {preset_names()}")
    p = (params or SwimmerParams()).replace(**PRESETS[name]["params"])
    n = (numerics or NumericsConfig()).replace(**PRESETS[name]["numerics"])
    return p, n
