"""Reference/material frames: parallel transport, frame orthonormality, reference twist."""

from __future__ import annotations

import numpy as np
import pytest

from physics.model.frames import (
    material_frames,
    parallel_transport,
    reference_twist,
    space_parallel_frames,
    tangents,
    time_parallel_transport,
    update_frames,
)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _random_q(rng: np.random.Generator, n: int) -> np.ndarray:
    """A wiggly 3-D polyline with random twist angles, DOF layout (4n-1,)."""
    x = np.cumsum(rng.normal(size=(n, 3)) * 0.3 + np.array([1.0, 0.0, 0.0]), axis=0)
    q = np.zeros(4 * n - 1)
    for i in range(n):
        q[4 * i:4 * i + 3] = x[i]
    q[3::4] = rng.uniform(-np.pi, np.pi, n - 1)
    return q


def _rotate_about(u: np.ndarray, axis: np.ndarray, ang: float) -> np.ndarray:
    k = _unit(axis)
    return u * np.cos(ang) + np.cross(k, u) * np.sin(ang) + k * k.dot(u) * (1 - np.cos(ang))


def _assert_adapted_orthonormal(d1: np.ndarray, d2: np.ndarray, t: np.ndarray) -> None:
    np.testing.assert_allclose(np.linalg.norm(d1, axis=1), 1.0, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(d2, axis=1), 1.0, atol=1e-13)
    np.testing.assert_allclose(np.einsum("ij,ij->i", d1, t), 0.0, atol=1e-13)
    np.testing.assert_allclose(np.einsum("ij,ij->i", d2, t), 0.0, atol=1e-13)
    np.testing.assert_allclose(np.einsum("ij,ij->i", d1, d2), 0.0, atol=1e-13)
    np.testing.assert_allclose(np.cross(d1, d2), t, atol=1e-13)  # right-handed


@pytest.mark.parametrize("seed", range(5))
def test_parallel_transport_is_rotation_taking_t1_to_t2(seed: int) -> None:
    rng = np.random.default_rng(seed)
    t1, t2 = _unit(rng.normal(size=3)), _unit(rng.normal(size=3))
    u, v = rng.normal(size=3), rng.normal(size=3)
    Pu, Pv = parallel_transport(u, t1, t2), parallel_transport(v, t1, t2)
    np.testing.assert_allclose(parallel_transport(t1, t1, t2), t2, atol=1e-14)
    np.testing.assert_allclose(Pu.dot(Pv), u.dot(v), atol=1e-13)
    np.testing.assert_allclose(np.cross(Pu, Pv), parallel_transport(np.cross(u, v), t1, t2), atol=1e-13)
    b = np.cross(t1, t2)
    np.testing.assert_allclose(parallel_transport(b, t1, t2), b, atol=1e-14)  # axis is fixed


