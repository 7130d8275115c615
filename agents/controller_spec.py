"""Controller specs (``KIND``, ``KIND:FILE``, ``KIND@line=W[:FILE]``): which controller a name means and the
environment settings its kind needs, kept apart from the controllers themselves so that the planners and the
agents can parse a spec without importing each other (``agents.path_following`` builds the controller)."""

from __future__ import annotations

import math
from typing import Any

#: Environment settings each controller kind needs (merged under the caller's settings).
#: The rule planner times its bursts to the flagellum's phase (~40 deg/s at 10 rpm) and its turns
#: grow by up to ~100 deg per second of burst (paper preset), so it steps every 0.1 s.
#: The PPO agents (``ppo``: stable-baselines3; ``rllib``: an RLlib checkpoint of a FlagellumTurn env) correct the
#: planner's turns (agents.residual_planner), so they step like the planner; ``ppo-scratch`` (a from-scratch burst
#: agent, agents.burst_pilot; ``rllib`` of a FlagellumBurst env too) hovers and bursts as the planner does.
CONTROLLER_ENV_DEFAULTS: dict[str, dict[str, Any]] = {"rule": {"control_dt": 0.1}, "adaptive": {"control_dt": 0.1},
                                                      "horizon": {"control_dt": 0.1}, "ppo": {"control_dt": 0.1},
                                                      "ppo-scratch": {"control_dt": 0.1},
                                                      "rllib": {"control_dt": 0.1}}
#: Kinds that have no default: the part after ``:`` is required.
_NEEDS_ARGUMENT = {"rllib": "rllib:CHECKPOINT_DIR"}


_ALLOWED_SPECS = ("'rule', 'rule:TURN_MAP.json', 'adaptive', 'adaptive:TURN_MAP.json', 'horizon', "
                  "'horizon:TURN_MAP.json', 'ppo', 'ppo:AGENT_DIR', 'ppo-scratch', 'ppo-scratch:AGENT_DIR', "
                  "'rllib:CHECKPOINT_DIR'; 'rule@line=W' and 'adaptive@line=W' (W >= 0, "
                  "also before ':TURN_MAP.json') score turns by the path's line too; '@cap=DEG' (DEG > 0; e.g. "
                  "'adaptive@line=2,cap=90') plans at most DEG degrees per burst")
#: Options a planner spec may carry after ``@`` (``KIND@line=W,cap=DEG``), by kind.
_SPEC_OPTIONS = {"rule": ("line", "cap"), "adaptive": ("line", "cap")}
_OPTION_RANGE = {"line": "line=W (W a number >= 0)", "cap": "cap=DEG (DEG a number > 0)"}


def controller_kind(spec: str) -> str:
    """``"rule"``, ``"adaptive"``, ``"horizon"``, ``"ppo"``, ``"ppo-scratch"`` or ``"rllib"`` from ``KIND``, ``KIND:FILE``, ``KIND@line=W`` or
    ``KIND@line=W:FILE``; ValueError otherwise (also for ``KIND:`` with nothing after the colon, which would
    silently mean the default map or agent, for ``rllib`` without its checkpoint, and for an option the kind does
    not take)."""
    head, sep, arg = spec.partition(":") if isinstance(spec, str) else ("", "", "")
    kind = head.partition("@")[0]
    if kind not in CONTROLLER_ENV_DEFAULTS:
        raise ValueError(f"controller {spec!r} is not allowed; allowed: {_ALLOWED_SPECS}")
    if sep and not arg.strip():
        raise ValueError(f"controller {spec!r} is not allowed: nothing follows {head + ':'!r}; allowed: {head!r} "
                         f"for the default, or {head}:FILE ({_ALLOWED_SPECS})")
    if kind in _NEEDS_ARGUMENT and not sep:
        raise ValueError(f"controller {spec!r} is not allowed: {kind!r} has no default; allowed: "
                         f"{_NEEDS_ARGUMENT[kind]!r} (a folder written by 'flagellum train --engine ray')")
    controller_options(spec)
    return kind


def controller_options(spec: str) -> dict[str, float]:
    """The options after ``@`` in a controller spec (``adaptive@line=2`` -> {"line": 2.0}); ValueError for an
    option the kind does not take, a value that is not a finite number >= 0, or an option given twice."""
    head = spec.partition(":")[0]
    kind, at, opts = head.partition("@")
    if not at:
        return {}
    allowed = _SPEC_OPTIONS.get(kind, ())
    out: dict[str, float] = {}
    for item in opts.split(","):
        name, eq, value = item.partition("=")
        if name not in allowed or not eq:
            raise ValueError(f"controller {spec!r}: option {item!r} is not allowed; allowed: "
                             + (", ".join(_OPTION_RANGE[n] for n in allowed) + f" for {kind!r}" if allowed
                                else f"none for {kind!r}") + f" ({_ALLOWED_SPECS})")
        try:
            w = float(value)
        except ValueError:
            w = math.nan
        if not (math.isfinite(w) and (w > 0.0 if name == "cap" else w >= 0.0)) or name in out:
            raise ValueError(f"controller {spec!r}: {name}={value!r} is not allowed; allowed: "
                             f"{_OPTION_RANGE[name]} once")
        out[name] = w
    return out
