"""Calibration study of the `reduced` tier (issue 48, item 2): local resistive-force theory (RFT) against `faithful`.

The swimmer of every case is `faithful`'s numerics (BDF3, step_tol 1e-4, Newton 1e-5, contact on,
default head b = 1.2 cm held against rotation) with, for the RFT cases, ``hydro_model=rft``
(physics/hydro/rft.py: f_j = -ell_j [zeta_perp (I - t t) + zeta_par t t] u_j with Lighthill's (1976)
coefficients, the head a plain Stokes sphere 6 pi mu b, 8 pi mu b^3: no flow coupling) on N nodes and the
factors ``rft_scale_perp``, ``rft_scale_par`` on (zeta_perp, zeta_par).

Metrics (one JSON line each in ``--out``, keyed by the case's overrides and the metric; a rerun skips what is
there, ``--fresh`` starts over):

* ``steady``: 30 s at 10 rpm from rest (5 motor turns, the turn map's steady start), then 12 s (2 motor turns):
  swim per turn (head displacement / 2, m), mean motor torque (N m, sampled every 0.1 s), CPU real-time factor;
* ``turn:<t_c>``: from the same steady start, ``agents.turn_measurement.measure_turn`` with omega_l = 10 rpm,
  omega_h = 150 rpm, burst t_c s, phase 0: theta, phi (deg), L'/L at the burst's end, the burst's CPU seconds;
* ``burst``: 6 s at 10 rpm, 7.5 s at 150 rpm, relaxation (``flagellum bench --quick``'s burst when it was run): the
  burst's CPU real-time factor (simulated s per CPU s), theta;
* ``buckle:<rpm>``: L'/L after 100 s at ``rpm`` from rest (buckled: < 0.98, as the fidelity ladder's omega_b);
* ``env``: ``FlagellumSteer-v0`` with the case's settings, control_dt 2 s, 40 random actions (seed 0): env steps
  per CPU s (the quick bench's random-policy metric).

Fits (``--fit N ...``): per node count, (rft_scale_perp, rft_scale_par) by Newton iteration in log space on the
two residuals log(swim per turn / faithful's) and log(torque / faithful's), finite-difference Jacobian
(step 0.05 in log), from (1, 1); every evaluation is a ``steady`` record, so a rerun replays the fit from the
cache. The fitted factors go to ``<out>.fits.json``.

Errors are against `faithful` (which is within 0.3 % of `reference` on swim per turn and the burst's theta,
docs/bench_quick.md): |x - x_f| / |x_f| (angles: floor 10 deg).

Usage (at most 2 worker processes on the shared machine):

    python scripts/calibrate_reduced.py --stage faithful --stage baseline   # faithful's values, Lighthill RFT
    python scripts/calibrate_reduced.py --stage fit --stage validate        # 2-factor fit, out of sample
    python scripts/calibrate_reduced.py --stage head                        # faithful with a Stokes head
    python scripts/calibrate_reduced.py --stage fit3 --stage validate3      # + head drag, fitted to the onset
    python scripts/calibrate_reduced.py --stage speed --stage rigid         # env steps/s; 6x6 rigid resistance
    python scripts/calibrate_reduced.py --table                             # what is there (--all: fit points)

Faithful's values are also written to ``<out dir>/faithful_reference.json``. Findings: docs/reduced_calibration.md.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

DEFAULT_OUT = Path("results/reduced/calibrate_reduced.jsonl")
OMEGA_L_RPM = 10.0
OMEGA_H_RPM = 150.0
START_S = 30.0      # 5 motor turns at 10 rpm from rest (agents.turn_calibration.SETTLE_TURNS)
CRUISE_S = 12.0     # 2 motor turns at 10 rpm
#: rising branch of the default's turn map at phase 0 (agents/turn_maps/faithful.json: theta 16-85 deg)
RISING_TC = (2.5, 2.75, 3.0, 3.25, 3.5)
NODE_COUNTS = (40, 60, 80, 122)
BUCKLE_RPM = (50.0, 60.0)
BUCKLED_RATIO = 0.98
#: onset of buckling in a 150 rpm burst from the steady start: the time L'/L first falls below this
ONSET_RATIO = 0.9
ONSET_MAX_S = 8.0


def rft_case(n_nodes: int, perp: float = 1.0, par: float = 1.0, head: float | None = None,
             **extra: Any) -> dict[str, Any]:
    """Overrides of `faithful` for an RFT case (JSON types; rounded factors so that keys are stable); ``head``:
    ``rft_head_drag_scale`` (None: left at 1 and out of the key)."""
    ov = {"n_nodes": int(n_nodes), "hydro_model": "rft", "rft_scale_perp": round(float(perp), 6),
          "rft_scale_par": round(float(par), 6), **extra}
    if head is not None:
        ov["rft_head_drag_scale"] = round(float(head), 6)
    return ov


def case_label(ov: dict[str, Any]) -> str:
    if not ov:
        return "faithful"
    if ov.get("hydro_model") != "rft":
        return "faithful " + " ".join(f"{k}={v}" for k, v in sorted(ov.items()))
    extra = " ".join(f"{k}={v}" for k, v in sorted(ov.items())
                     if k not in ("n_nodes", "hydro_model", "rft_scale_perp", "rft_scale_par", "rft_head_drag_scale"))
    head = f" s_head={ov['rft_head_drag_scale']:.4g}" if "rft_head_drag_scale" in ov else ""
    return (f"RFT N={ov['n_nodes']} s_perp={ov['rft_scale_perp']:.4g} s_par={ov['rft_scale_par']:.4g}{head}"
            + (f" {extra}" if extra else ""))


def key(ov: dict[str, Any], metric: str) -> str:
    return json.dumps({"case": ov, "metric": metric}, sort_keys=True)


# --- the measurements (run in worker processes) ------------------------------------------------------------------

def _sim(ov: dict[str, Any]):
    from physics import configure
    from physics.simulator import Simulator

    p, n = configure("faithful", ov)
    return Simulator(p, n)


def measure(ov: dict[str, Any], metric: str) -> dict[str, Any]:
    """One metric of one case; the record's ``result`` (SI units, angles in degrees)."""
    from physics import advance
    from physics.params import RPM_TO_RAD_S

    c_start = time.process_time()
    out: dict[str, Any] = {}
    if metric == "onset":
        # the steady cruise as in "steady", then 150 rpm until L'/L falls below ONSET_RATIO (sampled every 0.05 s,
        # the crossing interpolated linearly): the onset of buckling in the burst, s
        out.update(measure(ov, "steady"))
        sim = _sim(ov)
        sim.set_motor_speed(OMEGA_L_RPM * RPM_TO_RAD_S)
        advance(sim, START_S)
        sim.set_motor_speed(OMEGA_H_RPM * RPM_TO_RAD_S)
        t, prev, onset = 0.0, sim.end_to_end_ratio(), None
        while t < ONSET_MAX_S:
            advance(sim, 0.05)
            t += 0.05
            r = sim.end_to_end_ratio()
            if r < ONSET_RATIO:
                onset = t - 0.05 + 0.05 * (prev - ONSET_RATIO) / (prev - r)
                break
            prev = r
        out["onset_s"] = onset
    elif metric == "rigid":
        out.update(rigid_resistance(ov))
    elif metric == "steady":
        sim = _sim(ov)
        sim.set_motor_speed(OMEGA_L_RPM * RPM_TO_RAD_S)
        advance(sim, START_S)
        x0, c0, torques = sim.head_position, time.process_time(), []
        for _ in range(round(CRUISE_S / 0.1)):
            advance(sim, 0.1)
            torques.append(sim.motor_torque)
        cpu = time.process_time() - c0
        out.update(swim_per_turn_m=math.dist(sim.head_position, x0) / (CRUISE_S * OMEGA_L_RPM / 60.0),
                   torque_Nm=float(sum(torques) / len(torques)), lratio=float(sim.end_to_end_ratio()),
                   rtf_cpu=CRUISE_S / max(cpu, 1e-9))
    elif metric.startswith("turn:") or metric == "burst":
        from agents.turn_measurement import measure_turn

        tc = 7.5 if metric == "burst" else float(metric.split(":")[1])
        sim = _sim(ov)
        sim.set_motor_speed(OMEGA_L_RPM * RPM_TO_RAD_S)
        advance(sim, 6.0 if metric == "burst" else START_S)
        res = measure_turn(sim, OMEGA_L_RPM, OMEGA_H_RPM, tc, 0.0, relax_max_s=90.0 if metric == "burst" else 150.0)
        out.update(theta_deg=res.theta_deg, phi_deg=res.phi_deg, lratio_burst_end=res.burst_end_ratio,
                   straight=res.straight, relax_s=res.relax_s, burst_cpu_s=res.burst_cpu_s,
                   burst_rtf_cpu=tc / max(res.burst_cpu_s, 1e-9))
    elif metric.startswith("buckle:"):
        rpm = float(metric.split(":")[1])
        sim = _sim(ov)
        sim.set_motor_speed(rpm * RPM_TO_RAD_S)
        advance(sim, 100.0)
        ratio = float(sim.end_to_end_ratio())
        out.update(rpm=rpm, lratio_100s=ratio, buckled=ratio < BUCKLED_RATIO)
    elif metric == "env":
        import gymnasium as gym

        import flagellum_env  # noqa: F401  (registers the ids)

        params = {k: v for k, v in ov.items() if k == "n_nodes"}
        numerics = {k: v for k, v in ov.items() if k != "n_nodes"}
        env = gym.make("FlagellumSteer-v0", preset="faithful", params=params or None, numerics=numerics or None,
                       control_dt=2.0)
        env.reset(seed=0)
        env.action_space.seed(0)
        c0 = time.process_time()
        for _ in range(40):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()
        cpu = time.process_time() - c0
        env.close()
        out.update(env_steps_per_s=40 / cpu)
    else:
        raise ValueError(f"unknown metric {metric!r}")
    out["cpu_s"] = time.process_time() - c_start
    return out


