"""stop_vec_workers (agents/ppo_training.py): the env workers of an interrupted training run are stopped at once,
also a worker that ignores SIGTERM and is stuck inside a step (the raw-env baseline's workers ignore SIGINT and
SIGTERM; a worker inside a long compiled step answers no signal until it returns)."""

from __future__ import annotations

import functools
import os
import signal
import time

import pytest


def test_a_stuck_worker_that_ignores_sigterm_is_stopped_within_seconds():
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    import numpy as np
    from stable_baselines3.common.vec_env import SubprocVecEnv, VecMonitor

    from agents.ppo_training import stop_vec_workers

    old = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        venv = VecMonitor(SubprocVecEnv([functools.partial(gym.make, "CartPole-v1")] * 2, start_method="spawn"))
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    procs = venv.venv.processes
    venv.reset()
    os.kill(procs[0].pid, signal.SIGSTOP)  # stuck: it will not answer the step below
    venv.step_async(np.zeros(2, dtype=np.int64))
    t0 = time.monotonic()
    assert stop_vec_workers(venv)
    assert time.monotonic() - t0 < 10.0
    assert not any(p.is_alive() for p in procs) and venv.venv.closed
