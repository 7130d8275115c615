"""Parameter sweeps: configuration, expansion, parallel runs, incremental writing, resume, Dask."""

from __future__ import annotations

import concurrent.futures
import json
import os
import shutil
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import batch.pool as task_pool
from flagellum.cli import main
from batch.sweep import (SweepConfig, SweepConfigError, SweepError, SweepIncomplete, SweepInterrupted,
                             load_results, load_sweep_config, run_sweep)
from batch.backends import BackendError, DaskBackend
from batch.store import ResultsStore, read_results
from batch.sweep_task import PointTask, run_point
from batch.worker import PointOutcome
from physics.params import NumericsConfig, SwimmerParams
from physics.run import Trajectory

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "sweep_small.yaml"
FAST = {"n_nodes": 25, "dt": 0.02}
VARYING = ("wall_time_s", "worker", "finished_at")  # what may differ between identical runs


def small_config(**changes) -> SweepConfig:
    kw = dict(sweep={"omega_rpm": [10, 20], "head_radius": [0.0, 0.012]}, duration_s=0.3, fixed=FAST)
    kw.update(changes)
    return SweepConfig(**kw)


def numbers(records: list[dict]) -> list[dict]:
    """Records without wall times, worker names and timestamps."""
    out = []
    for r in records:
        r = {k: v for k, v in r.items() if k not in VARYING}
        if r["summary"] is not None:
            r["summary"] = {k: v for k, v in r["summary"].items() if k != "wall_time_s"}
        out.append(r)
    return out


def lines(out_dir: Path) -> list[dict]:
    return [json.loads(ln) for ln in (out_dir / "results.jsonl").read_text().splitlines() if ln.strip()]


@pytest.fixture(scope="module")
def base_run(tmp_path_factory):
    """The 4-point sweep run once on 2 local processes: (config, out_dir, returned records)."""
    config = small_config()
    out = tmp_path_factory.mktemp("sweep") / "base"
    return config, out, run_sweep(config, out, workers=2, progress=False)


# --- configuration --------------------------------------------------------------------
def test_grid_expansion_is_the_cartesian_product_with_the_last_key_fastest():
    config = small_config()
    assert len(config) == 4
    assert config.combinations() == [{"omega_rpm": 10, "head_radius": 0.0}, {"omega_rpm": 10, "head_radius": 0.012},
                                     {"omega_rpm": 20, "head_radius": 0.0}, {"omega_rpm": 20, "head_radius": 0.012}]
    points = config.points()
    assert [p.index for p in points] == [0, 1, 2, 3]
    assert points[1].omega_rpm == 10.0 and points[1].params.head_radius == 0.012
    assert all(p.params.n_nodes == 25 and p.numerics.dt == 0.02 for p in points)


def test_zip_expansion_pairs_the_i_th_values():
    config = small_config(mode="zip")
    assert len(config) == 2
    assert config.combinations() == [{"omega_rpm": 10, "head_radius": 0.0}, {"omega_rpm": 20, "head_radius": 0.012}]


def test_preset_then_fixed_then_point_values_are_applied_in_that_order():
    config = SweepConfig(sweep={"dt": [0.01]}, duration_s=0.1, preset="paper", fixed={"omega_rpm": 10, "n_nodes": 26})
    (point,) = config.points()
    assert point.params.n_nodes == 26 and point.numerics.dt == 0.01
    from physics.presets import PRESETS

    assert point.numerics.hydro_refresh_tol == PRESETS["paper"]["numerics"]["hydro_refresh_tol"]  # from the preset
    assert point.omega_rpm == 10.0