def rigid_resistance(ov: dict[str, Any]) -> dict[str, Any]:
    """The 6x6 rigid-body resistance of the swimmer's rest shape (head + helix, the default b): rows (F, T) N and
    N m about the head's centre, columns (U, Omega) m/s and rad/s, lab axes (the helix axis along -x), from the
    case's hydrodynamic model at the rest nodes (LSBT + Higdon head, or RFT + Stokes head); the head does not
    spin. ``diag``: its diagonal (N s/m, N m s)."""
    import numpy as np

    sim = _sim(ov)
    x = sim.nodes.copy()
    hyd = next(t for t in sim.scene.terms if t.name == "hydrodynamics")
    res = hyd.resistance_at(x)
    xc = x[0]
    out = np.zeros((6, 6))
    for k in range(6):
        u, w = np.zeros(3), np.zeros(3)
        (u if k < 3 else w)[k % 3] = 1.0
        v = (u + np.cross(w, x - xc)).ravel()
        if hyd.spin:
            v = np.append(v, 0.0)
        f = res.apply(v)[:x.size].reshape(-1, 3)
        out[:3, k], out[3:, k] = f.sum(0), np.cross(x - xc, f).sum(0)
    return {"matrix": out.tolist(), "diag": np.diag(out).tolist(), "thrust_coupling": float(out[0, 3])}


