"""The ``flagellum`` command line, run in-process through ``flagellum.cli.main``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flagellum.cli import main
from physics.errors import SimulationError
from physics.params import parameter_table


def test_params_table_lists_every_parameter_with_unit_and_range(capsys):
    assert main(["params"]) == 0
    out = capsys.readouterr().out
    for row in parameter_table():
        line = next(ln for ln in out.splitlines() if ln.split() and ln.split()[0] == row["name"])
        assert row["unit"] in line and row["allowed"] in line and row["help"] in line


def test_params_json_is_a_list_of_every_parameter(capsys):
    assert main(["params", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == [r["name"] for r in parameter_table()]
    assert {"name", "default", "unit", "allowed", "help", "value"} <= set(rows[0])


def test_params_with_set_shows_the_overridden_value(capsys):
    assert main(["params", "--json", "--set", "head_radius=0", "--set", "dt=0.002"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["head_radius"]["value"] == 0.0 and rows["head_radius"]["default"] == 0.012
    assert rows["dt"]["value"] == 0.002
    assert main(["params", "--set", "head_radius=0"]) == 0
    assert "value" in capsys.readouterr().out.splitlines()[0]


SIM = ["simulate", "--duration", "0.01"]


@pytest.mark.parametrize("argv, fragments", [
    (SIM + ["--omega-rpm", "-5"], ["-5", "allowed", ">= 0"]),
    (SIM + ["--omega-rpm", "nan"], ["nan", "allowed"]),
    (SIM + ["--omega-rpm", "fast"], ["'fast'", "not a number"]),
    (SIM + ["--omega-rpm", "20000"], ["20000", "<= 10000"]),
    (SIM + ["--omega-rpm", "10", "--head-radius", "-0.01"], ["head_radius=-0.01", ">= 0"]),
    (SIM + ["--omega-rpm", "10", "--head-radius", "big"], ["'big'", "not a number"]),
    (SIM + ["--omega-rpm", "10", "--set", "no_such=1"], ["'no_such'", "known parameters", "head_radius"]),
    (SIM + ["--omega-rpm", "10", "--set", "viscosity=thick"], ["viscosity='thick'", "not a number"]),
    (SIM + ["--omega-rpm", "10", "--set", "viscosity=-1"], ["viscosity=-1.0", "allowed"]),
    (SIM + ["--omega-rpm", "10", "--set", "novalue"], ["'novalue'", "NAME=VALUE"]),
    (SIM + ["--omega-rpm", "10", "--set", "head_rotation=wobble"], ["'wobble'", "torque_free"]),
    (SIM + ["--omega-rpm", "10", "--set", "head_rotation=literal", "--set", "head_model=stokes"],
     ["head_rotation='literal'", "head_model='stokes'", "allowed"]),
    (SIM + ["--omega-rpm", "10", "--head-radius", "0.01", "--set", "head_radius=0.02"], ["both given"]),
    (["simulate", "--omega-rpm", "10", "--duration", "-1"], ["'-1'", "> 0"]),
    (["simulate", "--omega-rpm", "10", "--duration", "1e-5", "--preset", "paper"], ["1e-05", "time step"]),
    (["simulate", "--omega-rpm", "10"], ["--duration"]),
    (["simulate", "--duration", "1"], ["--omega-rpm", "--schedule"]),
    (SIM + ["--omega-rpm", "10", "--schedule", "x.csv"], ["not allowed with"]),
    (SIM + ["--schedule", "does/not/exist.csv"], ["does/not/exist.csv"]),
    (["params", "--set", "dt=0"], ["dt=0.0", "> 0"]),
    (["fly"], ["'fly'", "simulate"]),
])
def test_bad_input_gives_one_line_error_and_status_2(usage_error, tmp_path, argv, fragments):
    line = usage_error(argv + (["--out", str(tmp_path / "o")] if argv[0] == "simulate" else []))
    for frag in fragments:
        assert frag in line, line
    assert not (tmp_path / "o" / "summary.json").exists()


def test_bad_schedule_file_error_names_file_and_row(usage_error, tmp_path):
    f = tmp_path / "s.csv"
    f.write_text("time_s,omega_rpm\n0,10\n5,-60\n")
    line = usage_error(SIM + ["--schedule", str(f), "--out", str(tmp_path / "o")])
    assert str(f) in line and "row 3" in line and "-60" in line


def _simulator_available() -> bool:
    try:
        import physics.simulator  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.skipif(not _simulator_available(), reason="physics.elastic is not available yet")
def test_simulate_writes_summary_trajectory_and_plot(capsys, tmp_path):
    out = tmp_path / "run"
    code = main(["simulate", "--omega-rpm", "60", "--duration", "0.02", "--preset", "paper", "--set", "n_nodes=20",
                 "--out", str(out), "--no-progress"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 20 and summary["error"] is None and summary["omega_rpm"] == 60.0
    assert summary["params"]["n_nodes"] == 20
    assert (out / "trajectory.npz").stat().st_size > 0
    assert (out / "trajectory.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "wrote" in capsys.readouterr().out


class _TinyFake:
    """Minimal duck-typed simulator: stands still, fails or is interrupted at step ``stop_at``."""

    def __init__(self, dt: float, stop_at: int, exc: BaseException) -> None:
        self.dt, self.stop_at, self.exc = dt, stop_at, exc
        self.time, self.step_count, self.motor_torque, self.motor_power = 0.0, 0, 0.0, 0.0
        self.nodes = np.column_stack([-0.01 * np.arange(8), np.zeros(8), np.zeros(8)])
        self.head_position = np.zeros(3)
        self.head_orientation = np.eye(3)

    def set_motor_speed(self, omega_rad_s: float) -> None:
        pass

    def step(self, duration_s: float | None = None) -> None:
        if self.step_count + 1 == self.stop_at:
            raise self.exc
        self.time += self.dt if duration_s is None else duration_s
        self.step_count += 1

    def end_to_end_ratio(self) -> float:
        return 1.0

    def displacement(self) -> float:
        return 0.0

    def reynolds_number(self) -> float:
        return 0.0


def _inject(monkeypatch, stop_at: int, exc: BaseException) -> None:
    import flagellum.commands.simulate as sim_cmd
    from physics.run import run_simulation as real_run

    def fake_run(params, numerics, schedule, duration_s, **kw):
        return real_run(params, numerics, schedule, duration_s, simulator=_TinyFake(numerics.dt, stop_at, exc), **kw)

    monkeypatch.setattr(sim_cmd, "run_simulation", fake_run)


def test_simulate_on_simulation_error_writes_partial_results_and_exits_1(capsys, tmp_path, monkeypatch):
    _inject(monkeypatch, 6, SimulationError("boom", 5, 0.005, "Newton"))
    out = tmp_path / "run"
    assert main(["simulate", "--omega-rpm", "60", "--duration", "1", "--out", str(out), "--no-progress"]) == 1
    captured = capsys.readouterr()
    assert "simulation failed" in captured.err and "boom" in captured.err
    assert "Traceback" not in captured.err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 5 and "boom" in summary["error"]
    assert (out / "trajectory.npz").exists() and (out / "trajectory.png").exists()


def test_simulate_on_ctrl_c_writes_partial_results_and_says_so(capsys, tmp_path, monkeypatch):
    _inject(monkeypatch, 4, KeyboardInterrupt())
    out = tmp_path / "run"
    assert main(["simulate", "--omega-rpm", "60", "--duration", "1", "--out", str(out), "--no-progress"]) == 130
    assert "interrupted" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["steps"] == 3
    assert (out / "trajectory.npz").exists() and (out / "trajectory.png").exists()


def test_the_simulate_plot_title_describes_the_schedule_not_its_mean():
    from flagellum.plots import schedule_label
    from physics.schedule import MotorSchedule

    assert schedule_label(MotorSchedule(((0.0, 10.0), (10.0, 90.0))), 20.0) == "omega: 10 → 90 rpm at t = 10 s"
    assert schedule_label(MotorSchedule(((0.0, 10.0), (10.0, 90.0))), 5.0) == "omega = 10 rpm"  # the step never came
    assert schedule_label(MotorSchedule.constant(60.0)) == "omega = 60 rpm"
    many = schedule_label(MotorSchedule(tuple((float(i), 10.0 + i) for i in range(7))), 20.0)
    assert many.startswith("omega: 10 → 11 → 12 → 13 → … rpm") and "(7 steps)" in many


def test_python_dash_m_flagellum_is_the_same_command_line():
    """``python -m flagellum`` runs ``flagellum.cli.main``: the same help and the same exit status for bad input."""
    import subprocess
    import sys

    ok = subprocess.run([sys.executable, "-m", "flagellum", "params", "--json"], capture_output=True, text=True)
    assert ok.returncode == 0 and ok.stdout.lstrip().startswith("["), ok.stderr
    bad = subprocess.run([sys.executable, "-m", "flagellum", "follow", "--controller", "adaptive@cap=0"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.strip().startswith("flagellum: error:") and "cap='0'" in bad.stderr


def test_train_engine_ray_without_ray_names_the_extra_and_sb3_refuses_an_address(usage_error, monkeypatch, tmp_path):
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    line = usage_error(["train", "--engine", "ray", "--out", str(tmp_path / "o")])
    assert "--engine ray" in line and "pip install '.[ray]'" in line
    line = usage_error(["train", "--address", "auto", "--out", str(tmp_path / "o")])
    assert "--address 'auto'" in line and "--engine ray" in line
    assert not (tmp_path / "o").exists()


def test_train_help_names_both_engines_and_the_ray_controller(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--engine {sb3,ray}" in text and "rllib_ppo_surrogate.yml" in text and "--controller rllib:DIR" in text


RETIRED = {"coarse": "slower than 'faithful' and wrong: it does not buckle"}


@pytest.mark.parametrize("preset", sorted(RETIRED))
@pytest.mark.parametrize("command", [["simulate", "--omega-rpm", "10", "--duration", "0.1"], ["params"],
                                     ["calibrate-turns", "--t-c", "5", "--phases", "0"],
                                     ["follow", "--path", "square"], ["evaluate", "--paths", "square"]])
def test_a_retired_preset_is_refused_on_one_line_with_status_2_before_any_output(usage_error, capsys, tmp_path,
                                                                                   command, preset):
    out = tmp_path / "o"
    argv = [*command, "--preset", preset] + ([] if command == ["params"] else ["--out", str(out)])
    line = usage_error(argv)
    assert line == (f"flagellum: error: argument --preset: preset {preset!r} was retired ({RETIRED[preset]}; "
                    "docs/presets.md); use 'faithful' (the default), or FlagellumTurn-surrogate-v0 / "
                    f"FlagellumBurst-surrogate-v0 for a cheap turn-level swimmer (see 'flagellum {command[0]} --help')")
    assert capsys.readouterr().out == "" and not out.exists()


def test_the_preset_choices_in_help_are_the_live_presets_only(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "{reference,paper,faithful,fast}" in text and "coarse" not in text


@pytest.mark.parametrize("preset", sorted(RETIRED))
def test_a_training_config_with_a_retired_preset_is_refused_before_any_output(usage_error, capsys, tmp_path, preset):
    import yaml

    from agents.assets import package_file

    doc = yaml.safe_load(package_file("configs", "ppo_residual_adaptive.yml").read_text())
    doc[next(iter(doc))]["task"]["preset"] = preset
    cfg, out = tmp_path / "cfg.yml", tmp_path / "o"
    cfg.write_text(yaml.safe_dump(doc))
    line = usage_error(["train", "--config", str(cfg), "--out", str(out)])
    assert str(cfg) in line and f"preset {preset!r} was retired ({RETIRED[preset]}; docs/presets.md); use " \
                                  "'faithful' (the default)" in line
    assert capsys.readouterr().out == "" and not out.exists()
