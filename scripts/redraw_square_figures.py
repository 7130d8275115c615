"""Redraw path.png of the square runs shown in the README from their saved traces (no simulation).

    python scripts/redraw_square_figures.py

For each folder of ``RUNS``: the traces ``trace_<controller>.npz`` (or ``trace.npz``) that ``flagellum follow`` wrote
under results/, the title from the docs folder's summary.json (as ``flagellum follow`` titles it), and
``agents.follow_plots.path_figure`` (start marker, direction arrows, Δz against ΔL). The other folders of
docs/square/ have no saved traces: their figures stay as drawn.
"""

from __future__ import annotations

import json
from pathlib import Path

from agents.follow_plots import path_figure, save
from agents.path_following import EpisodeTrace

#: docs folder -> results folder holding its traces
RUNS = {Path("docs/square/faithful"): Path("results/square_faithful"),
        Path("docs/square/faithful_adaptive"): Path("results/square_faithful_adaptive")}


def main() -> int:
    for docs, results in RUNS.items():
        summary = json.loads((docs / "summary.json").read_text(encoding="utf-8"))
        specs = list(summary["controllers"])
        traces = {}
        for spec in specs:
            file = results / f"trace_{spec}.npz"
            traces[spec] = EpisodeTrace.load(file if file.is_file() else results / "trace.npz")
        title = f"{summary['path']['name']} path, {summary['preset']} preset"
        print(f"wrote {save(path_figure(traces, title), docs / 'path.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
