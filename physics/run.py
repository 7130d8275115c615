"""Run loop: drive a simulator through a motor schedule, record a trajectory, summarise.

``run_simulation`` advances the simulator one time step at a time, sets the motor speed from
the schedule before each step (the schedule's value at the step's midpoint, so a switch at
t_s takes effect exactly at the step that starts at t_s), records, and stops cleanly on
Ctrl-C (``KeyboardInterrupt``) or ``SimulationError``, keeping everything computed so far.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from numbers import Integral, Real
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from physics.errors import SimulationError, is_interrupt
from physics.params import RPM_TO_RAD_S, NumericsConfig, SwimmerParams
from physics.schedule import MotorSchedule
from physics.threads import simulation_threads

DEFAULT_RECORD_INTERVAL_S = 0.01
DEFAULT_NODE_RECORD_INTERVAL_S = 0.1
#: Longest run, s of simulated time (about 11.6 days: far beyond any run of the paper; a larger value is a typo
#: that would otherwise run for ever).
MAX_DURATION_S = 1e6


class SimulatorLike(Protocol):
    """What ``run_simulation`` needs from a simulator (``physics.simulator.Simulator`` has it)."""

    time: float
    motor_torque: float

    def set_motor_speed(self, omega_rad_s: float) -> None: ...
    def step(self) -> None: ...
    @property
    def nodes(self) -> np.ndarray: ...
    @property
    def head_position(self) -> np.ndarray: ...
    @property
    def head_orientation(self) -> np.ndarray: ...
    @property
    def motor_power(self) -> float: ...
    def end_to_end_ratio(self) -> float: ...
    def displacement(self) -> float: ...
    def reynolds_number(self) -> float: ...


@dataclass
class Trajectory:
    """Recorded time series. K samples every ``record_interval_s``, J node snapshots.

    times: (K,) s since the start of the run; head_positions: (K, 3) m;
    head_orientations: (K, 3, 3), columns are the body axes X_b, Y_b, Z_b in the lab frame;
    node_times: (J,) s; node_positions: (J, n, 3) m; motor_torque: (K,) N m;
    omega_rad_s: (K,) motor speed of the step just taken, rad/s; end_to_end: (K,) L'/L;
    reynolds: (K,) Reynolds number.
    The first sample is the initial state and the last one the final state.
    """

    times: np.ndarray
    head_positions: np.ndarray
    head_orientations: np.ndarray
    node_times: np.ndarray
    node_positions: np.ndarray
    motor_torque: np.ndarray
    omega_rad_s: np.ndarray
    end_to_end: np.ndarray
    reynolds: np.ndarray

    def __len__(self) -> int:
        return int(self.times.shape[0])

    def save_npz(self, path: str | Path) -> Path:
        """Write every field to a compressed ``.npz`` file; returns the path."""
        path = Path(path)
        np.savez_compressed(path, **{f.name: getattr(self, f.name) for f in dataclasses.fields(self)})
        return path

    @classmethod
    def load_npz(cls, path: str | Path) -> Trajectory:
        """Read a file written by ``save_npz``."""
        with np.load(Path(path)) as data:
            return cls(**{f.name: np.array(data[f.name]) for f in dataclasses.fields(cls)})


@dataclass
class RunResult:
    """Outcome of ``run_simulation``: what was recorded, a JSON-ready summary, how it ended."""

    trajectory: Trajectory
    summary: dict[str, Any]
    interrupted: bool = False
    error: str | None = None

    @property
    def completed(self) -> bool:
        """True when the run reached its requested duration."""
        return not self.interrupted and self.error is None

    def save(self, out_dir: str | Path) -> dict[str, Path]:
        """Write ``summary.json`` and ``trajectory.npz`` into ``out_dir`` (created if needed)."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        summary_path = out / "summary.json"
        summary_path.write_text(json.dumps(self.summary, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        return {"summary": summary_path, "trajectory": self.trajectory.save_npz(out / "trajectory.npz")}


# --- recording ------------------------------------------------------------------------
class _Recorder:
    """Collects samples; each sample is appended as one tuple so an interrupt cannot tear it."""

    def __init__(self, stride: int, node_stride: int, t0: float) -> None:
        self.stride, self.node_stride, self.t0 = stride, node_stride, t0
        self.rows: list[tuple] = []
        self.node_rows: list[tuple[float, np.ndarray]] = []
        self.last_t = -math.inf
        self.last_node_t = -math.inf

    def sample(self, sim: SimulatorLike, step: int, omega: float, reynolds: float | None = None,
               force: bool = False) -> None:
        """Record after ``step`` steps if it falls on a stride (always when ``force``), once per time."""
        t = sim.time - self.t0
        if (force or step % self.stride == 0) and t != self.last_t:
            re = float(sim.reynolds_number()) if reynolds is None else reynolds
            self.rows.append((t, np.array(sim.head_position, dtype=float),
                              np.array(sim.head_orientation, dtype=float), float(sim.motor_torque),
                              float(omega), float(sim.end_to_end_ratio()), re))
            self.last_t = t
        if (force or step % self.node_stride == 0) and t != self.last_node_t:
            self.node_rows.append((t, np.array(sim.nodes, dtype=float)))
            self.last_node_t = t

    def trajectory(self) -> Trajectory:
        cols = list(zip(*self.rows))
        return Trajectory(
            times=np.array(cols[0], dtype=float),
            head_positions=np.stack(cols[1]).reshape(-1, 3),
            head_orientations=np.stack(cols[2]).reshape(-1, 3, 3),
            node_times=np.array([t for t, _ in self.node_rows], dtype=float),
            node_positions=np.stack([x for _, x in self.node_rows]),
            motor_torque=np.array(cols[3], dtype=float),
            omega_rad_s=np.array(cols[4], dtype=float),
            end_to_end=np.array(cols[5], dtype=float),
            reynolds=np.array(cols[6], dtype=float),
        )


@dataclass
class _Totals:
    """Time integrals over completed steps (s, rad, N m s, J) and the peak Reynolds number."""

    time_s: float = 0.0
    motor_angle_rad: float = 0.0
    torque_integral: float = 0.0
    energy_J: float = 0.0
    max_reynolds: float = 0.0
    steps: int = 0

    def add(self, sim: SimulatorLike, omega: float, h: float, reynolds: float) -> None:
        self.time_s += h
        self.motor_angle_rad += omega * h
        self.torque_integral += float(sim.motor_torque) * h
        self.energy_J += float(sim.motor_power) * h
        self.max_reynolds = max(self.max_reynolds, reynolds)
        self.steps += 1


# --- the loop -------------------------------------------------------------------------
#: Most memory a run may spend on its recorded trajectory (samples, node snapshots, the step plan), bytes: a
#: longer recording is refused up front instead of ending in a MemoryError hours into the run.
MAX_RECORDING_BYTES = 2 * 1024**3
#: Approximate bytes held per head sample, per node of a shape snapshot and per planned (adaptive) step.
_SAMPLE_BYTES, _NODE_BYTES, _PLAN_BYTES = 400, 24, 120


def recording_bytes(numerics: NumericsConfig, n_steps: int, record_interval_s: float, node_record_interval_s: float,
                    n_nodes: int) -> int:
    """Approximate memory of a run's recording (``run_simulation``) with ``n_steps`` steps of ``numerics.dt``."""
    dt = numerics.dt
    samples = n_steps // max(1, int(round(record_interval_s / dt))) + 2
    snapshots = n_steps // max(1, int(round(node_record_interval_s / dt))) + 2
    plan = n_steps if getattr(numerics, "step_tol", 0.0) > 0.0 else 0
    return samples * _SAMPLE_BYTES + snapshots * (n_nodes * _NODE_BYTES + 100) + plan * _PLAN_BYTES


def validate_run_arguments(numerics: NumericsConfig, duration_s: float, record_interval_s: float,
                           node_record_interval_s: float, n_nodes: int | None = None) -> int:
    """Check durations (s); return the number of steps. ValueError names the bad value. With ``n_nodes`` (the
    flagellum's node count), also that the recording fits in ``MAX_RECORDING_BYTES``."""
    n_steps = _check_durations(numerics, duration_s, record_interval_s, node_record_interval_s)
    if n_nodes is not None:
        need = recording_bytes(numerics, n_steps, record_interval_s, node_record_interval_s, n_nodes)
        if need > MAX_RECORDING_BYTES:
            raise ValueError(f"duration_s={duration_s!r} with record_interval_s={record_interval_s!r} and "
                             f"node_record_interval_s={node_record_interval_s!r} (dt = {numerics.dt:g} s) would "
                             f"record about {need / 1024**3:.3g} GB; allowed: at most "
                             f"{MAX_RECORDING_BYTES / 1024**3:g} GB: shorten the run or sample less often")
    return n_steps


def _check_durations(numerics: NumericsConfig, duration_s: float, record_interval_s: float,
                     node_record_interval_s: float) -> int:
    for name, value in (("duration_s", duration_s), ("record_interval_s", record_interval_s),
                        ("node_record_interval_s", node_record_interval_s)):
        if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value) or value <= 0:
            raise ValueError(f"{name}={value!r} is not allowed; allowed: a finite time > 0 s")
    if duration_s > MAX_DURATION_S:
        raise ValueError(f"duration_s={duration_s!r} is not allowed; allowed: a time > 0 and <= {MAX_DURATION_S:g} s")
    if getattr(numerics, "step_tol", 0.0) > 0.0:  # adaptive steps: any duration is covered exactly
        return max(1, int(math.ceil(duration_s / numerics.dt - 1e-9)))
    n_steps = int(round(duration_s / numerics.dt))
    if n_steps < 1:
        raise ValueError(f"duration_s={duration_s!r} is shorter than one time step; "
                         f"allowed: >= dt = {numerics.dt:g} s")
    return n_steps


def advance(sim: Any, duration_s: float | None = None, *, steps: int | None = None,
            spans: list[float] | None = None, on_step: Callable[[Any, int], bool | None] | None = None) -> int:
    """The run loop: step ``sim`` for ``duration_s`` seconds (as ``Simulator.advance``: rounded to whole steps
    of ``sim.numerics.dt`` with fixed steps, exact with adaptive ones) or for ``steps`` steps, calling ``on_step(sim, k)`` after step k = 1, 2, ...

    ``spans`` (adaptive steps only): one step per span, of that length (s). A callback that returns True ends
    the loop after its step. Returns the number of steps taken.
    ``SimulationError`` and ``KeyboardInterrupt`` propagate (the steps before them are taken). With no
    callback, ``advance(sim, T)`` takes exactly the steps of ``sim.advance(T)``.
    """
    if sum(x is not None for x in (duration_s, steps, spans)) != 1:
        raise ValueError("give exactly one of duration_s, steps and spans")
    if steps is not None:
        if isinstance(steps, bool) or not isinstance(steps, Integral) or steps < 0:
            raise ValueError(f"steps={steps!r} is not allowed; allowed: an integer >= 0")
        todo: Iterable[float | None] = itertools.repeat(None, int(steps))  # lazy: no list of a billion Nones
    elif spans is not None:
        todo = spans
    else:
        if (isinstance(duration_s, bool) or not isinstance(duration_s, Real) or not math.isfinite(duration_s)
                or duration_s < 0.0):
            raise ValueError(f"duration_s={duration_s!r} is not allowed; allowed: a finite time >= 0 s")
        from physics.integrate.time_integrator import step_spans

        todo = step_spans(duration_s, sim.numerics)
    k = 0
    with simulation_threads():  # one BLAS thread while stepping (physics.threads)
        for k, span in enumerate(todo, start=1):
            if span is None:
                sim.step()
            else:
                sim.step(span)
            if on_step is not None and on_step(sim, k):
                return k
    return k


class StopRequest:
    """Set by Ctrl-C or SIGTERM while ``stop_requests`` is active; the run loop ends after the current step."""

    def __init__(self) -> None:
        self.requested = False


@contextmanager
def stop_requests() -> Iterator[StopRequest]:
    """Ctrl-C (SIGINT) and SIGTERM ask the run loop to stop after the current step (a second signal stops at
    once). A flag, not an exception raised wherever the signal lands: raised inside a compiled (Numba) kernel,
    KeyboardInterrupt surfaces as a SystemError. Only signals that already interrupt (a Python handler such as
    Ctrl-C's, or the command line's SIGTERM handler) are taken over: ignored or default ones (worker processes)
    stay as they are; outside the main thread nothing changes."""
    stop = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum: int, frame: object) -> None:
        if stop.requested:
            raise KeyboardInterrupt
        stop.requested = True

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        if callable(signal.getsignal(sig)):
            previous[sig] = signal.signal(sig, handler)
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def run_simulation(params: SwimmerParams, numerics: NumericsConfig, schedule: MotorSchedule, duration_s: float,
                   record_interval_s: float = DEFAULT_RECORD_INTERVAL_S,
                   node_record_interval_s: float = DEFAULT_NODE_RECORD_INTERVAL_S,
                   progress: bool = True, simulator: SimulatorLike | None = None) -> RunResult:
    """Swim for ``duration_s`` seconds (rounded to whole steps of ``numerics.dt``).

    ``simulator`` defaults to ``Simulator(params, numerics)``; an injected one must use the
    same ``numerics.dt`` (tests pass a fake). Samples every ``record_interval_s`` and node
    snapshots every ``node_record_interval_s`` (both s, rounded to whole steps, at least one
    step). A tqdm bar in simulated seconds is shown on stderr when ``progress`` is true.
    Ctrl-C, SIGTERM and ``SimulationError`` end the run early (a signal after the current step,
    ``stop_requests``); the result keeps what was computed and says why in ``interrupted`` / ``error``.
    """
    from physics.model.geometry import layout_for

    n_steps = validate_run_arguments(numerics, duration_s, record_interval_s, node_record_interval_s,
                                     n_nodes=layout_for(params).n)
    dt = numerics.dt
    # adaptive steps: pieces of at most dt that end at every switch of the schedule (exact switch times)
    plan = schedule.spans(duration_s, dt) if getattr(numerics, "step_tol", 0.0) > 0.0 else None
    if plan is not None:
        n_steps = len(plan)
    if simulator is None:
        from physics.simulator import Simulator  # heavy (numba); imported only when running

        simulator = Simulator(params, numerics)
    sim = simulator
    rec = _Recorder(max(1, int(round(record_interval_s / dt))), max(1, int(round(node_record_interval_s / dt))),
                    sim.time)
    totals = _Totals()
    omega = schedule.omega_rad_s_at(0.0)
    rec.sample(sim, 0, omega, force=True)
    interrupted, error = False, None
    bar = _progress_bar(n_steps, dt if plan is None else duration_s / n_steps) if progress else None
    wall0 = time.perf_counter()
    try:
        with stop_requests() as stop:
            t_before = sim.time
            omega = schedule.omega_rad_s_at(t_before - rec.t0 + 0.5 * dt) if plan is None else plan[0][1]
            sim.set_motor_speed(omega)

            def on_step(sim: Any, step: int) -> None:
                # record step ``step``, then set the motor speed of the next one (the schedule's value at
                # its midpoint)
                nonlocal t_before, omega
                reynolds = float(sim.reynolds_number())
                totals.add(sim, omega, sim.time - t_before, reynolds)
                rec.sample(sim, step, omega, reynolds)
                if bar is not None:
                    bar.update(1)
                if stop.requested:
                    raise KeyboardInterrupt
                if step < n_steps:
                    t_before = sim.time
                    omega = (schedule.omega_rad_s_at(t_before - rec.t0 + 0.5 * dt) if plan is None
                             else plan[step][1])
                    sim.set_motor_speed(omega)

            if plan is None:
                advance(sim, steps=n_steps, on_step=on_step)
            else:
                advance(sim, spans=[span for span, _ in plan], on_step=on_step)
    except KeyboardInterrupt:
        interrupted = True
    except SimulationError as exc:
        error = str(exc)
    except SystemError as exc:  # a second signal raised inside a compiled kernel
        if not is_interrupt(exc):
            raise
        interrupted = True
    finally:
        wall = time.perf_counter() - wall0
        if bar is not None:
            bar.close()
    rec.sample(sim, totals.steps, omega, force=True)  # the final state, also after a partial step
    summary = _summarize(params, numerics, schedule, sim, sim.time - rec.t0, totals, wall, interrupted, error)
    return RunResult(rec.trajectory(), summary, interrupted, error)


