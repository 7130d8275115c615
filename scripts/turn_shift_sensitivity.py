"""How far a swimmer that differs from the model shifts the turn map, and what predicts it.

For swimmers drawn around the preset's (E, mu, b uniform within +-FRACTION, helix pitch and
radius within +-0.4 FRACTION, as ``flagellum evaluate --randomize``): from the steady start at
omega_l, the steady end-to-end strain L'/L - 1 and the flagellum's lab rotation rate (what a
controller sees while cruising, ``agents.turn_measurement.cruise_observables``), then one turn (``measure_turn``: a burst of T_C s
at omega_h, phase 0) and the buckling-time shift it reads against the preset's turn map
(``agents.online_turn_map.shift_reading``). Rows go to ``--out`` (JSON lines) as they finish;
running again skips the swimmers already there. ``--fit`` prints the least-squares fit of the
shift on the relative changes of strain and rotation rate and writes it beside ``--out``
(``*_fit.json``; its coefficients are ``agents.online_turn_map.OnlineMapConfig``'s defaults). Each row names the
reading of the head it was made with (``head_rotation``; rows without it were made with ``torque_free``, the
default when they were written); the fit uses only the rows of the preset's current reading.

    python scripts/turn_shift_sensitivity.py --count 30 --t-c 3.25 --workers 2 --fit
"""

from __future__ import annotations

import argparse
import json
import math
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

FIELDS = ("youngs_modulus", "viscosity", "head_radius", "pitch", "helix_radius")


def draw(seed: int, fraction: float) -> dict[str, float]:
    """Factors on the preset's parameters for swimmer ``seed`` (seed 0: the nominal swimmer)."""
    if seed == 0:
        return {f: 1.0 for f in FIELDS}
    rng = np.random.default_rng(seed)
    lim = (fraction, fraction, fraction, 0.4 * fraction, 0.4 * fraction)
    return {f: float(rng.uniform(1.0 - a, 1.0 + a)) for f, a in zip(FIELDS, lim)}


def swimmer(preset: str, factors: dict[str, float]):
    """(params, numerics) of the preset's swimmer scaled by ``factors``."""
    from physics.presets import configure

    p, n = configure(preset)
    f = factors
    return p.replace(youngs_modulus=p.youngs_modulus * f["youngs_modulus"],
                     shear_modulus=p.shear_modulus * f["youngs_modulus"], viscosity=p.viscosity * f["viscosity"],
                     head_radius=p.head_radius * f["head_radius"], pitch=p.pitch * f["pitch"],
                     helix_radius=p.helix_radius * f["helix_radius"]), n


def cruise(preset: str, factors: dict[str, float]) -> dict:
    """The swimmer's ``CruiseObservables`` from its steady start, sampled as the adaptive planner
    samples before its first turn (every control step of 0.1 s for one wobble period + 1 step)."""
    import dataclasses

    from agents.assets import default_turn_map
    from agents.turn_map import TurnMap
    from flagellum_env.steady_start import get_steady_start
    from agents.turn_measurement import cruise_observables
    from physics.params import RPM_TO_RAD_S

    tm = TurnMap.load(default_turn_map(preset))
    p, n = swimmer(preset, factors)
    start = get_steady_start(p, n, tm.omega_l_rpm * RPM_TO_RAD_S, 5 * 60.0 / tm.omega_l_rpm, disk=False)
    dt = 0.1
    steps = max(2, round(tm.period_s / dt)) + 1
    return dataclasses.asdict(cruise_observables(start.new_simulator(), tm.phase_node, steps * dt, dt))


def one(seed: int, fraction: float, preset: str, t_c: float) -> dict:
    from agents.assets import default_turn_map
    from agents.online_turn_map import OnlineMapConfig, shift_reading
    from agents.turn_map import TurnMap
    from flagellum_env.steady_start import get_steady_start
    from agents.turn_measurement import measure_turn
    from physics.params import RPM_TO_RAD_S

    t0 = time.perf_counter()
    tm = TurnMap.load(default_turn_map(preset))
    f = draw(seed, fraction)
    p, n = swimmer(preset, f)
    start = get_steady_start(p, n, tm.omega_l_rpm * RPM_TO_RAD_S, 5 * 60.0 / tm.omega_l_rpm, disk=False)
    res = measure_turn(start.new_simulator(), tm.omega_l_rpm, tm.omega_h_rpm, t_c, 0.0)
    reading = shift_reading(*tm.rising_branch(), t_c, res.theta_deg, OnlineMapConfig())
    return {"seed": seed, "fraction": fraction, "preset": preset, "head_rotation": p.head_rotation, "factors": f,
            "cruise": cruise(preset, f), "t_c": t_c,
            "theta_deg": res.theta_deg, "psi_deg": res.psi_deg, "map_theta_deg": float(np.interp(
                t_c, *tm.rising_branch())), "shift_s": None if reading is None else reading[0],
            "shift_std_s": None if reading is None else reading[1], "wall_s": time.perf_counter() - t0}


