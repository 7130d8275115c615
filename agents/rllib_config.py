"""Training configuration of the Ray RLlib engine (``flagellum train --engine ray``): a YAML file, validated.

The file has one top-level key, the run's name, holding::

    rllib_ppo_surrogate:
      env_id: FlagellumTurn-surrogate-v0   # any id this package registers (rllib_env_ids())
      env_kwargs: {}                       # gymnasium.make(env_id, **env_kwargs)
      num_env_runners: 2                   # Ray actors that step the envs (0: in the driver)
      num_envs_per_env_runner: 1
      train_batch_size: 2000               # env steps per training iteration
      minibatch_size: 128
      num_epochs: 10
      lr: 3.0e-4
      gamma: 0.9
      gae_lambda: 0.95
      net_arch: [64, 64]                   # hidden layers of the policy and value networks
      normalize_obs: true                  # RLlib's MeanStdFilter connector on the observations
      iterations: 50                       # stop after this many iterations ...
      max_wall_time_s: 3600                # ... or this much training wall time (null: no limit)
      seed: 0
      checkpoint_every: 5                  # iterations
      address: null                        # null: a local Ray in this process; "auto" or "host:port": a cluster

``RayTrainConfig.from_yaml`` raises a one-line ``ValueError`` naming the file, the key, the value and what is
allowed. Nothing here imports Ray: a config is checked on a machine without it. Whether ``address`` answers is
checked when training starts (``agents.rllib_training.check_address``).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

#: A checkpoint's folder name is this prefix and its iteration (6 digits); the file in it that says what it is
#: (the env, the shapes, the counters), written last: a checkpoint without it is incomplete.
CHECKPOINT_PREFIX = "iter_"
INFO_FILE = "flagellum.json"
#: Every key a config may hold, with its default (None: required).
DEFAULTS: dict[str, Any] = {
    "env_id": None, "env_kwargs": {}, "num_env_runners": 1, "num_envs_per_env_runner": 1,
    "train_batch_size": 2000, "minibatch_size": 128, "num_epochs": 10, "lr": 3.0e-4, "gamma": 0.99,
    "gae_lambda": 0.95, "net_arch": [64, 64], "normalize_obs": True, "iterations": None, "max_wall_time_s": None,
    "seed": 0, "checkpoint_every": 1, "address": None,
}
#: Keys that may change between a run and its ``--resume`` (the budget, checkpoints and where it runs); every
#: other key is the run's identity (``RayTrainConfig.identity``).
RESUMABLE_KEYS = ("iterations", "max_wall_time_s", "checkpoint_every", "address", "num_env_runners",
                  "num_envs_per_env_runner")


def rllib_env_ids() -> list[str]:
    """The Gymnasium ids this package registers (``FlagellumSteer-*``, ``FlagellumTurn-*`` and
    ``FlagellumBurst-*``)."""
    from flagellum_env.registration import ENV_IDS

    return [*ENV_IDS, *rllib_controller_env_ids()]


def rllib_controller_env_ids() -> list[str]:
    """The ids whose checkpoints fly as ``--controller rllib:DIR`` (``agents.rllib_policy``): ``FlagellumTurn-*``
    (a residual agent correcting the planner's turns) and ``FlagellumBurst-*`` (a burst agent with no planner,
    flown by ``agents.burst_pilot.BurstPilot``)."""
    from agents.registration import BURST_ENV_IDS, SURROGATE_TURN_ENV_IDS, TURN_ENV_IDS

    return [*TURN_ENV_IDS, *SURROGATE_TURN_ENV_IDS, *BURST_ENV_IDS]


_HOST_PORT = re.compile(r"^[A-Za-z0-9._-]+:(\d{1,5})$")


def check_address_format(address: Any, where: str) -> str | None:
    """``address`` if it is None, ``"auto"`` or ``"host:port"``; ValueError naming it otherwise."""
    if address is None or address == "auto":
        return address
    m = _HOST_PORT.match(address) if isinstance(address, str) else None
    if m is None or not 1 <= int(m.group(1)) <= 65535:
        raise ValueError(f"{where}={address!r} is not allowed; allowed: null (a local Ray started in-process), "
                         "'auto' (the cluster 'ray start' started on this machine) or 'host:port' of a cluster's head")
    return address


@dataclass(frozen=True)
class RayTrainConfig:
    """A validated RLlib PPO training configuration (module docstring)."""

    name: str
    env_id: str
    iterations: int | None = None
    max_wall_time_s: float | None = None
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    num_env_runners: int = 1
    num_envs_per_env_runner: int = 1
    train_batch_size: int = 2000
    minibatch_size: int = 128
    num_epochs: int = 10
    lr: float = 3.0e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    net_arch: tuple[int, ...] = (64, 64)
    normalize_obs: bool = True
    seed: int = 0
    checkpoint_every: int = 1
    address: str | None = None
    source: str = "<dict>"

    def identity(self) -> dict[str, Any]:
        """What makes a run the same run: every setting but ``RESUMABLE_KEYS`` (and where it was read from)."""
        out = {k: getattr(self, k) for k in ("name", *DEFAULTS) if k not in RESUMABLE_KEYS}
        return json.loads(json.dumps(out, sort_keys=True, default=list))

    def identity_hash(self) -> str:
        """sha256 of ``identity`` (canonical JSON), 16 hex digits."""
        text = json.dumps(self.identity(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def with_address(self, address: str | None) -> RayTrainConfig:
        """This config run on another cluster (``--address``); ValueError for a malformed address."""
        from dataclasses import replace

        return replace(self, address=check_address_format(address, "--address"))

    @classmethod
    def from_yaml(cls, path: str | Path) -> RayTrainConfig:
        """Read and validate a config file (module docstring)."""
        path = Path(path)
        try:
            doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as exc:
            raise ValueError(f"cannot read the training config {str(path)!r}: {' '.join(str(exc).split())}") from None
        return cls.from_dict(doc, source=str(path))

    @classmethod
    def from_dict(cls, doc: Any, source: str = "<dict>") -> RayTrainConfig:
        """Validate ``{name: {key: value, ...}}`` (module docstring)."""
        where = f"training config {source!r}"
        if not isinstance(doc, Mapping) or len(doc) != 1:
            raise ValueError(f"{where}: must hold exactly one top-level key, the run's name")
        (name, body), = doc.items()
        if not isinstance(body, Mapping):
            raise ValueError(f"{where}: {name!r} must be a mapping of settings; allowed keys: {list(DEFAULTS)}")
        at = f"{where}: {name}"
        unknown = sorted(set(map(str, body)) - set(DEFAULTS))
        if unknown:
            raise ValueError(f"{at}: unknown key(s) {unknown}; allowed: {list(DEFAULTS)}")
        v = {**DEFAULTS, **body}
        ids = rllib_env_ids()
        if v["env_id"] not in ids:
            raise ValueError(f"{at}.env_id={v['env_id']!r} is not allowed; allowed: one of {ids}")
        if not isinstance(v["env_kwargs"], Mapping) or not all(isinstance(k, str) for k in v["env_kwargs"]):
            raise ValueError(f"{at}.env_kwargs={v['env_kwargs']!r} is not allowed; allowed: a mapping of "
                             f"{v['env_id']}'s arguments")
        if v["iterations"] is None and v["max_wall_time_s"] is None:
            raise ValueError(f"{at}: iterations and max_wall_time_s are both null; allowed: at least one of them "
                             "(a budget)")
        net = v["net_arch"]
        if not (isinstance(net, list) and net and all(_is_int(n) and n >= 1 for n in net)):
            raise ValueError(f"{at}.net_arch={net!r} is not allowed; allowed: a non-empty list of layer sizes "
                             "(integers >= 1)")
        if not isinstance(v["normalize_obs"], bool):
            raise ValueError(f"{at}.normalize_obs={v['normalize_obs']!r} is not allowed; allowed: true or false")
        batch = _int(v["train_batch_size"], f"{at}.train_batch_size", 1)
        minibatch = _int(v["minibatch_size"], f"{at}.minibatch_size", 1)
        if minibatch > batch:
            raise ValueError(f"{at}.minibatch_size={minibatch} is not allowed; allowed: an integer from 1 to "
                             f"train_batch_size ({batch})")
        wall = v["max_wall_time_s"]
        if wall is not None:
            wall = _number(wall, f"{at}.max_wall_time_s", 0.0, None, lo_open=True, what="a number of seconds")
        return cls(
            name=str(name), env_id=v["env_id"], env_kwargs=dict(v["env_kwargs"]),
            iterations=None if v["iterations"] is None else _int(v["iterations"], f"{at}.iterations", 1),
            max_wall_time_s=wall,
            num_env_runners=_int(v["num_env_runners"], f"{at}.num_env_runners", 0),
            num_envs_per_env_runner=_int(v["num_envs_per_env_runner"], f"{at}.num_envs_per_env_runner", 1),
            train_batch_size=batch, minibatch_size=minibatch, num_epochs=_int(v["num_epochs"], f"{at}.num_epochs", 1),
            lr=_number(v["lr"], f"{at}.lr", 0.0, None, lo_open=True),
            gamma=_number(v["gamma"], f"{at}.gamma", 0.0, 1.0),
            gae_lambda=_number(v["gae_lambda"], f"{at}.gae_lambda", 0.0, 1.0),
            net_arch=tuple(net), normalize_obs=v["normalize_obs"], seed=_int(v["seed"], f"{at}.seed", 0),
            checkpoint_every=_int(v["checkpoint_every"], f"{at}.checkpoint_every", 1),
            address=check_address_format(v["address"], f"{at}.address"), source=source)


def _is_int(x: Any) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _int(x: Any, where: str, lo: int) -> int:
    if not _is_int(x) or x < lo:
        raise ValueError(f"{where}={x!r} is not allowed; allowed: an integer >= {lo}")
    return int(x)


def _number(x: Any, where: str, lo: float, hi: float | None, lo_open: bool = False,
            what: str = "a number") -> float:
    ok = isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
    ok = ok and (x > lo if lo_open else x >= lo) and (hi is None or x <= hi)
    if not ok:
        bound = f"{'>' if lo_open else '>='} {lo:g}" + (f" and <= {hi:g}" if hi is not None else "")
        raise ValueError(f"{where}={x!r} is not allowed; allowed: {what} {bound}")
    return float(x)