def _task(ov: dict[str, Any], metric: str) -> dict[str, Any]:
    rec: dict[str, Any] = {"case": ov, "metric": metric, "label": case_label(ov),
                           "measured": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    try:
        rec["result"], rec["error"] = measure(ov, metric), None
    except Exception as exc:  # a failing case is a result too
        rec["result"], rec["error"] = None, f"{type(exc).__name__}: {exc}"
    return rec


# --- the store -----------------------------------------------------------------------------------------------------

class Store:
    """Records in a JSON-lines file, appended as they finish; the latest per (case, metric) counts."""

    def __init__(self, path: Path, fresh: bool = False) -> None:
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        if fresh and path.exists():
            path.unlink()
        self.done: dict[str, dict] = {}
        if path.exists():
            for line in path.read_text().splitlines():
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # a line cut by an interrupted run
                self.done[key(rec["case"], rec["metric"])] = rec

    def get(self, ov: dict[str, Any], metric: str) -> dict | None:
        return self.done.get(key(ov, metric))

    def add(self, rec: dict[str, Any]) -> None:
        self.done[key(rec["case"], rec["metric"])] = rec
        with self.path.open("a") as f:
            f.write(json.dumps(rec) + "\n")

    def run(self, tasks: list[tuple[dict[str, Any], str]], workers: int) -> None:
        todo = [(ov, m) for ov, m in dict.fromkeys((json.dumps(o, sort_keys=True), m) for o, m in tasks)]
        todo = [(json.loads(o), m) for o, m in todo if self.get(json.loads(o), m) is None]
        if not todo:
            return
        print(f"{len(todo)} task(s) to run on {workers} worker(s)", flush=True)
        if workers <= 1:
            for ov, m in todo:
                self._report(_task(ov, m))
            return
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(_task, ov, m) for ov, m in todo]
            for fut in as_completed(futures):
                self._report(fut.result())

    def _report(self, rec: dict[str, Any]) -> None:
        self.add(rec)
        r = rec["result"]
        brief = rec["error"] or ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                          for k, v in r.items())
        print(f"  {rec['label']:<48} {rec['metric']:<10} {brief}", flush=True)


