"""Buckling onset against the discretisation (node count, time step, refresh rule), written to docs/.

    python scripts/bench_node_convergence.py [--workers N] [--report-only]

Resumable: finished runs are kept in results/bench/node_convergence.results.jsonl (committed). The reference is
`paper`'s turn_tc40 from results/bench/fidelity_full.results.jsonl (scripts/bench_fidelity.py).
Outputs docs/node_convergence.md, docs/node_convergence.json and docs/figures/node_convergence.png.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from flagellum_bench.fidelity import LADDER, load_done, run_fidelity
from flagellum_bench.node_convergence import METRIC, markdown, plot, sweep_configs, sweep_rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--results", default="results/bench/node_convergence.results.jsonl")
    ap.add_argument("--reference", default="results/bench/fidelity_full.results.jsonl")
    ap.add_argument("--report-only", action="store_true", help="run nothing; rebuild the report from --results")
    ap.add_argument("--no-progress", action="store_true")
    args = ap.parse_args(argv)
    configs = sweep_configs()
    if not args.report_only:
        run_fidelity(Path(args.results), configs, (METRIC,), workers=args.workers, progress=not args.no_progress)
    done = load_done(Path(args.results), configs)
    paper = load_done(Path(args.reference), LADDER).get(("paper", METRIC))
    reference = paper["result"] if paper and paper["result"] else None
    rows = sweep_rows(done, reference)
    # the records kept by load_done were measured with the configurations' current setup, head reading included
    head_rotation = configs[0].build()[0].head_rotation
    header = ("# Buckling onset against the discretisation\n\n"
              "Produced by `python scripts/bench_node_convergence.py` (one core per run, two at a time). "
              "Each run: steady 10 rpm swimming, a 40 s burst at 90 rpm, back to 10 rpm until the heading "
              "settles (`agents.turn_measurement.measure_turn`); θ is the turn. All runs start from the numerics of "
              "the retired `coarse` preset (implicit Euler, Newton tolerance 1e-5); N, h and the resistance-refresh tolerance vary. "
              f"Head reading: `head_rotation={head_rotation}`. θ error = |θ - θ_paper| / θ_paper.")
    Path("docs").mkdir(exist_ok=True)
    Path("docs/node_convergence.json").write_text(json.dumps({"reference": reference, "rows": rows}, indent=2) + "\n")
    Path("docs/node_convergence.md").write_text(markdown(rows, reference, header))
    plot(rows, reference, Path("docs/figures/node_convergence.png"))
    print(Path("docs/node_convergence.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
