"""run_simulation with a fake simulator: recording, summary, and clean stops."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from physics.errors import SimulationError
from physics.params import RPM_TO_RAD_S, NumericsConfig, SwimmerParams
from physics.run import RunResult, Trajectory, run_simulation, validate_run_arguments
from physics.schedule import MotorSchedule

SPEED_PER_OMEGA = 1e-4  # fake head speed per motor speed, m/s per rad/s
TORQUE_PER_OMEGA = 2e-5  # fake motor torque per motor speed, N m per rad/s


class FakeSimulator:
    """Duck-typed stand-in: the head moves along +x at SPEED_PER_OMEGA * omega."""

    def __init__(self, dt: float, n: int = 6, fail_at: int | None = None, interrupt_at: int | None = None):
        self.dt, self.n = dt, n
        self.fail_at, self.interrupt_at = fail_at, interrupt_at
        self.time = 0.0
        self.step_count = 0
        self.omega = 0.0
        self.motor_torque = 0.0
        self.x = np.zeros(3)
        self.omegas: list[float] = []

    def set_motor_speed(self, omega_rad_s: float) -> None:
        self.omega = omega_rad_s

    def step(self) -> None:
        k = self.step_count + 1
        if k == self.interrupt_at:
            raise KeyboardInterrupt
        if k == self.fail_at:
            raise SimulationError("Newton did not converge", self.step_count, self.time, "Newton")
        self.omegas.append(self.omega)
        self.x = self.x + np.array([SPEED_PER_OMEGA * self.omega * self.dt, 0.0, 0.0])
        self.motor_torque = TORQUE_PER_OMEGA * self.omega
        self.time += self.dt
        self.step_count = k

    @property
    def nodes(self) -> np.ndarray:
        return self.x + np.outer(-np.arange(self.n), [0.01, 0.0, 0.0])

    @property
    def head_position(self) -> np.ndarray:
        return self.x.copy()

    @property
    def head_orientation(self) -> np.ndarray:
        return np.eye(3)

    @property
    def motor_power(self) -> float:
        return self.motor_torque * self.omega

    def end_to_end_ratio(self) -> float:
        return 1.0 - 1e-3 * self.time

    def displacement(self) -> float:
        return float(np.linalg.norm(self.x))

    def reynolds_number(self) -> float:
        return 0.01 * self.omega


DT = 1e-3
PARAMS = SwimmerParams()
NUMERICS = NumericsConfig(dt=DT)


def _run(schedule: MotorSchedule, duration: float, **kw) -> tuple[RunResult, FakeSimulator]:
    fake_kw = {k: kw.pop(k) for k in ("fail_at", "interrupt_at", "n") if k in kw}
    sim = FakeSimulator(DT, **fake_kw)
    kw.setdefault("progress", False)
    return run_simulation(PARAMS, NUMERICS, schedule, duration, simulator=sim, **kw), sim


def test_recording_shapes_and_sampling_times():
    res, sim = _run(MotorSchedule.constant(60.0), 0.1, record_interval_s=0.01, node_record_interval_s=0.05)
    tr = res.trajectory
    assert res.completed and sim.step_count == 100
    assert tr.times.shape == (11,)
    np.testing.assert_allclose(tr.times, np.linspace(0.0, 0.1, 11), atol=1e-12)
    assert tr.head_positions.shape == (11, 3)
    assert tr.head_orientations.shape == (11, 3, 3)
    for name in ("motor_torque", "omega_rad_s", "end_to_end", "reynolds"):
        assert getattr(tr, name).shape == (11,)
    np.testing.assert_allclose(tr.node_times, [0.0, 0.05, 0.1], atol=1e-12)
    assert tr.node_positions.shape == (3, 6, 3)
    np.testing.assert_allclose(tr.head_positions[-1], sim.x)
    np.testing.assert_allclose(tr.node_positions[-1], sim.nodes)


def test_final_state_is_recorded_even_off_the_sampling_grid():
    res, sim = _run(MotorSchedule.constant(60.0), 0.025, record_interval_s=0.01, node_record_interval_s=1.0)
    assert res.trajectory.times[-1] == pytest.approx(0.025)
    np.testing.assert_allclose(res.trajectory.node_times, [0.0, 0.025])


def test_schedule_switch_takes_effect_at_the_step_that_starts_there():
    sched = MotorSchedule(((0.0, 10.0), (0.05, 60.0)))
    res, sim = _run(sched, 0.1)
    w = np.array(sim.omegas) / RPM_TO_RAD_S
    np.testing.assert_allclose(w[:50], 10.0)
    np.testing.assert_allclose(w[50:], 60.0)
    assert res.summary["omega_rpm"] == pytest.approx(35.0)


def test_summary_has_every_key_and_is_json_serialisable():
    res, sim = _run(MotorSchedule.constant(60.0), 0.2)
    s = res.summary
    expected = {"sim_time_s", "wall_time_s", "steps", "omega_rpm", "head_radius_m", "final_head_position_m",
                "displacement_m", "end_to_end_ratio", "mean_motor_torque_Nm", "mean_motor_power_W",
                "distance_per_motor_turn_m", "max_reynolds", "omega_bar", "t_bar", "interrupted", "error", "params"}
    assert expected <= set(s)
    json.dumps(s, allow_nan=False)
    omega = 60.0 * RPM_TO_RAD_S
    assert s["steps"] == 200
    assert s["sim_time_s"] == pytest.approx(0.2)
    assert s["omega_rpm"] == 60.0
    assert s["head_radius_m"] == PARAMS.head_radius
    assert s["final_head_position_m"] == pytest.approx(list(sim.x))
    assert s["displacement_m"] == pytest.approx(SPEED_PER_OMEGA * omega * 0.2)
    assert s["mean_motor_torque_Nm"] == pytest.approx(TORQUE_PER_OMEGA * omega)
    assert s["mean_motor_power_W"] == pytest.approx(TORQUE_PER_OMEGA * omega**2)
    turns = omega * 0.2 / (2 * math.pi)
    assert s["distance_per_motor_turn_m"] == pytest.approx(s["displacement_m"] / turns)
    assert s["max_reynolds"] == pytest.approx(0.01 * omega)
    assert s["omega_bar"] == pytest.approx(PARAMS.omega_bar(omega))
    assert s["t_bar"] == pytest.approx(PARAMS.t_bar(0.2))
    assert s["params"]["head_radius"] == PARAMS.head_radius and s["params"]["dt"] == DT
    assert s["interrupted"] is False and s["error"] is None


def test_zero_speed_has_no_distance_per_turn():
    res, _ = _run(MotorSchedule.constant(0.0), 0.01)
    assert res.summary["distance_per_motor_turn_m"] is None
    json.dumps(res.summary, allow_nan=False)


def test_keyboard_interrupt_stops_cleanly_and_keeps_the_data():
    res, sim = _run(MotorSchedule.constant(60.0), 1.0, interrupt_at=31, record_interval_s=0.01)
    assert res.interrupted and res.error is None and not res.completed
    assert res.summary["interrupted"] is True
    assert res.summary["steps"] == 30
    assert res.summary["sim_time_s"] == pytest.approx(0.03)
    tr = res.trajectory
    np.testing.assert_allclose(tr.times, [0.0, 0.01, 0.02, 0.03], atol=1e-12)
    np.testing.assert_allclose(tr.head_positions[-1], sim.x)
    assert tr.node_times[-1] == pytest.approx(0.03)


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_a_signal_during_a_step_ends_the_run_after_that_step(sig):
    """Ctrl-C or SIGTERM (when the command line turns it into an interrupt) arriving inside a step lets the
    step finish, then the run ends as interrupted: no exception is raised inside the step."""
    import os
    import signal

    signum = getattr(signal, sig)
    # as in an interactive run (a process started in the background inherits SIGINT ignored)
    previous_int = signal.signal(signal.SIGINT, signal.default_int_handler)
    previous = signal.signal(signal.SIGTERM, lambda s, f: (_ for _ in ()).throw(KeyboardInterrupt))
    sim = FakeSimulator(DT)
    plain_step = sim.step

    def step() -> None:
        if sim.step_count + 1 == 7:
            os.kill(os.getpid(), signum)  # the handler runs here, in the middle of the step
        plain_step()

    sim.step = step
    try:
        res = run_simulation(PARAMS, NUMERICS, MotorSchedule.constant(60.0), 1.0, simulator=sim, progress=False)
        restored = signal.getsignal(signal.SIGINT)
    finally:
        signal.signal(signal.SIGTERM, previous)
        signal.signal(signal.SIGINT, previous_int)
    assert res.interrupted and res.error is None
    assert res.summary["steps"] == 7 and sim.step_count == 7
    assert restored is signal.default_int_handler


def test_simulation_error_keeps_the_data_and_the_message():
    res, sim = _run(MotorSchedule.constant(60.0), 1.0, fail_at=26)
    assert not res.interrupted and not res.completed
    assert "Newton did not converge" in res.error and "step 25" in res.error
    assert res.summary["error"] == res.error
    assert res.summary["steps"] == 25
    assert res.trajectory.times[-1] == pytest.approx(0.025)
    json.dumps(res.summary, allow_nan=False)


def test_failure_on_the_first_step_still_gives_a_valid_result():
    res, _ = _run(MotorSchedule.constant(60.0), 1.0, fail_at=1)
    assert res.error is not None
    assert len(res.trajectory) == 1 and res.trajectory.node_positions.shape == (1, 6, 3)
    assert res.summary["mean_motor_torque_Nm"] is None
    json.dumps(res.summary, allow_nan=False)


def test_save_writes_summary_and_npz_that_round_trip(tmp_path):
    res, _ = _run(MotorSchedule.constant(60.0), 0.05)
    paths = res.save(tmp_path / "run")
    assert json.loads(paths["summary"].read_text()) == res.summary
    back = Trajectory.load_npz(paths["trajectory"])
    for name in ("times", "head_positions", "head_orientations", "node_times", "node_positions",
                 "motor_torque", "omega_rad_s", "end_to_end", "reynolds"):
        np.testing.assert_array_equal(getattr(back, name), getattr(res.trajectory, name))


def test_progress_bar_runs_without_error(capsys):
    res, _ = _run(MotorSchedule.constant(60.0), 0.02, progress=True)
    assert res.completed
    assert "simulated" in capsys.readouterr().err


@pytest.mark.parametrize("kw, fragment", [
    ({"duration_s": 0.0}, "duration_s=0.0"),
    ({"duration_s": math.nan}, "duration_s=nan"),
    ({"duration_s": 1e-4}, "shorter than one time step"),
    ({"record_interval_s": -1.0}, "record_interval_s=-1.0"),
    ({"node_record_interval_s": math.inf}, "node_record_interval_s=inf"),
])
def test_bad_run_arguments_name_the_value(kw, fragment):
    args = {"duration_s": 1.0, "record_interval_s": 0.01, "node_record_interval_s": 0.1, **kw}
    with pytest.raises(ValueError) as info:
        validate_run_arguments(NUMERICS, **args)
    assert fragment in str(info.value)
    with pytest.raises(ValueError):
        run_simulation(PARAMS, NUMERICS, MotorSchedule.constant(1.0), args.pop("duration_s"),
                       simulator=FakeSimulator(DT), progress=False, **args)


def test_a_recording_that_cannot_fit_in_memory_is_refused_up_front():
    """Issue 24: `simulate --duration 1e6 --set dt=1e-6` ended in a MemoryError; now refused before it runs."""
    from physics.run import MAX_RECORDING_BYTES

    numerics = NUMERICS.replace(dt=1e-6)
    with pytest.raises(ValueError, match="would record about .* GB; allowed: at most 2 GB"):
        validate_run_arguments(numerics, 1e6, 0.01, 0.1, n_nodes=45)
    with pytest.raises(ValueError, match="would record"):
        run_simulation(PARAMS, numerics, MotorSchedule.constant(1.0), 1e6, progress=False)
    assert validate_run_arguments(NUMERICS, 10.0, 0.01, 0.1, n_nodes=45) >= 1
    assert MAX_RECORDING_BYTES >= 1024**3


def test_simulate_refuses_a_run_whose_recording_would_not_fit_before_creating_output(usage_error, tmp_path):
    line = usage_error(["simulate", "--omega-rpm", "10", "--duration", "1e6", "--set", "dt=1e-6", "--out",
                        str(tmp_path / "o")])
    assert "duration_s=1000000.0" in line and "GB" in line
    assert not (tmp_path / "o").exists()


def test_simulate_refuses_a_schedule_that_is_neither_csv_nor_json(usage_error, tmp_path):
    f = tmp_path / "s.txt"
    f.write_text("0,10\n")
    line = usage_error(["simulate", "--schedule", str(f), "--duration", "1", "--out", str(tmp_path / "o")])
    assert str(f) in line and ".csv" in line
    assert not (tmp_path / "o").exists()
