"""Files shipped inside the package (package data, found with ``importlib.resources``) and the
user's own turn maps.

Shipped (``pyproject.toml``, ``[tool.setuptools.package-data]``):

- ``agents/turn_maps/<preset>.json``: the turn map of each preset (``flagellum calibrate-turns``);
- ``agents/eval_paths/*.json``: the 20 evaluation paths (``flagellum evaluate --paths eval``);
- ``agents/pretrained/ppo_residual_adaptive/``: the PPO agent of ``--controller ppo`` (``model.zip``,
  ``vecnormalize.pkl``, ``config.yml``, ``meta.json``; its training curve ``episodes.csv`` and
  ``training_curve.png``): the residual on the adaptive planner trained at ``faithful`` (docs/control.md). Its
  validation runs and checkpoints are results of its training run, not shipped.

Turn maps you measure yourself go to ``user_turn_map_dir()`` (``$FLAGELLUM_TURN_MAPS``, else
``$XDG_DATA_HOME/flagellum/turn_maps``, else ``~/.local/share/flagellum/turn_maps``): that is where
``flagellum calibrate-turns --preset P`` writes by default, and ``--controller rule`` / ``ppo``
use ``P.json`` from there in preference to the shipped one.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

from physics.presets import RETIRED_PRESETS, retired_preset_message

#: The agent ``--controller ppo`` loads.
SHIPPED_AGENT = "ppo_residual_adaptive"
#: Environment variable naming the folder of the user's turn maps.
TURN_MAPS_ENV = "FLAGELLUM_TURN_MAPS"


def package_file(*parts: str) -> Path:
    """A file or folder shipped in the ``agents`` package, as a filesystem path.

    The package is installed as files (a wheel or an editable install), so the resource is a
    ``pathlib.Path``; RuntimeError if it is not (a zipped install).
    """
    res = resources.files("agents")
    for p in parts:
        res = res / p
    if not isinstance(res, Path):
        raise RuntimeError(f"the package data {'/'.join(parts)!r} is not a file on disk ({res!r}); install the "
                           "package unzipped (pip install)")
    return res


def pretrained_dir() -> Path:
    """The folder of the shipped PPO agent."""
    return package_file("pretrained", SHIPPED_AGENT)


def eval_paths_dir() -> Path:
    """The folder of the shipped evaluation paths (``--paths eval``)."""
    return package_file("eval_paths")


def packaged_turn_map(preset: str) -> Path:
    """The turn map shipped for ``preset`` (it may not exist for a preset without one); ValueError (one line) for a
    retired preset."""
    _refuse_retired(preset)
    return package_file("turn_maps", f"{preset}.json")


def user_turn_map_dir() -> Path:
    """Where ``flagellum calibrate-turns`` writes a preset's map by default (see the module docstring)."""
    env = os.environ.get(TURN_MAPS_ENV)
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "flagellum" / "turn_maps"


def default_turn_map(preset: str) -> Path:
    """The turn map ``rule`` and ``ppo`` use for ``preset``: the user's (``user_turn_map_dir()``)
    if there is one, else the shipped one; ValueError (one line) for a retired preset."""
    _refuse_retired(preset)
    user = user_turn_map_dir() / f"{preset}.json"
    return user if user.is_file() else packaged_turn_map(preset)


def _refuse_retired(preset: str) -> None:
    if preset in RETIRED_PRESETS:
        raise ValueError(retired_preset_message(preset))


def missing_turn_map_message(path: Path, preset: str, given: bool = False) -> str:
    """What to say when the turn map at ``path`` does not exist."""
    if given:
        return (f"no turn map at {str(path)!r}; make one with "
                f"'flagellum calibrate-turns --preset {preset} --out {path}'")
    user = str(user_turn_map_dir() / f"{preset}.json")
    return (f"no turn map for preset {preset!r}: none shipped and none at {user!r}; make one with "
            f"'flagellum calibrate-turns --preset {preset}' (it writes there)")
