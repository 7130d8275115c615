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

#: What docs/fidelity.md says before the notes: what its rows are (the committed records of --results) and the figure.
DOCS_INTRO = (
    "The ladder: configurations of the model from `paper` (the paper's grid and scheme) down to local RFT on 30 "
    "nodes, each measured on the same metrics, errors against `paper`. The committed records "
    "(results/bench/fidelity_full.results.jsonl) were measured with the head torque-free "
    "(`head_rotation=torque_free`; the default reading is `fixed`). In the tables the row `fast` is N = 45, "
    "implicit Euler at h = 10 ms, refresh 0.1 r0, Newton 1e-5: the configuration of the `coarse` preset (retired "
    "since: [presets.md](presets.md)), named `fast` when it was measured, not today's `fast`. The "
    "error-controlled presets (`faithful`, `fast`, `reference`) are not in them: their speed by phase and their "
    "errors against `reference` are in [bench_quick.md](bench_quick.md) (`flagellum bench --quick`).\n\n"
    "![Fidelity ladder: error against paper vs real-time factor](figures/fidelity_pareto.png)\n\n"
    "*Error against `paper` against the real-time factor, the points labelled with the presets' names (the row "
    "`fast` as the retired `coarse`). Redrawn from docs/fidelity.json by `python scripts/bench_fidelity.py --figure-only` (no "
    "simulation).*")


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
                 missing=missing_tasks(done, LADDER, FULL_METRICS), notes=DOCS_INTRO + "\n\n" + REPORT_NOTES)
    print(Path("docs/fidelity.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
