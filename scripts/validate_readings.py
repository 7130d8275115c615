"""Validation against the paper (rows R1-R9, R11 of paper_targets.md, Fig. 4(c)-(f), Fig. 5(d)) under every
reading of the head, at the default preset, with contact on.

    python scripts/validate_readings.py [--workers 2] [--scheduler tcp://HOST:PORT] [--out results/validation]
                                        [--preset faithful] [--tight-step-tol 1e-5] [--check-preset paper]
                                        [--report-only]

The runs (``flagellum_bench.paper_validation``): 19 motor speeds (10-100 rpm) per head size and reading, each
100 s (t_bar = 1.02) from rest; omega_b bisected on L'/L(100 s) < 0.98 to +-1 rpm; Fig. 5(d)'s protocol
(steady 10 rpm, a burst of t_c at 60 rpm from four rotation phases, back to 10 rpm) for 12 burst lengths
0.05 <= t_bar_c <= 0.6; then omega_b's bracket ends, R8's point and R9's largest turn again at
``--tight-step-tol``, and (``--check-preset``) the bracket ends and R8's point at another preset. Each finished run is one line of
``<out>/results.jsonl``: an interrupted run (Ctrl-C, SIGTERM, kill) resumes where it stopped; a folder made
with other settings is refused. The report (docs/validation.json, docs/validation.md,
docs/figures/fig4_*.png, fig5d.png) is rebuilt from the records.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    from physics.presets import preset_names

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: all cores)")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler address tcp://HOST:PORT instead of local workers")
    ap.add_argument("--out", default="results/validation", help="results folder (resumed when it holds this run)")
    ap.add_argument("--docs", default="docs", help="where validation.md/.json and figures/ are written")
    ap.add_argument("--preset", default="faithful", choices=preset_names(), help="numerics of every run (default faithful)")
    ap.add_argument("--tight-step-tol", type=float, default=1e-5,
                    help="step_tol of the convergence runs (default 1e-5; faithful's is 1e-4)")
    ap.add_argument("--check-preset", default=None, choices=preset_names(),
                    help="also run omega_b's bracket ends and R8's point at this preset (e.g. paper: implicit Euler at 1 ms)")
    ap.add_argument("--report-only", action="store_true", help="rebuild the report from the records; run nothing")
    args = ap.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        ap.error(f"--workers {args.workers} is not allowed; allowed: an integer >= 1")
    if not args.tight_step_tol > 0:
        ap.error(f"--tight-step-tol {args.tight_step_tol} is not allowed; allowed: a number > 0")

    from batch.pool import TasksInterrupted
    from batch.store import SweepError, read_results
    from flagellum_bench.paper_validation import ValidationPlan, run_validation
    from validation_report import write_report

    plan = ValidationPlan(preset=args.preset, tight_step_tol=args.tight_step_tol, check_preset=args.check_preset)
    out = Path(args.out)
    if args.report_only:
        records = read_results(out / "results.jsonl")[0]
    else:
        signal.signal(signal.SIGTERM, signal.default_int_handler)  # SIGTERM as Ctrl-C: finished runs are kept
        try:
            records = run_validation(out, plan, workers=args.workers, scheduler=args.scheduler)
        except TasksInterrupted as exc:
            print(f"{exc}; run the same command again to resume", file=sys.stderr)
            return 130
        except (SweepError, ValueError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    write_report(records, Path(args.docs), plan)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
