"""scripts/control_report.py: docs/control.md and control.json from evaluation folders (made up here)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "control_report.py"
PATHS = ("3d_1", "planar_1")


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("control_report", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _folder(root: Path, name: str, level: float, success: dict[str, tuple[bool, bool]],
            xte_cm: dict[str, float]) -> Path:
    """An evaluate folder: two paths, the given controllers' success per path and mean cross-track."""
    per_path, aggregate = [], {}
    for c, ok in success.items():
        for path, s in zip(PATHS, ok):
            per_path.append({"path": path, "controller": c, "success": s, "mean_cross_track_m": xte_cm[c] / 100})
        aggregate[c] = {"episodes": 2, "success_rate": sum(ok) / 2, "mean_cross_track_m": xte_cm[c] / 100,
                        "max_out_of_plane_ratio": 0.05, "failed_runs": 0}
    overrides = {"randomize": {"youngs_modulus": level, "viscosity": level, "head_radius": level,
                               "geometry": 0.4 * level}} if level else {}
    folder = root / name
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps({
        "per_path": per_path, "aggregate": aggregate, "preset": "faithful", "env_overrides": overrides,
        "seeds": {p: 500 + k for k, p in enumerate(PATHS)}, "missing": []}))
    return folder


def test_the_report_tabulates_each_level(script, tmp_path):
    nominal = _folder(tmp_path, "a", 0.0, {"rule": (True, True), "ppo": (True, True)}, {"rule": 0.5, "ppo": 0.7})
    rand10 = _folder(tmp_path, "b", 0.1, {"rule": (False, True), "ppo": (True, True)}, {"rule": 3.0, "ppo": 1.5})
    docs = tmp_path / "docs"
    # given out of order: the table goes nominal, then ±10 %
    assert script.main(["--eval", str(rand10), str(nominal), "--docs", str(docs)]) == 0
    text = (docs / "control.md").read_text()
    assert "| `rule` | 100 %, 0.50 cm, 5.0 % | 50 %, 3.00 cm, 5.0 % |" in text
    assert "| `ppo` | 100 %, 0.70 cm, 5.0 % | 100 %, 1.50 cm, 5.0 % |" in text
    assert "- nominal: best `rule` (100 %, 0.50 cm); not finished: none" in text
    assert "- ±10 %: best `ppo` (100 %, 1.50 cm); not finished: `rule` 3d_1;" in text
    assert "env seed 500 + k" in text and "{" not in text.replace("{}", "")
    data = json.loads((docs / "control.json").read_text())
    assert list(data["heldout"]["levels"]) == ["nominal", "±10 %"]
    assert data["heldout"]["levels"]["±10 %"]["not_finished"] == {"rule": ["3d_1"], "ppo": []}


def test_folders_of_other_controllers_or_the_same_level_are_refused(script, tmp_path, capsys):
    a = _folder(tmp_path, "a", 0.0, {"rule": (True, True)}, {"rule": 0.5})
    b = _folder(tmp_path, "b", 0.05, {"ppo": (True, True)}, {"ppo": 0.5})
    c = _folder(tmp_path, "c", 0.0, {"rule": (True, True)}, {"rule": 0.6})
    assert script.main(["--eval", str(a), str(b), "--docs", str(tmp_path / "docs")]) == 2
    assert "other paths or controllers" in capsys.readouterr().err
    assert script.main(["--eval", str(a), str(c), "--docs", str(tmp_path / "docs")]) == 2
    assert "two folders hold the level 'nominal'" in capsys.readouterr().err
    assert not (tmp_path / "docs").exists()
    assert script.main(["--eval", str(tmp_path / "none"), "--docs", str(tmp_path / "docs")]) == 2
    assert "holds no results.json" in capsys.readouterr().err


def test_controllers_chooses_and_orders_the_rows(script, tmp_path, capsys):
    ctrl = {"rule": (True, True), "ppo": (True, False), "ppo:old": (False, False)}
    xte = {"rule": 0.5, "ppo": 0.7, "ppo:old": 2.0}
    nominal = _folder(tmp_path, "a", 0.0, ctrl, xte)
    docs = tmp_path / "docs"
    assert script.main(["--eval", str(nominal), "--controllers", "ppo", "rule", "--docs", str(docs)]) == 0
    text = (docs / "control.md").read_text()
    assert text.index("| `ppo` |") < text.index("| `rule` |") and "ppo:old" not in text
    data = json.loads((docs / "control.json").read_text())["heldout"]
    assert data["controllers"] == ["ppo", "rule"]
    assert list(data["levels"]["nominal"]["aggregate"]) == ["ppo", "rule"]
    assert data["levels"]["nominal"]["not_finished"] == {"ppo": ["planar_1"], "rule": []}
    assert script.main(["--eval", str(nominal), "--controllers", "horizon", "--docs", str(tmp_path / "d2")]) == 2
    assert "--controllers 'horizon' is not in" in capsys.readouterr().err and not (tmp_path / "d2").exists()


