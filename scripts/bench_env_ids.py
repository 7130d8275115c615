"""Env steps per CPU second of every registered id (random policy and a fixed action), for docs/env.md.

    python scripts/bench_env_ids.py [--steps 20] [--episodes 1] [--id ID ...] [--json docs/bench_env_ids.json]

Prints a Markdown table and writes the rows with the date, load averages and machine to --json. The library is
``flagellum_bench.env_ids`` (its docstring says what is timed). Run it with OPENBLAS_NUM_THREADS=1 on an
otherwise quiet core; the load averages in the JSON say how quiet it was.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tqdm import tqdm

from agents.registration import TURN_ENV_IDS
from flagellum_bench.env_ids import POLICIES, bench_steer, bench_turn, format_table, machine
from flagellum_env.registration import ENV_IDS

ALL_IDS = [*ENV_IDS, *TURN_ENV_IDS]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20, help="timed steps per FlagellumSteer id and policy (default 20)")
    ap.add_argument("--episodes", type=int, default=1,
                    help="timed one-turn episodes per FlagellumTurn id and policy (default 1)")
    ap.add_argument("--id", action="append", choices=ALL_IDS, default=None, help="an id (repeatable; default all)")
    ap.add_argument("--json", type=Path, default=Path("docs/bench_env_ids.json"), help="output JSON file")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.episodes < 1:
        ap.error("--steps and --episodes must be positive")
    ids = args.id or ALL_IDS
    start = machine()
    rows = []
    with tqdm(total=len(ids) * len(POLICIES), unit="run") as bar:
        for env_id in ids:
            for policy in POLICIES:
                bar.set_description(f"{env_id} {policy}")
                if env_id.startswith("FlagellumTurn"):
                    rows.append(bench_turn(env_id, policy, args.episodes))
                else:
                    rows.append(bench_steer(env_id, policy, args.steps))
                bar.update(1)
    table = format_table(rows)
    print(table)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"command": "python scripts/bench_env_ids.py", "start": start, "end": machine(),
                                     "rows": rows}, indent=1) + "\n")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