BAD_CONFIGS = [
    ({"sweeps": {"omega_rpm": [1]}}, ["'sweeps'", "allowed keys", "sweep"]),
    ({"sweep": {"omega": [10]}}, ["'omega'", "omega_rpm", "head_radius"]),
    ({"sweep": {"omega_rpm": []}}, ["sweep.omega_rpm", "non-empty list"]),
    ({"sweep": {"omega_rpm": 10}}, ["sweep.omega_rpm", "non-empty list"]),
    ({"sweep": {"omega_rpm": [10, "fast"]}}, ["sweep.omega_rpm[1]", "'fast'", "not a number", "rpm"]),
    ({"sweep": {"omega_rpm": [10, True]}}, ["sweep.omega_rpm[1]", "not a number"]),
    ({"sweep": {"omega_rpm": [-5]}}, ["sweep.omega_rpm[0]", "-5", ">= 0"]),
    ({"sweep": {"head_radius": [0.0, 0.5]}, "fixed": {"omega_rpm": 10}}, ["sweep.head_radius[1]", "0.5", "<= 0.1"]),
    ({"sweep": {"hydro_model": ["lsbt", "bem"]}, "fixed": {"omega_rpm": 10}}, ["sweep.hydro_model[1]", "'bem'", "rft"]),
    ({"sweep": {"omega_rpm": [10]}, "duration_s": -1}, ["duration_s", "-1", "> 0"]),
    ({"sweep": {"omega_rpm": [10]}, "duration_s": "long"}, ["duration_s", "'long'", "not a number"]),
    ({"sweep": {"omega_rpm": [10]}, "duration_s": 0.01}, ["duration_s", "dt = 0.02"]),
    ({"sweep": {"omega_rpm": [10]}, "preset": "turbo"}, ["preset", "'turbo'", "paper", "fast"]),
    ({"sweep": {"omega_rpm": [10]}, "preset": "coarse"}, ["preset 'coarse' was retired", "use 'faithful'"]),
    ({"sweep": {"omega_rpm": [10]}, "mode": "cartesian"}, ["mode", "'cartesian'", "grid", "zip"]),
    ({"sweep": {"omega_rpm": [10, 20], "head_radius": [0.0]}, "mode": "zip"}, ["zip", "equal length", "grid"]),
    ({"sweep": {"head_radius": [0.0]}}, ["omega_rpm", "missing", "fixed"]),
    ({"sweep": {"omega_rpm": [10]}, "fixed": {"omega_rpm": 20}}, ["fixed.omega_rpm", "also under 'sweep'"]),
    ({"sweep": {"omega_rpm": [10]}, "fixed": {"n_nodes": 30.5}}, ["fixed.n_nodes", "30.5", "integer"]),
    ({"sweep": {"omega_rpm": [10]}, "fixed": {"nodes": 30}}, ["fixed", "'nodes'", "n_nodes"]),
    ({"sweep": {"omega_rpm": [10, 10.0]}}, ["points 0 and 1", "same run"]),
    ({"sweep": {"omega_rpm": [10]}, "save_trajectories": "yes"}, ["save_trajectories", "'yes'", "true or false"]),
    ({"sweep": {"omega_rpm": [10]}, "fixed": {"anderson_depth": 0}}, ["fixed", "'anderson_depth' was removed",
                                                                      "cost more CPU than it saved"]),
    ({"sweep": {"omega_rpm": [10]}, "fixed": {"rod_radius": 0.01}}, ["fixed.rod_radius", "helix_radius"]),
    ({"sweep": {"omega_rpm": [10], "rod_radius": [0.005], "helix_radius": [0.004]}},
     ["point 0", "rod_radius=0.005", "helix_radius=0.004", "smaller"]),
]


@pytest.mark.parametrize("changes, fragments", BAD_CONFIGS)
def test_bad_config_is_rejected_naming_the_key_and_what_is_allowed(changes, fragments):
    data = {"sweep": {"omega_rpm": [10]}, "duration_s": 0.3, "fixed": dict(FAST)}
    data.update(changes)
    if "fixed" in changes:
        data["fixed"] = {**FAST, **changes["fixed"]}
    with pytest.raises(SweepConfigError) as info:
        SweepConfig.from_mapping(data, source="my.yaml")
    message = str(info.value)
    assert message.startswith("my.yaml: ")
    for fragment in fragments:
        assert fragment in message, message


def test_missing_required_key_is_named():
    with pytest.raises(SweepConfigError, match="duration_s is missing"):
        SweepConfig.from_mapping({"sweep": {"omega_rpm": [10]}})


def test_yaml_and_toml_files_give_the_same_config(tmp_path):
    (tmp_path / "s.yaml").write_text("sweep:\n  omega_rpm: [10, 20]\n  head_radius: [0.0, 0.012]\n"
                                     "duration_s: 0.3\nfixed: {n_nodes: 25, dt: 0.02}\n")
    (tmp_path / "s.toml").write_text("duration_s = 0.3\n[sweep]\nomega_rpm = [10, 20]\nhead_radius = [0.0, 0.012]\n"
                                     "[fixed]\nn_nodes = 25\ndt = 0.02\n")
    assert load_sweep_config(tmp_path / "s.yaml") == load_sweep_config(tmp_path / "s.toml") == small_config()


