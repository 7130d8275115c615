"""Issue 24: `follow` and `train` stopped by Ctrl-C (SIGINT) or SIGTERM write what they computed and exit 130 without
a traceback; killing `train` (SIGKILL) leaves none of its env worker processes behind. Real processes, as in
tests/test_cli_faults.py. The training runs are tiny (faithful preset, one-turn paths) but still take ~30-45 s each:
the start of a run (imports, the envs' steady start, the first decision) is most of it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

pytest.importorskip("psutil")
import psutil  # noqa: E402

# long enough that the episode is still running when the signal comes (~1000 simulated s: a minute even at faithful)
LONG = {"name": "long", "waypoints": [[0.2, 0.0, 0.0], [0.2, 0.2, 0.0]], "reach_radius_m": 0.01}
ONE_TURN = {"n_waypoints": 1, "segment_length_m": [0.03, 0.04], "min_turn_deg": 70.0, "max_turn_deg": 90.0}


def tiny_config(n_envs: int) -> dict:
    return {"tiny": {"n_envs": n_envs, "n_timesteps": 400, "seed": 0, "checkpoint_every": 100, "n_steps": 4,
                     "batch_size": 4, "n_epochs": 1, "policy_kwargs": {"net_arch": [8], "log_std_init": -1.0},
                     "task": {"preset": "faithful", "limits": {"max_dtc_fraction": 0.1},
                              "curriculum": [{"name": "one", "until": 400, "random_path": ONE_TURN}],
                              "validation": {"seeds": [5], "every": 1000, "random_path": ONE_TURN}}}}


def _cli(args: list[str], cwd: Path) -> subprocess.Popen:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    # a pytest-xdist worker ignores SIGINT and a child inherits that (then Python installs no KeyboardInterrupt
    # handler): give the command the default disposition a terminal's foreground process has
    return subprocess.Popen([sys.executable, "-m", "flagellum.cli", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def _wait_for(proc: subprocess.Popen, ready, deadline_s: float = 180.0) -> None:
    end = time.monotonic() + deadline_s
    while not ready():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end, "the run did not get going"
        time.sleep(0.2)


def _busiest_cpu_s(proc: subprocess.Popen, n: int) -> list[float]:
    """CPU seconds (user + system) of the ``n`` busiest child processes of ``proc`` (fewer if it has fewer)."""
    cpu = []
    for child in psutil.Process(proc.pid).children(recursive=True):
        try:
            times = child.cpu_times()
        except psutil.NoSuchProcess:
            continue
        cpu.append(times.user + times.system)
    return sorted(cpu, reverse=True)[:n] if len(cpu) >= n else []


def _running_after(procs: list[psutil.Process], seconds: float) -> list[psutil.Process]:
    """Those of ``procs`` still running after ``seconds`` (an exited child of a killed parent may stay a zombie
    until its new parent reaps it: that counts as gone)."""
    end = time.monotonic() + seconds
    while True:
        running = []
        for p in procs:
            try:
                if p.status() != psutil.STATUS_ZOMBIE:
                    running.append(p)
            except psutil.NoSuchProcess:
                pass
        if not running or time.monotonic() > end:
            return running
        time.sleep(0.05)


def _reap(proc: subprocess.Popen, extra=()) -> None:
    """Never leave a process of a test behind."""
    for p in [*extra, *([psutil.Process(proc.pid)] if proc.poll() is None else [])]:
        try:
            p.kill()
        except psutil.NoSuchProcess:
            pass


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_an_interrupted_follow_writes_the_episode_so_far(tmp_path, sig):
    path = tmp_path / "long.json"
    path.write_text(json.dumps(LONG))
    out = tmp_path / "o"
    proc = _cli(["follow", "--path", str(path), "--preset", "faithful", "--out", str(out), "--no-progress"], tmp_path)
    try:
        _wait_for(proc, lambda: out.is_dir())  # the episode is about to start (controllers built, folder made)
        time.sleep(3.0)  # into the episode
        proc.send_signal(sig)
        stdout, err = proc.communicate(timeout=120)
    finally:
        _reap(proc)
    assert proc.returncode == 130, err
    assert b"Traceback" not in err and b"SystemError" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["controllers"]["rule"]["interrupted"] is True
    assert 0.0 <= summary["controllers"]["rule"]["time_s"] < 200.0
    for name in ("trace.npz", "path.png", "omega.png"):
        assert (out / name).is_file(), name
    assert b"interrupted" in stdout


def test_an_interrupted_parallel_follow_writes_every_episode_so_far(tmp_path):
    # two controllers run at once (the default: one worker process per controller); SIGTERM to the command asks
    # both episodes to stop after their step, and each writes what it computed; no worker outlives the command
    path = tmp_path / "long.json"
    path.write_text(json.dumps(LONG))
    out = tmp_path / "o"
    proc = _cli(["follow", "--path", str(path), "--preset", "faithful", "--controller", "rule", "--controller",
                 "adaptive", "--out", str(out), "--no-progress"], tmp_path)
    kids: list[psutil.Process] = []
    try:
        _wait_for(proc, lambda: out.is_dir() and len(psutil.Process(proc.pid).children(recursive=True)) >= 2)
        # into both episodes: the two busiest workers have each had 6 s of CPU (on an idle machine, ~6 s of wall
        # time; counted in CPU so that a loaded machine does not interrupt an episode before its first step)
        _wait_for(proc, lambda: min(_busiest_cpu_s(proc, 2), default=0.0) >= 6.0)
        kids = psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGTERM)
        stdout, err = proc.communicate(timeout=120)
        alive = _running_after(kids, 2.0)
    finally:
        _reap(proc, kids)
    assert proc.returncode == 130, err
    assert b"Traceback" not in err and b"BrokenProcessPool" not in err
    assert not alive, f"worker processes {[p.pid for p in alive]} outlived the command"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["not_run"] == []
    for spec in ("rule", "adaptive"):
        m = summary["controllers"][spec]
        assert m["interrupted"] is True and 0.0 < m["time_s"] < 500.0, (spec, m["time_s"])
        assert (out / f"trace_{spec}.npz").is_file()
    for name in ("path.png", "omega.png"):
        assert (out / name).is_file(), name
    assert b"interrupted" in stdout


def test_sigterm_stops_train_and_saves_the_model_and_a_checkpoint(tmp_path):
    cfg = tmp_path / "tiny.yml"
    cfg.write_text(yaml.safe_dump(tiny_config(1)))
    out = tmp_path / "run"
    proc = _cli(["train", "--config", str(cfg), "--out", str(out), "--no-progress"], tmp_path)
    try:
        _wait_for(proc, lambda: (out / "meta.json").is_file())  # training has started
        time.sleep(2.0)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        _reap(proc)
    assert proc.returncode == 130, err
    assert b"Traceback" not in err
    meta = json.loads((out / "meta.json").read_text())
    assert meta["interrupted"] is True and meta["finished"] is False
    for name in ("model.zip", "vecnormalize.pkl", f"checkpoints/rl_model_{meta['decisions']}_steps.zip",
                 f"checkpoints/rl_model_vecnormalize_{meta['decisions']}_steps.pkl"):
        assert (out / name).is_file(), name


def test_killing_train_leaves_no_env_worker_behind(tmp_path):
    cfg = tmp_path / "tiny.yml"
    cfg.write_text(yaml.safe_dump(tiny_config(2)))
    out = tmp_path / "run"
    proc = _cli(["train", "--config", str(cfg), "--out", str(out), "--no-progress"], tmp_path)
    kids: list[psutil.Process] = []
    try:
        _wait_for(proc, lambda: (out / "meta.json").is_file())  # the two env workers are stepping
        time.sleep(1.0)
        kids = psutil.Process(proc.pid).children(recursive=True)
        assert len(kids) >= 2
        proc.kill()
        alive = _running_after(kids, 2.0)
        _, err = proc.communicate(timeout=30)
    finally:
        _reap(proc, kids)
    assert not alive, f"processes {[p.pid for p in alive]} outlived their killed parent by 2 s"
    assert b"BrokenPipeError" not in err and b"Traceback" not in err
