"""flagellum_bench.paper_validation (scripts/validate_readings.py): the plan of the validation runs (grid,
omega_b bisection, Fig. 5(d) turns, convergence runs), the folder check, and the report's arithmetic
(scripts/validation_report.py) on synthetic records."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

from batch.store import SweepError
from flagellum_bench.paper_validation import (BEYOND_RPM, GRID_RPM, HEADS_M, NO_HEAD, READINGS, RUN_FILE,
                                              TURN_PHASES_DEG, TURN_TC_BAR, ValidationPlan, ValidationRun,
                                              run_validation, t_c_of)

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


def _point(reading, b, rpm, ratio, disp=0.05, torque=1e-4, per_turn=0.004, preset="faithful", step_tol=None):
    run = ValidationRun("point", reading if b > 0 else NO_HEAD, b, rpm, preset=preset, step_tol=step_tol)
    return run.point_id, {"point_id": run.point_id, "kind": "point", "reading": run.reading, "head_radius": b,
                          "value": rpm, "phase_deg": 0.0, "preset": preset, "step_tol": step_tol,
                          "omega_bar": 10.282 * rpm, "end_to_end_ratio": ratio, "displacement_m": disp,
                          "mean_motor_torque_Nm": torque, "distance_per_turn_m": per_turn, "error": None,
                          "cpu_s": 1.0, "finished_at": "2026-12-02T00:00:00+00:00"}


def _grid(omega_b: dict[float, float], readings=("paper",)) -> dict[str, dict]:
    """Records of the whole Fig. 4 grid with buckling above omega_b[b] (rpm)."""
    recs = {}
    for reading in readings:
        for b in HEADS_M:
            for w in GRID_RPM:
                k, r = _point(reading, b, w, 0.5 if w > omega_b[b] else 1.01)
                recs[k] = r
    return recs


def test_empty_plan_is_the_grid_then_the_turns():
    plan = ValidationPlan(readings=("paper", "stokes_head"))
    todo = plan.pending({})
    points = [t for t in todo if t.kind == "point"]
    turns = [t for t in todo if t.kind == "turn"]
    assert len(points) == len(GRID_RPM) * (1 + 2 * 3)  # the headless swimmer once, three heads per reading
    assert len(turns) == 2 * len(TURN_TC_BAR) * len(TURN_PHASES_DEG)
    assert todo.index(turns[0]) > todo.index(points[-1])
    assert {t.reading for t in points if t.head_radius == 0.0} == {NO_HEAD}
    assert len({t.point_id for t in todo}) == len(todo)
    assert t_c_of(0.55) == pytest.approx(54.0, abs=0.05)  # the paper's t_bar = 0.55 is 54 s


def test_bisection_narrows_the_bracket_to_two_rpm():
    plan = ValidationPlan(readings=("paper",), tight_step_tol=None)
    recs = _grid({0.0: 88.3, 0.004: 71.2, 0.008: 59.6, 0.012: 51.3})
    for t in plan.pending(recs):  # the turns: done
        if t.kind == "turn":
            recs[t.point_id] = {"point_id": t.point_id, "kind": "turn", "reading": t.reading, "value": t.value,
                                "phase_deg": t.phase_deg, "preset": "faithful", "step_tol": None, "theta_deg": 1.0}
    true_b = {0.0: 88.3, 0.004: 71.2, 0.008: 59.6, 0.012: 51.3}
    for _ in range(10):
        todo = plan.pending(recs)
        if not todo:
            break
        for t in todo:
            assert t.kind == "point"
            k, r = _point("paper", t.head_radius, t.value, 0.5 if t.value > true_b[t.head_radius] else 1.01)
            recs[k] = r
    assert not plan.pending(recs)
    for b, w in true_b.items():
        lo, hi = plan.bracket(recs, "paper", b)
        assert lo < w < hi and hi - lo <= 2.0


def test_a_head_that_does_not_buckle_is_probed_beyond_the_grid_then_left():
    plan = ValidationPlan(readings=("torque_free",), tight_step_tol=None)
    recs = _grid({0.0: 92.0, 0.004: 1e9, 0.008: 1e9, 0.012: 77.0}, readings=("torque_free",))
    nxt = [t.value for t in plan.pending(recs) if t.kind == "point" and t.head_radius == 0.004]
    assert nxt == [BEYOND_RPM[0]]
    for w in BEYOND_RPM:
        k, r = _point("torque_free", 0.004, w, 1.03)
        recs[k] = r
    assert not [t for t in plan.pending(recs) if t.kind == "point" and t.head_radius == 0.004]
    assert plan.bracket(recs, "torque_free", 0.004) == (BEYOND_RPM[-1], None)


def test_convergence_runs_follow_the_final_bracket_and_the_largest_turn():
    plan = ValidationPlan(readings=("paper",), tight_step_tol=1e-5, check_preset="paper")
    recs = _grid({0.0: 88.0, 0.004: 71.0, 0.008: 59.0, 0.012: 51.0})
    for w in (52.5, 51.25):  # bisection of b = 1.2 cm done: bracket [50, 51.25]
        k, r = _point("paper", 0.012, w, 0.5)
        recs[k] = r
    tight = [t for t in plan.pending(recs) if t.step_tol is not None or t.preset != "faithful"]
    assert sorted({t.value for t in tight}) == [10.0, 50.0, 51.25]
    assert {(t.preset, t.step_tol) for t in tight} == {("faithful", 1e-5), ("paper", None)}
    for tcb in TURN_TC_BAR:  # the turns: theta peaks at t_bar 0.45
        for ph in TURN_PHASES_DEG:
            t = ValidationRun("turn", "paper", 0.012, t_c_of(tcb), ph)
            recs[t.point_id] = {"point_id": t.point_id, "kind": "turn", "reading": "paper", "value": t.value,
                                "phase_deg": ph, "preset": "faithful", "step_tol": None,
                                "theta_deg": 100 - 400 * (tcb - 0.45) ** 2 + ph / 100}
    assert plan.largest_turn_tc(recs, "paper") == t_c_of(0.45)
    turns = [t for t in plan.pending(recs) if t.kind == "turn"]
    assert {t.value for t in turns} == {t_c_of(0.45)} and len(turns) == len(TURN_PHASES_DEG)  # not at check_preset
    assert {(t.preset, t.step_tol) for t in turns} == {("faithful", 1e-5)}


def test_unknown_reading_is_refused():
    with pytest.raises(ValueError, match="readings=.*allowed: a non-empty subset of torque_free"):
        ValidationPlan(readings=("spinning",))
    assert set(READINGS) == {"torque_free", "fixed", "paper", "stokes_head", "literal"}


def test_a_folder_of_fewer_readings_is_extended_but_not_one_of_other_readings(tmp_path, monkeypatch):
    """A folder made with a subset of the readings (the same grid and preset) is this plan's too: it is resumed with
    the new readings' runs; one with a reading the plan lacks is refused."""
    import flagellum_bench.paper_validation as pv

    calls = []
    monkeypatch.setattr("batch.pool.run_tasks", lambda todo, *a, **k: calls.append(len(todo)) or [])
    older = {**ValidationPlan().identity(), "readings": ["torque_free", "fixed"]}
    (tmp_path / RUN_FILE).write_text(json.dumps({"run": older}))
    plan = ValidationPlan(readings=("torque_free", "fixed", "literal"), tight_step_tol=None)
    monkeypatch.setattr(pv.ValidationPlan, "pending", lambda self, records: [] if calls else ["a run"])
    run_validation(tmp_path, plan, workers=1, progress=False)
    assert calls == [1] and json.loads((tmp_path / RUN_FILE).read_text())["run"]["readings"] == list(plan.readings)
    with pytest.raises(SweepError, match="readings is"):
        run_validation(tmp_path, ValidationPlan(readings=("fixed",), tight_step_tol=None), workers=1, progress=False)