# --- the fit -------------------------------------------------------------------------------------------------------

def fit_scales(store: Store, n_nodes: int, target: tuple[float, float], extra: dict[str, Any], workers: int,
               tol: float = 2e-3, max_iter: int = 6) -> dict[str, Any]:
    """(rft_scale_perp, rft_scale_par) with the RFT swimmer's swim per turn and motor torque at 10 rpm equal to
    ``target`` = (m, N m) to ``tol`` in log. Newton in (log s_perp, log s_par) with a forward-difference Jacobian
    (step 0.05); the three steady runs of an iteration run in parallel."""
    import numpy as np

    def resid(rec):
        r = rec["result"]
        return np.array([math.log(r["swim_per_turn_m"] / target[0]), math.log(r["torque_Nm"] / target[1])])

    s = np.zeros(2)
    d = 0.05
    history = []
    for it in range(max_iter):
        pts = [s, s + [d, 0.0], s + [0.0, d]]
        cases = [rft_case(n_nodes, math.exp(p[0]), math.exp(p[1]), **extra) for p in pts]
        store.run([(c, "steady") for c in cases], workers)
        recs = [store.get(c, "steady") for c in cases]
        if any(r["error"] for r in recs):
            return {"n_nodes": n_nodes, "error": next(r["error"] for r in recs if r["error"]), "history": history}
        f0 = resid(recs[0])
        history.append({"scale_perp": cases[0]["rft_scale_perp"], "scale_par": cases[0]["rft_scale_par"],
                        "residual_log": f0.tolist()})
        if np.max(np.abs(f0)) < tol:
            break
        J = np.column_stack([(resid(recs[1]) - f0) / d, (resid(recs[2]) - f0) / d])
        step = -np.linalg.solve(J, f0)
        s = s + np.clip(step, -0.7, 0.7)
    return {"n_nodes": n_nodes, **extra, "scale_perp": cases[0]["rft_scale_perp"],
            "scale_par": cases[0]["rft_scale_par"], "residual_log": f0.tolist(), "iterations": len(history),
            "history": history}


