"""BLAS threads: importing the packages changes no environment variable; the run loop holds BLAS at one
thread with threadpoolctl while it steps and gives the caller's setting back afterwards."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from physics import Simulator, advance, configure

ROOT = Path(__file__).resolve().parents[2]
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@pytest.mark.parametrize("module", ["flagellum_env", "agents", "physics", "batch"])
def test_importing_the_package_sets_no_thread_variable(module):
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    code = (f"import {module}, os\n"
            "import flagellum_env.steer_env, physics.simulator  # the heavy modules too\n"
            f"print([os.environ.get(k) for k in {THREAD_VARIABLES!r}])")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300,
                       check=False)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[None, None, None]"


def test_the_issues_one_liner_prints_none():
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    r = subprocess.run([sys.executable, "-c", "import flagellum_env, os; print(os.environ.get('OPENBLAS_NUM_THREADS'))"],
                       capture_output=True, text=True, env=env, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "None"


def _blas_threads() -> set[int]:
    return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}


def test_the_run_loop_holds_blas_at_one_thread_and_restores_the_callers_setting():
    sim = Simulator(*configure("faithful", {"n_nodes": 25}))
    seen: list[set[int]] = []
    with threadpool_limits(limits=2, user_api="blas"):
        assert _blas_threads() == {2}
        advance(sim, steps=2, on_step=lambda s, k: seen.append(_blas_threads()))
        assert _blas_threads() == {2}  # the caller's setting is back
    assert seen == [{1}, {1}]


def test_a_direct_step_is_held_at_one_thread_too_and_gives_the_run_loops_numbers():
    import numpy as np

    from physics.params import RPM_TO_RAD_S
    from physics.threads import one_blas_thread

    seen: list[set[int]] = []
    probe = one_blas_thread(lambda: seen.append(_blas_threads()))
    a, b = (Simulator(*configure("faithful", {"n_nodes": 25})) for _ in range(2))
    for sim in (a, b):
        sim.set_motor_speed(30 * RPM_TO_RAD_S)
    with threadpool_limits(limits=2, user_api="blas"):
        probe()
        for _ in range(3):
            a.step()  # the caller's 2 threads outside the step
        advance(b, steps=3)
        assert _blas_threads() == {2}
    assert seen == [{1}] and np.array_equal(a.q, b.q)


def test_the_outermost_block_sets_only_what_differs_and_restores_it():
    from physics.threads import simulation_threads

    with threadpool_limits(limits=1, user_api="blas"):
        with simulation_threads():
            assert _blas_threads() == {1}
        assert _blas_threads() == {1}
    with threadpool_limits(limits=2, user_api="blas"):
        with simulation_threads():
            with simulation_threads():  # nested: nothing changes
                assert _blas_threads() == {1}
            assert _blas_threads() == {1}
        assert _blas_threads() == {2}
