"""The runs that validate the swimmer against Huang & Jawed 2020 (rows R1-R9, R11 of paper_targets.md,
Fig. 4(c)-(f) and Fig. 5(d)), under every reading of the head, planned so that they run in parallel and
resume (``batch.pool.run_tasks``: local workers or a Dask cluster).

Readings (``READINGS``; the head's rotation and its hydrodynamics, Sec. 2.4):

* ``fixed`` (the default swimmer): the head does not spin, the flagellum base turns at omega in the lab frame,
  reciprocal head flow forms (``physics.hydro.higdon_head``);
* ``torque_free``: the head spins per the torque balance, eqn (13), omega relative to the head, reciprocal forms;
* ``paper``: as ``fixed``, with the head flow and force of eqns (10)-(11) as printed;
* ``stokes_head``: as ``fixed``, with the head's own Stokes drag (eqn 12) and no head-flagellum flow
  coupling (eqns 10-11 left out);
* ``literal``: the text read literally with omega the flagellum's lab rate: theta^0 = omega t in the lab frame, the
  head spinning at the rate of eqn (13), its rotlet (eqn 10) acting on the flagellum.

Runs (``ValidationRun``):

* a *point*: 100 s (t_bar = 1.02) from rest at a constant motor speed; L'/L, ||s||, the motor torque
  averaged over the second half, the distance per motor turn over the last five turns, smallest gaps,
  largest Reynolds number, final shape (Fig. 4);
* a *turn*: the paper's protocol of Fig. 5(d): steady 10 rpm for 60 s, a burst of t_c at 60 rpm started
  at a chosen rotation phase, 10 rpm until the heading settles (``agents.turn_measurement``).

``ValidationPlan.pending`` says which runs are needed given the records so far: the Fig. 4 grid
(``GRID_RPM`` for every head and reading; the headless swimmer once, all readings being the same swimmer
without a head), omega_b bisected on L'/L(100 s) < 0.98 to a bracket of ``BRACKET_RPM``, the Fig. 5(d)
turns (``TURN_TC_BAR`` x ``TURN_PHASES_DEG``), then the convergence runs at ``tight_step_tol`` (the final
omega_b bracket ends, R8's point and R9's largest turn) and, with ``check_preset``, the points of those at
another preset (e.g. ``paper``, the fixed 1 ms step).
"""

from __future__ import annotations

import math
import os
import socket
import time
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

from batch.worker import PointOutcome

#: reading -> the SwimmerParams / NumericsConfig fields that make it
READINGS: dict[str, dict[str, str]] = {
    "torque_free": {"head_rotation": "torque_free", "head_model": "higdon"},
    "fixed": {"head_rotation": "fixed", "head_model": "higdon"},
    "paper": {"head_rotation": "paper", "head_model": "higdon"},
    "stokes_head": {"head_rotation": "fixed", "head_model": "stokes"},
    "literal": {"head_rotation": "literal", "head_model": "higdon"},
}
READING_TEXT: dict[str, str] = {
    "torque_free": "torque-free head spinning per eqn (13), omega relative to the head, reciprocal head forms",
    "fixed": "head not spinning, flagellum base at omega in the lab frame, reciprocal head forms",
    "paper": "head not spinning, base at omega in the lab frame, eqns (10)-(11) as printed",
    "stokes_head": "head not spinning, base at omega in the lab frame, the head's own Stokes drag (eqn 12) "
                   "without the head-flagellum coupling of eqns (10)-(11)",
    "literal": "base at omega in the lab frame, the head spinning per eqn (13) and its rotlet (eqn 10) acting on the "
               "flagellum, reciprocal head forms",
}
#: the headless swimmer is the same under every reading: its runs are stored under this name
NO_HEAD = "no_head"
HEADS_M = (0.0, 0.004, 0.008, 0.012)
#: Fig. 4 speeds, rpm (19 across the paper's 0-100 rpm axis)
GRID_RPM = tuple(float(w) for w in range(10, 101, 5))
#: probed in turn when nothing buckles up to 100 rpm (a head that raises omega_b)
BEYOND_RPM = (150.0, 240.0)
BRACKET_RPM = 2.0  # omega_b to +-1 rpm
BUCKLED_RATIO = 0.98
DURATION_S = 100.0
LOW_RPM, HIGH_RPM = 10.0, 60.0  # Fig. 5(d): omega_l, omega_h
SETTLE_S = 60.0
#: Fig. 5(d): burst lengths in t_bar = t EI / (mu L^4) (12 across 0 < t_bar_c <= 0.6) and start phases
TURN_TC_BAR = tuple(round(0.05 * k, 2) for k in range(1, 13))
TURN_PHASES_DEG = (0.0, 90.0, 180.0, 270.0)


