"""Write the seeded random evaluation paths (planar and 3-D, turns 30-150 deg) as path files.

    python scripts/make_eval_paths.py [--out agents/eval_paths] [--count 10] [--seed0 1000]

Seeds seed0 .. seed0 + count - 1 give the planar paths and the same seeds the 3-D ones (other
draws). Training (issue #7) must use seeds below 1000 so that these stay held out.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from flagellum_env.paths import RandomPathConfig, WaypointPath, random_path, save_path

#: Three waypoints, segments long enough for a turn's displacement (~5-8 cm at the fast preset).
EVAL_PATHS = RandomPathConfig(n_waypoints=3, segment_length_m=(0.12, 0.2), min_turn_deg=30.0, max_turn_deg=150.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("agents/eval_paths"))
    ap.add_argument("--count", type=int, default=10, help="paths of each kind (planar, 3-D)")
    ap.add_argument("--seed0", type=int, default=1000)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for planar in (True, False):
        kind = "planar" if planar else "3d"
        cfg = RandomPathConfig(**{**EVAL_PATHS.__dict__, "planar": planar})
        for k in range(args.count):
            seed = args.seed0 + k
            p = random_path(np.random.default_rng(seed), cfg)
            named = WaypointPath(name=f"{kind}_{seed}", waypoints=p.waypoints)
            save_path(named, args.out / f"{kind}_{seed}.json")
    print(f"wrote {2 * args.count} paths to {args.out}")


if __name__ == "__main__":
    main()