def test_a_folder_of_another_validation_is_refused(tmp_path):
    (tmp_path / RUN_FILE).write_text(json.dumps({"run": {**ValidationPlan().identity(), "preset": "paper"}}))
    with pytest.raises(SweepError, match="preset is 'paper' there and 'faithful' here"):
        run_validation(tmp_path, ValidationPlan(), workers=1, progress=False)
    assert not (tmp_path / "results.jsonl").exists()


def _report_module():
    sys.path.insert(0, str(SCRIPTS))
    try:
        spec = importlib.util.spec_from_file_location("validation_report", SCRIPTS / "validation_report.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    finally:
        sys.path.remove(str(SCRIPTS))


def test_report_rows_from_synthetic_records():
    rep = _report_module()
    plan = ValidationPlan(readings=("paper",), tight_step_tol=None)
    recs = _grid({0.0: 88.0, 0.004: 71.0, 0.008: 59.0, 0.012: 51.0})
    for b, (lo, hi) in {0.0: (87.5, 88.75), 0.004: (70.0, 71.25), 0.008: (58.75, 60.0), 0.012: (50.0, 51.25)}.items():
        for w, ratio in ((lo, 1.01), (hi, 0.5)):
            k, r = _point("paper", b, w, ratio)
            recs[k] = r
    # ||s|| at 10 rpm: drops of 20 / 30 / 45 % against the headless swimmer
    for b, disp in {0.0: 0.1, 0.004: 0.08, 0.008: 0.07, 0.012: 0.055}.items():
        k, r = _point("paper", b, 10.0, 1.01, disp=disp, per_turn=0.0036)
        recs[k] = r
    rows = {r["row"]: r for r in rep.rows_for(recs, "paper", plan)}
    assert rows["R1"]["ours"]["midpoint_rpm"] == pytest.approx(50.625) and rows["R1"]["pass"] is True
    red = [rows["R2"]["ours"][f"{x} cm"]["reduction_pct"] for x in ("0.4", "0.8", "1.2")]
    assert red == pytest.approx([100 * (1 - m / 88.125) for m in (70.625, 59.375, 50.625)])
    assert rows["R4"]["ours"] == pytest.approx([20.0, 30.0, 45.0]) and rows["R4"]["pass"] is True
    assert rows["R8"]["ours"] == pytest.approx(0.36) and rows["R8"]["pass"] is True
    assert rows["R11"]["pass"] is True
    assert rows["R9"]["pass"] is None  # no turns: not measured
    # R3 is scored at <= 30 rpm only: the grid's 1.01 there passes whatever L'/L does nearer omega_b
    assert rows["R3"]["pass"] is True and rows["R3"]["ours"]["up_to_30_rpm"] == pytest.approx([1.01, 1.01])


def test_script_rejects_bad_workers_before_any_output(tmp_path):
    out = tmp_path / "v"
    res = subprocess.run([sys.executable, str(SCRIPTS / "validate_readings.py"), "--workers", "0", "--out", str(out)],
                         capture_output=True, text=True)
    assert res.returncode == 2 and "--workers 0 is not allowed" in res.stderr
    assert not out.exists()
