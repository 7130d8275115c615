"""Which randomised swimmers the controllers fail: successes binned by the swimmer's burst time factor F.

    python scripts/success_by_burst_factor.py --eval DIR [DIR ...] [--edges -1 0 0.1 0.15 1] [--json FILE]

Each DIR is a ``flagellum evaluate`` folder flown with ``--randomize``. Every episode's swimmer is drawn again from
its seed (results.json's ``seeds``, the folder's ``env_overrides``) in the surrogate twin, which draws the same
swimmer from the same seed, and ln F is read from it (``SurrogateSwimmer.time_factor``: F > 1 buckles earlier in a
burst than the map's swimmer, and turns as the map's longer burst). Prints, per bin of ln F, the swimmers and each
controller's successes; ``--json`` writes the table and every episode's ln F.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import agents  # noqa: F401  (registers the ids)
from agents.evaluation_report import load_results


def burst_factor_logs(randomize: dict, seeds: list[int]) -> dict[int, float]:
    """ln F of the swimmer each seed draws under ``randomize`` (``FlagellumSteer-v0``'s randomisation dict)."""
    twin = gym.make("FlagellumBurst-surrogate-v0", env_kwargs={"randomize": randomize}).unwrapped
    out = {}
    for s in seeds:
        twin.reset(seed=s)
        out[s] = math.log(twin.swimmer.time_factor)
    return out


def binned(episodes: list[dict], edges: list[float]) -> list[dict]:
    """Per bin [edges[i], edges[i+1]) of ln F: the swimmers (distinct seeds) and each controller's successes.
    ``episodes``: dicts with ``seed``, ``ln_F``, ``controller`` and ``success``."""
    controllers = sorted({e["controller"] for e in episodes})
    rows = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = [e for e in episodes if lo <= e["ln_F"] < hi]
        swimmers = {e["seed"] for e in sel}   # one seed, one swimmer (folders of the same paths share them)
        rows.append({"ln_F": [lo, hi], "swimmers": len(swimmers),
                     "successes": {c: sum(bool(e["success"]) for e in sel if e["controller"] == c)
                                   for c in controllers}})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--eval", nargs="+", type=Path, required=True, metavar="DIR")
    ap.add_argument("--edges", nargs="+", type=float, default=[-1.0, 0.0, 0.1, 0.15, 1.0],
                    help="bin edges of ln F, increasing (default: -1 0 0.1 0.15 1)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    if len(args.edges) < 2 or any(b <= a for a, b in zip(args.edges[:-1], args.edges[1:])):
        print(f"success_by_burst_factor: --edges {args.edges} must be at least two increasing numbers",
              file=sys.stderr)
        return 2
    episodes = []
    try:
        for folder in args.eval:
            res = load_results(folder)
            randomize = (res.get("env_overrides") or {}).get("randomize")
            if not randomize:
                raise ValueError(f"{str(folder)!r} was flown without --randomize: its swimmers are all the map's")
            logs = burst_factor_logs(randomize, sorted(set(res["seeds"].values())))
            episodes += [{"folder": str(folder), "path": r["path"], "seed": res["seeds"][r["path"]],
                          "controller": r["controller"], "success": r["success"],
                          "ln_F": logs[res["seeds"][r["path"]]]} for r in res["per_path"]]
    except ValueError as exc:
        print(f"success_by_burst_factor: {exc}", file=sys.stderr)
        return 2
    rows = binned(episodes, args.edges)
    controllers = sorted(rows[0]["successes"])
    print("| ln F | swimmers | " + " | ".join(f"`{c}`" for c in controllers) + " |")
    print("|---|---|" + "---|" * len(controllers))
    for r in rows:
        lo, hi = r["ln_F"]
        print(f"| [{lo:g}, {hi:g}) | {r['swimmers']} | " + " | ".join(str(r["successes"][c]) for c in controllers)
              + " |")
    lnf = np.array(list({e["seed"]: e["ln_F"] for e in episodes}.values()))
    print(f"{lnf.size} swimmers, ln F from {lnf.min():.3f} to {lnf.max():.3f}")
    if args.json is not None:
        args.json.write_text(json.dumps({"bins": rows, "episodes": episodes}, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