def fit(rows: list[dict]) -> dict:
    """Least squares of the shift on the relative changes of strain and rotation rate (no
    intercept: the nominal swimmer reads 0), with the leave-one-out residual."""
    nominal = [r for r in rows if r["seed"] == 0]
    if not nominal:
        raise SystemExit("no nominal swimmer (seed 0) among the rows")
    ref = nominal[0]["cruise"]
    use = [r for r in rows if r["shift_s"] is not None and r["seed"] != 0]
    x = np.array([[r["cruise"]["strain"] / ref["strain"] - 1.0,
                   r["cruise"]["rotation_rate"] / ref["rotation_rate"] - 1.0] for r in use])
    y = np.array([r["shift_s"] for r in use])
    coef = np.linalg.lstsq(x, y, rcond=None)[0]
    loo = []
    for i in range(len(y)):
        keep = np.arange(len(y)) != i
        loo.append(y[i] - x[i] @ np.linalg.lstsq(x[keep], y[keep], rcond=None)[0])
    resid = y - x @ coef
    return {"n": len(use), "reference": ref, "strain_shift_s": float(coef[0]), "rate_shift_s": float(coef[1]),
            "residual_rms_s": float(np.sqrt(np.mean(resid ** 2))),
            "leave_one_out_rms_s": float(np.sqrt(np.mean(np.square(loo)))),
            "shift_rms_s": float(np.sqrt(np.mean(y ** 2))), "max_abs_residual_s": float(np.max(np.abs(resid)))}


def add_cruise(rows: list[dict], workers: int) -> None:
    """Measure the cruise observables of rows written before they were recorded (in place)."""
    need = [r for r in rows if "cruise" not in r]
    if not need:
        return
    with ProcessPoolExecutor(workers) as ex:
        for r, c in zip(need, ex.map(cruise, [r["preset"] for r in need], [r["factors"] for r in need])):
            r["cruise"] = c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--count", type=int, default=16, help="randomised swimmers (plus the nominal one)")
    ap.add_argument("--fraction", type=float, default=0.1, help="E, mu, b within +-this; geometry +-0.4x")
    ap.add_argument("--preset", default="faithful")
    ap.add_argument("--t-c", type=float, default=3.25, help="burst length, s (default: mid rising branch of the "
                    "default's map, theta ~55 deg)")
    ap.add_argument("--seed0", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default="results/online_turn_map/sensitivity.jsonl")
    ap.add_argument("--fit", action="store_true", help="print the fit of the shift on the strain")
    args = ap.parse_args()
    if args.count < 0 or not 0.0 <= args.fraction <= 0.5:
        ap.error(f"--count {args.count} / --fraction {args.fraction}: need count >= 0 and 0 <= fraction <= 0.5")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    rows = [json.loads(line) for line in out.read_text().splitlines()] if out.exists() else []
    from physics.presets import configure

    reading = configure(args.preset)[0].head_rotation
    done = {(r["seed"], r["fraction"], r["preset"], r["t_c"], r.get("head_rotation", "torque_free")) for r in rows}
    seeds = [0] + list(range(args.seed0, args.seed0 + args.count))
    todo = [s for s in seeds if (s, args.fraction, args.preset, args.t_c, reading) not in done]
    with ProcessPoolExecutor(args.workers) as ex, out.open("a") as fh:
        futs = {ex.submit(one, s, args.fraction, args.preset, args.t_c): s for s in todo}
        for fut in as_completed(futs):
            row = fut.result()
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            rows.append(row)
            print(f"seed {row['seed']}: strain {row['cruise']['strain']:.6f}, theta {row['theta_deg']:.1f} deg "
                  f"(map {row['map_theta_deg']:.1f}), shift {row['shift_s']}, {row['wall_s']:.0f} s", flush=True)
    if args.fit:
        if any("cruise" not in r for r in rows):
            add_cruise(rows, args.workers)
            tmp = out.with_name(out.name + ".tmp")
            tmp.write_text("".join(json.dumps(r) + "\n" for r in rows))
            tmp.replace(out)
        result = fit([r for r in rows if r["preset"] == args.preset and r["t_c"] == args.t_c
                      and r.get("head_rotation", "torque_free") == reading])
        result.update(preset=args.preset, head_rotation=reading, t_c=args.t_c, fraction=args.fraction)
        print(json.dumps(result, indent=1))
        Path(str(out).replace(".jsonl", "_fit.json")).write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
