"""Every code block of README.md, docs/cli.md and docs/env.md runs as written, within the time its document states.

Each fenced block is preceded by a marker line, an HTML comment the reader does not see (the time itself is
stated in the visible text beside the block):

- ``<!-- test_docs: as written, N s -->``: the block runs exactly as written and must finish within N s;
- ``<!-- test_docs: shortened NAME, N s -->``: the block is too long for CI (the document says so and names
  NAME); the test runs its shortened form ``SHORTENED[NAME]`` (these exact replacements, nothing else) within
  N s;
- ``<!-- test_docs: set-up -->``: ``make`` / ``pip`` lines that CI runs to set itself up; not run here.

How a block runs (in a scratch folder, so nothing is written into the repository): a ``python`` block is saved
as a file and run with ``python FILE`` (so a block that needs ``if __name__ == "__main__":`` fails here without
it); any other block is read line by line, each line starting with ``flagellum`` run as a command (a trailing
``# comment`` dropped) that must exit with status 0; other lines are an error. ``json`` blocks are data.
``test_every_block_has_a_marker`` and ``test_every_shortened_form_is_used`` keep the markers and forms in step
with the documents.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
DOCS = ("README.md", "docs/cli.md", "docs/env.md")
ONE_TURN = '{"name": "one_turn", "waypoints": [[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]], "reach_radius_m": 0.015}'
TINY_TRAINING = {"tiny": {
    "n_envs": 1, "n_timesteps": 3, "seed": 0, "checkpoint_every": 1, "n_steps": 3, "batch_size": 3, "n_epochs": 1,
    "policy_kwargs": {"net_arch": [8], "log_std_init": -1.0},
    "task": {"preset": "faithful", "limits": {"max_dtc_fraction": 0.1},
             "curriculum": [{"name": "one", "until": 3, "random_path": {
                 "n_waypoints": 1, "segment_length_m": [0.03, 0.04], "min_turn_deg": 70.0, "max_turn_deg": 90.0}}],
             "validation": {"seeds": [5], "every": 3, "random_path": {
                 "n_waypoints": 1, "segment_length_m": [0.03, 0.04], "min_turn_deg": 70.0, "max_turn_deg": 90.0}}}}}

#: Shortened forms of the blocks too long for CI: name -> (pattern, replacement) pairs; {scratch} is the scratch
#: folder. Each name is the one its document gives.
SHORTENED: dict[str, tuple[tuple[str, str], ...]] = {
    "one burst, one-turn path": (
        (r"calibrate-turns --preset faithful\b",
         "calibrate-turns --preset faithful --t-c 1 --phases 0 --out {scratch}/faithful.json"),
        (r"--path square\b", "--path {scratch}/one_turn.json"),
        (r"--paths eval\b", "--paths {scratch}/one_turn.json"),
    ),
    "tiny config, one-turn path": (
        (r"--config agents/configs/ppo_residual_adaptive\.yml", "--config {scratch}/tiny.yml"),
        (r"--path square\b", "--path {scratch}/one_turn.json"),
    ),
    "sweep only": ((r"(?m)^flagellum bench .*$", ""),),
    "one-turn path (planner)": (
        (r'path="square"', "path=[[0.02, 0.0, 0.0], [0.02, 0.08, 0.0]]"),
        (r"square_path\(\)", "env.config.fixed_path"),
    ),
    "8 steps": ((r"n_steps=256, batch_size=64\)\.learn\(2_048\)", "n_steps=4, batch_size=8).learn(8)"),),
}
MARKER = re.compile(r"^<!-- test_docs: (?:(as written), (\d+) s|shortened (.+), (\d+) s|(set-up)) -->$")


def code_blocks() -> list[tuple[str, int, str, str, str]]:
    """``(file, line, language, marker, text)`` of every fenced block of ``DOCS``; ``marker`` is the line before it."""
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
                marker = lines[i - 1].strip() if i > 0 else ""
                out.append((name, i + 1, m[1], marker, "\n".join(lines[i + 1:j]) + "\n"))
                i = j
            i += 1
    return out


def how_to_run(marker: str) -> tuple[str, str | None, float | None]:
    """("as written" | "shortened" | "set-up", the shortened form's name, the time limit in s) of a marker."""
    m = MARKER.match(marker)
    if m is None:
        raise ValueError(f"not a test_docs marker: {marker!r}")
    if m[1]:
        return "as written", None, float(m[2])
    if m[3]:
        return "shortened", m[3], float(m[4])
    return "set-up", None, None


def shortened(text: str, name: str, scratch: Path) -> str:
    """The block's shortened form ``name``: its replacements applied (each must match)."""
    for pattern, repl in SHORTENED[name]:
        assert re.search(pattern, text), f"shortened form {name!r}: {pattern!r} matches nothing in the block"
        text = re.sub(pattern, repl.replace("{scratch}", str(scratch)), text)
    return text


def _env(scratch: Path) -> dict[str, str]:
    # turn maps written by the blocks stay in the scratch folder; the user's are not read
    return {**os.environ, "OPENBLAS_NUM_THREADS": "1", "FLAGELLUM_TURN_MAPS": str(scratch / "user_turn_maps"),
            "MPLBACKEND": "Agg"}


BLOCKS = [b for b in code_blocks() if b[2] != "json"]


def test_the_documents_have_the_blocks_this_test_expects():
    langs = {(f, lang) for f, _, lang, _, _ in BLOCKS}
    assert {("README.md", "python"), ("README.md", ""), ("docs/cli.md", ""), ("docs/env.md", "python")} <= langs


def test_every_block_has_a_marker():
    bad = [f"{f}:{line}" for f, line, _, marker, _ in BLOCKS if not MARKER.match(marker)]
    assert not bad, f"code blocks without a '<!-- test_docs: ... -->' line before them: {bad}"
    names = [how_to_run(marker)[1] for *_, marker, _ in BLOCKS]
    unknown = sorted({n for n in names if n is not None and n not in SHORTENED})
    assert not unknown, f"shortened forms the documents name but SHORTENED lacks: {unknown}"


def test_every_shortened_form_is_used():
    used = {how_to_run(marker)[1] for *_, marker, _ in BLOCKS if MARKER.match(marker)}
    assert set(SHORTENED) <= used, f"shortened forms no document names: {sorted(set(SHORTENED) - used)}"


def test_a_shortened_block_says_so_in_its_document():
    for name, line, _, marker, _ in BLOCKS:
        kind, form, _ = how_to_run(marker)
        if kind == "shortened":
            around = "\n".join((ROOT / name).read_text(encoding="utf-8").splitlines()[max(0, line - 12):line + 40])
            assert "too long for ci" in around.lower() and form in around, f"{name}:{line}: say it is too long for CI and name {form!r}"


def _scratch(tmp_path: Path) -> None:
    """The scratch folder: the repository's inputs the blocks name (examples/; not agents/, which would shadow the
    package) and the shortened forms' files."""
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    (tmp_path / "one_turn.json").write_text(ONE_TURN)
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump(TINY_TRAINING))


