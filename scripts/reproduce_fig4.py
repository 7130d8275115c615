"""Reproduce Fig. 4 of Huang & Jawed 2020: a sweep of motor speed for four head sizes, each run
100 s (t_bar = 1.02) from rest, then the figures and the buckling-threshold brackets.

    python scripts/reproduce_fig4.py [--out data/fig4] [--workers N] [--resume]

A thin wrapper over the sweep runner (``flagellum.sweep``). Discretisation: the paper's N = 122
with edges 2 delta; time step 5 ms (the swim speed differs from 1 ms by < 0.05 %, see the
time-step test), resistance refreshed at 0.03 r0 (indistinguishable from every step). Both
readings of the head's rotation are run: eqn (13) torque-free (default) and "fixed".
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path

OMEGAS_RPM = [10.0, 30.0, 50.0, 60.0, 70.0, 90.0]
#: The torque-free reading buckles later (small heads not at all by 90 rpm): two more speeds
#: bracket omega_b for every head size (b = 0 is the baseline of both readings).
OMEGAS_TF_RPM = OMEGAS_RPM + [120.0, 150.0]
HEADS_M = [0.0, 0.004, 0.008, 0.012]
FIXED = {"n_nodes": 122, "dt": 0.005, "hydro_refresh_tol": 0.03}
BUCKLED_RATIO = 0.98  # L'/L below this at t_bar = 1.02 counts as buckled


def configs() -> dict[str, dict]:
    return {
        "torque_free": {"sweep": {"omega_rpm": OMEGAS_TF_RPM, "head_radius": HEADS_M}, "duration_s": 100.0,
                        "fixed": {**FIXED, "head_rotation": "torque_free"}, "record_interval_s": 0.1,
                        "node_record_interval_s": 10.0},
        "fixed_head": {"sweep": {"omega_rpm": OMEGAS_RPM, "head_radius": HEADS_M[1:]}, "duration_s": 100.0,
                       "fixed": {**FIXED, "head_rotation": "fixed"}, "record_interval_s": 0.1,
                       "node_record_interval_s": 10.0},
    }


def run(out: Path, workers: int | None, resume: bool) -> None:
    import yaml

    from flagellum.sweep import load_sweep_config, run_sweep

    for name, cfg in configs().items():
        d = out / name
        d.mkdir(parents=True, exist_ok=True)
        path = d / "config.yaml"
        path.write_text(yaml.safe_dump(cfg))
        run_sweep(load_sweep_config(path), d, workers=workers, resume=resume or (d / "results.jsonl").exists())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="data/fig4")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--resume", action="store_true")
    args = ap.parse_args(argv)
    run(Path(args.out), args.workers, args.resume)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
