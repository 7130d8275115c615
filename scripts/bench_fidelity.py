"""Full fidelity ladder: every configuration x every metric, written to docs/.

    python scripts/bench_fidelity.py [--metrics quick|full] [--workers N] [--report-only]

Resumable: finished tasks are kept in data/bench/fidelity_full.results.jsonl (committed); re-running skips them.
Outputs docs/fidelity.json, docs/fidelity.md and docs/figures/fidelity_pareto.png.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from flagellum.fidelity import (FULL_METRICS, LADDER, QUICK_METRICS, REPORT_NOTES, load_done, missing_tasks,
                                rows_from, run_fidelity)
from flagellum.fidelity_report import write_report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--metrics", choices=("quick", "full"), default="full")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--results", default="data/bench/fidelity_full.results.jsonl")
    ap.add_argument("--report-only", action="store_true", help="run nothing; rebuild the report from --results")
    args = ap.parse_args(argv)
    metrics = FULL_METRICS if args.metrics == "full" else QUICK_METRICS
    t0 = time.perf_counter()
    done = (load_done(Path(args.results)) if args.report_only
            else run_fidelity(Path(args.results), LADDER, metrics, workers=args.workers))
    rows = rows_from(done)
    write_report(rows, Path("docs/fidelity.json"), Path("docs/fidelity.md"), Path("docs/figures/fidelity_pareto.png"),
                 f"python scripts/bench_fidelity.py --metrics {args.metrics}", time.perf_counter() - t0,
                 missing=missing_tasks(done, LADDER, metrics), notes=REPORT_NOTES)
    print(Path("docs/fidelity.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
