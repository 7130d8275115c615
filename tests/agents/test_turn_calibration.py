"""Calibration end to end (faithful preset): a 4.5 s burst at 150 rpm (on the rising branch) turns the swimmer, by the same
angle whatever the flagellum's phase at the burst, and the phase sets the turn's direction."""

from __future__ import annotations

import pytest

import batch.pool as task_pool
from agents.turn_calibration import calibrate_turns, calibration_tasks, runs_dir
from agents.turn_map import TurnMap
from physics.presets import apply_preset


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    out = tmp_path_factory.mktemp("cal") / "faithful.json"
    p, n = apply_preset("faithful")
    tmap = calibrate_turns(p, n, out, preset="faithful", t_c_values=[4.5], phases_deg=[0.0, 90.0], workers=1,
                           progress=False)
    return out, tmap


def test_turn_is_phase_independent_in_size_and_tied_to_the_phase_in_direction(calibrated):
    _, tmap = calibrated
    a, b = sorted(tmap.points, key=lambda p: p.phase_deg)
    assert a.straight and b.straight
    assert 40.0 < a.theta_deg < 110.0  # a real turn (about 70 deg for this preset)
    assert abs(a.theta_deg - b.theta_deg) < 5.0
    assert abs((a.psi_deg - b.psi_deg + 180.0) % 360.0 - 180.0) < 20.0
    assert abs(a.phi_deg - b.phi_deg) > 20.0  # a quarter rotation later, the turn leaves the plane differently
    assert 5.0 < a.period_s < 15.0


def test_map_file_round_trip_and_resume_runs_nothing(calibrated, monkeypatch):
    out, tmap = calibrated
    assert TurnMap.load(out) == tmap
    assert (runs_dir(out) / "results.jsonl").is_file()
    monkeypatch.setattr(task_pool, "make_backend", lambda *a: pytest.fail("resume started workers"))
    p, n = apply_preset("faithful")
    again = calibrate_turns(p, n, out, preset="faithful", t_c_values=[4.5], phases_deg=[0.0, 90.0], resume=True,
                            progress=False)
    assert again.points == tmap.points


def test_bad_grid_is_rejected_naming_the_values():
    p, n = apply_preset("faithful")
    with pytest.raises(ValueError, match="omega_l_rpm=20"):
        calibration_tasks(p, n, omega_l_rpm=20.0, omega_h_rpm=10.0)
    with pytest.raises(ValueError, match="phases"):
        calibration_tasks(p, n, phases_deg=[400.0])


def test_a_turn_measured_on_a_dask_cluster_equals_the_local_one(calibrated, tmp_path):
    """``scheduler=``: the same task pool on a Dask LocalCluster (resume the run with one turn missing)."""
    import shutil

    distributed = pytest.importorskip("distributed")
    out, tmap = calibrated
    dask_out = tmp_path / "faithful.json"
    shutil.copytree(runs_dir(out), runs_dir(dask_out))
    records = runs_dir(dask_out) / "results.jsonl"
    records.write_text(records.read_text().splitlines(keepends=True)[0])
    p, n = apply_preset("faithful")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        again = calibrate_turns(p, n, dask_out, preset="faithful", t_c_values=[4.5], phases_deg=[0.0, 90.0],
                                resume=True, progress=False, scheduler=cluster.scheduler_address)
    assert len(records.read_text().splitlines()) == 2
    assert again.points == tmap.points
