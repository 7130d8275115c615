"""The code blocks of README.md and docs/env.md run as written, with small budgets.

How a block runs (in a scratch folder, so nothing is written into the repository):

- a ``python`` block is saved as a file and run with ``python FILE`` (so a block that needs
  ``if __name__ == "__main__":`` fails here without it);
- any other block is read line by line: each line that starts with ``flagellum`` is run as a command
  (a trailing ``# comment`` dropped) and must exit with status 0. Lines starting with ``make`` or
  ``pip`` are set-up (CI runs them), and ``flagellum bench`` is a benchmark of minutes to hours
  (``tests/test_fidelity.py`` tests it): those lines are not run. Other lines are an error.

Budgets: before running, ``BUDGETS`` replaces these exact texts (nothing else changes):

- ``--duration T`` -> ``--duration 0.02``; ``--path square`` and ``--paths eval`` -> a one-turn path
  (2 cm ahead, then 8 cm to the left); ``calibrate-turns --preset coarse`` -> one burst length and one
  phase, written in the scratch folder; the training config -> a 3-decision one (as in
  ``tests/agents/test_ppo.py``);
- Python: ``control_dt=2.0,`` -> ``control_dt=2.0, max_episode_steps=3,``; ``PPO("MlpPolicy", venv)``
  -> ``PPO("MlpPolicy", venv, n_steps=4, batch_size=8)``; ``.learn(10_000)`` -> ``.learn(8)``;
  ``path="square"`` and ``square_path()`` -> the one-turn path.

A block whose text does not contain a budget's text runs unchanged; ``test_every_budget_is_used``
fails when a budget no longer matches anything, so the list cannot go stale.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
DOCS = ("README.md", "docs/env.md")
ONE_TURN = '{"name": "one_turn", "waypoints": [[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], "reach_radius_m": 0.015}'
ONE_TURN_PY = ('path_from_waypoints([[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], name="one_turn", '
               'reach_radius_m=0.015)')
TINY_TRAINING = {"tiny": {
    "n_envs": 1, "n_timesteps": 3, "seed": 0, "checkpoint_every": 1, "n_steps": 3, "batch_size": 3, "n_epochs": 1,
    "policy_kwargs": {"net_arch": [8], "log_std_init": -1.0},
    "task": {"preset": "coarse", "limits": {"max_dtc_fraction": 0.1},
             "curriculum": [{"name": "one", "until": 3, "random_path": {
                 "n_waypoints": 1, "segment_length_m": [0.03, 0.04], "min_turn_deg": 70.0, "max_turn_deg": 90.0}}],
             "validation": {"seeds": [5], "every": 3, "random_path": {
                 "n_waypoints": 1, "segment_length_m": [0.03, 0.04], "min_turn_deg": 70.0, "max_turn_deg": 90.0}}}}}

#: (pattern, replacement) applied to every block; {scratch} is the scratch folder.
BUDGETS: tuple[tuple[str, str], ...] = (
    (r"--duration \S+", "--duration 0.02"),
    (r"--path square\b", "--path {scratch}/one_turn.json"),
    (r"--paths eval\b", "--paths {scratch}/one_turn.json"),
    (r"calibrate-turns --preset coarse\b", "calibrate-turns --preset coarse --t-c 1 --phases 0 --out {scratch}/coarse.json"),
    (r"--config agents/configs/ppo_residual_coarse\.yml", "--config {scratch}/tiny.yml"),
    (r"control_dt=2\.0,", "control_dt=2.0, max_episode_steps=3,"),
    (r'PPO\("MlpPolicy", venv\)', 'PPO("MlpPolicy", venv, n_steps=4, batch_size=8)'),
    (r"\.learn\(10_000\)", ".learn(8)"),
    (r'path="square"', f"path={ONE_TURN_PY}"),
    (r"square_path\(\)", ONE_TURN_PY),
)
NOT_RUN = ("make ", "pip ", "flagellum bench")


def code_blocks() -> list[tuple[str, int, str, str]]:
    """``(file, line, language, text)`` of every fenced block of ``DOCS``."""
    out = []
    for name in DOCS:
        lines = (ROOT / name).read_text(encoding="utf-8").splitlines()
        i = 0
        while i < len(lines):
            m = re.match(r"^```(\w*)\s*$", lines[i])
            if m:
                j = i + 1
                while not lines[j].startswith("```"):
                    j += 1
                out.append((name, i + 1, m[1], "\n".join(lines[i + 1:j]) + "\n"))
                i = j
            i += 1
    return out


def with_budgets(text: str, scratch: Path) -> str:
    for pattern, repl in BUDGETS:
        text = re.sub(pattern, repl.replace("{scratch}", str(scratch)), text)
    return text


def _env(scratch: Path) -> dict[str, str]:
    # turn maps written by the blocks stay in the scratch folder; the user's are not read
    return {**os.environ, "OPENBLAS_NUM_THREADS": "1", "FLAGELLUM_TURN_MAPS": str(scratch / "user_turn_maps"),
            "MPLBACKEND": "Agg"}


BLOCKS = [b for b in code_blocks() if b[2] != "json"]


def test_the_documents_have_the_blocks_this_test_expects():
    langs = {(f, lang) for f, _, lang, _ in BLOCKS}
    assert ("README.md", "python") in langs and ("docs/env.md", "python") in langs and ("README.md", "") in langs


def test_every_budget_is_used():
    texts = "\n".join(t for _, _, _, t in BLOCKS)
    unused = [p for p, _ in BUDGETS if not re.search(p, texts)]
    assert not unused, f"budgets that match no code block any more: {unused}"


@pytest.mark.parametrize("name, line, lang, text", BLOCKS, ids=[f"{b[0]}:{b[1]}" for b in BLOCKS])
def test_code_block_runs(tmp_path, name, line, lang, text):
    (tmp_path / "one_turn.json").write_text(ONE_TURN)
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump(TINY_TRAINING))
    text = with_budgets(text, tmp_path)
    env = _env(tmp_path)
    if lang == "python":
        script = tmp_path / "block.py"
        script.write_text("from flagellum_env.paths import path_from_waypoints  # added by tests/test_docs.py\n"
                          + text)
        proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=600)
        assert proc.returncode == 0, f"{name}:{line}\n{text}\n{proc.stderr[-3000:]}"
        return
    ran = 0
    for cmd in text.splitlines():
        cmd = cmd.split(" #", 1)[0].strip()
        if not cmd or cmd.startswith(NOT_RUN):
            continue
        assert cmd.startswith("flagellum "), f"{name}:{line}: a line this test cannot run: {cmd!r}"
        argv = shlex.split(cmd)[1:]
        argv = [str(ROOT / a) if a.startswith("examples/") else a for a in argv]  # the repository's inputs
        if argv[0] in ("simulate", "follow", "evaluate", "sweep", "calibrate-turns", "train") \
                and "--no-progress" not in argv:
            argv.append("--no-progress")
        proc = subprocess.run([sys.executable, "-m", "flagellum.cli", *argv], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"{name}:{line}: {cmd}\n{proc.stderr[-3000:]}"
        ran += 1
    if ran == 0:
        assert all(c.split(" #", 1)[0].strip().startswith(NOT_RUN) or not c.strip() for c in text.splitlines())
