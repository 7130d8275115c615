"""``flagellum calibrate-turns``: measure the turn map (t_c x burst phase) in parallel, resumably.

Every (t_c, phase) pair is one task of the shared task pool (``batch.pool``): it
starts from the environment's steady start (``flagellum_env.steady_start``: 5 motor turns at
omega_l from rest, cached), runs ``agents.turn_measurement.measure_turn`` and returns one JSON record.
Records go to ``<out>.runs/results.jsonl`` as they finish; running again with ``resume=True``
measures only what is missing. When all are done, the map is written to ``<out>`` (JSON).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from batch.provenance import git_commit
from agents.turn_map import DEFAULT_PHASES_DEG, DEFAULT_T_C_S, PAPER_OMEGA_L_RPM, PLANNER_OMEGA_H_RPM, TurnMap
from batch.store import ResultsStore, check_records_belong, check_same_run
from batch.worker import PointOutcome
from batch.pool import pending, run_tasks
from agents.turn_measurement import TurnResult, phase_node_index
from physics.model.geometry import layout_for
from physics.params import RPM_TO_RAD_S, NumericsConfig, SwimmerParams

class TurnsNotMeasured(RuntimeError):
    """Some turns of the grid could not be measured (the message names the first and what to do)."""


#: Steady start: motor turns at omega_l from rest (the environment's SETTLE_TURNS).
SETTLE_TURNS = 5


@dataclass(frozen=True)
class TurnTask:
    """One calibration turn (picklable; ``execute`` runs in a worker process)."""

    params: SwimmerParams
    numerics: NumericsConfig
    omega_l_rpm: float
    omega_h_rpm: float
    t_c: float
    phase_deg: float
    relax_max_s: float = 150.0

    @property
    def point_id(self) -> str:
        payload = json.dumps({"p": dataclasses.asdict(self.params), "n": dataclasses.asdict(self.numerics),
                              "wl": self.omega_l_rpm, "wh": self.omega_h_rpm, "tc": self.t_c,
                              "ph": self.phase_deg, "rm": self.relax_max_s}, sort_keys=True)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    def label(self) -> str:
        return f"t_c={self.t_c:g} s, phase={self.phase_deg:g} deg"

    def execute(self) -> PointOutcome:
        from agents.turn_measurement import measure_turn
        from flagellum_env.steady_start import get_steady_start

        t0 = time.perf_counter()
        record: dict[str, Any] = {"point_id": self.point_id, "values": {"t_c": self.t_c, "phase_deg": self.phase_deg},
                                  "status": "ok", "error": None, "result": None}
        try:
            start = get_steady_start(self.params, self.numerics, self.omega_l_rpm * RPM_TO_RAD_S,
                                     SETTLE_TURNS * 60.0 / self.omega_l_rpm)
            sim = start.new_simulator()
            res = measure_turn(sim, self.omega_l_rpm, self.omega_h_rpm, self.t_c, self.phase_deg,
                               relax_max_s=self.relax_max_s)
            record["result"] = dataclasses.asdict(res)
            record["sim_time_s"] = sim.time - start.state.get("time", 0.0)
        except Exception as exc:  # a failed turn is recorded, not raised
            record["status"], record["error"] = "error", f"{type(exc).__name__}: {exc}"
        record["wall_time_s"] = time.perf_counter() - t0
        record["finished_at"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
        return PointOutcome(record, None)


def calibration_tasks(params: SwimmerParams, numerics: NumericsConfig, omega_l_rpm: float = PAPER_OMEGA_L_RPM,
                      omega_h_rpm: float = PLANNER_OMEGA_H_RPM, t_c_values: Sequence[float] = DEFAULT_T_C_S,
                      phases_deg: Sequence[float] = DEFAULT_PHASES_DEG) -> list[TurnTask]:
    """The (t_c, phase) grid; ValueError naming a bad value."""
    if not 0.0 < omega_l_rpm < omega_h_rpm:
        raise ValueError(f"omega_l_rpm={omega_l_rpm!r} and omega_h_rpm={omega_h_rpm!r} must satisfy "
                         "0 < omega_l < omega_h (rpm)")
    if not t_c_values or any(not (0.0 < t <= 600.0) for t in t_c_values):
        raise ValueError(f"t_c values {list(t_c_values)!r} must be burst lengths in (0, 600] s")
    if not phases_deg or any(not (0.0 <= p < 360.0) for p in phases_deg):
        raise ValueError(f"phases {list(phases_deg)!r} must be in [0, 360) degrees")
    return [TurnTask(params, numerics, float(omega_l_rpm), float(omega_h_rpm), float(tc), float(ph))
            for tc in sorted(set(t_c_values)) for ph in sorted(set(phases_deg))]


#: In the runs folder: the settings of the calibration it holds (checked by ``resume=True``).
RUN_FILE = "calibration.json"


def _write_run_file(file: Path, identity: dict[str, Any]) -> None:
    tmp = file.with_name(file.name + ".tmp")
    tmp.write_text(json.dumps({"run": identity}, indent=1, default=str) + "\n", encoding="utf-8")
    os.replace(tmp, file)


def runs_dir(out_file: str | os.PathLike[str]) -> Path:
    """Where the per-turn records of ``out_file`` live: ``<out_file>.runs/``."""
    out = Path(out_file)
    return out.with_name(out.name + ".runs")


def calibrate_turns(params: SwimmerParams, numerics: NumericsConfig, out_file: str | os.PathLike[str],
                    preset: str | None = None, omega_l_rpm: float = PAPER_OMEGA_L_RPM,
                    omega_h_rpm: float = PLANNER_OMEGA_H_RPM, t_c_values: Sequence[float] = DEFAULT_T_C_S,
                    phases_deg: Sequence[float] = DEFAULT_PHASES_DEG, workers: int | None = None,
                    resume: bool = False, progress: bool = True, scheduler: Any | None = None) -> TurnMap:
    """Measure every turn of the grid (parallel, resumable) and write the map to ``out_file``.

    Raises ``TurnsNotMeasured`` naming the failed turns (their errors are in the runs folder) when a
    turn could not be measured; the others stay saved for ``resume=True``.
    """
    tasks = calibration_tasks(params, numerics, omega_l_rpm, omega_h_rpm, t_c_values, phases_deg)
    if Path(out_file).is_dir():
        raise ValueError(f"out_file={str(out_file)!r} is a folder; allowed: a turn-map file to write (.json)")
    identity = {"preset": preset, "params": dataclasses.asdict(params), "numerics": dataclasses.asdict(numerics),
                "omega_l_rpm": float(omega_l_rpm), "omega_h_rpm": float(omega_h_rpm),
                "t_c_values": sorted({t.t_c for t in tasks}), "phases_deg": sorted({t.phase_deg for t in tasks}),
                "relax_max_s": tasks[0].relax_max_s}
    t0 = time.perf_counter()
    with ResultsStore(runs_dir(out_file), resume) as store:
        if resume:  # the runs folder must hold turns of this calibration only (no mixing of two swimmers)
            check_same_run(store.out_dir, RUN_FILE, identity, "calibration")
            check_records_belong(store.records, {t.point_id for t in tasks}, store.out_dir, "calibration")
        _write_run_file(store.out_dir / RUN_FILE, identity)
        todo = pending(tasks, store, retry_failed=True)
        lost = run_tasks(todo, store, workers=workers, scheduler=scheduler, progress=progress, total=len(tasks),
                         desc="calibrate-turns")
        records = [store.records.get(t.point_id) for t in tasks]
    bad = [(t, r) for t, r in zip(tasks, records, strict=True) if r is None or r["status"] != "ok"]
    if lost or bad:
        first = bad[0] if bad else (lost[0][0], {"error": lost[0][1]})
        error = " ".join(str((first[1] or {}).get("error") or "not run").split())
        if len(error) > 300:
            error = error[:300] + "..."
        interrupted = not bad or all(r is None for _, r in bad)
        advice = ("run again with --resume to measure the rest" if interrupted else
                  "a turn whose simulation failed fails again on --resume: leave its burst length out of --t-c "
                  "(or change --omega-h, --preset or --set); --resume keeps the measured ones")
        raise TurnsNotMeasured(f"{len(bad)} of {len(tasks)} turns were not measured (first: {first[0].label()}: "
                               f"{error}); the others are saved in {runs_dir(out_file)}; {advice}")
    points = tuple(TurnResult(**{**r["result"], "offset_m": tuple(r["result"]["offset_m"])}) for r in records)
    meta = {"created": datetime.now(timezone.utc).isoformat(timespec="seconds"), "commit": git_commit(),
            "wall_time_s_this_run": round(time.perf_counter() - t0, 1),
            "wall_time_s_all_turns": round(sum(r["wall_time_s"] for r in records), 1),
            "sim_time_s_all_turns": round(sum(r.get("sim_time_s", 0.0) for r in records), 1)}
    tmap = TurnMap(params=params, numerics=numerics, preset=preset, omega_l_rpm=float(omega_l_rpm),
                   omega_h_rpm=float(omega_h_rpm), phase_node=phase_node_index(layout_for(params).n),
                   points=points, meta=meta)
    tmap.save(out_file)
    return tmap
