"""What the agent sees: the parts of the observation, their spaces, and how they are measured.

Parts, in the order they are concatenated into the flat vector (K = ``n_shape_nodes``,
W = ``n_lookahead``; L is the nominal axial length of the flagellum, 0.13 m for the paper):

================  ======  ====================================================================
part              size    meaning
================  ======  ====================================================================
waypoints         3 W     next W waypoints minus the head centre, in the head's body frame
                          (components along X_b, Y_b, Z_b), divided by L; once the path runs
                          out the last waypoint is repeated
orientation       9       head orientation in the start frame: the columns X_b, Y_b, Z_b of
                          the rotation matrix one after the other (X_b first), in [-1, 1]
velocity          3       head velocity in the body frame, mm/s
shape             3 K     K flagellum nodes evenly spread from its base to its tip, minus the
                          head centre, in the body frame, divided by L (a buckled flagellum
                          folds: its tip comes near the head)
end_to_end_ratio  1       L'/L of the flagellum (about 1 when straight, well below when buckled)
motor_speed       1       current motor speed / highest allowed speed, in [0, 1]
previous_action   1       the last action on the [-1, 1] scale (discrete: 2 i / (k - 1) - 1)
time_left         1       fraction of the episode's time budget left, in [0, 1]
================  ======  ====================================================================

In the ``Dict`` form each part is a 1-D ``Box`` of the size given (what stable-baselines3's
``MultiInputPolicy`` expects). Entries are clipped to finite bounds: waypoints +-50 (L), velocity +-1000 (mm/s), shape +-2
(L), L'/L [0, 2]; the others as given above.

The body frame turns with the head. With the default ``head_rotation=fixed`` the head does not spin;
with ``torque_free`` or ``literal`` it spins about X_b as the motor drives the flagellum, so the Y_b and
Z_b components rotate at the head's spin rate. The orientation part tells where Y_b and Z_b are.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from gymnasium import spaces

from flagellum_env.start_frame import StartFrame, to_body
from flagellum_env.tracking import PathTracker
from physics.simulator import Simulator

#: Unit of the velocity part, m/s.
VELOCITY_UNIT_M_S = 1e-3
#: Parts that carry sensor noise when randomisation adds observation noise.
NOISY_PARTS = ("waypoints", "orientation", "velocity", "shape", "end_to_end_ratio")
#: Bounds of the parts (entries are clipped to them): waypoints +-50 L (6.5 m for the paper),
#: velocity +-1000 mm/s, shape and L'/L +-2 (a flagellum reaches about 1.2 L from the head).
WAYPOINT_BOUND = 50.0
VELOCITY_BOUND = 1000.0
SHAPE_BOUND = 2.0


class ObservationModel:
    """Builds observations; ``space`` is a flat ``Box`` or a ``Dict`` of the parts (float32)."""

    def __init__(self, n_lookahead: int, n_shape_nodes: int, length_scale_m: float, n_nodes: int,
                 has_head: bool, observation_type: str = "flat") -> None:
        first = 1  # node 0 is the head centre (or, without a head, the base node itself)
        last = n_nodes - 1
        if n_shape_nodes > last - first + 1:
            raise ValueError(f"n_shape_nodes={n_shape_nodes!r} must be at most {last - first + 1}, "
                             f"the number of flagellum nodes of this preset")
        self.shape_nodes = np.round(np.linspace(first, last, n_shape_nodes)).astype(np.int64)
        self.length_scale_m = float(length_scale_m)
        self.observation_type = observation_type
        self.n_lookahead = n_lookahead
        self.has_head = has_head
        # 1-D parts (what stable-baselines3's dict policies expect); xyz triples one after the other
        self.part_shapes: dict[str, tuple[int, ...]] = {
            "waypoints": (3 * n_lookahead,), "orientation": (9,), "velocity": (3,),
            "shape": (3 * n_shape_nodes,), "end_to_end_ratio": (1,), "motor_speed": (1,),
            "previous_action": (1,), "time_left": (1,),
        }
        self.bounds: dict[str, tuple[float, float]] = {
            "waypoints": (-WAYPOINT_BOUND, WAYPOINT_BOUND), "orientation": (-1.0, 1.0),
            "velocity": (-VELOCITY_BOUND, VELOCITY_BOUND), "shape": (-SHAPE_BOUND, SHAPE_BOUND),
            "end_to_end_ratio": (0.0, SHAPE_BOUND), "motor_speed": (0.0, 1.0),
            "previous_action": (-1.0, 1.0), "time_left": (0.0, 1.0),
        }
        self.dict_space = spaces.Dict({
            name: spaces.Box(low=np.float32(lo), high=np.float32(hi), shape=shape, dtype=np.float32)
            for name, shape in self.part_shapes.items() for lo, hi in [self.bounds[name]]})
        lows = [np.full(int(np.prod(s)), self.bounds[n][0], np.float32) for n, s in self.part_shapes.items()]
        highs = [np.full(int(np.prod(s)), self.bounds[n][1], np.float32) for n, s in self.part_shapes.items()]
        self.flat_space = spaces.Box(low=np.concatenate(lows), high=np.concatenate(highs), dtype=np.float32)
        self.space = self.flat_space if observation_type == "flat" else self.dict_space
        self._low = np.concatenate(lows).astype(np.float64)  # the bounds per entry of the flat vector
        self._high = np.concatenate(highs).astype(np.float64)
        self._slices = self.slices()

    @property
    def size(self) -> int:
        """Length of the flat observation."""
        return int(self.flat_space.shape[0])

    def slices(self) -> dict[str, slice]:
        """Where each part sits in the flat vector."""
        out, start = {}, 0
        for name, shape in self.part_shapes.items():
            n = int(np.prod(shape))
            out[name] = slice(start, start + n)
            start += n
        return out

    def measure(self, sim: Simulator, frame: StartFrame, tracker: PathTracker, motor_speed_fraction: float,
                previous_action: float, time_left: float) -> dict[str, np.ndarray]:
        """The noise-free parts (float64) for the simulator's current state."""
        head = sim.head_position
        body = sim.head_orientation
        targets_lab = frame.points_to_lab(tracker.targets(self.n_lookahead))
        nodes = sim.nodes
        return {
            "waypoints": to_body(targets_lab - head, body) / self.length_scale_m,
            # rows of R^T are the columns of R: X_b, Y_b, Z_b in the start frame
            "orientation": frame.rotation_to_start(body).T.ravel(),
            "velocity": to_body(sim.head_velocity, body) / VELOCITY_UNIT_M_S,
            "shape": to_body(nodes[self.shape_nodes] - head, body) / self.length_scale_m,
            "end_to_end_ratio": np.array([sim.end_to_end_ratio()]),
            "motor_speed": np.array([motor_speed_fraction]),
            "previous_action": np.array([previous_action]),
            "time_left": np.array([time_left]),
        }

    def add_noise(self, parts: Mapping[str, np.ndarray], rng: np.random.Generator, std: float) -> dict[str, np.ndarray]:
        """Gaussian noise of ``std`` on the measured parts (``NOISY_PARTS``); others unchanged."""
        out = dict(parts)
        if std > 0.0:
            for name in NOISY_PARTS:
                out[name] = parts[name] + rng.normal(0.0, std, size=parts[name].shape)
        return out

    def finish(self, parts: Mapping[str, np.ndarray]) -> np.ndarray | dict[str, np.ndarray]:
        """float32, clipped to the bounds (non-finite entries zeroed); flat or dict per the type."""
        flat = np.concatenate([np.asarray(parts[name], dtype=np.float64).reshape(-1) for name in self.part_shapes])
        flat[~np.isfinite(flat)] = 0.0
        done = np.clip(flat, self._low, self._high).astype(np.float32)
        if self.observation_type == "dict":
            return {name: done[sl].copy() for name, sl in self._slices.items()}
        return done
