"""Named speed/accuracy presets, selectable everywhere (CLI ``--preset``, API, environment).

``paper`` is the reference: the paper's discretisation (N = 122, edges 2 delta, LSBT + Higdon
head) at the paper's h = 1 ms, with the resistance refreshed whenever the shape has changed by
more than 0.03 r0 (indistinguishable from refreshing every step, see docs/fidelity.md).
``balanced`` and ``fast`` trade accuracy for speed; their measured costs and errors against
``paper`` are in docs/fidelity.md (scripts/bench_fidelity.py). Coarser grids than N = 45 (e.g.
N = 30) keep the swim speed within ~1 % but raise the buckling threshold: at N = 30 the
swimmer did not buckle in 60 s at 90 rpm, where N = 45 and N = 122 do (docs/fidelity.md).
"""

from __future__ import annotations

from typing import Any

from physics.params import NumericsConfig, SwimmerParams

PRESETS: dict[str, dict[str, dict[str, Any]]] = {
    "paper": {"params": {"n_nodes": 122},
              "numerics": {"dt": 1e-3, "hydro_model": "lsbt", "head_model": "higdon",
                           "hydro_refresh_tol": 0.03, "newton_tol": 1e-6}},
    "balanced": {"params": {"n_nodes": 60},
                 "numerics": {"dt": 5e-3, "hydro_model": "lsbt", "head_model": "higdon",
                              "hydro_refresh_tol": 0.1, "newton_tol": 1e-6}},
    "fast": {"params": {"n_nodes": 45},
             "numerics": {"dt": 1e-2, "hydro_model": "lsbt", "head_model": "higdon",
                          "hydro_refresh_tol": 0.1, "newton_tol": 1e-5}},
}


def preset_names() -> list[str]:
    return list(PRESETS)


def apply_preset(name: str, params: SwimmerParams | None = None,
                 numerics: NumericsConfig | None = None) -> tuple[SwimmerParams, NumericsConfig]:
    """(params, numerics) with the preset's discretisation and numerics applied on top."""
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r}; choose one of {preset_names()}")
    p = (params or SwimmerParams()).replace(**PRESETS[name]["params"])
    n = (numerics or NumericsConfig()).replace(**PRESETS[name]["numerics"])
    return p, n
