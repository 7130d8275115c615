"""The README is a manual and docs/ are reference pages: short, current, without dates or commit hashes, every
relative link resolving; generated results are not tracked (issue 47)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = sorted((ROOT / "docs").glob("*.md"))
DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")
#: a commit hash: 7-40 hex digits with at least one digit and one letter (not a word, not a number)
HASH = re.compile(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def _text(page: Path) -> str:
    return page.read_text(encoding="utf-8")


def test_date_and_hash_patterns_find_what_they_should():
    assert DATE.search("measured 2026-12-04 17:00 UTC") and not DATE.search("ω̄ = 2026")
    assert HASH.search("against d89cc86, the code before") and HASH.search("6ae70afc3fe5c25dee22ba958a0e14976a212341")
    assert not HASH.search("deadbeef faced 1234567 ffffff")


def test_the_readme_is_a_manual():
    text = _text(ROOT / "README.md")
    assert len(text.splitlines()) <= 150
    assert not DATE.findall(text), DATE.findall(text)
    assert not HASH.findall(text), HASH.findall(text)
    for heading in ("## Install and run", "## Quickstart", "## Commands", "## Documentation"):
        assert heading in text


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_docs_page_is_a_reference_page(page):
    text = _text(page)
    assert len(text.splitlines()) <= 400, f"{page.name}: {len(text.splitlines())} lines (at most 400)"
    assert not DATE.findall(text), f"{page.name}: dates {DATE.findall(text)}"
    assert not HASH.findall(text), f"{page.name}: commit hashes {HASH.findall(text)}"


@pytest.mark.parametrize("page", [ROOT / "README.md", *PAGES], ids=["README.md", *(p.name for p in PAGES)])
def test_relative_links_resolve(page):
    missing = [link for link in LINK.findall(_text(page))
               if "://" not in link and not (page.parent / link).exists()]
    assert not missing, f"{page.name}: links to missing files {missing}"


def test_generated_results_are_ignored_by_git():
    probe = "results/some_new_run/results.jsonl"
    proc = subprocess.run(["git", "check-ignore", "-q", "--no-index", probe], cwd=ROOT)
    if proc.returncode == 128:
        pytest.skip("not a git checkout")
    assert proc.returncode == 0, f"{probe} would be tracked: .gitignore must cover results/"


def test_tracked_results_are_small_summaries():
    """Issue 47's target: what git tracks under results/ is at most 5 MB in all and holds no .npz trace."""
    proc = subprocess.run(["git", "ls-files", "-z", "results"], cwd=ROOT, capture_output=True)
    if proc.returncode != 0:
        pytest.skip("not a git checkout")
    files = [f for f in proc.stdout.decode().split("\0") if f]
    traces = [f for f in files if f.endswith(".npz")]
    assert not traces, f"{len(traces)} .npz files tracked under results/, e.g. {traces[:3]}"
    total = sum((ROOT / f).stat().st_size for f in files if (ROOT / f).exists())
    assert total <= 5_000_000, f"tracked results/ holds {total / 1e6:.1f} MB (at most 5 MB)"
