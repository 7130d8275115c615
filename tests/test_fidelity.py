"""The fidelity ladder machinery (flagellum.fidelity): metrics, resumable results, errors vs paper."""

from __future__ import annotations

import json

import pytest

from flagellum.fidelity import FidelityConfig, load_done, rows_from, run_fidelity, run_metric
from flagellum.fidelity_report import markdown

TINY = FidelityConfig("tiny", params={"n_nodes": 20}, numerics={"dt": 0.05, "hydro_refresh_tol": 0.3})


def test_swim_metric_reports_a_forward_distance_and_a_cost():
    out = run_metric(TINY, "swim_per_turn_10rpm")
    assert 0.001 < out["swim_per_turn_10rpm"] < 0.01  # m per motor turn
    assert out["rtf"] > 0


def test_unknown_metric_is_rejected():
    with pytest.raises(ValueError, match="unknown metric"):
        run_metric(TINY, "speed")


def test_results_are_written_incrementally_and_resumed(tmp_path):
    path = tmp_path / "r.jsonl"
    done = run_fidelity(path, (TINY,), ("swim_per_turn_10rpm",), workers=1, progress=False)
    assert len(path.read_text().splitlines()) == 1
    again = run_fidelity(path, (TINY,), ("swim_per_turn_10rpm",), workers=1, progress=False)
    assert len(path.read_text().splitlines()) == 1  # nothing re-run
    assert again == done == load_done(path)


def test_errors_are_relative_to_paper_with_an_angle_floor():
    done = {
        ("paper", "m"): {"config": "paper", "metric": "m", "error": None,
                         "result": {"swim_per_turn_10rpm": 0.004, "theta_tc10": 2.0, "rtf": 1.0}},
        ("tiny", "m"): {"config": "tiny", "metric": "m", "error": None,
                        "result": {"swim_per_turn_10rpm": 0.005, "theta_tc10": 5.0, "rtf": 10.0}},
    }
    rows = rows_from(done, (FidelityConfig("paper", "paper"), TINY))
    tiny = rows[1]
    assert tiny["errors"]["swim_per_turn_10rpm"] == pytest.approx(0.25)
    assert tiny["errors"]["theta_tc10"] == pytest.approx(3.0 / 10.0)  # floor of 10 degrees
    assert rows[0]["errors"]["swim_per_turn_10rpm"] == 0.0
    assert "tiny" in markdown(rows, "# t")
    json.dumps(rows)
