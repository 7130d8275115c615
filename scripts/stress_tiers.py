"""Stability at the extremes for every tier (issue 48, item 6): each physics preset and each turn-level surrogate at
the corners of docs/stability.md, classified as ok, error (a clear one-line error) or crash (a bug).

    python scripts/stress_tiers.py [--workers N] [--out out/stress_tiers] [--json docs/stability_tiers.json]

Physics tiers (``physics.presets``): reference, paper, faithful, fast, each from rest with its own grid and numerics:
0 rpm; 300 rpm; a long burst at 150 rpm; the largest step (the output interval ``dt`` raised to 1 s, the largest
allowed, so that the error-controlled steps can grow up to it; 20 ms, 20x its step, for ``paper``'s fixed implicit
Euler) in a 150 rpm burst; three randomised swimmers at +-20 % (E, mu, b, helix pitch and radius, drawn by
``flagellum_env.config.draw_randomization``) in a 150 rpm burst. ``reference`` flies shorter runs (its burst is
~20x slower than real time). ok: the state is finite and every edge within 0.5-2x its rest length; error: a
``SimulationError`` (its message names step, time and quantity) or a ``ValueError`` naming the value.

Surrogate tiers (``FlagellumTurn-surrogate-v0``, ``FlagellumBurst-surrogate-v0``): 200 episodes each with the actions
at their bounds (all -1, all +1) and random, nominal and randomised at the calibrated range's edge (+-15 %); ok: every
observation and reward finite; how many episodes left the calibrated range (``info["out_of_range"]``) is counted.
Randomised at +-20 %, outside the calibrated range: the expected outcome is a one-line ``ValueError`` at ``make``.

Results are appended to ``--out``/results.jsonl as they finish (resumable) and summarised in ``--json`` and in the
"Every tier" section of docs/stability.md (between its markers).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

PHYSICS_TIERS = ("faithful", "fast", "paper", "reference")
SURROGATE_IDS = ("FlagellumTurn-surrogate-v0", "FlagellumBurst-surrogate-v0")
#: simulated seconds of each physics corner (reference: shorter, it is the slow yardstick)
DURATIONS = {"zero": 10.0, "omega300": 2.0, "long_burst": 20.0, "largest_step": 6.0, "randomised": 6.0}
REFERENCE_DURATIONS = {"zero": 4.0, "omega300": 1.0, "long_burst": 6.0, "largest_step": 4.0, "randomised": 3.0}
RANDOM_SEEDS = (0, 1, 2)
SURROGATE_EPISODES = 200
MARKERS = ("<!-- every-tier -->", "<!-- /every-tier -->")


def physics_corners() -> list[dict]:
    """Every (tier, corner) run of the physics presets."""
    runs = []
    for tier in PHYSICS_TIERS:
        d = REFERENCE_DURATIONS if tier == "reference" else DURATIONS
        big_dt = {"dt": 0.02} if tier == "paper" else {"dt": 1.0}
        runs += [
            {"tier": tier, "corner": "0 rpm", "rpm": 0.0, "duration": d["zero"], "numerics": {}},
            {"tier": tier, "corner": "300 rpm", "rpm": 300.0, "duration": d["omega300"], "numerics": {}},
            {"tier": tier, "corner": "long burst, 150 rpm", "rpm": 150.0, "duration": d["long_burst"], "numerics": {}},
            {"tier": tier, "corner": f"largest step (dt {big_dt['dt']:g} s), 150 rpm", "rpm": 150.0,
             "duration": d["largest_step"], "numerics": big_dt},
        ]
        runs += [{"tier": tier, "corner": f"randomised +-20 % (seed {s}), 150 rpm", "rpm": 150.0,
                  "duration": d["randomised"], "numerics": {}, "randomise_seed": s} for s in RANDOM_SEEDS]
    return runs


def surrogate_corners() -> list[dict]:
    """Every (env id, corner) run of the surrogates."""
    runs = []
    for env_id in SURROGATE_IDS:
        for policy in ("low", "high", "random"):
            for frac in (0.0, 0.15):
                label = "nominal" if frac == 0.0 else "randomised +-15 %"
                runs.append({"tier": env_id, "corner": f"{label}, actions {policy}", "policy": policy,
                             "fraction": frac})
        runs.append({"tier": env_id, "corner": "randomised +-20 % (outside the calibrated range)",
                     "policy": "random", "fraction": 0.2})
    return runs


def key(run: dict) -> str:
    return f"{run['tier']} | {run['corner']}"


def run_physics(run: dict) -> dict:
    import numpy as np

    from flagellum_env.config import RandomizationConfig, draw_randomization
    from physics.errors import SimulationError
    from physics.model.geometry import nodes_of
    from physics.params import RPM_TO_RAD_S
    from physics.presets import configure
    from physics.simulator import Simulator

    rec = dict(run)
    c0, t0 = time.process_time(), time.perf_counter()
    try:
        p, n = configure(run["tier"], run["numerics"])
        if "randomise_seed" in run:
            r = RandomizationConfig(youngs_modulus=0.2, viscosity=0.2, head_radius=0.2, geometry=0.2)
            p, _ = draw_randomization(p, r, np.random.default_rng(run["randomise_seed"]))
            rec["swimmer"] = {"youngs_modulus": p.youngs_modulus, "viscosity": p.viscosity,
                              "head_radius": p.head_radius, "pitch": p.pitch, "helix_radius": p.helix_radius}
        sim = Simulator(p, n)
        sim.set_motor_speed(run["rpm"] * RPM_TO_RAD_S)
        steps = int(round(run["duration"] / n.dt))
        for _ in range(steps):
            sim.step()
        lengths = np.linalg.norm(np.diff(nodes_of(sim.q), axis=0), axis=1) / sim.rest.l_bar
        finite = bool(np.all(np.isfinite(sim.q)))
        bounded = finite and 0.5 <= lengths.min() and lengths.max() <= 2.0
        rec.update(outcome="ok" if bounded else "crash", sim_time_s=sim.time, halvings=sim.stats.halvings,
                   edge_ratio=[float(lengths.min()), float(lengths.max())], end_to_end=sim.end_to_end_ratio(),
                   min_gaps_mm=[1e3 * g for g in sim.min_gaps()],
                   message=None if bounded else "state not finite/bounded without an error")
    except SimulationError as exc:
        rec.update(outcome="error", message=str(exc))
    except ValueError as exc:
        rec.update(outcome="error", message=f"ValueError: {exc}")
    except Exception as exc:  # a bug: report it
        rec.update(outcome="crash", message=f"{type(exc).__name__}: {exc}")
    rec["cpu_s"], rec["wall_s"] = time.process_time() - c0, time.perf_counter() - t0
    return rec


def run_surrogate(run: dict) -> dict:
    import gymnasium as gym
    import numpy as np

    import agents  # noqa: F401  (registers the ids)

    rec = dict(run)
    c0, t0 = time.process_time(), time.perf_counter()
    f = run["fraction"]
    env_kwargs = {} if f == 0.0 else {"randomize": {"youngs_modulus": f, "viscosity": f, "head_radius": f,
                                                    "geometry": f, "obs_noise_std": 0.0}}
    try:
        env = gym.make(run["tier"], env_kwargs=env_kwargs)
    except ValueError as exc:
        rec.update(outcome="error", message=f"ValueError at make: {exc}")
        rec["cpu_s"], rec["wall_s"] = time.process_time() - c0, time.perf_counter() - t0
        return rec
    env.action_space.seed(0)
    low, high = env.action_space.low, env.action_space.high
    decisions, out_of_range, reached, finite = 0, 0, 0, True
    try:
        for ep in range(SURROGATE_EPISODES):
            obs, _ = env.reset(seed=ep)
            finite &= bool(np.all(np.isfinite(obs)))
            done, left = False, False
            while not done:
                a = low if run["policy"] == "low" else high if run["policy"] == "high" else env.action_space.sample()
                obs, reward, term, trunc, info = env.step(a)
                decisions += 1
                finite &= bool(np.all(np.isfinite(obs))) and bool(np.isfinite(reward))
                left |= bool(info.get("out_of_range", False))
                done = term or trunc
            out_of_range += left
            reached += bool(info.get("is_success", False))
        rec.update(outcome="ok" if finite else "crash", episodes=SURROGATE_EPISODES, decisions=decisions,
                   out_of_range_episodes=out_of_range, successes=reached,
                   message=None if finite else "an observation or reward was not finite")
    except ValueError as exc:
        rec.update(outcome="error", message=f"ValueError: {exc}")
    except Exception as exc:  # a bug: report it
        rec.update(outcome="crash", message=f"{type(exc).__name__}: {exc}")
    env.close()
    rec["cpu_s"], rec["wall_s"] = time.process_time() - c0, time.perf_counter() - t0
    return rec


def run_one(run: dict) -> dict:
    return run_surrogate(run) if run["tier"] in SURROGATE_IDS else run_physics(run)


def _init() -> None:
    os.environ["OPENBLAS_NUM_THREADS"] = "1"


def table(recs: list[dict]) -> list[str]:
    """The markdown tables of the runs (physics, then surrogates)."""
    lines = ["| tier | corner | outcome | sim time (s) | halvings | L'/L | edges (min / max of rest) | CPU s | message |",
             "|---|---|---|---:|---:|---:|---|---:|---|"]
    for r in recs:
        if r["tier"] in SURROGATE_IDS:
            continue
        edges = " / ".join(f"{e:.2f}" for e in r["edge_ratio"]) if r.get("edge_ratio") else "—"
        lines.append(f"| {r['tier']} | {r['corner']} | {r['outcome']} | {r.get('sim_time_s', 0):.3g} | "
                     f"{r.get('halvings', '—')} | {r.get('end_to_end', float('nan')):.3f} | {edges} | "
                     f"{r['cpu_s']:.1f} | {(r.get('message') or '').replace('|', '/')[:160]} |")
    lines += ["", "| env id | corner | outcome | episodes | decisions | left the calibrated range | reached | CPU s | "
                  "message |", "|---|---|---|---:|---:|---:|---:|---:|---|"]
    for r in recs:
        if r["tier"] not in SURROGATE_IDS:
            continue
        lines.append(f"| {r['tier']} | {r['corner']} | {r['outcome']} | {r.get('episodes', '—')} | "
                     f"{r.get('decisions', '—')} | {r.get('out_of_range_episodes', '—')} | {r.get('successes', '—')} | "
                     f"{r['cpu_s']:.1f} | {(r.get('message') or '').replace('|', '/')[:160]} |")
    return lines


def write_section(md: Path, recs: list[dict], command: str) -> None:
    """Replace the text between ``MARKERS`` in ``md`` by the tables (appended with the markers if absent)."""
    body = [MARKERS[0], "## Every tier", "",
            f"Produced by `{command.strip()}`. Each physics preset from rest with its own grid and numerics: 0 rpm, "
            "300 rpm, a long burst at 150 rpm, its largest step (the output interval `dt` at its largest allowed, "
            "1 s, so that the error-controlled steps may grow up to it; `paper`: 20 ms, 20x its fixed step) and "
            "three swimmers at +-20 % (E, mu, b, helix pitch and radius) in a 150 rpm burst; `reference` flies "
            "shorter runs. ok: finite, every edge within 0.5-2x its rest length. Each surrogate: 200 episodes with "
            "the actions at their bounds and random, nominal and at the calibrated range's edge (+-15 %; ok: every "
            "observation and reward finite), and at +-20 %, outside its calibrated range, where `make` refuses.",
            "", *table(recs), MARKERS[1]]
    text = md.read_text() if md.exists() else ""
    if MARKERS[0] in text and MARKERS[1] in text:
        head, rest = text.split(MARKERS[0], 1)
        tail = rest.split(MARKERS[1], 1)[1]
        text = head + "\n".join(body) + tail
    else:
        text = text.rstrip("\n") + "\n\n" + "\n".join(body) + "\n"
    md.write_text(text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    ap.add_argument("--out", default="out/stress_tiers", help="results folder (resumable)")
    ap.add_argument("--json", default="docs/stability_tiers.json", help="summary JSON")
    ap.add_argument("--md", default="docs/stability.md", help="page whose 'Every tier' section is rewritten")
    ap.add_argument("--only", choices=("physics", "surrogate", "all"), default="all")
    args = ap.parse_args(argv)
    if args.workers < 1:
        ap.error(f"--workers={args.workers} must be >= 1")
    runs = ((physics_corners() if args.only != "surrogate" else [])
            + (surrogate_corners() if args.only != "physics" else []))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    res = out / "results.jsonl"
    done: dict[str, dict] = {}
    if res.exists():
        for line in res.read_text().splitlines():
            try:
                r = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut by a kill: run again
            done[key(r)] = r
    todo = [r for r in runs if key(r) not in done]
    from tqdm import tqdm

    # the slow runs first, so that the pool's last minutes are not one long run
    todo.sort(key=lambda r: (r["tier"] != "reference", r["tier"] in SURROGATE_IDS))
    with ProcessPoolExecutor(max_workers=args.workers, initializer=_init) as pool, open(res, "a") as fh:
        futs = [pool.submit(run_one, r) for r in todo]
        for f in tqdm(as_completed(futs), total=len(futs), desc="stress tiers", unit="run"):
            r = f.result()
            fh.write(json.dumps(r) + "\n")
            fh.flush()
            done[key(r)] = r
            tqdm.write(f"{key(r):70s} {r['outcome']:6s} {(r.get('message') or '')[:80]}")
    recs = [done[key(r)] for r in runs if key(r) in done]
    Path(args.json).write_text(json.dumps({"runs": recs, "load_average": list(os.getloadavg())}, indent=1) + "\n")
    write_section(Path(args.md), recs, "python scripts/stress_tiers.py " + " ".join(argv or []))
    crashes = [key(r) for r in recs if r["outcome"] == "crash"]
    print(f"{len(recs)} runs: {sum(r['outcome'] == 'ok' for r in recs)} ok, "
          f"{sum(r['outcome'] == 'error' for r in recs)} error, {len(crashes)} crash")
    return 1 if crashes else 0


if __name__ == "__main__":
    raise SystemExit(main())
