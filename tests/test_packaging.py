"""pyproject.toml: the [rl] extra asks for a torch range (not a pin) that the pinned CPU build of the
Makefile (and .ci/run, which reads it from there) satisfies; threadpoolctl is a dependency."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parent.parent


def _project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def test_the_rl_extra_asks_for_a_torch_range_that_the_makefiles_pin_satisfies():
    (torch,) = [r for r in map(Requirement, _project()["optional-dependencies"]["rl"]) if r.name == "torch"]
    assert not any(s.operator in ("==", "===") for s in torch.specifier), torch
    pin = re.search(r"^TORCH_PIN := (\S+)$", (ROOT / "Makefile").read_text(), re.M)
    assert pin, "the Makefile names the pinned torch as TORCH_PIN"
    pinned = Requirement(pin.group(1))
    (version,) = [s.version for s in pinned.specifier if s.operator == "=="]
    assert torch.specifier.contains(version), (torch, version)
    assert "TORCH_PIN" in (ROOT / ".ci" / "run").read_text()


def test_threadpoolctl_is_a_dependency():
    assert "threadpoolctl" in {Requirement(r).name for r in _project()["dependencies"]}


def test_moviepy_is_in_the_video_extra_only_and_at_a_version_without_a_pillow_cap():
    """moviepy 2.x requires pillow < 12 (it downgraded pillow 13 -> 11.3); 1.0.3 does not."""
    extras = _project()["optional-dependencies"]
    assert not any(Requirement(r).name == "moviepy" for name, reqs in extras.items() if name != "video" for r in reqs)
    (moviepy,) = [Requirement(r) for r in extras["video"] if Requirement(r).name == "moviepy"]
    assert moviepy.specifier.contains("1.0.3") and not moviepy.specifier.contains("2.2.1"), moviepy
    assert ".[test,rl,video]" in (ROOT / "Makefile").read_text()  # make test runs RecordVideo's test