def run_reading(reading: str, head_radius: float) -> str:
    """The reading a run is stored under: ``NO_HEAD`` without a head (every reading is the same swimmer)."""
    return NO_HEAD if head_radius == 0.0 else reading


@dataclass(frozen=True)
class ValidationRun:
    """One validation run (picklable; ``batch.pool`` task). ``kind`` "point": ``value`` is the motor speed,
    rpm; "turn": ``value`` is t_c, s, and ``phase_deg`` the hover before the burst (fraction of one rotation).
    ``preset`` and ``step_tol`` (None: the preset's) set the numerics; ``reading`` one of ``READINGS`` or
    ``NO_HEAD``."""

    kind: str
    reading: str
    head_radius: float
    value: float
    phase_deg: float = 0.0
    preset: str = "faithful"
    step_tol: float | None = None

    @property
    def point_id(self) -> str:
        tol = "" if self.step_tol is None else f"|tol{self.step_tol:g}"
        phase = f"|ph{self.phase_deg:g}" if self.kind == "turn" else ""
        return f"{self.kind}|{self.reading}|b{self.head_radius:.4f}|{self.value:.4f}{phase}|{self.preset}{tol}"

    def label(self) -> str:
        what = f"{self.value:g} rpm" if self.kind == "point" else f"t_c {self.value:.1f} s, phase {self.phase_deg:g}°"
        return f"{self.reading} b={100 * self.head_radius:g} cm {what}"

    def configuration(self) -> tuple[Any, Any]:
        from physics.presets import configure

        fields = READINGS["torque_free" if self.reading == NO_HEAD else self.reading]
        overrides: dict[str, Any] = {"head_radius": self.head_radius, **fields}
        if self.step_tol is not None:
            overrides["step_tol"] = self.step_tol
        return configure(self.preset, overrides)

    def execute(self) -> PointOutcome:
        t0 = time.perf_counter()
        record: dict[str, Any] = {"point_id": self.point_id, "kind": self.kind, "reading": self.reading,
                                  "head_radius": self.head_radius, "value": self.value, "phase_deg": self.phase_deg,
                                  "preset": self.preset, "step_tol": self.step_tol}
        record.update(run_point(self) if self.kind == "point" else run_turn(self))
        record.update({"status": "ok" if record.get("error") is None else "error",
                       "wall_time_s": time.perf_counter() - t0, "worker": f"{socket.gethostname()}:{os.getpid()}",
                       "load_avg": os.getloadavg()[0],
                       "finished_at": datetime.now(timezone.utc).isoformat(timespec="seconds")})
        return PointOutcome(record, None)


#: sampling interval of a point's torque, Reynolds number and gaps, s
SAMPLE_S = 0.25


