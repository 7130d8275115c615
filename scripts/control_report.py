"""docs/control.md and docs/control.json: the controllers on held-out paths and swimmers, and the shipped agent.

    python scripts/control_report.py --eval DIR [DIR ...] [--controllers SPEC [SPEC ...]] [--change BEFORE AFTER ...]

Each DIR is a ``flagellum evaluate`` folder (its results.json) of the same paths at one level of model error; several
folders of one level (the same paths and swimmer seeds, other controllers) are merged. Made by, for example::

    python scripts/make_eval_paths.py --count 6 --seed0 11000 --out out/heldout/paths
    flagellum evaluate --paths out/heldout/paths --seed0 11000 --workers 2 [--randomize 0.05 | 0.1] \\
        --controller rule --controller adaptive --controller adaptive@line=2 --controller ppo --out out/heldout/LEVEL

``--controllers`` tabulates those controllers of the folders, in that order (default: all of them). The shipped
agent's facts come from its meta.json (package data); the prose is scripts/templates/control.md.

``--change BEFORE AFTER`` (repeatable, one pair per set of paths) adds the table of how the default reading's change
moved each controller: BEFORE a folder made by the tree before the default became ``head_rotation=fixed`` (0fe63c0:
``torque_free``, its maps and agent), AFTER one of the same paths, swimmer seeds and level made now::

    git worktree add --detach ../before 0fe63c0
    PYTHONPATH=../before python -m flagellum evaluate --paths P --seed0 S --randomize 0.1 --controller ... --out B
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from agents.assets import package_file
from agents.evaluation_report import load_results
from agents.turn_map import PLANNER_OMEGA_H_RPM
from physics.presets import DEFAULT_PRESET, configure

TEMPLATE = Path(__file__).with_name("templates") / "control.md"
#: What each reading of the head means, in the words of docs/validation.md.
HEAD_READINGS = {"fixed": "the default: the head held against rotation, ω the flagellum's rate in the lab",
                 "literal": "ω the flagellum's lab rate, the head spinning by eqn (13)",
                 "torque_free": "ω relative to a counter-rotating head", "paper": "the printed eqns (10)-(11)"}
AGENT = ("pretrained", "ppo_residual_adaptive")


def level_of(results: dict[str, Any]) -> float:
    """The model error of an evaluation: the largest randomised fraction of E, μ, b (0 for the nominal swimmer)."""
    randomize = results.get("env_overrides", {}).get("randomize") or {}
    return max((float(randomize.get(k, 0.0)) for k in ("youngs_modulus", "viscosity", "head_radius")), default=0.0)


def level_label(level: float) -> str:
    return "nominal" if level == 0 else f"±{100 * level:g} %"


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %"


def summarise(folders: list[Path], only: list[str] | None = None) -> dict[str, Any]:
    """Per level: the controllers' aggregates and the paths each did not finish. Folders of the same level (the same
    paths, preset and swimmer seeds) are merged, each giving its controllers; ``only``: those controllers, in that
    order. ValueError if a level's folders differ in paths, preset or seeds or give a controller twice, if the
    levels do not hold the same paths and controllers, or if a controller of ``only`` is in none of them."""
    merged: dict[str, dict[str, Any]] = {}
    for folder in folders:
        res = load_results(folder)
        label = level_label(level_of(res))
        key = {"paths": sorted({r["path"] for r in res["per_path"]}), "preset": res.get("preset"),
               "seeds": res.get("seeds", {})}
        lv = merged.setdefault(label, {"folders": [], "level": level_of(res), **key, "missing": [],
                                       "aggregate": {}, "per_path": []})
        if any(lv[k] != v for k, v in key.items()):
            raise ValueError(f"{str(folder)!r} holds other paths, preset or seeds than {lv['folders'][0]!r} "
                             f"(both {label})")
        twice = sorted(set(res["aggregate"]) & set(lv["aggregate"]))
        if twice:
            raise ValueError(f"two folders hold the level {label!r} of controller {twice[0]!r}: "
                             f"{lv['folders'][0]!r} and {str(folder)!r}")
        lv["folders"].append(str(folder))
        lv["aggregate"].update(res["aggregate"])
        lv["per_path"] += res["per_path"]
        lv["missing"] += res.get("missing", [])
    first = next(iter(merged.values()), None)
    for label, lv in merged.items():
        if (lv["paths"], sorted(lv["aggregate"])) != (first["paths"], sorted(first["aggregate"])):
            raise ValueError(f"{lv['folders'][0]!r} holds other paths or controllers than {first['folders'][0]!r}")
    controllers = list(first["aggregate"]) if first else []
    if only is not None:
        unknown = [c for c in only if c not in controllers]
        if unknown:
            raise ValueError(f"--controllers {unknown[0]!r} is not in the folders; allowed: {controllers}")
        controllers = list(only)
    levels = {label: {"folder": ", ".join(lv["folders"]), "level": lv["level"], "preset": lv["preset"],
                      "seeds": lv["seeds"], "missing": lv["missing"],
                      "aggregate": {c: lv["aggregate"][c] for c in controllers},
                      "not_finished": {c: sorted(r["path"] for r in lv["per_path"]
                                                 if r["controller"] == c and not r.get("success"))
                                       for c in controllers}}
              for label, lv in merged.items()}
    return {"paths": first["paths"] if first else [], "controllers": controllers,
            "levels": dict(sorted(levels.items(), key=lambda kv: kv[1]["level"]))}


def reading_change(pairs: list[tuple[Path, Path]], only: list[str] | None = None) -> dict[str, Any]:
    """Per pair (before, after) of evaluate folders: the successes and mean cross-track before and after of each
    controller in both (of ``only``, in that order, if given), and the same pooled over the pairs for the controllers
    in every pair. ValueError if a pair differs in paths, swimmer seeds or level."""
    sets, pooled = [], {}
    for before, after in pairs:
        res = {"before": load_results(before), "after": load_results(after)}
        keys = {k: (sorted({r["path"] for r in v["per_path"]}), v.get("seeds", {}), level_of(v))
                for k, v in res.items()}
        if keys["before"] != keys["after"]:
            raise ValueError(f"--change {str(before)!r} {str(after)!r}: the folders hold other paths, swimmer seeds or "
                             "levels")
        common = [c for c in (only or res["after"]["aggregate"]) if c in res["before"]["aggregate"]
                  and c in res["after"]["aggregate"]]
        paths, seeds, level = keys["after"]
        row: dict[str, Any] = {"paths": len(paths), "level": level, "seed0": min(seeds.values()) if seeds else None,
                               "controllers": {}}
        for c in common:
            counts = {}
            for k, v in res.items():
                eps = [r for r in v["per_path"] if r["controller"] == c]
                counts[k] = {"success": sum(bool(r.get("success")) for r in eps), "episodes": len(eps),
                             "cross_track_sum_m": sum(float(r["mean_cross_track_m"]) for r in eps)}
            row["controllers"][c] = counts
            for k, cnt in counts.items():
                acc = pooled.setdefault(c, {}).setdefault(k, {"success": 0, "episodes": 0, "cross_track_sum_m": 0.0})
                for f in acc:
                    acc[f] += cnt[f]
        sets.append(row)
    in_all = [c for c in pooled if all(c in s["controllers"] for s in sets)]
    return {"sets": sets, "pooled": {c: pooled[c] for c in in_all}}


def reading_change_table(change: dict[str, Any]) -> str:
    """The markdown of ``reading_change``: successes before -> after per set, and pooled with the mean cross-track."""
    if not change["sets"]:
        return "*(Not measured in this report: `scripts/control_report.py --change BEFORE AFTER`.)*"
    sets = change["sets"]
    head = ("| controller | " + " | ".join(f"{level_label(s['level'])}, seeds {s['seed0']} ({s['paths']} paths)"
                                         for s in sets) + " | all: success, cross-track |")
    rows = [head, "|---" * (len(sets) + 2) + "|"]
    for c, pool in change["pooled"].items():
        cells = [f"{s['controllers'][c]['before']['success']} → {s['controllers'][c]['after']['success']}"
                 for s in sets]
        b, a = pool["before"], pool["after"]
        xte = [100 * x["cross_track_sum_m"] / max(x["episodes"], 1) for x in (b, a)]
        cells.append(f"{b['success']}/{b['episodes']} → {a['success']}/{a['episodes']}, {xte[0]:.2f} → {xte[1]:.2f} cm")
        rows.append(f"| `{c}` | " + " | ".join(cells) + " |")
    worse = [c for c, pool in change["pooled"].items() if pool["after"]["success"] < pool["before"]["success"]]
    verdict = (f"Over all sets, fewer successes after the change: {', '.join(f'`{c}`' for c in worse)}."
               if worse else "Over all sets, no controller has fewer successes after the change than before.")
    return "\n".join(rows) + "\n\n" + verdict


def heldout_table(summary: dict[str, Any]) -> str:
    levels = summary["levels"]
    head = "| controller | " + " | ".join(f"{lv}: success, cross-track, Δz/ΔL" for lv in levels) + " |"
    rows = [head, "|---" * (len(levels) + 1) + "|"]
    for c in summary["controllers"]:
        cells = []
        for lv in levels.values():
            a = lv["aggregate"][c]
            xte = a.get("mean_cross_track_m")
            dz = a.get("max_out_of_plane_ratio")
            cells.append(f"{_pct(a['success_rate'])}, {'-' if xte is None else f'{100 * xte:.2f} cm'}, "
                         f"{'-' if dz is None else f'{100 * dz:.1f} %'}")
        rows.append(f"| `{c}` | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def heldout_intro(summary: dict[str, Any]) -> str:
    seeds = sorted(s for lv in summary["levels"].values() for s in lv["seeds"].values())
    presets = sorted({str(lv["preset"]) for lv in summary["levels"].values()})
    n = len(summary["paths"])
    planar = sum(p.startswith("planar") for p in summary["paths"])
    return (f"{n} paths ({planar} planar, {n - planar} 3-D; three waypoints, segments of 12-20 cm, turns of 30-150°, "
            f"`scripts/make_eval_paths.py`) flown at `{'`, `'.join(presets)}` by the nominal swimmer and by swimmers "
            f"off the model (E, μ and b drawn within ±F, the helix's pitch and radius within ±0.4 F; the controllers "
            f"keep the nominal turn map), one episode per path and controller; the k-th path's swimmer is drawn with "
            f"env seed {min(seeds) if seeds else '-'} + k. No controller was trained or tuned on these paths or "
            f"swimmers.")


def _paths_or_count(paths: list[str], n: int) -> str:
    return ", ".join(paths) if len(paths) <= 4 else f"{len(paths)} of {n} paths"


def heldout_notes(summary: dict[str, Any]) -> str:
    lines = []
    for label, lv in summary["levels"].items():
        agg = lv["aggregate"]
        best = max(agg, key=lambda c: (agg[c]["success_rate"], -(agg[c].get("mean_cross_track_m") or 1e9)))
        n = len(summary["paths"])
        lost = "; ".join(f"`{c}` {_paths_or_count(p, n)}" for c, p in lv["not_finished"].items() if p) or "none"
        errors = sum(int(a.get("failed_runs", 0)) for a in agg.values())
        lines.append(f"- {label}: best `{best}` ({_pct(agg[best]['success_rate'])}, "
                     f"{100 * agg[best]['mean_cross_track_m']:.2f} cm); not finished: {lost}; episodes ending in an "
                     f"error: {errors}.")
    return "\n".join(lines)


def agent_facts() -> tuple[str, str, dict[str, Any]]:
    meta = json.loads(package_file(*AGENT, "meta.json").read_text(encoding="utf-8"))
    default_head = configure(DEFAULT_PRESET)[0].head_rotation
    mk = meta["make_kwargs"]
    rnd = mk["env_kwargs"].get("randomize", {})
    rp = mk["random_path"]
    agent = (f"`agents/pretrained/{AGENT[1]}/` (model, VecNormalize statistics, config, meta, episode log and "
             f"training curve): PPO (stable-baselines3 {meta['versions']['stable_baselines3']}, PyTorch "
             f"{meta['versions']['torch']}) in `{meta['env_id']}` at `{meta['preset']}` on the `{meta['planner']}` "
             f"planner, {meta['decisions']} decisions (planned turns) in {meta['wall_time_s'] / 60:.0f} min of wall "
             f"time with {meta['n_envs']} env workers on this 2-core machine"
             f"{', stopped by its wall-time budget' if meta.get('stopped_by_wall_time_budget') else ''}, on the "
             f"swimmer with `head_rotation={meta['head_rotation']}` ({HEAD_READINGS[meta['head_rotation']]})"
             + ("." if meta["head_rotation"] == default_head else
                f"; the table above flies it on the default swimmer (`head_rotation={default_head}`)."))
    training = (f"It was trained on randomised swimmers (E ±{100 * rnd.get('youngs_modulus', 0):g} %, μ "
                f"±{100 * rnd.get('viscosity', 0):g} %, b ±{100 * rnd.get('head_radius', 0):g} %, the helix "
                f"±{100 * rnd.get('geometry', 0):g} %, drawn per episode) on paths of {rp['n_waypoints'][0]}-"
                f"{rp['n_waypoints'][1]} waypoints, segments of {100 * rp['segment_length_m'][0]:g}-"
                f"{100 * rp['segment_length_m'][1]:g} cm and turns of {rp['min_turn_deg']:g}-{rp['max_turn_deg']:g}°, "
                f"with a price of {mk['action_cost']:g} |a|² per decision.")
    return agent, training, meta


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--eval", nargs="+", type=Path, required=True, metavar="DIR",
                    help="flagellum evaluate folders of the same paths, one per level of model error")
    ap.add_argument("--controllers", nargs="+", metavar="SPEC",
                    help="the controllers to tabulate, in this order (default: every one in the folders)")
    ap.add_argument("--change", nargs=2, action="append", type=Path, default=[], metavar=("BEFORE", "AFTER"),
                    help="evaluate folders of the same paths, swimmer seeds and level made before the default reading "
                         "changed (0fe63c0) and now; repeatable, one pair per set of paths")
    ap.add_argument("--docs", type=Path, default=Path("docs"), help="where control.md and control.json go")
    args = ap.parse_args(argv)
    try:
        summary = summarise(args.eval, args.controllers)
        change = reading_change([tuple(p) for p in args.change], args.controllers)
    except ValueError as exc:
        print(f"control_report: {exc}", file=sys.stderr)
        return 2
    agent, training, meta = agent_facts()
    values = {"omega_h": PLANNER_OMEGA_H_RPM, "heldout_intro": heldout_intro(summary),
              "heldout_table": heldout_table(summary), "heldout_notes": heldout_notes(summary), "agent": agent,
              "agent_training": training, "agent_config": meta["config"],
              "reading_change": reading_change_table(change)}
    args.docs.mkdir(parents=True, exist_ok=True)
    (args.docs / "control.json").write_text(json.dumps(
        {"heldout": {**summary, "levels": {k: {kk: vv for kk, vv in v.items() if kk != "folder"}
                                           for k, v in summary["levels"].items()}},
         "reading_change": change}, indent=1) + "\n")
    (args.docs / "control.md").write_text(TEMPLATE.read_text(encoding="utf-8").format(**values))
    print(f"wrote {args.docs / 'control.md'} and control.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