def test_yaml_exponent_without_dot_is_read_as_a_number(tmp_path):
    path = tmp_path / "s.yaml"  # PyYAML reads 1e-3 as a string
    path.write_text("sweep: {omega_rpm: [10]}\nduration_s: 1e-2\nfixed: {dt: 1e-3, n_nodes: 25}\n")
    (point,) = load_sweep_config(path).points()
    assert point.numerics.dt == 1e-3


@pytest.mark.parametrize("name, text, fragments", [
    ("s.ini", "", ["s.ini", "'.ini'", ".yaml", ".toml"]),
    ("s.yaml", "sweep: [unclosed\n", ["s.yaml", "not valid YAML"]),
    ("s.toml", "sweep = \n", ["s.toml", "not valid TOML"]),
    ("s.yaml", "- 1\n- 2\n", ["s.yaml", "top level must be a mapping"]),
])
def test_unreadable_file_is_rejected_naming_the_file(tmp_path, name, text, fragments):
    (tmp_path / name).write_text(text)
    with pytest.raises(SweepConfigError) as info:
        load_sweep_config(tmp_path / name)
    for fragment in fragments:
        assert fragment in str(info.value)


def test_example_sweep_file_is_valid():
    config = load_sweep_config(EXAMPLE)
    assert len(config) == 4 and config.duration_s <= 1.0
    assert all(p.params.n_nodes <= 40 for p in config.points())


def test_point_ids_depend_on_every_setting_and_survive_adding_values():
    ids = [p.point_id for p in small_config().points()]
    assert ids == [p.point_id for p in small_config().points()] and len(set(ids)) == 4
    assert ids[0] not in {p.point_id for p in small_config(fixed={**FAST, "dt": 0.01}).points()}
    assert ids[0] not in {p.point_id for p in small_config(duration_s=0.4).points()}
    extended = small_config(sweep={"omega_rpm": [10, 20, 30], "head_radius": [0.0, 0.012]})
    assert set(ids) <= {p.point_id for p in extended.points()}


# --- results file ---------------------------------------------------------------------
def test_store_drops_a_torn_last_line_and_refuses_a_damaged_middle_line(tmp_path):
    good = json.dumps({"point_id": "a", "index": 0}) + "\n"
    (tmp_path / "results.jsonl").write_text(good + '{"point_id": "b", "ind')
    with ResultsStore(tmp_path, resume=True) as store:
        assert list(store.records) == ["a"]
        store.append({"point_id": "c", "index": 2})
        assert [r["point_id"] for r in lines(tmp_path)] == ["a", "c"]  # on disk at once
    (tmp_path / "results.jsonl").write_text(good + "garbage\n" + good)
    with pytest.raises(SweepError, match="line 2"):
        read_results(tmp_path / "results.jsonl")


def test_store_refuses_a_second_writer(tmp_path):
    with ResultsStore(tmp_path, resume=False):
        with pytest.raises(SweepError, match="another sweep"):
            with ResultsStore(tmp_path, resume=True):
                pass


def test_failed_point_is_recorded_with_its_error_not_raised():
    task = PointTask(0, "x", {"omega_rpm": 10}, 10.0, SwimmerParams(n_nodes=25),
                     NumericsConfig(dt=0.02), -1.0, 0.02, 0.1, True)
    outcome = run_point(task)
    assert outcome.record["status"] == "error" and "duration_s=-1.0" in outcome.record["error"]
    assert outcome.record["summary"] is None and outcome.trajectory is None


class FakeBackend:
    """Runs nothing: point ``lost`` fails as if its worker process died, the others 'finish' at once."""

    description = "fake"

    def __init__(self, lost: int | None = None) -> None:
        self.lost, self.submitted = lost, []

    def submit(self, task: PointTask) -> concurrent.futures.Future:
        self.submitted.append(task.index)
        fut: concurrent.futures.Future = concurrent.futures.Future()
        if task.index == self.lost:
            fut.set_exception(concurrent.futures.process.BrokenProcessPool("a worker died"))
        else:
            fut.set_result(PointOutcome({"index": task.index, "point_id": task.point_id, "values": task.values,
                                         "status": "ok", "error": None, "summary": {}, "trajectory": None}, None))
        return fut

    def as_completed(self, futures):
        return concurrent.futures.as_completed(list(futures))

    def abort(self, futures) -> None:
        pass

    def close(self) -> None:
        pass