def fit_scales3(store: Store, n_nodes: int, target: tuple[float, float, float], workers: int,
                start: tuple[float, float, float] = (1.05, 1.1, 2.5), max_iter: int = 7) -> dict[str, Any]:
    """(rft_scale_perp, rft_scale_par, rft_head_drag_scale) with the RFT swimmer's swim per turn (m) and motor
    torque (N m) at 10 rpm and its onset of buckling at 150 rpm (s, ``onset``) equal to ``target``: Newton in log
    of the three factors on the residuals log(swim ratio), log(torque ratio), onset / target - 1, forward
    differences (step 0.05). Stops when the first two are below 2e-3 and the onset within 1 % (its sampling
    noise is about 0.5 %)."""
    import numpy as np

    def resid(rec):
        r = rec["result"]
        if r["onset_s"] is None:
            return np.array([math.log(r["swim_per_turn_m"] / target[0]), math.log(r["torque_Nm"] / target[1]),
                             ONSET_MAX_S / target[2]])
        return np.array([math.log(r["swim_per_turn_m"] / target[0]), math.log(r["torque_Nm"] / target[1]),
                         r["onset_s"] / target[2] - 1.0])

    s = np.log(np.array(start))
    d = 0.05
    history = []
    best = None
    for _ in range(max_iter):
        pts = [s] + [s + d * e for e in np.eye(3)]
        cases = [rft_case(n_nodes, *np.exp(p)) for p in pts]
        store.run([(c, "onset") for c in cases], workers)
        recs = [store.get(c, "onset") for c in cases]
        if any(r["error"] for r in recs):
            return {"n_nodes": n_nodes, "error": next(r["error"] for r in recs if r["error"]), "history": history}
        f0 = resid(recs[0])
        history.append({"case": cases[0], "residual": f0.tolist()})
        if best is None or np.max(np.abs(f0)) < np.max(np.abs(best[1])):
            best = (cases[0], f0)
        if np.max(np.abs(f0[:2])) < 2e-3 and abs(f0[2]) < 1e-2:
            break
        J = np.column_stack([(resid(r) - f0) / d for r in recs[1:]])
        s = s + np.clip(-np.linalg.solve(J, f0), -0.7, 0.7)
    c, f0 = best
    return {"n_nodes": n_nodes, "scale_perp": c["rft_scale_perp"], "scale_par": c["rft_scale_par"],
            "head_drag_scale": c["rft_head_drag_scale"], "residual": f0.tolist(), "iterations": len(history),
            "history": history}


# --- the table -----------------------------------------------------------------------------------------------------

def rel(x: float, ref: float, floor: float = 0.0) -> float:
    return abs(x - ref) / max(abs(ref), floor)


