"""Full fidelity ladder: every configuration x every metric, written to docs/.

    python scripts/bench_fidelity.py [--metrics quick|full|M1,M2] [--config NAME ...] [--workers N] [--report-only]
    python scripts/bench_fidelity.py --figure-only   # only the figure, from the committed docs/fidelity.json

Resumable: finished tasks are kept in results/bench/fidelity_full.results.jsonl (committed); re-running skips them.
Outputs docs/fidelity.json, docs/fidelity.md and docs/figures/fidelity_pareto.png.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from flagellum_bench.fidelity import (FULL_METRICS, LADDER, QUICK_METRICS, REPORT_NOTES, load_done, missing_tasks,
                                rows_from, run_fidelity)
from flagellum_bench.report import pareto_plot, write_report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--metrics", default="full",
                    help=f"quick, full, or a comma-separated list of {', '.join(FULL_METRICS)}")
    ap.add_argument("--config", action="append", default=None, metavar="NAME",
                    help="a ladder configuration to run (repeatable; default: all; 'paper' is always included)")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--results", default="results/bench/fidelity_full.results.jsonl")
    ap.add_argument("--report-only", action="store_true", help="run nothing; rebuild the report from --results")
    ap.add_argument("--figure-only", action="store_true",
                    help="run nothing; redraw docs/figures/fidelity_pareto.png from docs/fidelity.json")
    args = ap.parse_args(argv)
    if args.figure_only:
        pareto_plot(json.loads(Path("docs/fidelity.json").read_text()), Path("docs/figures/fidelity_pareto.png"))
        print("wrote docs/figures/fidelity_pareto.png")
        return 0
    metrics = {"full": FULL_METRICS, "quick": QUICK_METRICS}.get(args.metrics) or tuple(args.metrics.split(","))
    bad = [m for m in metrics if m not in FULL_METRICS]
    if bad:
        ap.error(f"--metrics: unknown {bad}; allowed: quick, full or a list of {', '.join(FULL_METRICS)}")
    configs = LADDER
    if args.config:
        names = set(args.config) | {"paper"}
        unknown = names - {c.name for c in LADDER}
        if unknown:
            ap.error(f"--config: unknown {sorted(unknown)}; the ladder has {[c.name for c in LADDER]}")
        configs = tuple(c for c in LADDER if c.name in names)
    t0 = time.perf_counter()
    if not args.report_only:
        run_fidelity(Path(args.results), configs, metrics, workers=args.workers)
    done = load_done(Path(args.results), LADDER)  # records of a redefined configuration are stale
    rows = rows_from(done)
    write_report(rows, Path("docs/fidelity.json"), Path("docs/fidelity.md"), Path("docs/figures/fidelity_pareto.png"),
                 "python scripts/bench_fidelity.py " + ("--report-only" if args.report_only else f"--metrics {args.metrics}"),
                 time.perf_counter() - t0,
                 missing=missing_tasks(done, LADDER, FULL_METRICS), notes=REPORT_NOTES)
    print(Path("docs/fidelity.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
