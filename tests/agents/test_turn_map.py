"""Turn geometry and the TurnMap: angles, inversion of theta(t_c), file round trip, refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from agents.turn_geometry import (angle_between, azimuth, direction_from, perpendicular_basis, turn_angles,
                                  wrap_angle)
from agents.turn_map import TurnMap, TurnMapMismatch
from agents.turn_measurement import TurnResult, phase_node_index
from physics.params import NumericsConfig, SwimmerParams


def test_perpendicular_basis_is_right_handed_and_orthonormal():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = rng.normal(size=3)
        a /= np.linalg.norm(a)
        e1, e2 = perpendicular_basis(a)
        m = np.column_stack([e1, e2, a])
        assert np.allclose(m.T @ m, np.eye(3), atol=1e-12)
        assert np.linalg.det(m) == pytest.approx(1.0)


def test_direction_from_inverts_angle_and_azimuth():
    d0 = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    for theta, az in [(0.4, 1.0), (2.5, -2.0), (math.pi / 2, 3.0)]:
        t1 = direction_from(d0, theta, az)
        assert angle_between(d0, t1) == pytest.approx(theta)
        assert wrap_angle(azimuth(t1, d0) - az) == pytest.approx(0.0, abs=1e-12)


def test_turn_angles_of_known_directions():
    frame = np.eye(3)  # body frame = lab frame
    assert turn_angles(np.array([1, 0, 0.0]), np.array([0, 1, 0.0]), frame) == pytest.approx((90.0, 0.0))
    theta, phi = turn_angles(np.array([1, 0, 0.0]), np.array([1, 0, 1.0]), frame)
    assert theta == pytest.approx(45.0) and phi == pytest.approx(45.0)
    assert turn_angles(np.array([1, 0, 0.0]), np.array([0, 0, -1.0]), frame)[1] == pytest.approx(-90.0)


def test_wrap_angle_range():
    for a in np.linspace(-10, 10, 41):
        w = wrap_angle(float(a))
        assert -math.pi < w <= math.pi and math.isclose(math.cos(w), math.cos(a), abs_tol=1e-12)


def _map(points, params=None) -> TurnMap:
    return TurnMap(params=params or SwimmerParams(), numerics=NumericsConfig(), preset="faithful",
                   omega_l_rpm=10.0, omega_h_rpm=150.0, phase_node=7, points=tuple(points))


def _pt(tc, ph, theta, psi, offset=(0.01, 0.0, 0.0)):
    return TurnResult(t_c=tc, phase_deg=ph, theta_deg=theta, phi_deg=0.0, psi_deg=psi, relax_s=30.0, straight=True,
                      period_s=9.0, offset_m=offset)


def test_inverse_of_theta_curve_on_the_rising_branch():
    # theta rises 0 -> 150, falls, then rises again higher: the inverse uses the first rise only
    pts = [_pt(tc, ph, th + (1 if ph else -1), 170.0)
           for tc, th in [(5, 10), (10, 60), (20, 150), (30, 120), (40, 160)] for ph in (0, 90)]
    m = _map(pts)
    assert m.max_theta_deg == pytest.approx(150.0)
    assert m.t_c_for(60.0) == pytest.approx(10.0)
    assert m.t_c_for(35.0) == pytest.approx(7.5)
    assert m.t_c_for(500.0) == pytest.approx(20.0)  # clipped to the largest turn
    assert m.t_c_for(0.0) == 0.0
    tcs, th, spread = m.theta_curve()
    assert list(tcs) == [5, 10, 20, 30, 40] and np.allclose(spread, 2.0)


def test_psi_mean_is_circular():
    m = _map([_pt(10, 0, 50, 179.0), _pt(10, 90, 50, -179.0), _pt(20, 0, 90, 170.0)])
    _, psi, spread = m.psi_curve()
    assert abs(wrap_angle(math.radians(psi[0] - 180.0))) < 1e-9
    assert spread[0] == pytest.approx(1.0)
    # interpolation across the +-180 seam stays near 175, not near 0
    assert abs(m.psi_for(15.0)) > 170.0


def test_offset_is_interpolated_in_t_c():
    m = _map([_pt(10, 0, 50, 0, (0.02, 0.0, 0.0)), _pt(20, 0, 90, 0, (0.04, -0.02, 0.0))])
    assert np.allclose(m.offset_for(15.0), [0.03, -0.01, 0.0])


def test_save_load_round_trip_and_version_check(tmp_path):
    m = _map([_pt(10, 0, 50, 10.0), _pt(20, 90, 90, 20.0)])
    f = m.save(tmp_path / "map.json")
    back = TurnMap.load(f)
    assert back == m
    doc = json.loads(f.read_text())
    doc["version"] = 99
    f.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="version 99"):
        TurnMap.load(f)
    (tmp_path / "x.json").write_text("{}")
    with pytest.raises(ValueError, match="not a turn map"):
        TurnMap.load(tmp_path / "x.json")
    doc["version"] = m.to_dict()["version"]
    doc["numerics"]["anderson_depth"] = 0  # a map calibrated when the parameter existed
    f.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="names a removed parameter: parameter 'anderson_depth' was removed"):
        TurnMap.load(f)


def test_map_refuses_other_parameters_naming_them():
    m = _map([_pt(10, 0, 50, 10.0)])
    m.check_compatible(SwimmerParams())
    with pytest.raises(TurnMapMismatch, match=r"head_radius: map 0.012, here 0.008"):
        m.check_compatible(SwimmerParams(head_radius=0.008))
    with pytest.raises(TurnMapMismatch, match="omega_h_rpm"):
        m.check_compatible(SwimmerParams(), omega_h_rpm=60.0)


def test_phase_node_is_an_observed_node():
    from flagellum_env.observations import ObservationModel

    for n in (45, 60, 122):
        model = ObservationModel(2, 8, 0.13, n, True)
        assert phase_node_index(n) == model.shape_nodes[1]
