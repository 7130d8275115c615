"""physics/model/body_frame.py: the compiled transport of the head's body frame against its defining properties."""

from __future__ import annotations

import math

import numpy as np

from physics.model.body_frame import rotate_about, transport, transported_body_frame


def test_transport_is_the_minimal_rotation_and_rotate_about_is_rodrigues():
    rng = np.random.default_rng(4)
    a = rng.normal(size=3)
    a /= np.linalg.norm(a)
    b = rng.normal(size=3)
    b /= np.linalg.norm(b)
    np.testing.assert_allclose(transport(a, a, b), b, atol=1e-14)  # a goes to b
    axis = np.cross(a, b) / np.linalg.norm(np.cross(a, b))
    np.testing.assert_allclose(transport(axis, a, b), axis, atol=1e-14)  # the rotation axis stays
    np.testing.assert_allclose(rotate_about(np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), math.pi / 2),
                               [0.0, 1.0, 0.0], atol=1e-15)


def test_body_frame_stays_orthonormal_follows_the_axis_and_spins_by_dpsi():
    frame = np.eye(3)
    head, node = np.array([0.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])  # X_b = head - node = +x: no tilt
    spun = transported_body_frame(frame, head, node, 0.3, True)
    np.testing.assert_allclose(spun @ spun.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(spun[:, 0], [1.0, 0.0, 0.0], atol=1e-15)
    # the spin dpsi turns Y_b about t0 = -X_b by +dpsi, i.e. about X_b by -dpsi
    np.testing.assert_allclose(spun[:, 1], [0.0, math.cos(0.3), -math.sin(0.3)], atol=1e-14)
    tilted = transported_body_frame(frame, head, np.array([-1.0, -1.0, 0.0]), 0.3, False)
    np.testing.assert_allclose(tilted[:, 0], np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0), atol=1e-15)
    np.testing.assert_allclose(tilted @ tilted.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(tilted[:, 2], [0.0, 0.0, 1.0], atol=1e-14)  # tilt in the x-y plane keeps Z_b