def run_point(run: ValidationRun) -> dict[str, Any]:
    """100 s from rest at ``run.value`` rpm: L'/L, ||s||, mean torque over the second half (N m), distance per
    motor turn over the last five turns (m), smallest gaps (mm), largest Reynolds number, final nodes (m)."""
    import numpy as np

    from physics.errors import SimulationError
    from physics.params import RPM_TO_RAD_S
    from physics.simulator import Simulator

    p, n = run.configuration()
    sim = Simulator(p, n)
    omega = run.value * RPM_TO_RAD_S
    sim.set_motor_speed(omega)
    turns_avg = 5
    t_avg0 = DURATION_S - turns_avg * 60.0 / run.value
    samples = int(round(DURATION_S / SAMPLE_S))
    torque, re_max, g_rr, g_h = [], 0.0, math.inf, math.inf
    x_avg0, error = None, None
    cpu0 = time.process_time()
    try:
        for k in range(samples):
            t_next = (k + 1) * SAMPLE_S
            if x_avg0 is None and t_next > t_avg0:  # stop exactly at the start of the last five turns
                sim.advance(max(0.0, t_avg0 - sim.time))
                x_avg0 = sim.head_position
            sim.advance(max(0.0, t_next - sim.time))
            re_max = max(re_max, sim.reynolds_number())
            if sim.time > 0.5 * DURATION_S:
                torque.append(sim.motor_torque)
            a, c = sim.min_gaps()
            g_rr, g_h = min(g_rr, a), min(g_h, c)
    except SimulationError as exc:
        error = str(exc)
    cpu = time.process_time() - cpu0
    x = sim.nodes
    b = run.head_radius
    inside = int((np.linalg.norm(x[2:] - x[0], axis=1) < b).sum()) if b > 0 else 0
    per_turn = (float(np.linalg.norm(sim.head_position - x_avg0)) / turns_avg
                if x_avg0 is not None and error is None else None)
    return {"omega_rpm": run.value, "omega_bar": p.omega_bar(omega), "end_to_end_ratio": sim.end_to_end_ratio(),
            "displacement_m": sim.displacement(), "mean_motor_torque_Nm": float(np.mean(torque)) if torque else None,
            "distance_per_turn_m": per_turn, "max_reynolds": re_max, "min_rod_rod_gap_mm": g_rr * 1e3,
            "min_head_gap_mm": g_h * 1e3 if b > 0 else None, "nodes_inside_head_at_end": inside, "error": error,
            "simulated_s": sim.time, "cpu_s": cpu, "final_nodes": x.tolist()}


def run_turn(run: ValidationRun) -> dict[str, Any]:
    """Fig. 5(d): steady ``LOW_RPM`` for ``SETTLE_S``, a burst of ``run.value`` s at ``HIGH_RPM`` after a hover of
    ``run.phase_deg`` of a rotation, then ``LOW_RPM`` until the heading settles: theta, phi (deg)."""
    from agents.turn_measurement import measure_turn
    from physics.errors import SimulationError
    from physics.params import RPM_TO_RAD_S
    from physics.simulator import Simulator

    p, n = run.configuration()
    sim = Simulator(p, n)
    sim.set_motor_speed(LOW_RPM * RPM_TO_RAD_S)
    cpu0 = time.process_time()
    out: dict[str, Any] = {"t_c_s": run.value, "t_bar_c": p.t_bar(run.value)}
    try:
        sim.advance(SETTLE_S)
        r = measure_turn(sim, LOW_RPM, HIGH_RPM, run.value, phase_deg=run.phase_deg)
        out.update({"theta_deg": r.theta_deg, "phi_deg": r.phi_deg, "straight": r.straight,
                    "burst_end_ratio": r.burst_end_ratio, "relax_s": r.relax_s, "error": None})
    except SimulationError as exc:
        out.update({"theta_deg": None, "phi_deg": None, "straight": False, "error": str(exc)})
    out["cpu_s"] = time.process_time() - cpu0
    return out


def t_c_of(t_bar: float) -> float:
    """Burst length in s for a nondimensional t_bar = t EI / (mu L^4) of the paper's swimmer."""
    from physics.params import SwimmerParams

    p = SwimmerParams()
    return round(t_bar * p.viscosity * p.axial_length ** 4 / p.bending_stiffness, 2)


def is_buckled(record: Mapping[str, Any]) -> bool:
    """A point counts as buckled when it failed or ends with L'/L(100 s) < ``BUCKLED_RATIO``."""
    return record.get("error") is not None or record["end_to_end_ratio"] < BUCKLED_RATIO


