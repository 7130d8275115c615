"""ObservationModel.finish: float32, every entry clipped to its part's bounds, non-finite entries zeroed, in the
order of the parts (flat) or per part (dict) -- against the part-by-part definition."""

from __future__ import annotations

import numpy as np
import pytest

from flagellum_env.observations import ObservationModel


def _part_by_part(model: ObservationModel, parts: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    out = {}
    for name in model.part_shapes:
        lo, hi = model.bounds[name]
        a = np.nan_to_num(np.asarray(parts[name], dtype=np.float64).reshape(-1), nan=0.0, posinf=0.0, neginf=0.0)
        out[name] = np.clip(a, lo, hi).astype(np.float32)
    return out


@pytest.mark.parametrize("observation_type", ["flat", "dict"])
def test_finish_clips_zeroes_and_orders_as_the_parts_define(observation_type):
    model = ObservationModel(n_lookahead=2, n_shape_nodes=5, length_scale_m=0.13, n_nodes=122, has_head=True,
                             observation_type=observation_type)
    rng = np.random.default_rng(0)
    for _ in range(20):
        parts = {name: rng.normal(0.0, 30.0, size=shape) for name, shape in model.part_shapes.items()}
        parts["shape"][rng.integers(0, parts["shape"].size)] = np.nan
        parts["waypoints"][0] = np.inf
        parts["velocity"][1] = -np.inf
        want = _part_by_part(model, parts)
        got = model.finish(parts)
        if observation_type == "flat":
            assert got.dtype == np.float32 and np.array_equal(got, np.concatenate(list(want.values())))
            assert model.flat_space.contains(got)
        else:
            assert list(got) == list(want)
            for name in want:
                assert got[name].dtype == np.float32 and np.array_equal(got[name], want[name])
            assert model.dict_space.contains(got)