def table(store: Store, show_all: bool = False) -> str:
    """A markdown table: one row per case, columns per metric, errors against `faithful` in brackets; the fits'
    intermediate points (cases with only steady / onset records) only with ``show_all``."""
    cases: dict[str, dict] = {}
    for rec in store.done.values():
        cases.setdefault(json.dumps(rec["case"], sort_keys=True), {})[rec["metric"]] = rec
    ref = cases.get(json.dumps({}), {})

    def val(recs, metric, field):
        rec = recs.get(metric)
        if rec is None:
            return None
        if rec["error"]:
            return "err"
        return rec["result"].get(field)

    turn_metrics = sorted({m for c in cases.values() for m in c if m.startswith("turn:")},
                          key=lambda m: float(m.split(":")[1]))
    buckle_metrics = sorted({m for c in cases.values() for m in c if m.startswith("buckle:")},
                            key=lambda m: float(m.split(":")[1]))
    head = (["case", "swim/turn mm", "torque uN m", "steady RTF"] + [f"θ t_c={m[5:]}" for m in turn_metrics]
            + ["onset s", "burst θ", "burst RTF"] + [f"L'/L 100 s @{m[7:]}" for m in buckle_metrics] + ["env steps/s"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def cell(recs, metric, field, scale=1.0, floor=0.0, fmt="{:.4g}", err=True):
        v = val(recs, metric, field)
        if v is None:
            return "—"
        if v == "err":
            return "fail"
        if isinstance(v, bool):
            return str(v)
        s = fmt.format(v * scale)
        r = val(ref, metric, field)
        if err and recs is not ref and isinstance(r, (int, float)) and not isinstance(r, bool) and r != "err":
            s += f" ({100 * rel(v, r, floor):.1f} %)"
        return s

    order = sorted(cases, key=lambda c: (json.loads(c) != {}, json.loads(c).get("hydro_model", ""),
                                         json.loads(c).get("n_nodes", 0), json.loads(c).get("rft_scale_perp", 0),
                                         c))
    for c in order:
        recs = cases[c]
        if not show_all and c != json.dumps({}) and set(recs) <= {"steady", "onset", "rigid"}:
            continue  # a fit's intermediate point (``--all`` shows them)
        row = [case_label(json.loads(c)), cell(recs, "steady", "swim_per_turn_m", 1e3),
               cell(recs, "steady", "torque_Nm", 1e6), cell(recs, "steady", "rtf_cpu", fmt="{:.3g}", err=False)]
        row += [cell(recs, m, "theta_deg", floor=10.0, fmt="{:.1f}") for m in turn_metrics]
        row += [cell(recs, "onset", "onset_s", fmt="{:.3f}"),
                cell(recs, "burst", "theta_deg", floor=10.0, fmt="{:.1f}"),
                cell(recs, "burst", "burst_rtf_cpu", fmt="{:.3g}", err=False)]
        row += [cell(recs, m, "lratio_100s", fmt="{:.3f}", err=False) for m in buckle_metrics]
        row += [cell(recs, "env", "env_steps_per_s", fmt="{:.3g}", err=False)]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--stage", choices=("faithful", "baseline", "fit", "validate", "head", "fit3", "validate3",
                                        "speed", "rigid"), action="append",
                    default=[])
    ap.add_argument("--nodes", type=int, nargs="+", default=list(NODE_COUNTS))
    ap.add_argument("--tc", type=float, nargs="+", default=list(RISING_TC))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--fresh", action="store_true", help="start over (default: resume, skipping finished cases)")
    ap.add_argument("--table", action="store_true", help="print the table of what is there")
    ap.add_argument("--all", action="store_true", help="the table with the fits' intermediate points")
    a = ap.parse_args(argv)
    workers = min(max(a.workers, 1), 2)
    store = Store(a.out, fresh=a.fresh)
    turn_metrics = [f"turn:{t:g}" for t in a.tc]
    buckle_metrics = [f"buckle:{r:g}" for r in BUCKLE_RPM]
    fits_path = a.out.with_suffix(".fits.json")
    fits = json.loads(fits_path.read_text()) if fits_path.exists() else {}
    fits3_path = a.out.with_suffix(".fits3.json")
    fits3 = json.loads(fits3_path.read_text()) if fits3_path.exists() else {}

    def fitted3(n):
        f = fits3.get(str(n))
        return rft_case(n, f["scale_perp"], f["scale_par"], f["head_drag_scale"]) if f and "scale_perp" in f else None

    for stage in a.stage:
        if stage == "faithful":
            store.run([({}, "steady"), ({}, "onset")] + [({}, m) for m in turn_metrics] + [({}, "burst")]
                      + [({}, m) for m in buckle_metrics], workers)
            summary = {m: store.get({}, m) for m in ["steady", "burst", *turn_metrics, *buckle_metrics]}
            a.out.with_name("faithful_reference.json").write_text(json.dumps(summary, indent=1) + "\n")
        elif stage == "baseline":
            store.run([(rft_case(n), m) for n in a.nodes for m in ["steady", *turn_metrics, "buckle:60"]], workers)
        elif stage == "fit":
            ref = store.get({}, "steady")
            if ref is None or ref["error"]:
                print("run --stage faithful first", file=sys.stderr)
                return 2
            target = (ref["result"]["swim_per_turn_m"], ref["result"]["torque_Nm"])
            for n in a.nodes:
                fits[str(n)] = fit_scales(store, n, target, {}, workers)
                print(f"fit N={n}: {fits[str(n)].get('scale_perp')}, {fits[str(n)].get('scale_par')}, "
                      f"residual {fits[str(n)].get('residual_log')}", flush=True)
            fits_path.write_text(json.dumps(fits, indent=1) + "\n")
        elif stage == "validate":
            tasks = []
            for n in a.nodes:
                f = fits.get(str(n))
                if not f or "scale_perp" not in f:
                    continue
                c = rft_case(n, f["scale_perp"], f["scale_par"])
                tasks += [(c, m) for m in [*turn_metrics, *buckle_metrics, "burst"]]
            store.run(tasks, workers)
        elif stage == "fit3":
            ref = store.get({}, "onset")
            if ref is None or ref["error"]:
                print("run --stage faithful first", file=sys.stderr)
                return 2
            r = ref["result"]
            for n in a.nodes:
                fits3[str(n)] = fit_scales3(store, n, (r["swim_per_turn_m"], r["torque_Nm"], r["onset_s"]), workers)
                f = fits3[str(n)]
                print(f"fit3 N={n}: {f.get('scale_perp')}, {f.get('scale_par')}, {f.get('head_drag_scale')}, "
                      f"residual {f.get('residual')}", flush=True)
                fits3_path.write_text(json.dumps(fits3, indent=1) + "\n")
        elif stage == "validate3":
            store.run([(fitted3(n), m) for n in a.nodes if fitted3(n)
                       for m in ["steady", *turn_metrics, *buckle_metrics, "burst"]], workers)
        elif stage == "rigid":
            cases = [{}] + [rft_case(n) for n in a.nodes]
            cases += [rft_case(n, f["scale_perp"], f["scale_par"]) for n, f in
                      ((int(k), v) for k, v in fits.items()) if "scale_perp" in f and n in a.nodes]
            cases += [fitted3(n) for n in a.nodes if fitted3(n)]
            store.run([(c, "rigid") for c in cases], workers)
            ref = store.get({}, "rigid")["result"]
            print("\nRigid-body resistance of the rest shape, diagonal RFT / LSBT (F_x axial, F_y, F_z lateral, "
                  "T_x axial, T_y, T_z lateral) and the thrust coupling F_x/Omega_x:")
            for c in cases[1:]:
                r = store.get(c, "rigid")["result"]
                ratios = " ".join(f"{x / y:.3f}" for x, y in zip(r["diag"], ref["diag"]))
                print(f"  {case_label(c):<48} {ratios}  coupling {r['thrust_coupling'] / ref['thrust_coupling']:.3f}")
            print("  faithful (LSBT + Higdon) diagonal:", " ".join(f"{x:.4g}" for x in ref["diag"]),
                  f" coupling {ref['thrust_coupling']:.4g}")
            # the helix alone (b = 0): RFT's resistance is linear in the factors, R = s_perp A + s_par B; which
            # factors would match two of LSBT's rigid-body resistances at once
            import numpy as np

            lsbt0, a0, b0 = {"head_radius": 0.0}, rft_case(122, 1.0, 1e-6, head_radius=0.0), \
                rft_case(122, 1e-6, 1.0, head_radius=0.0)
            store.run([(c, "rigid") for c in (lsbt0, a0, b0)], 1)
            L, A, B = (np.array(store.get(c, "rigid")["result"]["matrix"]) for c in (lsbt0, a0, b0))
            print("\nThe helix alone (b = 0, N = 122): (s_perp, s_par) that match LSBT's rigid-body resistance on "
                  "two entries at once (R_rft = s_perp A + s_par B; A, B at factors (1, 1e-6), (1e-6, 1)):")
            for name, (i, j), (k, m) in (("axial translation F_x/U_x + axial rotation T_x/Omega_x", (0, 0), (3, 3)),
                                         ("lateral translation F_y/U_y + axial rotation", (1, 1), (3, 3)),
                                         ("thrust coupling F_x/Omega_x + axial rotation", (0, 3), (3, 3))):
                sol = np.linalg.solve([[A[i, j], B[i, j]], [A[k, m], B[k, m]]], [L[i, j], L[k, m]])
                print(f"  {name:<58} s_perp {sol[0]:+.3f}, s_par {sol[1]:+.3f}")
        elif stage == "head":
            # what the Higdon head's flow coupling does in the nonlocal model: faithful with a plain Stokes head
            ov = {"head_model": "stokes"}
            store.run([(ov, m) for m in ["steady", *turn_metrics]], workers)
        elif stage == "speed":
            tasks = [({}, "env")]
            for n in a.nodes:
                f = fits.get(str(n))
                if f and "scale_perp" in f:
                    tasks.append((rft_case(n, f["scale_perp"], f["scale_par"]), "env"))
                if fitted3(n):
                    tasks.append((fitted3(n), "env"))
            store.run(tasks, workers)
    if a.table or a.stage:
        print(table(store, a.all))
    return 0


if __name__ == "__main__":
    sys.exit(main())