@dataclass(frozen=True)
class ValidationPlan:
    """Which runs a validation needs (``pending``) given those done (``records`` by point id)."""

    readings: tuple[str, ...] = tuple(READINGS)
    preset: str = "faithful"
    tight_step_tol: float | None = 1e-5
    check_preset: str | None = None

    def __post_init__(self) -> None:
        bad = [r for r in self.readings if r not in READINGS]
        if bad or not self.readings:
            raise ValueError(f"readings={list(self.readings)!r} is not allowed; allowed: a non-empty subset of "
                             f"{', '.join(READINGS)}")

    def identity(self) -> dict[str, Any]:
        """What makes a validation folder this run's (``batch.store.check_same_run``). The convergence checks
        (``tight_step_tol``, ``check_preset``) only add runs, named by their numerics: not part of it."""
        return {"readings": list(self.readings), "preset": self.preset,
                "grid_rpm": list(GRID_RPM), "beyond_rpm": list(BEYOND_RPM),
                "turn_tc_bar": list(TURN_TC_BAR), "turn_phases_deg": list(TURN_PHASES_DEG),
                "duration_s": DURATION_S, "bracket_rpm": BRACKET_RPM, "buckled_ratio": BUCKLED_RATIO}

    def point_readings(self) -> list[tuple[str, float]]:
        """(stored reading, head radius) of every Fig. 4 series: the headless swimmer once, then each head."""
        return [(NO_HEAD, 0.0)] + [(r, b) for r in self.readings for b in HEADS_M if b > 0.0]

    def points(self, records: Mapping[str, dict], reading: str, b: float, preset: str | None = None,
               step_tol: float | None = None) -> list[dict]:
        preset = preset or self.preset
        out = [r for r in records.values() if r["kind"] == "point" and r["reading"] == run_reading(reading, b)
               and abs(r["head_radius"] - b) < 1e-9 and r["preset"] == preset and r["step_tol"] == step_tol]
        return sorted(out, key=lambda r: r["value"])

    def bracket(self, records: Mapping[str, dict], reading: str, b: float) -> tuple[float | None, float | None]:
        """(fastest unbuckled speed below the slowest buckled one, slowest buckled speed), rpm; None where unknown."""
        pts = self.points(records, reading, b)
        hi = min((r["value"] for r in pts if is_buckled(r)), default=None)
        lo = max((r["value"] for r in pts if not is_buckled(r) and (hi is None or r["value"] < hi)), default=None)
        return lo, hi

    def turns(self, records: Mapping[str, dict], reading: str, preset: str | None = None,
              step_tol: float | None = None) -> list[dict]:
        preset = preset or self.preset
        out = [r for r in records.values() if r["kind"] == "turn" and r["reading"] == reading
               and r["preset"] == preset and r["step_tol"] == step_tol]
        return sorted(out, key=lambda r: (r["value"], r["phase_deg"]))

    def largest_turn_tc(self, records: Mapping[str, dict], reading: str) -> float | None:
        """The t_c (s) whose phase-mean theta is largest (None until every Fig. 5(d) turn of ``reading`` is done)."""
        turns = [r for r in self.turns(records, reading) if r["theta_deg"] is not None]
        if len(self.turns(records, reading)) < len(TURN_TC_BAR) * len(TURN_PHASES_DEG):
            return None
        by_tc: dict[float, list[float]] = {}
        for r in turns:
            by_tc.setdefault(r["value"], []).append(r["theta_deg"])
        return max(by_tc, key=lambda tc: sum(by_tc[tc]) / len(by_tc[tc]), default=None)

    def pending(self, records: Mapping[str, dict]) -> list[ValidationRun]:
        """The runs whose inputs are known and that have no record yet, most needed first: the Fig. 4 grid, the
        omega_b bisection steps, the Fig. 5(d) turns, the convergence runs, the check at ``check_preset``."""
        grid, bisect, turns, tight = [], [], [], []
        for reading, b in self.point_readings():
            have = {r["value"] for r in self.points(records, reading, b)}
            missing = [w for w in GRID_RPM if w not in have]
            grid += [ValidationRun("point", reading, b, w, preset=self.preset) for w in missing]
            if missing:
                continue
            nxt = self._next_speed(records, reading, b)
            if nxt is not None:
                bisect.append(ValidationRun("point", reading, b, nxt, preset=self.preset))
        for reading in self.readings:
            for tcb in TURN_TC_BAR:
                for ph in TURN_PHASES_DEG:
                    turns.append(ValidationRun("turn", reading, 0.012, t_c_of(tcb), ph, preset=self.preset))
        checks = [(self.preset, self.tight_step_tol, True)] if self.tight_step_tol is not None else []
        if self.check_preset is not None:
            checks.append((self.check_preset, None, False))  # points only: a turn at 1 ms steps costs ~4 CPU-min
        for preset, tol, with_turns in checks:
            for reading in self.readings:
                lo, hi = self.bracket(records, reading, 0.012)
                if lo is not None and hi is not None and hi - lo <= BRACKET_RPM:
                    tight += [ValidationRun("point", reading, 0.012, w, preset=preset, step_tol=tol)
                              for w in sorted({LOW_RPM, lo, hi})]
                tc = self.largest_turn_tc(records, reading)
                if tc is not None and with_turns:
                    tight += [ValidationRun("turn", reading, 0.012, tc, ph, preset=preset, step_tol=tol)
                              for ph in TURN_PHASES_DEG]
        return [run for run in grid + bisect + turns + tight if run.point_id not in records]

    def _next_speed(self, records: Mapping[str, dict], reading: str, b: float) -> float | None:
        """The next omega_b bisection speed (rpm), or None when the bracket is narrow enough (or nothing buckles
        up to the last of ``BEYOND_RPM``)."""
        lo, hi = self.bracket(records, reading, b)
        if lo is None:
            return None  # buckled at the slowest grid speed: omega_b is below the grid (reported as such)
        if hi is None:
            return next((w for w in BEYOND_RPM if w > lo), None)
        if hi - lo <= BRACKET_RPM:
            return None
        return round(0.5 * (lo + hi), 3)


