"""docs/robust_steering.md and its figures: steering a swimmer that differs from the turn map.

    python scripts/robust_steering_report.py

Inputs (each made by a committed command; missing ones are reported as not measured):
- results/eval_line/<level>/results.json for level nominal, rand05, rand10, results/eval_line/square/summary.json
  and results/eval_line/dev/<level>/results.json: the planners with and without the line weight
  (``PlannerConfig.line_weight``) and the shipped agent, held-out paths and swimmers from seeds 10300 (section first);
- results/eval_model/<level>/results.json for level nominal, rand05, rand10, rand10_helix10 and
  results/eval_model/square/summary.json: the adaptive planner that steers a swimmer cruising like the map's by the
  paper's rule (a1befc7) and the rule planner, held-out paths and swimmers from seeds 7600 (section first);
- results/eval_cruise/<level>/results.json for level nominal, rand05, rand10, rand10_helix10 and
  results/eval_cruise/square/summary.json: the adaptive planner whose cruise can confirm the map (d348e58) and the
  rule planner, held-out paths and swimmers from seeds 7400;
- results/eval_restart/<level>/results.json for level nominal, rand05, rand10, rand10_helix10 and
  results/eval_restart/square/summary.json: the planners with the hover restart (24a4a99), held-out paths and
  swimmers from seeds 6900;
- results/eval_hover/<level>/results.json for level nominal, rand05, rand10, rand10_helix10 and
  results/eval_hover/square/summary.json: the adaptive planner with the hover and small-burst fixes (c4d707e) and
  the rule planner, held-out paths and swimmers from seeds 6800;
- results/eval_softswim2/<level>/results.json for level nominal, rand05, rand10, rand10_helix10: the same
  planner on a second held-out set, seeds 6600 (no square run);
- results/eval_softswim/<level>/results.json for level nominal, rand05, rand10, rand10_helix10 and
  results/eval_softswim/square/summary.json: the adaptive planner swimming on within the soft corridor (e4e4c15)
  and the rule planner, held-out paths and swimmers from seeds 6500;
- results/eval_clock/<level>/results.json for level nominal, rand05, rand10, rand10_helix10 and
  results/eval_clock/square/summary.json: the adaptive planner on the finer turn map with bursts timed by the
  ratio clock (issue #23, 2026-12-03) against the rule planner on held-out paths and swimmers (``CLOCK_COMMANDS``)
- results/eval_robust/<level>/results.json for level nominal, rand05, rand10, rand10_helix10 and
  results/eval_robust/square/summary.json: the adaptive planner with spread-scored turns (issue #23, 2026-12-03)
  against the rule planner on held-out paths and swimmers (``ROBUST_COMMANDS`` below)
- results/eval_horizon/<level>/results.json for level nominal, rand05, rand10 and
  results/eval_horizon/square_horizon/summary.json: the receding-horizon planner (issue #23) against
  the rule and adaptive planners on held-out paths and swimmers (``HORIZON_COMMANDS`` below)
- results/online_turn_map/sensitivity.jsonl and sensitivity_fit.json: randomised swimmers, the
  shift of their turns and what predicts it
      python scripts/turn_shift_sensitivity.py --count 16 --seed0 1 --fit
      python scripts/turn_shift_sensitivity.py --count 16 --seed0 101 --fit
- results/eval_adaptive/<level>/results.json for level nominal, rand05, rand10: the rule planner
  and the adaptive planner on the held-out paths results/eval_adaptive/paths (seeds 7100-7102,
  ``python scripts/make_eval_paths.py --out results/eval_adaptive/paths --count 3 --seed0 7100``)
      flagellum evaluate --paths results/eval_adaptive/paths --controller rule --controller adaptive \\
          --out results/eval_adaptive/<level> [--randomize 0.05 | 0.1]
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from agents.follow_plots import save
from agents_report import ROWS, _fmt  # the same metric rows as docs/agents.md

DOCS = Path("docs")
SENS = Path("results/online_turn_map")
EVAL = Path("results/eval_adaptive")
LEVELS = (("nominal", "nominal swimmer"), ("rand05", "E, μ, b within ±5 %, helix ±2 %"),
          ("rand10", "E, μ, b within ±10 %, helix ±4 %"))
CONTROLLERS = (("rule", "rule planner"), ("adaptive", "adaptive planner"))


def sensitivity_section(lines: list[str]) -> None:
    rows_file, fit_file = SENS / "sensitivity.jsonl", SENS / "sensitivity_fit.json"
    lines += ["## How much a swimmer that differs from the map moves its turns", ""]
    if not rows_file.is_file() or not fit_file.is_file():
        lines += ["Not measured.", ""]
        return
    rows = [json.loads(x) for x in rows_file.read_text().splitlines() if x.strip()]
    fit = json.loads(fit_file.read_text())
    nominal = next(r for r in rows if r["seed"] == 0)
    others = [r for r in rows if r["seed"] != 0]
    theta = np.array([r["theta_deg"] for r in others])
    lines += [f"{len(others)} swimmers of the `faithful` preset with E, μ, b drawn within ±10 % and the helix pitch "
              f"and radius within ±4 %, each from its steady start at 10 rpm, one burst of {nominal['t_c']:g} s at "
              f"150 rpm (`measure_turn`, phase 0). The nominal swimmer turns {nominal['theta_deg']:.1f}°; these "
              f"turned {theta.min():.1f}-{theta.max():.1f}° (median {np.median(theta):.1f}°). Read as a shift of "
              "the buckling time (the map's burst length for the angle turned, minus the burst flown), the "
              f"shift's rms over them is {fit['shift_rms_s']:.2f} s; a 150 rpm burst turns ~20-70°/s, so a "
              "burst planned from the nominal map turns a different swimmer by anything from a few degrees "
              "to past the branch's peak, where the flagellum tumbles on and the direction flips.", "",
              "What a controller can see before its first turn (`cruise_observables`: the steady strain L'/L - 1 "
              "and the flagellum's lab rotation rate at 10 rpm, over one wobble period) predicts the shift by "
              f"shift ≈ {fit['strain_shift_s']:.2f} s × Δstrain/strain + {fit['rate_shift_s']:.2f} s × Δrate/rate "
              f"(least squares, {fit['n']} swimmers): residual rms {fit['residual_rms_s']:.2f} s, "
              f"{fit['leave_one_out_rms_s']:.2f} s leave-one-out. A linear fit on the true five factors does no "
              "better (docstring of `agents/online_turn_map.py`), so what is left is what one shift per swimmer "
              "cannot say.", "",
              f"![shift and its prediction](figures/{_shift_figure(rows, fit)})", ""]


def _shift_figure(rows: list[dict], fit: dict) -> str:
    import matplotlib.pyplot as plt

    ref = fit["reference"]
    use = [r for r in rows if r["seed"] != 0 and r["shift_s"] is not None]
    pred = [fit["strain_shift_s"] * (r["cruise"]["strain"] / ref["strain"] - 1)
            + fit["rate_shift_s"] * (r["cruise"]["rotation_rate"] / ref["rotation_rate"] - 1) for r in use]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].scatter(pred, [r["shift_s"] for r in use], s=14)
    lim = [-2.5, 2.0]
    ax[0].plot(lim, lim, "k:", lw=1)
    ax[0].set(xlabel="shift predicted from the cruise (s)", ylabel="shift read from the turn (s)",
              title="buckling-time shift of randomised swimmers")
    from agents.assets import default_turn_map
    from agents.turn_map import TurnMap

    tm = TurnMap.load(default_turn_map(use[0]["preset"]))
    dev = [abs((r["psi_deg"] - tm.psi_for(r["t_c"] + r["shift_s"]) + 180.0) % 360.0 - 180.0) for r in use]
    ax[1].scatter([r["theta_deg"] for r in use], dev, s=14)
    ax[1].set(xlabel="angle turned (deg)", ylabel="|ψ - map's ψ at the same map time| (deg)",
              title="direction error grows with the turn")
    fig.tight_layout()
    return save(fig, DOCS / "figures" / "turn_shift.png").name


def evaluation_section(lines: list[str]) -> dict[str, dict[str, Any]]:
    lines += ["## Held-out paths, nominal and randomised swimmers", "",
              "Paths: `results/eval_adaptive/paths` (3 planar and 3 3-D, seeds 7100-7102, three waypoints, segments "
              "12-20 cm, turns 30-150°, reach radius 1.5 cm; no tuning here used them: the adaptive planner was "
              "developed on seeds 7000-7001). Preset `faithful`; with randomisation the k-th path's swimmer is "
              "drawn with env seed k, the same for both controllers; both keep the nominal turn map.", ""]
    found: dict[str, dict[str, Any]] = {}
    for level, label in LEVELS:
        f = EVAL / level / "results.json"
        lines += [f"### {label} (`{level}`)", ""]
        if not f.is_file():
            lines += ["Not measured.", ""]
            continue
        res = json.loads(f.read_text())
        agg = res["aggregate"]
        have = [(c, lab) for c, lab in CONTROLLERS if c in agg]
        found[level] = res
        lines += ["| metric | " + " | ".join(lab for _, lab in have) + " |", "|---" * (len(have) + 1) + "|"]
        for name, key, scale, digits in ROWS:
            lines.append(f"| {name} | " + " | ".join(_fmt(agg[c].get(key), scale, digits) for c, _ in have) + " |")
        lines += ["", *paired(res), ""]
        fig = trajectory_figure(level, res)
        if fig:
            lines += [f"![head paths, {label}](figures/{fig})", ""]
    return found


def trajectory_figure(level: str, res: dict[str, Any]) -> str | None:
    """Both controllers' head paths (x-y, start frame) on every path of one level."""
    import matplotlib.pyplot as plt

    from agents.path_following import EpisodeTrace

    rows = [r for r in res["per_path"] if r.get("trace")]
    names = sorted({r["path"] for r in rows})
    if not names:
        return None
    fig, axes = plt.subplots(2, (len(names) + 1) // 2, figsize=(3.2 * ((len(names) + 1) // 2), 6.4), squeeze=False)
    for ax, name in zip(axes.flat, names):
        for c, label in CONTROLLERS:
            r = next((r for r in rows if r["path"] == name and r["controller"] == c), None)
            if r is None or not (EVAL / level / r["trace"]).is_file():
                continue
            tr = EpisodeTrace.load(EVAL / level / r["trace"])
            ax.plot(tr.head[:, 0] * 100, tr.head[:, 1] * 100, lw=1,
                    label=f"{label} ({'reached' if r['success'] else 'failed'})")
            w = np.vstack([np.zeros(3), tr.waypoints]) * 100
        ax.plot(w[:, 0], w[:, 1], "ko--", ms=3, lw=0.8)
        ax.set_title(name, fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.legend(fontsize=6)
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    fig.supxlabel("x (cm)")
    fig.supylabel("y (cm)")
    fig.tight_layout()
    return save(fig, DOCS / "figures" / f"robust_steering_{level}.png").name


def paired(res: dict[str, Any]) -> list[str]:
    by = {(r["path"], r["controller"]): r for r in res["per_path"]}
    names = sorted({r["path"] for r in res["per_path"]})
    out = ["| path | rule: reached, mean / max cross-track (cm), buckles | adaptive: reached, mean / max (cm), "
           "buckles |", "|---|---|---|"]
    for n in names:
        cells = []
        for c, _ in CONTROLLERS:
            r = by.get((n, c))
            cells.append("-" if r is None else (
                f"{'yes' if r['success'] else 'no'} ({r['waypoints_reached']}/3), {_fmt(r['mean_cross_track_m'], 100, 2)}"
                f" / {_fmt(r['max_cross_track_m'], 100, 1)}, {r['buckling_events']}"
                + (f", {r['error']}" if r.get("error") else "")))
        out.append(f"| {n} | " + " | ".join(cells) + " |")
    return out


def targets_section(found: dict[str, dict[str, Any]], lines: list[str]) -> None:
    lines += ["## Against the targets of issue #17", ""]
    for level, need in (("rand05", 0.9), ("rand10", 0.75)):
        res = found.get(level)
        if res is None:
            lines.append(f"- `{level}`: not measured.")
            continue
        agg = res["aggregate"]
        best = max((c for c, _ in CONTROLLERS if c in agg), key=lambda c: agg[c]["success_rate"] or 0.0)
        rate = agg[best]["success_rate"] or 0.0
        errors = sum(1 for r in res["per_path"] if r.get("error"))
        lines.append(f"- `{level}`: best success {100 * rate:.0f} % ({best}), target ≥ {100 * need:.0f} % — "
                     f"{'reached' if rate >= need else 'not reached'}; episodes ending in an error: {errors}.")
    nominal = found.get("nominal")
    if nominal is not None and all(c in nominal["aggregate"] for c, _ in CONTROLLERS):
        r, a = nominal["aggregate"]["rule"], nominal["aggregate"]["adaptive"]
        lines.append(f"- nominal swimmer: success {100 * r['success_rate']:.0f} % (rule) and "
                     f"{100 * a['success_rate']:.0f} % (adaptive); the adaptive planner's mean cross-track is "
                     f"{a['mean_cross_track_m'] / r['mean_cross_track_m']:.2f} x the rule planner's "
                     f"({100 * a['mean_cross_track_m']:.2f} vs {100 * r['mean_cross_track_m']:.2f} cm): the price of "
                     "capping a burst at 80° (large turns in several bursts) on a swimmer the map already fits. The "
                     "issue's nominal target is for a PPO agent (success ≥ rule's, cross-track ≤ 0.8 x rule's): no "
                     "agent was trained at the default preset (below).")
    lines.append("")


METHOD = """## The adaptive planner as first built (80° cap; the tables below are of that version)

The rule planner (docs/planner.md) with three changes, each from a measurement above (the third was
replaced on 2026-12-03 by the spread-scored choice at the top of this page):

1. **A per-swimmer shift of the turn map, learnt online** (`OnlineTurnMap`): a parameter error moves
   *when* the flagellum buckles, so the swimmer's turn after a burst of t seconds is taken as the
   map's turn after t + s. s has a Gaussian prior (rms 1.1 s, the spread above) and is updated by
   precision weighting from (a) the cruise before the first turn (strain and rotation rate, the fit
   above, its spread widened by the readings' own noise, so sensor noise makes it count less),
   (b) every burst: the L'/L the flagellum reached and the time it took, (c) every settled turn: the
   angle turned. A direction offset (the new heading's azimuth against the map's ψ) is the
   weighted circular mean of the turns seen.
2. **Bursts flown by L'/L, not by a clock**: the map records L'/L at the end of every calibration
   burst, and L'/L falls steadily once the flagellum buckles (1.0 → 0.4 between 4.9 and 8 s of a
   150 rpm burst at `faithful`). A burst planned for the map's turn at map time m ends at the
   control step nearest to L'/L = the map's ratio at m (cut at 2.5 σ of the shift past its expected
   length if the ratio never comes). So the buckling the swimmer actually does sets the burst's
   end. On a dev swimmer that buckles 2.7 s late (E, μ, b off by up to 10 %), planned turns of 79°,
   79° and 34° came out 76°, 78° and 38° (the time-flown planner: planned 59°, got 24°).
3. **No single burst beyond 80° until turns confirm the map, and a target behind counts its angle**: turns of 94° and more came
   out 35-180° off the map's direction on randomised swimmers (figure above, right), those up to
   80° mostly within 35°. Larger turns are made in several bursts, each observed; the miss measure
   gives a target behind its distance plus 0.2 m × the cosine of how far behind it is, so a partial
   turn towards it counts as progress.

With the nominal swimmer it reads no shift before the first turn (tested: the reference cruise is
the env's own steady start) and flies its turns like the rule planner, except for the 80° cap.
Since 2026-12-03 (after the evaluations below, which are of the capped planner) the cap is lifted after
two turns in a row that came out within 10° + 15 % of the planned angle and 15° of the predicted
direction (a turn that does not restores it), and a turn not predicted to reach the target waits while
the same choice made up to 8 cm further on is (swim on, then turn); on two development sets this
finished one path more at most randomisation levels (`OnlineMapConfig.lift_after_turns`).
"""


LIMITS = """## What still fails, and what was not done

- **Circling a waypoint** (3d_7101 at ±5 % and ±10 %, planar_7101 at ±10 %: 20-23 bursts, the time limit): the
  swimmer passes its waypoint just outside the reach radius (1.5 cm) and then circles it 5-6 cm away. A turn of up to
  80° displaces the head by about as much as the target is away (the map's offsets: 4-7 cm), so from inside that
  circle every single turn ends with the target beside or behind again. The planner is myopic (it picks the best
  *next* turn); it needs to plan two moves (swim on to gain room, then turn), e.g. by comparing a turn now with turns
  from points further along the heading, within the env's 10 cm corridor. Tried offline on the recorded circling
  (dev path, not evaluated): waiting helps while the target is close, but the corridor soon forces the turn; not
  shipped.
- **First turns of paths that start with a turn behind the swimmer**: capped turns move the head forwards by several
  cm each; with the 10 cm corridor this is where the rule planner's failures start (the head paths above).
- **A PPO agent trained with domain randomisation on the default preset** was not trained: the raw env runs at
  ~0.2 steps/s at `faithful` (docs/agents.md, the raw-PPO section), a turn decision of `FlagellumTurn-v0` costs
  30-60 s, so a 2-hour budget on this machine gives a few hundred decisions, fewer than the residual agent that did not
  beat the planner at `paper` (docs/agents.md). The compiled step of issue #15 is the prerequisite.
- The fit of the cruise reading used 31 swimmers with the helix within ±4 %; with the helix within ±10 % (the
  issue's reading of "geometry") the direction of even small turns moves by up to ~100° (pitch, measured on one dev
  swimmer) and the cruise reading missed the shift by ~1.3 s; that level was not evaluated on the held-out paths.
"""


ROBUST = Path("results/eval_robust")
ROBUST_DESIGN = """`agents/adaptive_planner.py` with `agents/online_turn_map.py` (controller `adaptive`, the default since
commit f55d6a2). The online correction (buckling-time shift, ratio-turn bias, direction offset; bursts flown
by L'/L) is as below; what changed is how a turn is chosen:

1. **Each turn is scored by its expected miss over what the swimmer may do**, not by the map's single
   prediction under an 80° cap (`OnlineTurnMap.outcomes`, `expected_misses`). Every candidate (map time m on
   the rising branch every control step x flagellum phase every 5°) is predicted at three Gauss-Hermite points
   of its timing error (the correction's spread: the ratio-turn bias's when flown by L'/L, prior 0.3 s), read
   over the *whole* map, so a point past the branch's peak predicts the tumbling turn there; each point's
   direction error is normal (20°) for turns up to 80°, and for larger turns, with a chance rising linearly to 1
   at 100°, anything (eight evenly spread directions): across 31 randomised swimmers turns of 94° and more came
   out 35-180° off the map's direction, and on development swimmers turns of 114-136° came out 128-170° off.
   Once two turns in a row confirmed the corrected map the direction spread is 10° for every turn. So a large
   turn is taken where any direction will do (a target straight behind: one burst near the peak instead of two
   or three capped ones, each carrying the head several cm forward), and a turn whose direction matters stays
   below the size whose direction is unpredictable: the cap is a consequence of the spread.
2. **The corridor is part of the score**: the planner tracks the current segment (the start, then each reached
   waypoint, to the target) and a predicted head position (after the turn's forward travel, and at its end)
   more than 6 cm from it costs its excess, more than 8.5 cm 0.5 m (the episode ends at 10 cm).
3. **Swim on, then turn**, from the same score: if the best turn made 2-10 cm further on (staying within 9 cm of
   the target and 6 cm of the segment) is expected to miss by more than 1 cm less (counting 0.1 m per m swum),
   the swimmer cruises there first (without re-planning on the way).
4. **A late buckler's burst is not cut at its planned length**: once L'/L falls below 0.98 the burst may run
   until the map's time from buckling to the target ratio, x 1.5, + 0.5 s after it.

A search costs ~40 ms of CPU (NumPy), ~0.1-0.2 s when swimming on is considered.

Tried and dropped on the way (development swimmers only): ending each burst by a *prediction of the turn's
outcome from the observed flagellum shape* (a ridge fit of the final heading, in the head's frame, on the eight
observed shape nodes at the moment the motor would slow, over 13 training swimmers at +-5 to +-12 %:
leave-one-swimmer-out heading error median 5.5° / 7.6° / 15° / 23° for turns of < 20° / 20-60° / 60-120° /
> 120°; offline, stopping when the predicted heading came within 10° of a wanted one left 9° (median) of error
for 20-60° turns but 53° for turns beyond 100°): on the development paths at +-10 % it made 3 of 8 where the
capped planner made 4 (the failures were the planner's choice of turns, not the burst's end). The head's axis
at the burst's end does not predict the new heading (median 51° off): most of the turn happens while the
flagellum relaxes."""
ROBUST_HELD_OUT = """Development used paths from `python scripts/make_eval_paths.py --count 4 --seed0 5200`, `--seed0 5300`
and `--count 3 --seed0 9800` (not committed) with swimmers from env seeds 5200-5207, 5300-5307 and
9800-9805 (faithful preset, E, μ, b +-5 % / +-10 %, helix +-2 % / +-4 %), plus 13 swimmers (the nominal one, seeds 9901-9907 and
9910-9914) for the shape-prediction experiment. The numbers below are on paths drawn with seeds 6100-6102 (planar and 3-D,
three waypoints, segments 12-20 cm, turns 30-150°, reach radius 1.5 cm) and swimmers from env seeds 6100-6105
(the k-th path sorted by name gets seed 6100 + k), preset `faithful`, two workers; both controllers keep the
nominal turn map. The controller evaluated is commit 983d46e (4ea49a4, a refactor that decides the same, landed
while it ran; episodes started after it used it); nothing was changed after the results were seen."""
ROBUST_COMMANDS = """```
python scripts/make_eval_paths.py --out results/eval_robust/paths --count 3 --seed0 6100
flagellum evaluate --paths results/eval_robust/paths --controller rule --controller adaptive --seed0 6100 \
    --workers 2 --out results/eval_robust/nominal
flagellum evaluate ... --randomize 0.1 --seed0 6100 --out results/eval_robust/rand10    # swimmers 6100-6105
flagellum evaluate ... --randomize 0.05 --seed0 6100 --out results/eval_robust/rand05
flagellum evaluate --paths results/eval_robust/paths --controller adaptive --randomize 0.1 --randomize-geometry 0.1 \
    --seed0 6100 --workers 2 --out results/eval_robust/rand10_helix10
flagellum follow --path square --controller rule --controller adaptive --out results/eval_robust/square
python scripts/robust_steering_report.py
```"""
ROBUST_FINDINGS = """**Verdict (held out, 6 paths per level, 2026-12-03):** with E, μ, b within ±10 % (helix ±4 %) the default
controller finished 6 of 6 paths (rule 1 of 6; the adaptive planner as first built made 4 and 5 of 6 on the
two earlier held-out sets below, other paths and swimmers): the issue's ≥ 75 % is reached on this set. Within
±5 % (helix ±2 %) it finished 5 of 6 (rule 1 of 6; first built: 4 of 6 on both earlier sets): ≥ 90 % needs 6 of
6, **not reached**. On the nominal swimmer it finished every path,
as the rule planner did, but at 1.12 cm mean cross-track against the rule planner's 0.80 cm: **the nominal
target (cross-track ≤ the rule planner's) is not reached** -- until two turns confirm the map, the timing
spread of the prior (0.3 s) makes it prefer turns whose outcome is predictable, more of them (5.2 bursts per
path against 4.0). With the helix within ±10 % as well it finished 1 of 6. No episode ended in a
`SimulationError`. The paper's square (R10): Δz/ΔL 4.37 % < 5 % with the default controller (rule 4.73 %).

What still fails: (1) circling a waypoint that stays just behind after each turn -- ±5 % 3d_6100 (14 bursts, 1
of 3 waypoints at the time limit) and three of the five helix ±10 % failures (15-21 bursts); a one-move score
cannot see that a turn lands the head where the next turn cannot reach the target; (2) leaving the 10 cm
corridor in the first two bursts (helix ±10 %: 3d_6100 and planar_6102 after 2 bursts, 160-165 s), swimmers
whose turns the map describes worst; (3) out-of-plane drift on planar paths: max Δz/ΔL 37.6 % (nominal,
planar_6100, a path both controllers found hard: rule 17.5 %); the score has no planar term. Six paths per
level is a small sample: one path is 17 %."""


def held_out_commands(root: str, seed0: int, square: bool) -> str:
    """The commands of a held-out evaluation of the rule and the adaptive planner in ``root`` (paths drawn with
    ``seed0``, swimmers from it on; ``square``: the paper's square run too), as a Markdown code block."""
    run = f"flagellum evaluate --paths {root}/paths --controller"
    return "\n".join([
        "```", f"python scripts/make_eval_paths.py --out {root}/paths --count 5 --seed0 {seed0}",
        f"{run} rule --controller adaptive --seed0 {seed0} \\", f"    --workers 2 --out {root}/nominal",
        f"flagellum evaluate ... --randomize 0.05 --seed0 {seed0} --out {root}/rand05   # swimmers {seed0}-{seed0 + 9}",
        f"flagellum evaluate ... --randomize 0.1 --seed0 {seed0} --out {root}/rand10",
        f"{run} adaptive --randomize 0.1 --randomize-geometry 0.1 \\",
        f"    --seed0 {seed0} --workers 2 --out {root}/rand10_helix10",
        *([f"flagellum follow --path square --controller rule --controller adaptive --out {root}/square"] if square else []),
        "python scripts/robust_steering_report.py", "```"])


SOFTSWIM = Path("results/eval_softswim")
SOFTSWIM_DESIGN = """The adaptive planner of the next section with one change (commit e4e4c15): **swimming on before a turn
stays within the soft corridor** (6 cm of the segment; the next section's version swam on up to the hard limit,
8.5 cm). Swimming on to the hard limit left no room for the next burst's forward travel (~5 cm): on the held-out
set of the next section a ±5 % swimmer swam on 6-7 cm past a waypoint and its turn left the corridor. On the
development paths (seeds 5200-5203 and 5300-5303, 16 paths) the change took ±5 % from 13 to 16 of 16 and ±10 %
from 10 to 13 of 16; nominal unchanged on one set (0.67 cm), 0.76 cm on the other (rule 0.66 cm)."""
SOFTSWIM_HELD_OUT = """Development: the paths and swimmers of the sections below (seeds 5200-5207 and 5300-5307); no path or
swimmer of this section was seen before the run. Paths drawn with seeds 6500-6504 (`--count 5`: five planar, five
3-D, three waypoints, segments 12-20 cm, turns 30-150°, reach radius 1.5 cm), swimmers from env seeds 6500-6509
(the k-th path sorted by name gets seed 6500 + k), preset `faithful`, two workers, 12:19-12:54 UTC; both
controllers keep the nominal turn map. The controller evaluated is commit e4e4c15; nothing was changed after the
results were seen."""
SOFTSWIM_COMMANDS = held_out_commands("results/eval_softswim", 6500, square=True)
SOFTSWIM_FINDINGS = """**Verdict (held out, 10 paths per level, 2026-12-03):** within ±5 % (helix ±2 %) the adaptive planner finished
10 of 10 paths (rule 0 of 10): **≥ 90 % reached**. Within ±10 % (helix ±4 %) 9 of 10 (rule 0 of 10): **≥ 75 %
reached**. With the helix within ±10 % as well, 8 of 10. No episode ended in a `SimulationError`. On the nominal
swimmer both finished every path, mean cross-track 0.72 cm (adaptive, 3.6 bursts per path) against the rule
planner's 0.65 cm (3.2): **the nominal target (≤ the rule planner's) is still not reached** (it was 0.83 against
0.74 cm on the previous set); the adaptive planner is worse on 8 of 10 paths: by 0.01-0.08 cm on six with the same
number of bursts, by 0.20 cm on planar_6504 (4 bursts each) and 0.52 cm on planar_6502 (6 bursts against 3); better
on 3d_6504 and planar_6503. The paper's square (R10): the same runs as in the next section (the change did not
alter them): Δz/ΔL 4.36 % < 5 % with the default controller (rule 4.85 %), mean cross-track 0.65 cm (rule 0.74
cm). Max Δz/ΔL on the planar held-out paths, nominal: adaptive 6.9 %, rule 7.2 % (the means over them 6.1 and
6.4 %).

One set of ten paths is a small sample: on the previous set (6400) the version before this change made 8 and 4 of
10 (that set was harder for every version run on it), and on the development paths this version made 16 and 13 of
16. The failures here all left the corridor: at ±10 % planar_6502 after its first waypoint; with the helix within
±10 %, 3d_6501 (the target at the start behind and beside, three bursts) and planar_6504 after its first
waypoint (856 s, five bursts)."""


MODEL = Path("results/eval_model")
MODEL_DESIGN = """The planner of the next section with its cruise match taken to its end (commit a1befc7): **a swimmer whose
cruise matches the map's is steered by the paper's rule** on the map (the rule planner's own choice of burst and
phase, each burst flown by time) until a turn of 20° or more comes out off the map (more than 10° + 15 % off its
angle or 15° off its direction: the confirmation test of `OnlineTurnMap`); from then on by the corrections, with
what the turns so far have taught them. The next section's version (the match only narrowed the direction spread)
flew the rule planner's first turns but still lost to it on the nominal swimmer at later turns, on that set (0.77
against 0.73 cm) and on a sixth set of nominal paths drawn for the purpose (paths 7500-7504, swimmer seed 7500,
the code of d3f9c7c: 0.723 against 0.694 cm, 10/10 each; that run's folder was lost with its worktree, the numbers
are from its printed table): where the adaptive planner chooses by expected miss under a spread the nominal swimmer
does not have, it gives away a little at every turn. On paths 7500-7504 with this version all ten nominal episodes
are the rule planner's (every metric equal; every turn in the rule's mode; results/eval_model/check_7500). A
swimmer that does not match is steered exactly as by the next section's planner; one that matches but is not the
map's (none did among the 60 randomised held-out swimmers of this set and the next, nor the 16 development ones at
±5 %, whose cruise readings were recorded: the larger relative change 1.1-30 %) flies the rule planner's turns until
one comes out off the map. Since the section below, the simulator also starts each Newton-Krylov step's force
unknowns from their extrapolation (082bfb6, d3f9c7c: the same equations and tolerances, trajectories within the
tolerance of the old ones)."""
MODEL_HELD_OUT = """Development: as below; paths 7500-7504 were drawn and run (nominal swimmer only) to check the next section's
version on the nominal swimmer, and again to check that this version's nominal episodes are the rule planner's.
Paths drawn with seeds 7600-7604 (`--count 5`), swimmers from env seeds 7600-7609, preset `faithful`, two workers,
19:44-20:01 UTC, from a worktree at a1befc7. No path or swimmer of this set was seen before the run and nothing was
changed after it. The run's folder was deleted by mistake before it was copied; the same commands were run again
from the same commit (20:05-20:21 UTC) and gave the same episodes (every metric of the tables printed after the
first run), which are the files here."""
MODEL_COMMANDS = held_out_commands("results/eval_model", 7600, square=True)
MODEL_FINDINGS = """**Verdict (sixth held-out set, 10 paths per level, 2026-12-03):** within ±5 % (helix ±2 %) the adaptive
planner finished 10 of 10 paths (rule 5 of 10): **≥ 90 % reached**; within ±10 % (helix ±4 %) 9 of 10 (rule 3 of
10): **≥ 75 % reached**; with the helix within ±10 % as well 8 of 10. No episode ended in a `SimulationError`; no
randomised swimmer's cruise matched the map (the larger relative change 1.6-30 %). **Nominal swimmer: the target is
met, by construction**: its cruise matched, every turn was the rule planner's, and all ten episodes are the rule
planner's (10 of 10, mean cross-track 0.71 cm each, every metric equal) — this compares the adaptive planner with
itself and says nothing more about it than that it loses nothing on the swimmer its map was made for. The paper's
square (R10), the default controller: Δz/ΔL 4.86 % < 5 %, mean cross-track 0.74 cm, every corner in 3 bursts (the
rule planner's episode). Max Δz/ΔL on the planar held-out paths, nominal: 10.1 % (both).

What failed: ±10 % 3d_7600, a late buckler (shift read -1.6 s before the first turn): two bursts stretched to
11.2 and 12.5 s, then out of the corridor after 257 s; with the helix within ±10 % the same path's swimmer (-2.2 s)
left the corridor after two such bursts (118 s), and 3d_7602 (15 bursts of 9-11 s) reached two of three waypoints
in 1411 s. Late buckling, whose first burst the planner must stretch far beyond anything on the map, remains the
commonest failure (also on the sets below).

All six fresh held-out sets together (60 paths per level; the first two before the hover and small-burst fixes,
the fifth with the narrower cruise match, this one as the code stands): ±5 % 58 of 60, ±10 % 51 of 60, helix ±10 %
44 of 60; rule 14 and 7 of 60. Nominal: 58 of 60 (rule 60 of 60): the two failures were on sets 6600 and 6900,
before the cruise match."""


CRUISE = Path("results/eval_cruise")
CRUISE_DESIGN = """The planner of the next section with one change (commit d348e58; the rule planner is unchanged): **a cruise
that matches the map's swimmer confirms the map**. Before its first turn the adaptive planner reads the steady
strain L'/L - 1 and the rotation rate of the flagellum at 10 rpm against the map swimmer's (`observe_cruise`); when
both are within 1 % (`OnlineMapConfig.cruise_match_tol`), the map counts as confirmed for every turn (direction
spread 10°, no turn "goes anywhere") until a turn contradicts it, as two confirming turns did before. The 31
randomised swimmers of the shift fit (±10 %) differed from the reference by 3.3-21.6 % in the larger of the two
changes, the development swimmers at ±5 % by 1.1-8.7 %; the nominal swimmer reads 0.00 %. So the swimmer the map
was made for flies a large first turn whole, as the rule planner does, instead of 77-84° and a correction (the cause
of the nominal gap on every earlier set); a swimmer that cruises differently keeps the cautious model. Development
(paths 5200-5203 and 5300-5303): nominal 0.650 cm against the rule planner's 0.644 cm (was 0.665 cm), 16/16; at ±5 %
every episode identical to before (no swimmer matched). The first turn's record keeps the cruise reading
(`cruise`: relative changes, shift read, matched)."""
CRUISE_HELD_OUT = """Development: the paths and swimmers named above; the earlier held-out sets (6500, 6600, 6800, 6900) were
read to find the cause of the nominal gap. Paths drawn with seeds 7400-7404 (`--count 5`), swimmers from env seeds
7400-7409, preset `faithful`, two workers, 19:05-19:28 UTC, from a worktree at d348e58. No path or swimmer of this set
was seen before the run and nothing was changed after it."""
CRUISE_COMMANDS = held_out_commands("results/eval_cruise", 7400, square=True)
CRUISE_FINDINGS = """**Verdict (fifth held-out set, 10 paths per level, 2026-12-03):** within ±5 % (helix ±2 %) the adaptive planner
finished 10 of 10 paths (rule 3 of 10): **≥ 90 % reached**; within ±10 % (helix ±4 %) 8 of 10 (rule 2 of 10): **≥ 75 %
reached**; with the helix within ±10 % as well 6 of 10. No episode ended in a `SimulationError`; no randomised
swimmer's cruise matched the map (the larger relative change 1.7-25.8 %), so at every randomised level the planner
behaved as the one of the next section. The paper's square (R10): Δz/ΔL 4.45 % < 5 % with the default controller
(rule 4.85 %), mean cross-track 0.58 cm (rule 0.74 cm), both every corner in 3 bursts.

**Nominal swimmer: every first turn is now the rule planner's** (147°, 128°, 102° on the paths that start with a
large turn: the change did what it was for), and both finished 10 of 10, but **the mean cross-track target is still
not met: 0.77 cm against 0.73 cm** (worse on 5 paths by 0.09-0.29 cm, better on 4 by 0.08-0.13 cm; mean paired
difference +0.04 cm, standard error 0.04 cm). With the same first turns the two part at later turns, where the
adaptive planner picks by expected miss under the corrected map's spread (a shift spread of 0.08-0.14 s and a
direction spread of 10° after the first turns, which the nominal swimmer does not have) and ends each burst by the
ratio clock (the nominal swimmer's observed turns were within 1.8° rms of the planned ones), the rule planner by the
map alone; from there the paths differ by small amounts that the rest of the episode carries either way. On the
development paths the same change gave 0.650 cm against 0.644 cm. Energy 0.253 J against 0.258 J, time 553 s
against 544 s. Max Δz/ΔL on the planar held-out paths, nominal: adaptive 9.2 %, rule 9.1 %.

What failed: ±10 % 3d_7400 (an early buckler, shift +2.0 s read from the cruise, the cruise's strain 26 % off the
map's; target behind at the start): two bursts whose headings came out 138-178° off the predicted direction, out of
the corridor after 155 s; ±10 % 3d_7403 (target behind at the start; shift +1.3 s after the first turn): seven
bursts, each planned at 109-124° and each ended by the ratio clock after 6.6 s, came out 141-151° — the clock
target fell in the map's L'/L pause (7.6-7.8 s of map time), so each burst ran to the first reading past it, ~0.2 s
of map time late; the angle then agreed with the clock's last reading, so the correction learnt nothing, and the
head circled its first waypoint until the episode ended (497 s). With the helix within ±10 %, the same two paths
(two bursts each), 3d_7401 (30 bursts of 4.7-5.8 s, two of three waypoints) and planar_7402 (out of the plane after
two bursts).

All five fresh held-out sets together (50 paths per level): ±5 % 48 of 50, ±10 % 42 of 50, helix ±10 % 36 of 50;
rule 9 and 4 of 50. Nominal: adaptive 48 of 50, rule 50 of 50; the adaptive planner's mean cross-track above the
rule planner's on every set (0.72/0.65, 1.01/0.64, 0.72/0.65, 1.04/0.67 and, with the cruise match, 0.77/0.73
cm).

These are the episodes of d348e58. The commit after it (082bfb6, d3f9c7c) starts the Newton-Krylov step's force
unknowns from their extrapolation: the same equations solved to the same tolerance from a better start, so every
trajectory moves within the tolerance (the bench burst's θ by 0.005°) and an episode's later decisions can part
from these."""


RESTART = Path("results/eval_restart")
RESTART_DESIGN = """The planner of the next section with the hover restart (commit 24a4a99; both planners): a hover whose phase
node has turned less than once in 1.5 map periods is given up and the heading measured again (at most twice per
turn). Built after the next section's held-out run from a replay of one of its episodes, so that set cannot judge
it; this is a fresh set for the planner as it stands (HEAD 4f52d96: the commits after 24a4a99 change text only)."""
RESTART_HELD_OUT = """Paths drawn with seeds 6900-6904 (`--count 5`), swimmers from env seeds 6900-6909, preset `faithful`, two
workers, 17:48-18:12 UTC, from a worktree at 4f52d96. No path or swimmer of this set was seen before the run and nothing
was changed after it."""
RESTART_COMMANDS = held_out_commands("results/eval_restart", 6900, square=True)
RESTART_FINDINGS = """**Verdict (fourth held-out set, 10 paths per level, 2026-12-03):** within ±5 % (helix ±2 %) the adaptive
planner finished 9 of 10 paths (rule 2 of 10): **≥ 90 % reached** (just); within ±10 % (helix ±4 %) 8 of 10 (rule 2
of 10): **≥ 75 % reached**; with the helix within ±10 % as well 7 of 10. No episode ended in a `SimulationError`.
The paper's square (R10): the same episodes as in the next section (the restart did not come into play): Δz/ΔL
4.53 % < 5 % with the default controller (rule 4.85 %). **The nominal target is not met**: the adaptive planner finished 9 of 10 (rule 10 of 10), mean cross-track
1.04 cm against 0.67 cm (0.76 against 0.65 cm over the nine both finished; worse on 6 paths, better on 4). Max
Δz/ΔL on the planar held-out paths, nominal: adaptive 27.9 % (planar_6903, five bursts; the others 4.9-7.1 %), rule
8.3 %.

No hover swung or timed out on this set and no turn was flown more than 5° off its phase (481 turns): the restart
never came into play, so this set measures the planner of the next section on fresh paths and swimmers.

What failed: nominal 3d_6901: at its first waypoint the adaptive planner turned 84° where the rule planner turned
102° (the capped first large turn, as in the next section), passed the second waypoint and then circled it: nine
U-turns of 128-178°, each as the map predicted (azimuth errors ≤ 12°), each ending 4-8 cm to one side of the
waypoint or the other, until the episode ended (1402 s) — the issue's failure kind 1 (circling a waypoint about as
far away as a turn carries the head), here on the nominal swimmer. ±5 % planar_6904 reached two waypoints in 11
bursts, not the third (1456 s). ±10 %: 3d_6902 (a late buckler, shift read -1.6 s before the first turn;
bursts of 9-13 s) ended after one waypoint (501 s); planar_6900 (shift -0.9 s) flew 23 bursts of ~10 s
without reaching its first waypoint.

All four fresh held-out sets together (40 paths per level; 6500 and 6600 with the planner before the hover and
small-burst fixes): ±5 % 38 of 40, ±10 % 34 of 40, helix ±10 % 30 of 40; rule 6 and 2 of 40. Nominal:
adaptive 38 of 40, rule 40 of 40, and the adaptive planner's mean cross-track above the rule planner's on every
set."""


HOVER = Path("results/eval_hover")
HOVER_DESIGN = """The planner of the two sections below (e4e4c15) with two fixes, each motivated by a failure and checked on the
development paths:

1. **The hover no longer jumps its phase** (commit 17ee099; shared with the rule planner, the paper's baseline, which
   this changes too): the burst starts at the first control step within half a step before the planned phase *or
   past it* (`agents.turn_planner.burst_phase_reached`); before, only the window of half a step either side
   counted, which a step longer than the one before can jump (the phase node turns 3.5-4.5° per 0.1 s step at
   10 rpm), and the hover then waited for its limit of 1.5 map periods (13.5 s; the node passes the phase once per
   ~9 s map period, so one missed pass runs into it) and flew
   the turn at whatever phase it had: nominal planar_6600 of the set below, a 34° correction flown 156° off its
   phase. The limit is now 3 map periods, and each turn records `phase_error_deg` and `hover_timed_out`
   (`flagellum evaluate` keeps the planners' turns in results.jsonl). On the development episodes below no
   turn's phase error exceeded 3° and no hover timed out.
2. **A burst planned to end before buckling is flown by time** (commit c4d707e): the ratio clock reads only once
   L'/L has fallen below 0.98 (at ~4.9 s of map time at `faithful`); a small correction planned shorter than
   that waited for a reading that never came and was cut at its longest allowed length (planned 4.2 s, flown
   4.9 s: ~10° instead of ~5°, on 6 of 45 nominal development turns), so the next decision saw a miss and turned
   again.

Development (paths 5200-5203 and 5300-5303, swimmers 5200-5207 and 5300-5307, 16 paths per level): nominal mean
cross-track 0.665 cm against the rule planner's 0.644 cm (16/16 each; before fix 2 on the 5300 half 0.754 against
0.660 cm), ±5 % 16/16, ±10 % 13/16 (both as before). Tried on the same development paths and not kept: the ratio-turn bias prior at 0.15 s
instead of 0.3 s (nominal 0.750 cm on the 5300 half, no better); and, for the nominal swimmer's sake, letting an
unconfirmed large turn go "anywhere" with a chance of at most 0.3 instead of 1 (a variant in a worktree, not in the code; on these
development swimmers 3 of 36 unconfirmed turns of 100-180° came out more than 45° off, at ±10 %; none at ±5 %):
nominal 0.649 cm against the rule planner's 0.644 cm (the first turn of planar_5302 became the rule planner's
128° instead of 114°), ±5 % 16/16, but ±10 % 11/16 instead of 13/16 — the nominal swimmer's gain is paid for by
the swimmers the planner is for."""
HOVER_HELD_OUT = """Development: the paths and swimmers named above; no path or swimmer of this section was seen before the run,
and the numbers are those of the evaluated commit (the hover restart described under the verdict came after them). Paths drawn with seeds 6800-6804 (`--count 5`: five planar, five 3-D, three
waypoints, segments 12-20 cm, turns 30-150°, reach radius 1.5 cm), swimmers from env seeds 6800-6809 (the k-th
path sorted by name gets seed 6800 + k), preset `faithful`, two workers, from a worktree at c4d707e, 16:17-16:45 UTC;
both controllers keep the nominal turn map. The paper's square was run again (both fixes can change it)."""
HOVER_COMMANDS = held_out_commands("results/eval_hover", 6800, square=True)
HOVER_FINDINGS = """**Verdict (third held-out set, 10 paths per level, 2026-12-03):** within ±5 % (helix ±2 %) the adaptive
planner finished 10 of 10 paths (rule 2 of 10): **≥ 90 % reached**; within ±10 % (helix ±4 %) 8 of 10 (rule 0 of
10): **≥ 75 % reached**; with the helix within ±10 % as well 7 of 10. No episode ended in a `SimulationError`. The
paper's square (R10): Δz/ΔL 4.53 % < 5 % with the default controller (rule 4.85 %), mean cross-track 0.50 cm (rule
0.74 cm), both every corner with 3 bursts. **The nominal target is again not met**: both planners finished 10 of
10, but the adaptive planner's mean cross-track is 0.72 cm against the rule planner's 0.65 cm (4.3 bursts per path
against 3.2; worse on 6 paths, better on 3, one tie). Max Δz/ΔL on the planar held-out paths, nominal: adaptive
8.1 %, rule 8.8 % (means 7.1 % each).

The hover: over the 449 turns of this set no turn of either planner at nominal, ±5 % or with the helix ±10 % was
flown more than 5° off its phase; one hover timed out (the rule planner at ±10 % on planar_6801, after its first
128° turn: 3 map periods without the phase node reaching the planned azimuth, flown 153° off; that episode was
lost anyway). Replayed (deterministic; seed 6806): during that hover the phase node's azimuth about the heading
measured when the hover began did not turn at all, it swung between -32° and +13° with the wobble period, and the
planned azimuth was 150°, so no waiting could reach it. An azimuth that swings instead of turning is what a
flagellum axis tilted off the measured heading by more than the node's radius over its distance along the axis
gives (inferred, not measured; L'/L was still 0.984 at the hover's start, rising to 1.005). Built after this
set's run (commit 24a4a99; not in the numbers above, and this set cannot judge it): a hover whose phase node has
turned less than once in 1.5 map periods is given up and the heading measured again over one period (at most twice
per turn, then the time-out fires as before; `hover_phase_stuck`, turns record `hover_restarts`). The replayed
episode then flew that turn 1.2° off its phase after one restart; on the development paths (nominal with both
planners, ±5 % and ±10 % with the adaptive planner, 64 episodes) no hover swung and every episode came out the
same as before it.

Why the nominal swimmer loses, read from the turn records (`results.jsonl`): where a path starts with a turn of
100° or more, the adaptive planner flies 77-84° (the map's large turns count as going "anywhere" until two turns
have confirmed the map) and then a 22-34° correction, where the rule planner flies one 92-102° turn (3d_6800,
planar_6802, planar_6803); the detour costs 0.16-0.24 cm of mean cross-track on those paths. The development
check above (large turns allowed sooner) shows the price of removing this: fewer swimmers within ±10 % finish.
What failed: at ±10 % planar_6800 and planar_6802, and with the helix ±10 % planar_6800, planar_6802 and 3d_6804,
are all late bucklers (shift read -1.0 to -2.1 s before the first turn, -2.6 to -4.7 s after it). On the planar
three the first burst, stretched to 10-13 s because the flagellum was seen to buckle late, came out 21-95° off
the predicted direction (one turned 10° instead of 84°), and the head left the 10 cm corridor or the plane (Δz/ΔL
up to 59 %); 3d_6804 reached its first waypoint and not the second (nine bursts of 8-12 s, the episode ended after 685 s).

All three fresh held-out sets together (6500 and 6600 with the planner before these fixes, 6800 with them; 30
paths per level): ±5 % 29 of 30, ±10 % 26 of 30, helix ±10 % 23 of 30; rule 4 and 0 of 30. Nominal: adaptive 29
of 30 (the one failure, planar_6600, was the hover fixed here), rule 30 of 30; the adaptive planner's mean
cross-track above the rule planner's on every set (0.72/0.65, 1.01/0.64, 0.72/0.65 cm)."""


SOFTSWIM2 = Path("results/eval_softswim2")
SOFTSWIM2_DESIGN = """The same planner as the section below (commit e4e4c15; the commits after it, up to 6282840, change no
episode: `flagellum follow` runs its controllers in parallel, bit for bit the same), on a second held-out set drawn
after the first one's results were in, to see how much one set of ten paths says."""
SOFTSWIM2_HELD_OUT = """Paths drawn with seeds 6600-6604 (`--count 5`, as below), swimmers from env seeds 6600-6609, preset
`faithful`, two workers, 13:19-13:44 UTC, from a worktree at 6282840. No path or swimmer of this set was seen
before the run and nothing was changed after it. The paper's square was not run again: its episodes are those of
the section below (same planner, same swimmer)."""
SOFTSWIM2_COMMANDS = held_out_commands("results/eval_softswim2", 6600, square=False)
SOFTSWIM2_FINDINGS = """**Verdict (second held-out set, 10 paths per level, 2026-12-03):** within ±5 % (helix ±2 %) the adaptive
planner finished 9 of 10 (rule 2 of 10): **≥ 90 % reached** (just); within ±10 % (helix ±4 %) 9 of 10 (rule 0 of
10): **≥ 75 % reached**; with the helix within ±10 % as well 8 of 10. No episode ended in a `SimulationError`. On
the two fresh sets together (6500 and 6600, 20 paths): ±5 % 19 of 20, ±10 % 18 of 20, helix ±10 % 16 of 20, rule
2 and 0 of 20. **The nominal swimmer is where this set is worse**: the adaptive planner failed one of ten
(planar_6600; rule 10 of 10), so the nominal target (success = the rule planner's, mean cross-track ≤ it) is **not
met**: mean cross-track 1.01 cm against 0.64 cm (without planar_6600 0.83 cm against 0.64 cm over the same nine; the
adaptive planner is worse on 8 of 10 paths). Max Δz/ΔL on the planar held-out paths, nominal: adaptive 29.1 %
(planar_6600, the failure; the others 5.9-11.5 %), rule 11.0 %.

What failed: nominal planar_6600 left the corridor after its first waypoint (238 s, five turns of which three
buckled). Replayed (the episode is deterministic): its third turn (84°, at the waypoint, toward a second waypoint
16 cm away at ~110° to the heading) came out as predicted (azimuth error -6°); the fourth, a 34° correction aimed
at the waypoint (azimuth 102° about the heading, the waypoint's own; predicted miss 0.5 cm), **was flown 156° off
its burst phase**: the hover that waits at 10 rpm for the flagellum's phase node to reach the planned azimuth gave
up after its limit of 1.5 periods and started the burst where the node was (`RulePlanner`'s hover, shared by both
planners; the turn record's `phase_error_deg` -155.8°). The turn went where that phase sends it (azimuth -43°, 2.7°
from the phase-corrected prediction): from -163° to about -146° in the plane and from 6° to 30° up out of it, the
waypoint 40° the other way; at the next decision the straight line missed by 17 cm with the head 3.6 cm out of the
plane, and the fifth turn (104°) took it out (4.8 cm out of the plane at the end). Replayed (the episode is
deterministic); the other four turns had phase errors below 1°. How often the hover gives up, and why it missed
the phase here, is for the next version (re-planning at the phase reached instead of flying the old plan is the
obvious remedy). ±5 % 3d_6604 and ±10 % 3d_6600 left the
corridor after their first waypoint (3 and 4 bursts); with the helix within ±10 %, 3d_6600 (5 bursts, no waypoint)
and planar_6604 (23 bursts in 1353 s without reaching its first waypoint; not analysed)."""


CLOCK = Path("results/eval_clock")
CLOCK_DESIGN = """The adaptive planner of the next section with four changes (commits 5bb8449 and 54c21a0):

1. **The shipped `faithful` turn map measured again on a finer grid** (0.1 s from 7.0 to 8.3 s, 33 turns;
   docs/time_integration.md has the table). The old map's straight lines between 7.5 and 8.0 s promised
   7-10° more than the swimmer turns at 7.6-7.9 s, and hid that L'/L pauses (at 0.60 from 7.0 to 7.2 s and at
   0.48 from 7.6 to 7.8 s) while the turn keeps growing. Both planners use it.
2. **Bursts timed by the ratio clock** (`OnlineTurnMap.clock_reading`): L'/L is read as the map time the
   swimmer has reached only where the map's L'/L falls (at least 0.05 per s), each time it makes a new low;
   every reading gives the swimmer's shift, and the burst ends at the control step nearest to the planned map
   time by the last reading (on a pause, the reading before it plus the time flown since; past the map's
   recorded ratios too). Before, a burst ended when L'/L reached the map's value at the planned time, which on
   a pause could be anywhere in it. The last reading is the turn's shift reading (clipped to ±5 s, was ±3 s:
   the clock read -3.8 s on a development swimmer).
3. **Misses scored up to a scale**: each predicted miss m counts as c (1 - exp(-m / c)), c = max(3 cm, half the
   straight-line miss), so a large turn with spread-out outcomes is not ruled out by its unlikely worst cases
   (a bad turn is followed by another); and swimming on before a turn is checked every cm up to 8.5 cm from the
   segment (was every 2 cm up to 6 cm: past a waypoint that limit is where a swimmer circled it).
4. **A confirmed map is trusted only as far as turns tested it**: after two confirming turns the narrow direction
   spread (10°) holds up to 20° beyond the largest of them, and the chance that a larger turn goes anywhere
   ramps up from there (before, every turn was trusted: on development swimmers at ±5 % a map confirmed by
   turns of 92-131° let 177-178° turns near the branch's cliff through)."""
CLOCK_HELD_OUT = """Development: the paths and swimmers of the sections below (seeds 5200-5207 and 5300-5307 for these
changes; nothing from 6100-6105 or any set below was used to tune them, 3d_6100 at ±5 % was replayed to read
why it circled). The numbers here are on paths drawn with seeds 6400-6404 (`--count 5`: five planar, five
3-D, three waypoints, segments 12-20 cm, turns 30-150°, reach radius 1.5 cm) and swimmers from env seeds
6400-6409 (the k-th path sorted by name gets seed 6400 + k), preset `faithful`, two workers; both controllers
keep the nominal turn map. The controller evaluated is commit 54c21a0; nothing was changed after the
results were seen."""
CLOCK_COMMANDS = """```
python scripts/make_eval_paths.py --out results/eval_clock/paths --count 5 --seed0 6400
flagellum evaluate --paths results/eval_clock/paths --controller rule --controller adaptive --seed0 6400 \
    --workers 2 --out results/eval_clock/nominal
flagellum evaluate ... --randomize 0.05 --seed0 6400 --out results/eval_clock/rand05   # swimmers 6400-6409
flagellum evaluate ... --randomize 0.1 --seed0 6400 --out results/eval_clock/rand10
flagellum evaluate --paths results/eval_clock/paths --controller adaptive --randomize 0.1 --randomize-geometry 0.1 \
    --seed0 6400 --workers 2 --out results/eval_clock/rand10_helix10
flagellum follow --path square --controller rule --controller adaptive --out results/eval_clock/square
# the commit before (2233812), afterwards, same paths and swimmers, for comparison only:
flagellum evaluate --paths results/eval_clock/paths --controller adaptive --randomize 0.1 --seed0 6400 \
    --workers 2 --out results/eval_clock_prev/rand10      # and --randomize 0.05 ... rand05
python scripts/robust_steering_report.py
```"""
CLOCK_FINDINGS = """**Verdict (held out, 10 paths per level, 2026-12-03):** on the nominal swimmer both controllers finished
every path; mean cross-track 0.83 cm (adaptive, 3.7 bursts per path) against the rule planner's 0.74 cm (3.0):
**the nominal target (≤ the rule planner's) is not reached**, though the gap shrank (previous held-out set: 1.12
against 0.80 cm, 5.2 against 4.0 bursts); the rule planner gained from the finer map as well (development paths:
0.91 -> 0.63 cm). Within ±5 % (helix ±2 %) the adaptive planner finished 8 of 10 (rule 2 of 10): **≥ 90 % not
reached**. Within ±10 % (helix ±4 %) 4 of 10 (rule 1 of 10): **≥ 75 % not reached**; with the helix within ±10 %
3 of 10. No episode ended in a `SimulationError`. The paper's square (R10): Δz/ΔL 4.36 % < 5 % with the default
controller (rule 4.85 %), mean cross-track 0.65 cm (rule 0.74 cm).

The commit before these changes (2233812, the old map, bursts ended at a target L'/L), run afterwards on the same
paths and swimmers (`results/eval_clock_prev`, commands below): ±10 % also 4 of 10 (the same four paths but one:
it made planar_6404 and missed planar_6401, the new one the reverse; 8.1 bursts per path against 4.2, mean
cross-track 3.35 against 3.32 cm); ±5 % 7 of 10 against 8 of 10 (it missed 3d_6404 and planar_6401, which the
new one made, and made planar_6404, which the new one missed; 7.8 bursts per path against 4.8, 2.42 against 2.08
cm). So this set is harder than the previous one (where that commit made
6 of 6 at ±10 % and 5 of 6 at ±5 %), and the changes did not make steering less robust on it; on the
development paths they cost one or two paths per eight at ±5 / ±10 % (13 of 16 and 10 of 16 against 14 of 15
and 8 of 10 of those run with 2233812), within what eight paths can tell.

What fails, from the failed episodes' traces (every failure left the 10 cm corridor; none timed out): (1) **the
target passed at 2-4 cm with no room left for a correction**: after a turn the planner waits for the heading to
settle (~45 s, the flagellum relaxing) before it plans again, and by then the waypoint is 3-6 cm ahead, closer than
any burst can correct (a burst that buckles at all, ≥ 5 s at 150 rpm, carries the head ~5 cm forward); the
swimmer passes it and must turn back near the corridor's edge (development ±5 %: 3d_5202, planar_5203; held-out
±5 % planar_6404 passed its first waypoint 1.7 cm away, 1.4 cm of it out of the plane). (2) **Swimming on past a
waypoint up to 8.5 cm from the segment** (this version's change 3) then turning there: on held-out ±5 % planar_6404
it swam on 6-7 cm past the waypoint and the turn took it out of the corridor; limiting it back is for the next
version (it was not changed after these results). (3) **A target behind at the start** with large turns whose
direction the unconfirmed map cannot predict (held-out ±5 % 3d_6401: five turns of 114-130° each left the target
behind, drifting to the corridor's edge). (4) Out-of-plane drift: max Δz/ΔL on planar held-out paths 8.8 %
(nominal, adaptive; rule 9.4 %); the score still has no planar term."""


#: the held-out evaluations of the adaptive planner against the rule planner, newest first: (title, results folder,
#: (design, what was held out, commands), the folder of its square run under it or None, findings, figure prefix)
LINE = Path("results/eval_line")
LINE_CONTROLLERS = ("rule", "adaptive", "adaptive@line=2", "ppo")
LINE_DESIGN = """`PlannerConfig.line_weight` (`agents/turn_planner.py`, controllers `rule@line=W` and `adaptive@line=W`): both
planners choose a turn by how close its new straight line passes to the next waypoint; with a line weight W they
also count W × the distance of the turn's predicted end (the head after the burst, from the map's displacement)
from the line of the segment being followed (the previous waypoint, or the start, to the target), and swimming
on counts the head's distance from it now. A turn is made when it lowers the miss or this score by
`improvement_m` (5 mm). The mean cross-track error is measured against that segment, and the rule picks, among
turns that all reach the waypoint, one that puts the swimmer back on the path's line rather than on a parallel
line a few cm off it (an exact first turn already leaves 0.85-0.90 of the rule planner's cross-track, docs/agents.md:
the rest is how the turns land). The adaptive planner adds the term in expectation over its timing outcomes; on a
swimmer whose cruise matches the map it flies the rule planner's choice, now with the term. W = 0 (the default)
is the paper's rule, bit-identical (head trajectories of a rule and an adaptive episode hashed before and after).

Development (seeds 9100-9104 for the paths, `--count 5`, swimmers 9100-9109; a first probe outside the product
code on the same nominal paths gave the same numbers), faithful, the controllers' aggregates (success, mean
cross-track, bursts per path):"""
LINE_HELD_OUT = """W = 2 was chosen on the development set above before the held-out set was drawn: W = 4 gave the lowest
nominal cross-track but lost a path at ±5 %; W = 8 was started and stopped after two paths (more bursts). Held out:
paths drawn with seeds 10300-10307 (`--count 8`: 8 planar, 8 3-D, three waypoints, segments 12-20 cm, turns
30-150°, reach radius 1.5 cm), swimmers from env seeds 10300-10315, preset `faithful`, two workers, 2026-12-04
from 09:19 UTC, code of the commit that added `line_weight` (7220d52; the later commits change the residual
agent's plumbing only). `ppo` is the shipped agent (agents/pretrained/ppo_residual_adaptive, trained on the plain
adaptive planner). Nothing was changed after the results were seen."""
LINE_COMMANDS = """```
python scripts/make_eval_paths.py --out results/eval_line/paths --count 8 --seed0 10300
flagellum evaluate --paths results/eval_line/paths --controller rule --controller adaptive \\
    --controller adaptive@line=2 --controller ppo --seed0 10300 --workers 2 --out results/eval_line/nominal
flagellum evaluate ... --randomize 0.05 --seed0 10300 --out results/eval_line/rand05   # swimmers 10300-10315
flagellum evaluate ... --randomize 0.1 --seed0 10300 --out results/eval_line/rand10
flagellum follow --path square --controller adaptive --controller adaptive@line=2 --out results/eval_line/square
python scripts/robust_steering_report.py
```
Development: the same with `--controller rule --controller adaptive --controller rule@line=4 --controller
adaptive@line=2 --controller adaptive@line=4` on `--count 5 --seed0 9100` paths, `--seed0 9100`, in
results/eval_line/dev/<level>."""

LINE_FINDINGS = """**Verdict (held out, 16 paths per level):** the line weight lowers the mean cross-track error at every level
and finishes more paths within ±10 %, but lost one path within ±5 %. Nominal swimmer: 16/16 at **0.59 cm against
0.73 cm** for the rule and the adaptive planner (0.82×; lower on 14 of 16 paths, with 3.3 bursts per path against
3.1), the paper's square at 0.56 cm against 0.75 cm with the same 3 bursts and **Δz/ΔL 4.16 %, within the paper's
5 % (R10)** where the rule planner's 5.04 % is not. Within ±5 % (helix ±2 %): 15/16 (adaptive 16/16, rule 2/16),
1.11 cm against 1.39 cm; the lost path, planar_10305, left the 10 cm corridor after 264 s and 5 bursts. Within
±10 % (helix ±4 %): 13/16 against the adaptive planner's 11/16 (rule 1/16), 1.86 cm against 2.34 cm, in 501 s
against 763 s simulated with 6.3 bursts against 8.4. Not better: the out-of-plane drift on the planar held-out
paths (nominal swimmer), max Δz/ΔL 9.0 % on average against the rule planner's 8.0 %, worst 16.5 % against 10.3 %
(planar_10307, where the line weight flew 5 bursts against 3 and ended at 0.85 against 0.58 cm; planar_10302
11.0 % against 7.4 %): the term counts the distance from the line in 3-D, and each extra burst lifts the head out
of the plane by its own amount. With the development set (10 paths per level) pooled, 26 paths:
±5 % 24 against 25, ±10 % 20 against 17. No episode ended in a `SimulationError`. The shipped agent `ppo` (trained on
the plain adaptive planner) made 16/16, 16/16 and 15/16 at 0.81, 1.24 and 1.90 cm: behind the line weight on the
nominal swimmer, ahead of every planner in success within ±10 % (docs/agents.md pools this set with its other
two).

`make demo` now flies `rule` against `adaptive@line=2` (on the demo's nominal square `adaptive` alone flew the rule
planner's episode). `adaptive` keeps W = 0: the agents trained on it see its plans, and the ±5 % loss here is one
path in 16 on one set, too little to tell from chance either way; W is a choice between a tighter path and the
extra turns it takes, which a user makes with the spec.

**A second held-out set** (paths `--count 8 --seed0 10500`, swimmers 10500-10515, drawn 2026-12-04 around 12:10 UTC after
all of the above; results/eval_set4, per-path tables in docs/agents.md, held-out set 4): `adaptive@line=2` against
`adaptive` (= `rule` on the nominal swimmer): nominal 16/16 at 0.55 against 0.68 cm (0.82× again; 3.2 bursts
against 3.0; planar max Δz/ΔL 7.46 % against 7.55 %), ±5 % 15/16 each at 1.19 against 1.89 cm, ±10 % 12/16 each
at 2.12 against 2.61 cm; the rule planner 2/16 and 1/16. No `SimulationError`."""


def dev_table(root: Path) -> list[str]:
    """Markdown: per level (rows) and controller (columns) of the evaluate folders ``root/<level>``: success,
    mean cross-track (cm), bursts per path."""
    found = {lv: json.loads((root / lv / "results.json").read_text()) for lv, _ in LEVELS
             if (root / lv / "results.json").is_file()}
    if not found:
        return ["Not measured."]
    ctrl = list(dict.fromkeys(c for res in found.values() for c in res["aggregate"]))
    out = ["| level | " + " | ".join(f"`{c}`" for c in ctrl) + " |", "|---" * (len(ctrl) + 1) + "|"]
    for lv, res in found.items():
        cells = []
        for c in ctrl:
            a = res["aggregate"].get(c)
            cells.append("—" if a is None else f"{round(a['episodes'] * a['success_rate'])}/{a['episodes']}, "
                         f"{100 * a['mean_cross_track_m']:.2f} cm, {a['buckling_events']:.1f}")
        out.append(f"| {lv} | " + " | ".join(cells) + " |")
    return out


def line_section(lines: list[str]) -> None:
    """The line weight (``PlannerConfig.line_weight``): development table, then the held-out set."""
    design = "\n".join([LINE_DESIGN, "", *dev_table(LINE / "dev")])
    held_out_section(lines, "## Turns that end on the path's line (controller `adaptive@line=2`, issue #26; measured "
                     "2026-12-04)", LINE, LINE_CONTROLLERS, "adaptive@line=2", (design, LINE_HELD_OUT, LINE_COMMANDS),
                     "square", LINE_FINDINGS, "line")


ADAPTIVE_EVALUATIONS = (
    ("## The map's own swimmer steered by the paper's rule, on a sixth held-out set (controller `adaptive`, issue #23; "
     "measured 2026-12-03)", MODEL, (MODEL_DESIGN, MODEL_HELD_OUT, MODEL_COMMANDS), "square", MODEL_FINDINGS, "model"),
    ("## A cruise that matches the map confirms it, on a fifth held-out set (controller `adaptive`, issue #23; "
     "measured 2026-12-03)", CRUISE, (CRUISE_DESIGN, CRUISE_HELD_OUT, CRUISE_COMMANDS), "square", CRUISE_FINDINGS,
     "cruise"),
    ("## The hover restart on a fourth held-out set (controller `adaptive`, issue #23; measured 2026-12-03)", RESTART,
     (RESTART_DESIGN, RESTART_HELD_OUT, RESTART_COMMANDS), "square", RESTART_FINDINGS, "restart"),
    ("## A hover that no longer jumps its phase, and small bursts flown by time (controller `adaptive`, issue #23; "
     "measured 2026-12-03)", HOVER, (HOVER_DESIGN, HOVER_HELD_OUT, HOVER_COMMANDS), "square", HOVER_FINDINGS, "hover"),
    ("## The same planner on a second held-out set (controller `adaptive`, issue #23; measured 2026-12-03)",
     SOFTSWIM2, (SOFTSWIM2_DESIGN, SOFTSWIM2_HELD_OUT, SOFTSWIM2_COMMANDS), None, SOFTSWIM2_FINDINGS, "softswim2"),
    ("## The adaptive planner swimming on within the soft corridor (controller `adaptive`, issue #23; measured "
     "2026-12-03)", SOFTSWIM, (SOFTSWIM_DESIGN, SOFTSWIM_HELD_OUT, SOFTSWIM_COMMANDS), "square", SOFTSWIM_FINDINGS,
     "softswim"),
    ("## The adaptive planner on a finer turn map, bursts timed by the ratio clock (controller `adaptive`, issue #23; "
     "measured 2026-12-03)", CLOCK, (CLOCK_DESIGN, CLOCK_HELD_OUT, CLOCK_COMMANDS), "square", CLOCK_FINDINGS, "clock"),
    ("## The adaptive planner, turns scored by their spread (controller `adaptive`, issue #23; measured 2026-12-03)",
     ROBUST, (ROBUST_DESIGN, ROBUST_HELD_OUT, ROBUST_COMMANDS), "square", ROBUST_FINDINGS, "robust"),
)


HORIZON = Path("results/eval_horizon")
HORIZON_CONTROLLERS = ("rule", "adaptive", "horizon")
HORIZON_LEVELS = (*LEVELS, ("rand10_helix10", "E, μ, b within ±10 %, helix ±10 %"))
HORIZON_COMMANDS = """```
python scripts/make_eval_paths.py --out results/eval_horizon/paths --count 3 --seed0 9500
flagellum follow --path square --controller horizon --out results/eval_horizon/square_horizon
flagellum evaluate --paths results/eval_horizon/paths --controller rule --controller adaptive --controller horizon \\
    --seed0 9500 --workers 1 --out results/eval_horizon/nominal
flagellum evaluate ... --randomize 0.05 --seed0 9500 --out results/eval_horizon/rand05   # swimmers from seeds 9500-9505
flagellum evaluate ... --randomize 0.1 --seed0 9500 --out results/eval_horizon/rand10
flagellum evaluate ... --randomize 0.1 --randomize-geometry 0.1 --seed0 9500 --out results/eval_horizon/rand10_helix10
python scripts/report_evaluation.py results/eval_horizon/{nominal,rand05,rand10,rand10_helix10}   # tables, figures
```"""


def held_out_section(lines: list[str], title: str, root: Path, controllers: tuple[str, ...], judged: str,
                     texts: tuple[str, str, str], square: str | None, findings: str, figure_prefix: str) -> None:
    """One held-out evaluation: design, what was held out and the commands (``texts``), the tables and figures
    of each level under ``root`` (``agents.evaluation_report``), the paper's square (``root/square``'s
    summary.json, controller ``judged``; ``square`` None: not run for this set) and the targets of issue #23 for ``judged``."""
    from agents.evaluation_report import folder_report

    design, held_out, commands = texts
    lines += [title, "", design, "", "### What was held out, and the commands", "", held_out, "", commands, ""]
    found = {}
    for level, _ in HORIZON_LEVELS:
        folder = root / level
        if not (folder / "results.json").is_file():
            lines += [f"### {level}", "", "Not measured.", ""]
            continue
        found[level] = json.loads((folder / "results.json").read_text())
        present = [c for c in controllers if c in found[level]["aggregate"]]
        lines += folder_report(folder, DOCS / "figures", f"{figure_prefix}_{level}", present, link_from=DOCS)
    sq = None if square is None else root / square / "summary.json"
    lines += ["### The paper's square (nominal swimmer)", ""]
    if sq is None:
        lines += ["Not run for this set (the same episodes as in the next section).", ""]
    elif sq.is_file():
        for c, m in json.loads(sq.read_text())["controllers"].items():
            lines.append(f"- `{c}`: {'every corner made' if m['success'] else 'failed'}, mean cross-track "
                         f"{100 * m['mean_cross_track_m']:.2f} cm (max {100 * m['max_cross_track_m']:.2f} cm), Δz/ΔL "
                         f"{100 * m['max_out_of_plane_ratio']:.2f} % (R10: < 5 %), {m['time_s']:.0f} s simulated in "
                         f"{m['wall_time_s']:.0f} s wall, {m['buckling_events']} bursts.")
        lines.append("")
    else:
        lines += ["Not measured.", ""]
    lines += ["### Against the targets of issue #23", ""]
    for level, need in (("rand05", 0.9), ("rand10", 0.75)):
        res = found.get(level)
        if res is None:
            lines.append(f"- `{level}`: not measured.")
            continue
        agg = res["aggregate"]
        rates = ", ".join(f"{c} {100 * (agg[c]['success_rate'] or 0.0):.0f} %" for c in controllers if c in agg)
        rate = (agg.get(judged) or {}).get("success_rate") or 0.0
        errors = sum(1 for r in res["per_path"] if r.get("error"))
        lines.append(f"- `{level}`: success {rates}; target ≥ {100 * need:.0f} % — "
                     f"{'reached' if rate >= need else 'not reached'} by `{judged}`; episodes ending in an error: "
                     f"{errors}.")
    nominal = found.get("nominal")
    if nominal is not None and {"rule", judged} <= set(nominal["aggregate"]):
        r, h = nominal["aggregate"]["rule"], nominal["aggregate"][judged]
        lines.append(f"- nominal swimmer: success {100 * r['success_rate']:.0f} % (rule), {100 * h['success_rate']:.0f} "
                     f"% ({judged}); mean cross-track {100 * r['mean_cross_track_m']:.2f} cm (rule), "
                     f"{100 * h['mean_cross_track_m']:.2f} cm ({judged}).")
        planar = [x["max_out_of_plane_ratio"] for x in nominal["per_path"]
                  if x["controller"] == judged and x.get("max_out_of_plane_ratio") is not None]
        if planar:
            lines.append(f"- max Δz/ΔL on the planar held-out paths, nominal swimmer, `{judged}`: "
                         f"{100 * max(planar):.1f} %.")
    lines += ["", findings, ""]


def horizon_section(lines: list[str]) -> None:
    """The receding-horizon planner on the held-out set of issue #23, 2026-12-02."""
    held_out_section(lines, "## The receding-horizon planner (controller `horizon`, issue #23; measured 2026-12-02)",
                     HORIZON, HORIZON_CONTROLLERS, "horizon", (HORIZON_DESIGN, HORIZON_HELD_OUT, HORIZON_COMMANDS),
                     "square_horizon", HORIZON_SQUARE_NOTE + "\n\n" + HORIZON_FINDINGS, "horizon")


HORIZON_SQUARE_NOTE = """On the square, the same day's runs of the other planners with the same solvers (10:55 UTC): rule
0.74 cm (max 2.35 cm, Δz/ΔL 4.8 %), adaptive 0.56 cm (max 2.26 cm, 4.1 %); the README's later run (15:01
UTC, after the afternoon's solver changes): rule 0.76 cm, adaptive 0.57 cm."""


HORIZON_DESIGN = """`agents/horizon_planner.py`. At each decision it searches sequences of two *moves*, each a
cruise at 10 rpm for d ∈ {0, 0.5, 1.5, 3, 5} cm and then a burst planned for map time m (every 0.2 s
of the rising branch, ≥ 5°) at flagellum phase β (every 10°; the second move: d ∈ {0, 2} cm, 6 map
times, every 30°). The head path each sequence predicts (cruises, the map's offset of each turn, then
the straight line of the last heading) is scored by: its closest approach to the next waypoint and,
once that is passed within the reach radius, to the one after (weight 0.3); the largest distance from
the path (0.5 per m) and the 10 cm corridor (soft from 7 cm); on planar segments the largest |z| and
the last heading's slope; 1.5 cm per burst and 0.1 per m of cruise. The predictions come from the
adaptive planner's online map (buckling-time shift, ratio-turn bias, direction offset; bursts flown by
L'/L), and its uncertainty is *used*: each first move is predicted at five sigma points of (map-time
error, direction error) — the map read over its whole measured range, so a sample past the branch's
peak predicts the tumble there — the best second move is chosen for each sampled outcome (closed
loop), and the move's score is the mean over the samples plus their standard deviation. The direction
spread is learnt from the azimuth errors of the turns seen (prior 20°). There is no 80° cap: a large
turn near the peak loses to smaller ones while its outcome is uncertain. If the best sequence starts
with a cruise, the planner cruises and searches again 5 s later; if it starts with a burst, the burst
is flown as the adaptive planner flies it, observed, and the correction updated. A search costs
~50 ms of CPU (NumPy), a few per turn; per episode 1-6 s against 20-70 s of simulation."""

HORIZON_HELD_OUT = """Development used paths from `python scripts/make_eval_paths.py --count 3 --seed0 5000`
(not committed) with swimmers from env seeds 5000-5005 (E, μ, b ±10 %, `fast` preset), and the nominal
square at the default preset. The final numbers below are on paths drawn with seeds 9500-9502
(planar and 3-D, three waypoints, segments 12-20 cm, turns 30-150°, reach radius 1.5 cm) and
swimmers from env seeds 9500-9505 (the k-th path sorted by name gets seed 9500 + k), preset
`faithful`, one worker; all three controllers keep the nominal turn map. The controller evaluated is
commit 8182c07. A first start of this run with the commit before it (052702e) was stopped after the
square and one rule episode at ±5 % (deleted unread); the square (the paper's path, not part of the
held-out set) had shown loose corners, which led to 8182c07 (the path-distance term, cruise options
up to 5 cm, the bias prior at 0.15 s). Nothing was changed after the held-out results were seen."""

HORIZON_FINDINGS = """**Verdict: `horizon` does not beat `adaptive` on swimmers that differ from the map, so the defaults
stay as they were** (`make demo`: rule and adaptive; `flagellum follow`: rule; the rule planner the
paper's baseline). On the held-out swimmers it made 3/6 paths at ±5 % (adaptive 4/6, rule 1/6; it
made 3d_9500, where the adaptive planner did not, and lost planar_9500 and planar_9502) and
1/6 at ±10 % (adaptive 5/6, rule 1/6): neither target (≥ 90 %, ≥ 75 %) is reached by any controller
at ±5 %, and at ±10 % only `adaptive` reaches it (83 %). On the nominal swimmer it made 6/6 like the
rule planner, where `adaptive` made 4/6 (planar_9500 and planar_9502: 20 and 17 bursts circling a
waypoint), but with a larger mean cross-track (1.24 cm against the rule planner's 0.69 cm): the
issue's nominal target (≤ rule's) is not met. On the paper's square it meets R10 (Δz/ΔL 3.5 %
< 5 %, rule 4.8 %, adaptive 4.1 %) but corners loosely (0.76 cm mean, a 6 cm overshoot at the second
corner, where a 5° burst was used as a way of waiting before the 80° turn). No episode ended in a
`SimulationError`.

What fails, from the head paths above and the burst lengths in the traces (s at 150 rpm):

1. **Larger turns than the map predicts for a swimmer off it.** Without the 80° cap the search
   flies bursts of 7.4-7.9 s (90-150° on the map) whenever its sigma points say the outcome is
   tight, and with the ratio-turn bias prior at 0.15 s (`HORIZON_ONLINE`, chosen on the nominal
   square and three dev swimmers) they say so from the first turn. On the randomised swimmers the
   direction and offset of such turns moved more than a timing error and one global direction
   offset describe: on the planar paths the head left the plane by 4-7 cm (adaptive ≤ 2.6 cm),
   Δz/ΔL up to 40 %, and the 10 cm corridor ended the episode (planar_9500 and planar_9502 at
   ±5 % and ±10 %, planar_9501 at ±10 %). The earlier measurement above (turns of 94° and more came
   out 35-180° off the map's direction) said as much; the spread model here knows only the timing.
2. **A target behind at the start** (3d_9502 at ±5 % and ±10 %): two bursts of 6.4-7.2 s, then out
   of the corridor after ~190 s; the adaptive planner made it at ±10 % with eight bursts of ≤ 5.8 s.
3. **Circling is not gone**: 3d_9500 at ±10 %: 27 bursts to the time limit, most of them 9.8 s (the
   longest allowed; the ratio target never came: the swimmer buckles later than even the corrected
   map says), i.e. flown past the branch's peak.
4. On the nominal swimmer, the cost of looking at the waypoint after the next: corners are cut
   early and loosely (max cross-track 4.6 cm on average against the rule planner's 2.4 cm).

What would come next (not done): a spread model that is swimmer-specific for large turns (learn the
direction and offset error against the turn's size, or keep a cap set by the spread as the adaptive
planner's t_peak - 2σ does) with the prior bias spread back at 0.3 s; the head's excursion *during*
a burst (not only at its end) counted against the plane and the corridor; the offset's error among
the sigma points; and a longer development set (the three dev paths at `fast` were too few to see
failure 1). The search itself is cheap (0.6-6 s of CPU per episode against 20-160 s of simulation)
and its machinery (closed-loop two-move search, sigma points, corridor and planar terms, `--seed0`,
the report script) can carry such a model. With the helix within ±10 % as well (`rand10_helix10`, same
paths and swimmer seeds): rule 0/6, adaptive 2/6, horizon 1/6, no `SimulationError`."""


def main() -> None:
    lines = ["# Steering a swimmer that differs from the model", "",
             "Produced by `python scripts/robust_steering_report.py` from the files listed in its docstring. Design: "
             "`agents/online_turn_map.py` (the correction), `agents/adaptive_planner.py` (the planner that uses it, "
             "controller `adaptive`), `agents/horizon_planner.py` (the receding-horizon planner over it, controller "
             "`horizon`).", ""]
    line_section(lines)
    for title, root, texts, square, findings, prefix in ADAPTIVE_EVALUATIONS:
        held_out_section(lines, title, root, ("rule", "adaptive"), "adaptive", texts, square, findings, prefix)
    horizon_section(lines)
    sensitivity_section(lines)
    lines += [METHOD]
    found = evaluation_section(lines)
    targets_section(found, lines)
    lines += [LIMITS]
    (DOCS / "robust_steering.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {DOCS / 'robust_steering.md'}")


if __name__ == "__main__":
    main()
