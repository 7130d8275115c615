"""Where the cross-track error of evaluated episodes is made (experiments.cross_track_budget), per controller.

    python scripts/cross_track_budget.py FOLDER [FOLDER ...] [--controller C ...] [--json OUT.json]

FOLDER: written by ``flagellum evaluate --out FOLDER`` (its results.json and the traces under points/). Prints a
markdown table: the episode-mean cross-track error and what the cruise before the turns, the turns (burst and
relaxation), the cruise between a turn and a corrective one, and the cruise after the last turn of each segment
add to it; and the estimate with every segment's first turn exact (no corrective turns, then straight at the
waypoint), which bounds what correcting each planned turn can gain.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from experiments.cross_track_budget import budget_table, folder_budgets


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path, help="folders written by flagellum evaluate")
    ap.add_argument("--controller", action="append", help="only these controllers (repeatable)")
    ap.add_argument("--json", type=Path, help="also write the numbers here")
    args = ap.parse_args(argv)
    try:
        budgets = {str(f): folder_budgets(f, args.controller) for f in args.folders}
    except ValueError as exc:
        print(f"cross_track_budget: {exc}", file=sys.stderr)
        return 2
    print("\n".join(budget_table(budgets)))
    if args.json:
        args.json.write_text(json.dumps(budgets, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
