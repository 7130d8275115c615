"""Benchmark FlagellumSteer-v0: env steps per second (median over many steps) under fixed policies.

Prints a table and writes JSON. Default: the ``fast`` preset at the env's default control_dt,
300 steps holding the low speed, 300 random steps, 40 steps holding the high speed (buckled).

    python scripts/bench_env.py [--preset fast] [--steps low=300,random=300,high=40] [--json docs/bench_env.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from tqdm import tqdm  # noqa: E402

from flagellum_env.bench import POLICIES, bench_env, format_table  # noqa: E402
from flagellum_env.config import SteerConfig  # noqa: E402


def _steps(text: str) -> dict[str, int]:
    out = {}
    for item in text.split(","):
        name, _, n = item.partition("=")
        if name not in POLICIES or not n.isdigit() or int(n) < 1:
            raise argparse.ArgumentTypeError(f"{item!r}: expected POLICY=N with POLICY one of {list(POLICIES)}")
        out[name] = int(n)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="fast", help="physics preset (default: fast)")
    ap.add_argument("--control-dt", type=float, default=SteerConfig.control_dt,
                    help=f"simulated seconds per env step (default: {SteerConfig.control_dt})")
    ap.add_argument("--steps", type=_steps, default=_steps("low=300,random=300,high=40"),
                    help="env steps per policy, POLICY=N,... (default: low=300,random=300,high=40)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", type=Path, default=Path("docs/bench_env.json"), help="output JSON file")
    args = ap.parse_args(argv)
    kwargs = {"preset": args.preset, "control_dt": args.control_dt, "path": "random"}
    with tqdm(total=sum(args.steps.values()), unit="step") as bar:
        t0 = time.perf_counter()
        rows = bench_env(args.steps, seed=args.seed, env_kwargs=kwargs, on_step=lambda: bar.update(1))
        wall = time.perf_counter() - t0
    print(format_table(rows))
    result = {"env": "FlagellumSteer-v0", "env_kwargs": kwargs, "rows": rows, "wall_s": wall,
              "machine": {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                          "platform": platform.platform()}}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