RUN_FILE = "validation_run.json"


def _extends(file: Any, identity: dict[str, Any]) -> bool:
    """Is ``identity`` the run stored in ``file`` with readings added (the folder's runs are this plan's runs too, and
    it is resumed with the new readings' runs to do)?"""
    import json

    try:
        old = json.loads(file.read_text(encoding="utf-8"))["run"]
    except (OSError, ValueError, KeyError, TypeError):
        return False
    new = json.loads(json.dumps(identity))
    if not isinstance(old, dict) or set(old) != set(new):
        return False
    same_rest = all(old[k] == new[k] for k in new if k != "readings")
    return same_rest and set(old["readings"]) < set(new["readings"])


def run_validation(out_dir: str | os.PathLike[str], plan: ValidationPlan, workers: int | None = None,
                   scheduler: Any | None = None, progress: bool = True) -> dict[str, dict]:
    """Run ``plan`` into ``out_dir`` (``results.jsonl``, one line per finished run), round after round until
    nothing is pending; resumes what the folder holds and refuses (``SweepError``) a folder of another plan.
    Ctrl-C raises ``batch.pool.TasksInterrupted`` with every finished run saved. Returns the records by id."""
    import json
    from pathlib import Path

    from batch.pool import run_tasks
    from batch.store import ResultsStore, SweepError, check_same_run

    out = Path(out_dir)
    if not _extends(out / RUN_FILE, plan.identity()):
        check_same_run(out, RUN_FILE, plan.identity(), "validation")
    with ResultsStore(out, resume=True) as store:
        (out / RUN_FILE).write_text(json.dumps({"run": plan.identity()}, indent=1) + "\n")
        rounds = 0
        while True:
            todo = plan.pending(store.records)
            if not todo:
                return dict(store.records)
            rounds += 1
            failed = run_tasks(todo, store, workers=workers, scheduler=scheduler, progress=progress,
                               desc=f"validation round {rounds}")
            if failed:
                task, why = failed[0]
                raise SweepError(f"{len(failed)} validation run(s) did not finish (e.g. {task.label()}: {why}); "
                                 "run again to resume")