def _progress_bar(n_steps: int, dt: float):
    """tqdm bar counting steps but displaying simulated seconds (unit_scale = dt)."""
    from tqdm import tqdm

    return tqdm(total=n_steps, unit_scale=dt, unit="s", desc="simulated", mininterval=0.5, dynamic_ncols=True,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.2f}/{total:.2f} s [{elapsed}<{remaining}]")


# --- summary --------------------------------------------------------------------------
def _num(x: float | None) -> float | None:
    """JSON-safe float: None for missing or non-finite values."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _summarize(params: SwimmerParams, numerics: NumericsConfig, schedule: MotorSchedule, sim: SimulatorLike,
              sim_time_s: float, totals: _Totals, wall_time_s: float, interrupted: bool,
              error: str | None) -> dict[str, Any]:
    """JSON-ready summary of a run (SI units; see the README).

    ``sim_time_s`` is the simulator's time since the start (it can include part of a failed
    step); means, the average speed and motor turns are over completed steps only.
    """
    t = totals.time_s
    if t > 0.0 and not schedule.is_constant:
        omega_rpm = totals.motor_angle_rad / t / RPM_TO_RAD_S  # time average over the steps taken
    else:
        omega_rpm = schedule.steps[0][1]
    turns = totals.motor_angle_rad / (2.0 * math.pi)
    displacement = float(sim.displacement())
    return {
        "sim_time_s": _num(sim_time_s),
        "wall_time_s": _num(wall_time_s),
        "steps": totals.steps,
        "omega_rpm": _num(omega_rpm),
        "schedule": schedule.to_list(),
        "head_radius_m": _num(params.head_radius),
        "final_head_position_m": [_num(v) for v in np.asarray(sim.head_position, dtype=float)],
        "displacement_m": _num(displacement),
        "end_to_end_ratio": _num(sim.end_to_end_ratio()),
        "mean_motor_torque_Nm": _num(totals.torque_integral / t) if t > 0 else None,
        "mean_motor_power_W": _num(totals.energy_J / t) if t > 0 else None,
        "motor_turns": _num(turns),
        "distance_per_motor_turn_m": _num(displacement / turns) if turns > 0 else None,
        "max_reynolds": _num(totals.max_reynolds),
        "omega_bar": _num(params.omega_bar(omega_rpm * RPM_TO_RAD_S)),
        "t_bar": _num(params.t_bar(sim_time_s)),
        "interrupted": interrupted,
        "error": error,
        "params": {**dataclasses.asdict(params), **dataclasses.asdict(numerics)},
    }
