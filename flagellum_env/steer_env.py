"""``FlagellumSteer-v0``: steer a buckling-flagellum swimmer through waypoints with its motor speed."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from flagellum_env.config import (DEFAULT_REACH_RADIUS_M, SteerConfig, draw_randomization, make_config,
                                   resolve_path)
from flagellum_env.observations import ObservationModel
from flagellum_env.paths import WaypointPath, random_path
from flagellum_env.registration import STEER_ENV_ID, STEER_FAST_ENV_ID, registered_max_episode_steps
from flagellum_env.render import HumanWindow, Renderer, Scene
from flagellum_env.rewards import TERMS, reward_terms
from flagellum_env.start_frame import StartFrame
from flagellum_env.steady_start import SteadyStart, get_steady_start
from flagellum_env.tracking import BucklingMonitor, PathTracker
from physics.errors import SimulationError, is_interrupt
from physics.model.geometry import layout_for
from physics.params import RPM_TO_RAD_S, SwimmerParams
from physics.run import advance
from physics.simulator import Simulator

#: Motor turns at the low speed that make the steady start (when ``settle_time_s`` is None).
SETTLE_TURNS = 5
RESET_OPTIONS = ("path",)
#: Simulated seconds a second of rendered video shows: ``metadata["render_fps"] = PLAYBACK_SPEEDUP / control_dt``.
PLAYBACK_SPEEDUP = 8.0


class FlagellumSteerEnv(gym.Env):
    """
    ## Description

    A bacterium-like swimmer (Huang & Jawed, Soft Matter 2020): a spherical head driven by a
    rotating, elastic, left-handed helical flagellum in a viscous fluid (Stokes flow). The
    only control is the motor speed. At low speed the flagellum stays straight and the swimmer
    goes straight, head first (about 0.28 cm per motor turn). Above a critical speed the
    flagellum buckles after a while and the swimmer turns; when the speed drops again the
    flagellum relaxes and it swims straight in the new direction. The task is to steer through
    a sequence of waypoints (the paper's square, a random path or your own) with this run and
    tumble-like mechanism. The physics is ``physics.simulator.Simulator`` (implicit discrete
    elastic rod, Lighthill slender-body theory, Higdon head); an env step advances it by
    ``control_dt`` simulated seconds at the chosen speed.

    ## Action Space

    ``action_type="continuous"`` (default): ``Box(-1, 1, (1,), float32)``, mapped linearly onto
    the motor speed ``omega = lo + (a + 1) / 2 * (hi - lo)`` with ``(lo, hi) = omega_range_rpm``
    (values outside [-1, 1] are clipped).

    | Num | Action                          | Min | Max | Unit                    |
    |-----|---------------------------------|-----|-----|-------------------------|
    | 0   | motor speed on the [-1, 1] scale | -1  | 1   | -> rpm in omega_range_rpm |

    ``action_type="discrete"``: ``Discrete(k)``, action i runs the motor at
    ``discrete_speeds_rpm[i]`` (default 10, 60 and 150 rpm: cruise, fast straight, buckle).

    ## Observation Space

    ``observation_type="flat"`` (default): ``Box(float32)`` of size 22 + 3 K (K =
    ``n_shape_nodes``, 46 by default; with ``n_lookahead=1``, 3 fewer). ``"dict"``: a ``Dict``
    of the same parts by name, each a 1-D ``Box`` holding that part's rows. L is the flagellum's
    nominal axial length (0.13 m). Body frame = the head's axes X_b (head first), Y_b, Z_b;
    the start frame is defined under Starting State. Entries are clipped to finite bounds
    (waypoints +-50 L, velocity +-1000 mm/s, shape +-2 L, L'/L [0, 2]).

    | Index (K = 8) | Part             | Meaning                                                | Unit |
    |---------------|------------------|--------------------------------------------------------|------|
    | 0 - 2         | waypoints        | next waypoint minus head centre, body frame            | L    |
    | 3 - 5         | waypoints        | the waypoint after it (n_lookahead = 2; last repeated) | L    |
    | 6 - 8         | orientation      | X_b in the start frame                                 | -    |
    | 9 - 11        | orientation      | Y_b in the start frame                                 | -    |
    | 12 - 14       | orientation      | Z_b in the start frame                                 | -    |
    | 15 - 17       | velocity         | head velocity, body frame                              | mm/s |
    | 18 - 41       | shape            | K flagellum nodes, base to tip, minus the head centre, body frame (x, y, z per node) | L |
    | 42            | end_to_end_ratio | L'/L (~1 straight, well below 1 buckled)               | -    |
    | 43            | motor_speed      | motor speed / highest allowed speed, [0, 1]            | -    |
    | 44            | previous_action  | last action on the [-1, 1] scale                       | -    |
    | 45            | time_left        | fraction of the time budget left, [0, 1]               | -    |

    The buckled state shows in ``shape`` (the tip folds back towards the head) and in
    ``end_to_end_ratio``. With the default reading of the head (``head_rotation=fixed``) the head
    does not spin and the body frame turns only as the swimmer turns; with ``torque_free`` or ``literal``
    the head spins about X_b, so Y_b, Z_b and every body-frame component across X_b turn at its spin
    rate; ``orientation`` tells where they are. With randomisation, Gaussian noise is added to the measured parts
    (rows waypoints to end_to_end_ratio). See ``flagellum_env.observations``.

    ## Rewards

    The sum of these terms, each also in ``info["reward_<term>"]`` (weights in ``reward``,
    a ``RewardConfig`` or dict):

    - ``progress``: +1 per cm of progress along the path in the step (arc length of the head's
      projection onto the current segment plus the finished segments; negative when going back);
    - ``cross_track``: -0.005 per cm of distance from the current segment per simulated second;
    - ``energy``: -0.01 per mJ of motor work |T omega| dt in the step;
    - ``waypoint``: +10 per waypoint reached;
    - ``penalty``: -20 once when the episode ends off the path or in a ``SimulationError``.

    ## Starting State

    Steady straight swimming at the lowest allowed motor speed: the state after
    ``settle_time_s`` (default 5 motor turns, 30 s at 10 rpm) from rest, computed once per
    configuration and cached in memory and on disk (``flagellum_env.steady_start``; a cached
    state is bit-identical to a computed one). The *start frame* of the episode is the head's
    pose at that moment: origin at the head centre, +x along X_b (the swimming direction), +z
    along Z_b, y = z x x. Paths are given in this frame. With ``randomize``, the physical
    parameters are drawn first and the steady start is computed for them (memory cache only).

    ## Episode End

    - Termination: the last waypoint is reached (``info["is_success"] = True``); or the head is
      farther than ``off_path_m`` from the current path segment ("hopelessly off the path",
      penalty); or the simulation fails (``SimulationError``: penalty, ``info["error"]`` holds
      the message, the observation is that of the last good state). Never an exception.
    - Truncation: after ``max_sim_time_s`` simulated seconds (rounded up to whole steps). By
      default ``max_sim_time_s = time_factor * path length / v0`` where v0 is the steady
      straight-swimming speed at the low motor speed (measured on the steady start; about
      0.07 cm/s at 10 rpm) and ``time_factor = 1.5``: enough to swim the whole path at the low
      speed (at most about 250 steps on a default random path).
    - ``gymnasium.make`` adds a ``TimeLimit`` at the registered ``max_episode_steps`` = 400: the
      largest budget of a default random path (3 segments of at most 8 cm), so it never cuts an
      episode short with the registered defaults. For a longer path (``"square"``: ~1670 steps) or
      a shorter ``control_dt``, give ``gym.make`` a larger ``max_episode_steps`` or -1 (no
      ``TimeLimit``); the env warns once when it sees the registered limit would cut its budget
      (``flagellum_env.registration.steer_max_episode_steps`` computes the bound).

    ## Info

    ``is_success``, ``waypoint_index`` (the current target = waypoints reached),
    ``n_waypoints``, ``cross_track_error_m``, ``distance_to_waypoint_m``, ``path_progress_m``,
    ``path_length_m``, ``energy_j`` (this step), ``energy_used_j`` (episode), ``buckled``,
    ``buckling_events`` (L'/L fell below ``buckling_threshold``; re-armed above
    ``buckling_release``), ``end_to_end_ratio``, ``motor_speed_rpm``, ``sim_time_s``,
    ``max_sim_time_s``, ``head_position_m`` (start frame), ``off_path``, ``reward_<term>``, and
    ``error`` / ``error_quantity`` after a failed step.

    ## Arguments

    | Argument            | Default              | Meaning                                                   |
    |---------------------|----------------------|-----------------------------------------------------------|
    | path                | "random"             | "square" (paper, side 0.25 m), "random" (new each reset), a path-file name (JSON), a list of [x, y, z] waypoints (m) or a ``WaypointPath`` |
    | random_path         | None                 | ``RandomPathConfig`` or dict: n_waypoints 3, segment_length_m (0.03, 0.08), max_turn_deg 90, planar True |
    | preset              | "faithful"           | physics preset: "faithful", "fast", "reference" or "paper" |
    | params / numerics   | None                 | dicts of ``SwimmerParams`` / ``NumericsConfig`` fields applied after the preset |
    | control_dt          | 2.0                  | simulated seconds per env step (a whole number of physics steps; <= 600) |
    | omega_range_rpm     | (10, 150)            | motor speeds of the continuous action, rpm (0 < lo < hi)  |
    | action_type         | "continuous"         | "continuous" or "discrete"                                |
    | discrete_speeds_rpm | (10, 60, 150)        | motor speeds of the discrete actions, increasing, rpm     |
    | observation_type    | "flat"               | "flat" or "dict"                                          |
    | n_lookahead         | 2                    | waypoints in the observation: 1 or 2                      |
    | n_shape_nodes       | 8                    | flagellum nodes in the observation (K)                    |
    | reach_radius_m      | None                 | waypoint reached within this distance, m (None: the path file's value, else 0.015) |
    | max_sim_time_s      | None                 | time budget, s (None: the rule under Episode End)         |
    | time_factor         | 1.5                  | factor of that rule                                       |
    | off_path_m          | 0.1                  | terminate when this far from the current segment, m      |
    | randomize           | False                | True (defaults), dict or ``RandomizationConfig``: E, mu, b, geometry fractions and observation noise |
    | reward              | None                 | ``RewardConfig`` or dict of reward weights                |
    | settle_time_s       | None                 | steady-start settle time, s (None: 5 motor turns)         |
    | buckling_threshold  | 0.9                  | L'/L below which a buckling event starts                  |
    | buckling_release    | 0.95                 | L'/L above which the next event can start                 |
    | cache_dir           | None                 | steady-start disk cache (None: $FLAGELLUM_CACHE_DIR or ~/.cache/flagellum_swimmer) |
    | disk_cache          | True                 | False keeps steady starts in memory only                  |
    | render_mode         | None                 | None, "rgb_array" or "human"                              |
    | render_size         | (640, 480)           | frame (width, height), pixels; frames are (height, width, 3) uint8 |

    ``metadata["render_fps"]`` is ``PLAYBACK_SPEEDUP / control_dt`` (4 at the default 2 s): a video
    (``gymnasium.wrappers.RecordVideo``) plays 8 simulated seconds per second.

    ## Variants

    Registered ids with other defaults (``flagellum_env.registration``): ``FlagellumSteer-fast-v0``
    (``FlagellumSteerFastEnv``, preset ``fast``); its docstring says what it costs and how it differs. The
    ``-coarse`` variant was retired with its preset (``gym.make`` of it raises a one-line ValueError naming the
    replacement; ``flagellum_env.registration.RETIRED_ENV_IDS``). Other presets: ``preset=``.

    Invalid values raise ``ValueError`` naming the argument and the allowed values.
    ``reset(options={"path": ...})`` replaces the path for one episode (same forms as ``path``).

    ## Version History

    - v0: initial version; ``max_episode_steps`` at registration, ``render_fps`` from ``control_dt``
      and the ``-fast`` / ``-coarse`` variants added without changing the dynamics; the ``-coarse``
      variant retired with its preset (``FlagellumSteer-v0`` itself unchanged).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"],
                                          "render_fps": PLAYBACK_SPEEDUP / 2.0}
    #: This class's registered id and its defaults (a variant overrides both; ``make`` arguments override them).
    env_id: ClassVar[str] = STEER_ENV_ID
    defaults: ClassVar[dict[str, Any]] = {}

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not allowed; choose one of "
                             f"{[None] + self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.config: SteerConfig = make_config(**{**self.defaults, **kwargs})
        cfg = self.config
        self.metadata = {**type(self).metadata, "render_fps": PLAYBACK_SPEEDUP / cfg.control_dt}
        self._warned_time_limit = False
        self.params, self.numerics = cfg.physics()
        dt = self.numerics.dt
        n_sub = cfg.control_dt / dt
        if n_sub < 0.999999 or abs(n_sub - round(n_sub)) > 1e-6 * n_sub:
            raise ValueError(f"control_dt={cfg.control_dt!r} s must be a whole multiple of the physics time "
                             f"step dt={dt!r} s (preset {cfg.preset!r})")
        self.n_substeps = round(n_sub)
        self.low_speed_rpm = cfg.low_speed_rpm
        self.high_speed_rpm = cfg.high_speed_rpm
        self.settle_time_s = (cfg.settle_time_s if cfg.settle_time_s is not None
                              else SETTLE_TURNS * 60.0 / self.low_speed_rpm)
        if cfg.action_type == "continuous":
            self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(1,), dtype=np.float32)
        else:
            self.action_space = spaces.Discrete(len(cfg.discrete_speeds_rpm))
        self.obs_model = ObservationModel(cfg.n_lookahead, cfg.n_shape_nodes, self.params.axial_length,
                                          layout_for(self.params).n, self.params.has_head, cfg.observation_type)
        self.observation_space = self.obs_model.space
        # episode state (set by reset)
        self.simulator: Simulator | None = None
        self.path: WaypointPath | None = None
        self.tracker: PathTracker | None = None
        self.start_frame: StartFrame | None = None
        self.episode_params: SwimmerParams = self.params
        self.max_sim_time_s = math.nan
        self._nominal: SteadyStart | None = None
        self._renderer: Renderer | None = None
        self._window: HumanWindow | None = None
        self._ended_by_error = False
        self._noise_std = 0.0
        self.steps = 0
        self.physics_steps = 0

    # --- Gymnasium API ---------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: {list(RESET_OPTIONS)}")
        cfg, rng = self.config, self.np_random
        if "path" in options:
            path = resolve_path(options["path"]) or random_path(rng, cfg.random_path)
        else:
            path = cfg.fixed_path or random_path(rng, cfg.random_path)
        self.episode_params, self._noise_std = self._draw_randomization(rng)
        nominal = self._nominal_start()
        if self.episode_params == self.params:
            start = nominal
        else:
            start = get_steady_start(self.episode_params, self.numerics, self.low_speed_rpm * RPM_TO_RAD_S,
                                     self.settle_time_s, cache_dir=cfg.cache_dir, disk=False)
        sim = start.new_simulator()
        self.simulator = sim
        self.start_frame = StartFrame.from_pose(sim.head_position, sim.head_orientation)
        self.path = path
        reach = cfg.reach_radius_m or path.reach_radius_m or DEFAULT_REACH_RADIUS_M
        self.tracker = PathTracker(path, reach)
        self.max_sim_time_s = (cfg.max_sim_time_s if cfg.max_sim_time_s is not None
                               else cfg.time_factor * path.length_m / nominal.speed_m_s)
        self.max_steps = max(1, math.ceil(self.max_sim_time_s / cfg.control_dt - 1e-9))
        self._warn_if_time_limit_cuts(path)
        self.buckling = BucklingMonitor(cfg.buckling_threshold, cfg.buckling_release)
        self.buckling.update(sim.end_to_end_ratio())
        self.steps = 0
        self.physics_steps = 0
        self.energy_used_j = 0.0
        self.motor_speed_rpm = self.low_speed_rpm
        self.previous_action = -1.0
        self._ended_by_error = False
        head = self._head_start()
        self._progress = self.tracker.progress(head)
        self._trail = [head]
        zero = {t: 0.0 for t in TERMS}
        obs = self._observation()
        info = self._info(zero, energy_j=0.0, off_path=False)
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action: Any):
        if self.simulator is None:
            raise RuntimeError("call reset() before step()")
        if self._ended_by_error:
            raise RuntimeError("the episode ended in a simulation error; call reset() before step()")
        omega_rpm, scaled = self._decode(action)
        sim, tracker, dt = self.simulator, self.tracker, self.numerics.dt
        sim.set_motor_speed(omega_rpm * RPM_TO_RAD_S)
        self.motor_speed_rpm, self.previous_action = omega_rpm, scaled
        energy, reached, n_done, error = 0.0, 0, 0, None

        def on_step(sim: Simulator, k: int) -> bool:
            # after each physics step: energy, waypoints, buckling; stop at a non-finite head or the path's end
            nonlocal energy, reached, n_done, error
            n_done += 1
            energy += abs(sim.motor_power) * dt
            head = self._head_start()
            if not np.all(np.isfinite(head)):
                error = SimulationError("non-finite head position", sim.step_count, sim.time, "positions")
                return True
            reached += tracker.update(head)
            self.buckling.update(sim.end_to_end_ratio())
            return tracker.done

        try:
            advance(sim, steps=self.n_substeps, on_step=on_step)
        except (SimulationError, np.linalg.LinAlgError) as exc:
            error = exc
        except SystemError as exc:  # Ctrl-C that landed inside a compiled kernel: report it as what it is
            if is_interrupt(exc):
                raise KeyboardInterrupt from None
            raise
        self.steps += 1
        self.physics_steps += n_done
        duration = n_done * dt
        self.energy_used_j += energy
        head = self._head_start()
        if not np.all(np.isfinite(head)):
            head = self._trail[-1]
        self._trail.append(head)
        progress = tracker.progress(head)
        cross = tracker.cross_track_error(head)
        failed = error is not None
        off_path = not failed and not tracker.done and cross > self.config.off_path_m
        terms = reward_terms(self.config.reward, progress - self._progress, cross, duration, energy, reached,
                             off_path=off_path, failed=failed)
        self._progress = progress
        terminated = tracker.done or off_path or failed
        truncated = not terminated and self.steps >= self.max_steps
        obs = self._observation()
        info = self._info(terms, energy_j=energy, off_path=off_path)
        if failed:
            self._ended_by_error = True
            info["error"] = str(error)
            info["error_quantity"] = getattr(error, "quantity", type(error).__name__)
        if self.render_mode == "human":
            self.render()
        return obs, float(sum(terms.values())), terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() was called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.simulator is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            self._renderer = Renderer(*self.config.render_size)
        frame = self._renderer.draw(self.scene())
        if self.render_mode == "rgb_array":
            return frame
        if self._window is None:
            self._window = HumanWindow(self.metadata["render_fps"])
        self._window.show(frame)
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._window is not None:
            self._window.close()
            self._window = None

    # --- helpers ---------------------------------------------------------------------------
    def _warn_if_time_limit_cuts(self, path: WaypointPath) -> None:
        """Made by ``gymnasium.make`` (a spec is set) with a registered ``max_episode_steps`` below this
        episode's own budget: say so once (the ``TimeLimit`` would end the episode early)."""
        cap = registered_max_episode_steps(self.spec.id if self.spec is not None else None)
        if self._warned_time_limit or cap is None or self.max_steps <= cap:
            return
        self._warned_time_limit = True
        gym.logger.warn(
            f"{self.spec.id}: this episode's time budget is {self.max_steps} steps (path {path.name!r}, "
            f"{path.length_m:.3g} m, control_dt {self.config.control_dt:g} s) but the id is registered with "
            f"max_episode_steps={cap}: the TimeLimit of gymnasium.make ends it at step {cap} unless make was "
            f"given max_episode_steps=-1 (no TimeLimit) or >= {self.max_steps}")

    def scene(self) -> Scene:
        """What a rendered frame shows (start frame, m)."""
        sim = self.simulator
        return Scene(vertices=self.path.vertices, n_reached=self.tracker.index,
                     reach_radius_m=self.tracker.reach_radius_m, trail=np.array(self._trail),
                     nodes=self.start_frame.points_to_start(sim.nodes), head_radius_m=self.episode_params.head_radius,
                     time_s=self.sim_time_s, motor_speed_rpm=self.motor_speed_rpm,
                     end_to_end_ratio=sim.end_to_end_ratio(), buckled=self.buckling.buckled, path_name=self.path.name)

    @property
    def sim_time_s(self) -> float:
        """Simulated time since the episode started, s."""
        return self.physics_steps * self.numerics.dt

    @property
    def steady_speed_m_s(self) -> float:
        """Straight-swimming speed at the low motor speed (nominal parameters), m/s."""
        return self._nominal_start().speed_m_s

    def _nominal_start(self) -> SteadyStart:
        if self._nominal is None:
            self._nominal = get_steady_start(self.params, self.numerics, self.low_speed_rpm * RPM_TO_RAD_S,
                                             self.settle_time_s, cache_dir=self.config.cache_dir,
                                             disk=self.config.disk_cache)
        return self._nominal

    def _draw_randomization(self, rng: np.random.Generator) -> tuple[SwimmerParams, float]:
        return draw_randomization(self.params, self.config.randomize, rng)

    def _decode(self, action: Any) -> tuple[float, float]:
        """(motor speed rpm, action on the [-1, 1] scale)."""
        cfg = self.config
        if cfg.action_type == "continuous":
            raw = np.asarray(action)
            if raw.dtype.kind not in "iuf":  # complex, bool, str, object: not a speed on the [-1, 1] scale
                raise ValueError(f"action={action!r} must be one finite number in [-1, 1]")
            a = raw.astype(np.float64).reshape(-1)
            if a.size != 1 or not np.isfinite(a[0]):
                raise ValueError(f"action={action!r} must be one finite number in [-1, 1]")
            x = float(np.clip(a[0], -1.0, 1.0))
            lo, hi = cfg.omega_range_rpm
            return lo + 0.5 * (x + 1.0) * (hi - lo), x
        k = len(cfg.discrete_speeds_rpm)
        a = np.asarray(action)
        if a.size != 1 or not np.issubdtype(a.dtype, np.integer) or not 0 <= int(a.reshape(-1)[0]) < k:
            raise ValueError(f"action={action!r} must be an integer from 0 to {k - 1}")
        i = int(a.reshape(-1)[0])
        return cfg.discrete_speeds_rpm[i], 2.0 * i / (k - 1) - 1.0

    def _head_start(self) -> np.ndarray:
        return self.start_frame.points_to_start(self.simulator.head_position)

    def _observation(self):
        time_left = max(0.0, 1.0 - self.steps / self.max_steps)
        parts = self.obs_model.measure(self.simulator, self.start_frame, self.tracker,
                                       self.motor_speed_rpm / self.high_speed_rpm, self.previous_action, time_left)
        parts = self.obs_model.add_noise(parts, self.np_random, self._noise_std)
        return self.obs_model.finish(parts)

    def _info(self, terms: dict[str, float], energy_j: float, off_path: bool) -> dict[str, Any]:
        sim, tracker = self.simulator, self.tracker
        head = self._trail[-1]
        info: dict[str, Any] = {
            "is_success": bool(tracker.done),
            "waypoint_index": int(tracker.index),
            "n_waypoints": int(tracker.path.n_waypoints),
            "cross_track_error_m": tracker.cross_track_error(head),
            "distance_to_waypoint_m": tracker.distance_to_target(head),
            "path_progress_m": self._progress,
            "path_length_m": tracker.path_length_m,
            "energy_j": float(energy_j),
            "energy_used_j": float(self.energy_used_j),
            "buckled": bool(self.buckling.buckled),
            "buckling_events": int(self.buckling.events),
            "end_to_end_ratio": float(sim.end_to_end_ratio()),
            "motor_speed_rpm": float(self.motor_speed_rpm),
            "sim_time_s": float(self.sim_time_s),
            "max_sim_time_s": float(self.max_sim_time_s),
            "head_position_m": np.array(head, dtype=np.float64),
            "off_path": bool(off_path),
        }
        for t in TERMS:
            info[f"reward_{t}"] = float(terms[t])
        return info


class FlagellumSteerFastEnv(FlagellumSteerEnv):
    """``FlagellumSteer-fast-v0``: ``FlagellumSteer-v0`` (``FlagellumSteerEnv``, whose docstring is the
    manual) at the ``fast`` preset.

    The paper's grid (N = 122) and variable-step BDF3 with Newton-Krylov steps as ``faithful``, with a ten
    times looser local error tolerance (``step_tol`` 1e-3): the same swimmer and grid at a lower cost per step,
    with larger integration errors (docs/bench_quick.md measures the presets against ``reference``: 1.4x
    ``faithful``'s speed cruising, 1.5x in a burst, 1.3x its random-policy env steps/s; θ 0.6 % and φ 7 % off). Every
    argument and default is ``FlagellumSteer-v0``'s except ``preset="fast"``; ``max_episode_steps`` = 400
    at registration as there.
    """

    env_id: ClassVar[str] = STEER_FAST_ENV_ID
    defaults: ClassVar[dict[str, Any]] = {"preset": "fast"}
