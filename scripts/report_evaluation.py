"""Paired per-path tables (markdown) and head-path figures for ``flagellum evaluate`` results folders.

    python scripts/report_evaluation.py FOLDER [FOLDER ...] [--out report.md] [--figures DIR]
        [--controller C ...]

For each folder (written by ``flagellum evaluate --out FOLDER``): the aggregate table, the paired
per-path table (each path's episodes of every controller side by side, with the env seed of its
swimmer) and a figure of the head paths (``--figures``, default: beside ``--out``, else each folder).
Prints the markdown, and writes it to ``--out`` if given. The library calls are in
``agents.evaluation_report``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from agents.evaluation_report import folder_report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path, help="folders written by flagellum evaluate")
    ap.add_argument("--out", type=Path, help="write the markdown here (and print it)")
    ap.add_argument("--figures", type=Path, help="folder for the head-path figures (default: beside --out, or "
                                                   "each results folder)")
    ap.add_argument("--controller", action="append", help="only these controllers, in this order (repeatable)")
    ap.add_argument("--names", nargs="+", help="a name per folder for headings and figure files (default: the "
                                               "folder's name)")
    args = ap.parse_args(argv)
    if args.names and len(args.names) != len(args.folders):
        ap.error(f"--names: {len(args.names)} names for {len(args.folders)} folders")
    lines: list[str] = []
    for k, folder in enumerate(args.folders):
        fig_dir = args.figures or (args.out.parent / "figures" if args.out else folder)
        name = args.names[k] if args.names else None
        try:
            lines += folder_report(folder, fig_dir, name, args.controller,
                                   link_from=args.out.parent if args.out else None)
        except ValueError as exc:
            print(f"report_evaluation: {exc}", file=sys.stderr)
            return 2
    text = "\n".join(lines) + "\n"
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
