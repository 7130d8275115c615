"""The steady start: computed once per configuration, cached in memory and on disk, exact."""

from __future__ import annotations

import numpy as np
import pytest

from flagellum_env import steady_start as ss
from physics.params import RPM_TO_RAD_S
from physics.presets import apply_preset

W10 = 10 * RPM_TO_RAD_S


@pytest.fixture(scope="module")
def faithful():
    return apply_preset("faithful")


def test_disk_cache_round_trip_is_bit_identical(faithful, tmp_path):
    params, numerics = faithful
    fresh = ss.compute_steady_start(params, numerics, W10, 3.0)
    ss.clear_memory_cache()
    stored = ss.get_steady_start(params, numerics, W10, 3.0, cache_dir=tmp_path)
    ss.clear_memory_cache()
    loaded = ss.get_steady_start(params, numerics, W10, 3.0, cache_dir=tmp_path)
    assert list((tmp_path / "steady_start").glob("*.npz")) == [tmp_path / "steady_start" / f"{fresh.key}.npz"]
    for s in (stored, loaded):
        assert s.speed_m_s == fresh.speed_m_s
        assert set(s.state) == set(fresh.state)
        for k, v in fresh.state.items():
            assert type(s.state[k]) is type(v)
            assert np.array_equal(s.state[k], v)
    assert ss.get_steady_start(params, numerics, W10, 3.0, cache_dir=tmp_path) is loaded  # memory hit


def test_the_steady_state_swims_straight_ahead(faithful):
    params, numerics = faithful
    s = ss.get_steady_start(params, numerics, W10, 6.0)
    sim = s.new_simulator()
    assert 0.5e-3 < s.speed_m_s < 0.9e-3  # ~0.42 cm per turn at 10 rpm (the flagellum turns at 10 rpm in the lab)
    assert sim.head_velocity @ sim.head_orientation[:, 0] > 0
    assert sim.omega == W10


def test_key_depends_on_every_input(faithful):
    params, numerics = faithful
    k = ss.cache_key(params, numerics, W10, 6.0)
    assert k != ss.cache_key(params.replace(viscosity=3.0), numerics, W10, 6.0)
    assert k != ss.cache_key(params, numerics.replace(newton_tol=1e-7), W10, 6.0)
    assert k != ss.cache_key(params, numerics, 2 * W10, 6.0)
    assert k != ss.cache_key(params, numerics, W10, 7.0)
    assert k == ss.cache_key(params, numerics, W10, 6.0)


def test_cache_dir_comes_from_the_environment_variable(monkeypatch, tmp_path):
    monkeypatch.setenv(ss.CACHE_ENV_VAR, str(tmp_path))
    assert ss.default_cache_dir() == tmp_path
    monkeypatch.delenv(ss.CACHE_ENV_VAR)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert ss.default_cache_dir() == tmp_path / "xdg" / "flagellum_swimmer"


def test_unreadable_cache_file_is_recomputed(faithful, tmp_path):
    params, numerics = faithful
    key = ss.cache_key(params, numerics, W10, 2.0)
    (tmp_path / "steady_start").mkdir()
    (tmp_path / "steady_start" / f"{key}.npz").write_bytes(b"garbage")
    ss.clear_memory_cache()
    with pytest.warns(RuntimeWarning, match="unreadable"):
        s = ss.get_steady_start(params, numerics, W10, 2.0, cache_dir=tmp_path)
    assert np.array_equal(s.state["q"], ss.compute_steady_start(params, numerics, W10, 2.0).state["q"])


def test_bad_arguments_are_rejected(faithful):
    params, numerics = faithful
    with pytest.raises(ValueError, match="omega_rad_s"):
        ss.get_steady_start(params, numerics, 0.0, 1.0)
    with pytest.raises(ValueError, match="settle_time_s"):
        ss.get_steady_start(params, numerics, W10, -1.0)