def test_the_agent_paragraph_names_its_head_reading(script):
    agent, _, meta = script.agent_facts()
    assert f"`head_rotation={meta['head_rotation']}`" in agent and meta["head_rotation"] in script.HEAD_READINGS


def test_folders_of_one_level_merge_their_controllers(script, tmp_path, capsys):
    planners = _folder(tmp_path, "p", 0.1, {"rule": (False, True)}, {"rule": 3.0})
    agents = _folder(tmp_path, "a", 0.1, {"ppo": (True, True)}, {"ppo": 1.5})
    docs = tmp_path / "docs"
    assert script.main(["--eval", str(planners), str(agents), "--docs", str(docs)]) == 0
    data = json.loads((docs / "control.json").read_text())["heldout"]
    assert data["controllers"] == ["rule", "ppo"]
    assert data["levels"]["±10 %"]["not_finished"] == {"rule": ["3d_1"], "ppo": []}
    other = _folder(tmp_path, "o", 0.1, {"adaptive": (True, True)}, {"adaptive": 1.0})
    res = json.loads((other / "results.json").read_text())
    (other / "results.json").write_text(json.dumps({**res, "seeds": {p: 900 for p in PATHS}}))
    assert script.main(["--eval", str(planners), str(other), "--docs", str(tmp_path / "d2")]) == 2
    assert "other paths, preset or seeds" in capsys.readouterr().err and not (tmp_path / "d2").exists()


def test_the_change_table_pairs_before_and_after(script, tmp_path, capsys):
    nominal = _folder(tmp_path, "n", 0.0, {"rule": (True, True), "ppo": (True, True)}, {"rule": 0.5, "ppo": 0.7})
    before = _folder(tmp_path, "b", 0.1, {"rule": (True, True), "ppo": (False, True)}, {"rule": 2.0, "ppo": 3.0})
    after = _folder(tmp_path, "a", 0.1, {"rule": (False, True), "ppo": (True, True), "ppo-scratch": (True, True)},
                    {"rule": 4.0, "ppo": 1.0, "ppo-scratch": 1.0})
    docs = tmp_path / "docs"
    assert script.main(["--eval", str(nominal), "--change", str(before), str(after), "--docs", str(docs)]) == 0
    text = (docs / "control.md").read_text()
    # only the controllers flown before and after; the pooled column gives the counts and mean cross-track
    assert "| `rule` | 2 → 1 | 2/2 → 1/2, 2.00 → 4.00 cm |" in text
    assert "| `ppo` | 1 → 2 | 1/2 → 2/2, 3.00 → 1.00 cm |" in text
    assert "`ppo-scratch` |" not in text.split("Successes before → after")[1].split("## The shipped agent")[0]
    assert "fewer successes after the change: `rule`." in text
    data = json.loads((docs / "control.json").read_text())["reading_change"]
    assert data["pooled"]["ppo"]["after"] == {"success": 2, "episodes": 2, "cross_track_sum_m": 0.02}
    # a pair of other swimmers is refused before anything is written
    res = json.loads((after / "results.json").read_text())
    (after / "results.json").write_text(json.dumps({**res, "seeds": {p: 900 for p in PATHS}}))
    assert script.main(["--eval", str(nominal), "--change", str(before), str(after), "--docs", str(tmp_path / "d2")]) == 2
    assert "other paths, swimmer seeds or levels" in capsys.readouterr().err and not (tmp_path / "d2").exists()


def test_without_a_change_the_section_says_it_was_not_measured(script, tmp_path):
    nominal = _folder(tmp_path, "n", 0.0, {"rule": (True, True)}, {"rule": 0.5})
    assert script.main(["--eval", str(nominal), "--docs", str(tmp_path / "docs")]) == 0
    assert "Not measured in this report" in (tmp_path / "docs" / "control.md").read_text()