def test_points_lost_to_a_dead_worker_are_reported_and_rerun_on_resume(tmp_path, monkeypatch):
    config = small_config()
    monkeypatch.setattr(task_pool, "make_backend", lambda workers, scheduler: FakeBackend(lost=1))
    with pytest.raises(SweepIncomplete, match=r"1 of 4 points did not finish \(point 1.*--resume") as info:
        run_sweep(config, tmp_path, progress=False)
    assert [r["index"] for r in info.value.results] == [0, 2, 3] and len(lines(tmp_path)) == 3
    again = FakeBackend()
    monkeypatch.setattr(task_pool, "make_backend", lambda workers, scheduler: again)
    assert [r["index"] for r in run_sweep(config, tmp_path, resume=True, progress=False)] == [0, 1, 2, 3]
    assert again.submitted == [1]


def test_failed_points_count_as_done_unless_retried(tmp_path, monkeypatch):
    config = small_config()
    first = FakeBackend()
    monkeypatch.setattr(task_pool, "make_backend", lambda workers, scheduler: first)
    run_sweep(config, tmp_path, progress=False)
    failed = {**lines(tmp_path)[2], "status": "error", "error": "SimulationError: diverged"}
    with open(tmp_path / "results.jsonl", "a") as f:
        f.write(json.dumps(failed) + "\n")
    for retry, expected in ((False, []), (True, [failed["index"]])):
        backend = FakeBackend()
        monkeypatch.setattr(task_pool, "make_backend", lambda workers, scheduler: backend)
        records = run_sweep(config, tmp_path, resume=True, progress=False, retry_failed=retry)
        assert backend.submitted == expected
        assert records[failed["index"]]["status"] == ("ok" if retry else "error")  # the last line counts


# --- real sweeps ----------------------------------------------------------------------
def test_sweep_writes_one_line_per_point_with_values_id_summary_and_trajectory(base_run):
    config, out, records = base_run
    points = config.points()
    assert [r["index"] for r in records] == [0, 1, 2, 3]
    on_disk = lines(out)
    assert sorted(r["point_id"] for r in on_disk) == sorted(p.point_id for p in points)
    for point, record in zip(points, records):
        assert record["point_id"] == point.point_id and record["values"] == point.values
        assert record["status"] == "ok" and record["error"] is None and record["wall_time_s"] > 0
        s = record["summary"]
        assert s["omega_rpm"] == point.omega_rpm and s["head_radius_m"] == point.params.head_radius
        assert s["steps"] == 15 and s["params"]["n_nodes"] == 25 and s["displacement_m"] > 0
        trajectory = Trajectory.load_npz(out / record["trajectory"])
        assert np.allclose(trajectory.head_positions[-1], s["final_head_position_m"])
    assert json.loads((out / "sweep_config.json").read_text())["config"] == config.to_dict()
    assert numbers(load_results(out, config)) == numbers(records)


def test_resume_runs_nothing_new_and_returns_the_same_records(base_run, monkeypatch):
    config, out, records = base_run
    before = (out / "results.jsonl").read_bytes()
    monkeypatch.setattr(task_pool, "make_backend", lambda *a: pytest.fail("resume started workers"))
    assert run_sweep(config, out, resume=True, progress=False) == records
    assert (out / "results.jsonl").read_bytes() == before


def test_running_again_without_resume_is_an_error(base_run):
    config, out, _ = base_run
    with pytest.raises(SweepError, match="--resume.*another --out"):
        run_sweep(config, out, progress=False)


def test_two_fresh_runs_give_identical_numbers(base_run, tmp_path):
    config, out, records = base_run
    again = run_sweep(config, tmp_path / "again", workers=2, progress=False)
    assert numbers(again) == numbers(records)
    first, second = (Trajectory.load_npz(d / records[3]["trajectory"]) for d in (out, tmp_path / "again"))
    assert np.array_equal(first.node_positions, second.node_positions)


def test_resume_after_a_crash_runs_only_the_missing_points(base_run, tmp_path):
    config, out, records = base_run
    survived = (out / "results.jsonl").read_text().splitlines(keepends=True)[:2]
    crashed = tmp_path / "crashed"
    crashed.mkdir()
    (crashed / "results.jsonl").write_text("".join(survived) + survived[0][:40])  # last line torn by the kill
    result = run_sweep(config, crashed, workers=2, resume=True, progress=False)
    assert numbers(result) == numbers(records)
    written = (crashed / "results.jsonl").read_text().splitlines(keepends=True)
    assert written[:2] == survived and len(written) == 4
    done_before = {json.loads(s)["point_id"] for s in survived}
    assert {json.loads(s)["point_id"] for s in written[2:]} == {r["point_id"] for r in records} - done_before