@pytest.mark.parametrize("name, line, lang, marker, text", BLOCKS, ids=[f"{b[0]}:{b[1]}" for b in BLOCKS])
def test_code_block_runs(tmp_path, name, line, lang, marker, text):
    kind, form, limit = how_to_run(marker)
    if kind == "set-up":
        assert all(c.startswith(("make ", "pip ")) or not c.strip() for c in text.splitlines()), f"{name}:{line}"
        pytest.skip("set-up block (make / pip lines): .ci/run itself runs make install and make test")
    _scratch(tmp_path)
    if kind == "shortened":
        text = shortened(text, form, tmp_path)
    env = _env(tmp_path)
    deadline = time.monotonic() + limit
    where = f"{name}:{line} ({kind}{' ' + repr(form) if form else ''}, {limit:g} s)"
    if lang == "python":
        script = tmp_path / "block.py"
        script.write_text(text)
        proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=limit)
        assert proc.returncode == 0, f"{where}\n{text}\n{proc.stderr[-3000:]}"
        return
    ran = 0
    for cmd in text.splitlines():
        cmd = cmd.split(" #", 1)[0].strip()
        if not cmd:
            continue
        assert cmd.startswith("flagellum "), f"{where}: a line this test cannot run: {cmd!r}"
        proc = subprocess.run([sys.executable, "-m", "flagellum.cli", *shlex.split(cmd)[1:]], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=max(1.0, deadline - time.monotonic()))
        assert proc.returncode == 0, f"{where}: {cmd}\n{proc.stderr[-3000:]}"
        ran += 1
    assert ran > 0, f"{where}: nothing to run"
    assert time.monotonic() <= deadline, f"{where}: took longer than the stated {limit:g} s"