def test_parallel_transport_is_identity_for_equal_tangents() -> None:
    t = _unit(np.array([0.3, -1.0, 0.2]))
    u = np.array([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(parallel_transport(u, t, t), u)


def test_parallel_transport_of_antiparallel_tangents_maps_t1_to_t2() -> None:
    t = _unit(np.array([0.3, -1.0, 0.2]))
    np.testing.assert_allclose(parallel_transport(t, t, -t), -t, atol=1e-14)


def test_tangents_are_unit_edge_directions() -> None:
    q = _random_q(np.random.default_rng(1), 6)
    x = np.stack([q[4 * i:4 * i + 3] for i in range(6)])
    e = np.diff(x, axis=0)
    np.testing.assert_allclose(tangents(q), e / np.linalg.norm(e, axis=1)[:, None], atol=1e-15)


def test_space_parallel_frames_are_adapted_orthonormal_and_twist_free() -> None:
    q = _random_q(np.random.default_rng(2), 9)
    t = tangents(q)
    d1, d2 = space_parallel_frames(t)
    _assert_adapted_orthonormal(d1, d2, t)
    for i in range(1, t.shape[0]):
        np.testing.assert_allclose(d1[i], parallel_transport(d1[i - 1], t[i - 1], t[i]), atol=1e-13)
    np.testing.assert_allclose(reference_twist(d1, t, np.zeros(t.shape[0] - 1)), 0.0, atol=1e-13)


def test_space_parallel_frames_are_deterministic() -> None:
    t = tangents(_random_q(np.random.default_rng(3), 5))
    a1, a2 = space_parallel_frames(t)
    b1, b2 = space_parallel_frames(t.copy())
    np.testing.assert_array_equal(a1, b1)
    np.testing.assert_array_equal(a2, b2)


def test_time_parallel_transport_keeps_frames_of_unmoved_edges() -> None:
    t = tangents(_random_q(np.random.default_rng(4), 7))
    d1, d2 = space_parallel_frames(t)
    e1, e2 = time_parallel_transport(d1, t, t)
    np.testing.assert_allclose(e1, d1, atol=1e-14)
    np.testing.assert_allclose(e2, d2, atol=1e-14)


def test_time_parallel_transport_gives_adapted_orthonormal_frames() -> None:
    rng = np.random.default_rng(5)
    q = _random_q(rng, 7)
    t_old = tangents(q)
    d1_old, _ = space_parallel_frames(t_old)
    t_new = tangents(q + 0.2 * rng.normal(size=q.shape))
    d1, d2 = time_parallel_transport(d1_old, t_old, t_new)
    _assert_adapted_orthonormal(d1, d2, t_new)
    for i in range(t_new.shape[0]):  # no rotation about the tangent: d1 . (t_old x t_new) kept
        b = np.cross(t_old[i], t_new[i])
        np.testing.assert_allclose(d1[i].dot(b), d1_old[i].dot(b), atol=1e-13)


def test_reference_twist_is_angle_of_director_about_tangent() -> None:
    t = tangents(_random_q(np.random.default_rng(6), 4))
    d1, _ = space_parallel_frames(t)
    d1[2] = _rotate_about(d1[2], t[2], 0.7)
    ref = reference_twist(d1, t, np.zeros(2))
    np.testing.assert_allclose(ref, [0.0, 0.7], atol=1e-13)


def test_reference_twist_is_continuous_past_pi() -> None:
    t = tangents(_random_q(np.random.default_rng(7), 3))
    d1_0, _ = space_parallel_frames(t)
    ref = np.zeros(1)
    angles = np.linspace(0.0, 3.5 * np.pi, 60)
    history = []
    for a in angles:
        d1 = d1_0.copy()
        d1[1] = _rotate_about(d1_0[1], t[1], a)
        ref = reference_twist(d1, t, ref)
        history.append(ref[0])
    np.testing.assert_allclose(history, angles, atol=1e-12)
    # and unwinding goes back through the same branch
    for a in angles[::-1]:
        d1 = d1_0.copy()
        d1[1] = _rotate_about(d1_0[1], t[1], a)
        ref = reference_twist(d1, t, ref)
    np.testing.assert_allclose(ref, 0.0, atol=1e-12)


def test_material_frames_are_orthonormal_and_rotated_by_theta() -> None:
    rng = np.random.default_rng(8)
    t = tangents(_random_q(rng, 6))
    d1, d2 = space_parallel_frames(t)
    theta = rng.uniform(-4.0, 4.0, t.shape[0])
    m1, m2 = material_frames(d1, d2, theta)
    _assert_adapted_orthonormal(m1, m2, t)
    np.testing.assert_allclose(np.einsum("ij,ij->i", m1, d1), np.cos(theta), atol=1e-13)
    np.testing.assert_allclose(np.einsum("ij,ij->i", m1, d2), np.sin(theta), atol=1e-13)


@pytest.mark.parametrize("case", ["generic", "edge_reversed", "hairpin"])
def test_update_frames_matches_the_frame_functions_in_sequence(case: str) -> None:
    """The fused per-step kernel behind ``rod_frames`` gives what ``tangents`` ->
    ``time_parallel_transport`` -> ``reference_twist`` -> ``material_frames`` give,
    including the anti-parallel fallbacks (an edge reversed between steps; a hairpin)."""
    rng = np.random.default_rng(9)
    q_old = _random_q(rng, 9)
    t_old = tangents(q_old)
    d1_old, _ = space_parallel_frames(t_old)
    ref_old = rng.uniform(-1.0, 1.0, 7)
    q = q_old + 0.05 * rng.normal(size=q_old.shape)
    if case == "edge_reversed":  # edge 3 flips direction: t_old[3] -> -t_old[3]
        e = q_old[16:19] - q_old[12:15]
        q[16:19] = q[12:15] - e
        q[20:23] = q[16:19] + (q_old[20:23] - q_old[16:19])
    elif case == "hairpin":  # edge 5 (nodes 5 -> 6) folds back onto edge 4 (nodes 4 -> 5)
        q[24:27] = q[20:23] - 0.7 * (q[20:23] - q[16:19])
    t = tangents(q)
    d1, d2 = time_parallel_transport(d1_old, t_old, t)
    ref = reference_twist(d1, t, ref_old)
    m1, m2 = material_frames(d1, d2, np.ascontiguousarray(q[3::4]))
    got = update_frames(q, d1_old, t_old, ref_old)
    for a, b in zip(got, (t, d1, d2, ref, m1, m2)):
        np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-14)
    if case == "edge_reversed":
        assert 1.0 + t_old[3] @ t[3] <= 1e-12
    if case == "hairpin":
        assert 1.0 + t[4] @ t[5] <= 1e-12