def test_ctrl_c_keeps_finished_points_and_resume_runs_the_rest(tmp_path):
    config = small_config(sweep={"omega_rpm": [10, 20, 30]}, duration_s=2.0, save_trajectories=False)
    out = tmp_path / "interrupted"
    results_file = out / "results.jsonl"

    def press_ctrl_c_after_first_point() -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if results_file.exists() and results_file.read_text().count("\n") >= 1:
                os.kill(os.getpid(), signal.SIGINT)
                return
            time.sleep(0.005)

    # Ctrl-C as in an interactive run (a process started in the background inherits SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    watcher = threading.Thread(target=press_ctrl_c_after_first_point, daemon=True)
    watcher.start()
    try:
        with pytest.raises(SweepInterrupted) as info:
            run_sweep(config, out, workers=1, progress=False)
    finally:
        signal.signal(signal.SIGINT, previous)
    watcher.join()
    assert 1 <= len(info.value.results) < 3 and info.value.total == 3
    kept = lines(out)
    assert 1 <= len(kept) < 3
    rest = run_sweep(config, out, workers=2, resume=True, progress=False)
    assert [r["index"] for r in rest] == [0, 1, 2] and len(lines(out)) == 3
    assert not (out / "points").exists()


# --- Dask -----------------------------------------------------------------------------
def test_local_dask_cluster_gives_the_same_numbers_and_resumes(base_run, tmp_path):
    distributed = pytest.importorskip("distributed")
    config, out, records = base_run
    dask_out = tmp_path / "dask"
    dask_out.mkdir()
    shutil.copy(out / "results.jsonl", dask_out / "results.jsonl")
    kept = (dask_out / "results.jsonl").read_text().splitlines(keepends=True)[:1]
    (dask_out / "results.jsonl").write_text("".join(kept))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        result = run_sweep(config, dask_out, resume=True, progress=False, scheduler=cluster.scheduler_address)
    assert numbers(result) == numbers(records)
    assert len(lines(dask_out)) == 4
    ran = [r for r in result if r["point_id"] != json.loads(kept[0])["point_id"]]
    assert len(ran) == 3 and all((dask_out / r["trajectory"]).exists() for r in ran)


def test_missing_dask_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "distributed", None)
    with pytest.raises(BackendError, match=r"pip install 'dask\[distributed\]'"):
        DaskBackend("tcp://127.0.0.1:8786")


# --- command line ---------------------------------------------------------------------
def test_cli_runs_the_example_sweep_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "cli"
    argv = ["sweep", "--config", str(EXAMPLE), "--out", str(out), "--workers", "2", "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "omega_rpm" in printed and "head_radius" in printed and "wrote" in printed
    assert len(lines(out)) == 4
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flagellum: error: ") and "--resume" in err[0]
    assert main(argv + ["--resume"]) == 0


@pytest.mark.parametrize("text, fragments", [
    ("sweep: {omega: [10]}\nduration_s: 0.3\n", ["'omega'", "omega_rpm"]),
    ("sweep: {omega_rpm: [10]}\nduration_s: -2\n", ["duration_s", "> 0"]),
    ("sweep: {omega_rpm: []}\nduration_s: 0.3\n", ["sweep.omega_rpm", "non-empty"]),
])
def test_cli_bad_config_exits_2_with_one_line(tmp_path, capsys, text, fragments):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(SystemExit) as info:
        main(["sweep", "--config", str(path), "--out", str(tmp_path / "o")])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flagellum: error: ") and "Traceback" not in err[0]
    for fragment in fragments:
        assert fragment in err[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("extra, fragments", [
    (["--set", "head_radius=0"], ["--set head_radius", "swept"]),
    (["--set", "dt=abc"], ["--set", "dt", "'abc'", "not a number"]),
    (["--workers", "0"], ["--workers", "'0'", ">= 1"]),
    (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], ["--workers and --scheduler"]),
])
def test_cli_bad_options_exit_2_with_one_line(tmp_path, capsys, extra, fragments):
    with pytest.raises(SystemExit) as info:
        main(["sweep", "--config", str(EXAMPLE), "--out", str(tmp_path / "o"), *extra])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flagellum: error: ")
    for fragment in fragments:
        assert fragment in err[0]
