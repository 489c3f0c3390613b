"""Quaternion operations of section 2.1 / Paper B against scipy (explicitly reordered)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from analysis import quaternion as quat

RNG = np.random.default_rng(42)


def _random_q(n: int) -> np.ndarray:
    return quat.normalize(RNG.normal(size=(n, 4)))


def test_multiply_matches_scipy_composition() -> None:
    q, r = _random_q(50), _random_q(50)
    got = quat.multiply(q, r)
    want = quat.from_scipy(quat.to_scipy(q) * quat.to_scipy(r))
    # same rotation: equal up to the overall sign of q
    assert np.allclose(np.abs(np.sum(got * want, axis=1)), 1.0)


def test_table_2_1_rules() -> None:
    j, k, l_ = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    assert np.allclose(quat.multiply(j, j), [-1, 0, 0, 0])
    assert np.allclose(quat.multiply(j, k), l_)  # Hamilton: i·j = k
    assert np.allclose(quat.multiply(k, j), -l_)  # (2.12) non-commutative


def test_scalar_first_order_is_explicit_at_the_scipy_boundary() -> None:
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    assert np.allclose(quat.to_scipy(identity).as_matrix(), np.eye(3))
    r = Rotation.from_euler("x", 90, degrees=True)
    assert np.allclose(quat.from_scipy(r), [np.sqrt(0.5), np.sqrt(0.5), 0, 0])


def test_rotate_matches_scipy_apply() -> None:
    q = _random_q(20)
    v = RNG.normal(size=(20, 3))
    assert np.allclose(quat.rotate(q, v), quat.to_scipy(q).apply(v))


def test_inverse_and_axis_angle() -> None:
    q = quat.from_axis_angle([0, 0, 1], np.pi / 2)
    assert np.allclose(quat.rotate(q, [1, 0, 0]), [0, 1, 0])
    assert np.allclose(quat.multiply(q, quat.conjugate(q)), [1, 0, 0, 0])


def test_euler_round_trip_and_b6_matches_scipy_zyx() -> None:
    rpy = np.c_[RNG.uniform(-3, 3, 30), RNG.uniform(-1.4, 1.4, 30), RNG.uniform(-3, 3, 30)]
    q = quat.from_euler(rpy)
    assert np.allclose(quat.to_euler(q), rpy)
    scipy_rpy = quat.to_scipy(q).as_euler("ZYX")[:, ::-1]
    assert np.allclose(scipy_rpy, rpy)


def test_integration_of_constant_rate_converges_to_exact_rotation() -> None:
    w = np.array([0.3, -0.2, 0.5])
    q = np.array([1.0, 0, 0, 0])
    dt = 1e-4
    for _ in range(10_000):
        q = quat.integrate(q, w, dt)
    exact = quat.from_axis_angle(w, np.linalg.norm(w) * 1.0)
    assert np.degrees(quat.angle_between(q, exact)) < 1e-3


def test_derivative_is_body_rate_law_b5() -> None:
    q = _random_q(1)[0]
    w = np.array([0.1, 0.2, -0.3])
    dt = 1e-6
    numeric = (quat.from_scipy(quat.to_scipy(q) * Rotation.from_rotvec(w * dt)) - q) / dt
    assert np.allclose(quat.derivative(q, w), numeric, atol=1e-5)


@pytest.mark.parametrize("v2", [[0, 0, 1], [1, 0, 0], [0.3, -0.5, 0.8]])
def test_shortest_arc_rotates_v1_onto_v2(v2: list[float]) -> None:
    v1 = RNG.normal(size=(10, 3))
    q = quat.shortest_arc(v1, np.asarray(v2, float))
    unit = v1 / np.linalg.norm(v1, axis=1, keepdims=True)
    target = np.asarray(v2) / np.linalg.norm(v2)
    assert np.allclose(quat.rotate(q, unit), target, atol=1e-9)
    # shortest: the rotation angle equals the angle between the vectors
    assert np.allclose(quat.angle_between(q, [1, 0, 0, 0]), np.arccos(unit @ target))


def test_shortest_arc_opposite_vectors_is_a_valid_half_turn() -> None:
    for v in ([0, 0, 1], [1, 0, 0], [0.6, 0, 0.8]):
        q = quat.shortest_arc(v, -np.asarray(v, float))
        assert np.all(np.isfinite(q))
        assert np.allclose(quat.rotate(q, v), -np.asarray(v, float), atol=1e-12)


def test_controller_input_is_half_angles_for_small_angles() -> None:
    rpy = np.radians([3.0, -2.0, 0.0])
    u = quat.controller_input(quat.from_euler(rpy))
    assert np.allclose(u, rpy / 2, atol=1e-3)  # (B.26), second-order terms dropped
    assert not np.allclose(quat.controller_input(quat.from_euler(rpy * 10)), rpy * 5, atol=1e-3)


def test_yaw_part_splits_heading_and_tilt() -> None:
    q = quat.from_euler(np.radians([20.0, -10.0, 70.0]))
    h = quat.yaw_part(q)
    tilt = quat.multiply(quat.conjugate(h), q)
    assert abs(tilt[3]) < 1e-12  # the tilt has no z part
    assert np.allclose(h[1:3], 0.0)  # the heading is a pure rotation about navigation z
    up = np.array([0.0, 0.0, 1.0])  # gravity direction in the body depends on the tilt only
    assert np.allclose(quat.rotate(quat.conjugate(q), up), quat.rotate(quat.conjugate(tilt), up))


unit_q = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
    lambda v: float(np.linalg.norm(v)) > 0.1).map(lambda v: quat.normalize(np.asarray(v)))


@settings(max_examples=60, deadline=None)
@given(unit_q, unit_q, unit_q)
def test_product_is_associative_and_keeps_unit_length(q: np.ndarray, r: np.ndarray,
                                                      s: np.ndarray) -> None:
    left = quat.multiply(quat.multiply(q, r), s)  # (2.13)
    right = quat.multiply(q, quat.multiply(r, s))
    assert np.allclose(left, right, atol=1e-12)
    assert math.isclose(float(np.linalg.norm(left)), 1.0, rel_tol=1e-12)
    v = np.array([0.3, -1.2, 2.0])
    assert math.isclose(float(np.linalg.norm(quat.rotate(q, v))), float(np.linalg.norm(v)),
                        rel_tol=1e-12)


def test_nlerp_ends_midpoint_and_short_way() -> None:
    q = quat.from_axis_angle([0, 0, 1], 0.2)
    r = quat.from_axis_angle([0, 0, 1], 0.6)
    np.testing.assert_allclose(quat.nlerp(q, r, 0.0), q, atol=1e-12)
    np.testing.assert_allclose(quat.nlerp(q, r, 1.0), r, atol=1e-12)
    np.testing.assert_allclose(quat.nlerp(q, r, 0.5), quat.from_axis_angle([0, 0, 1], 0.4),
                               atol=1e-12)  # symmetric: the midpoint is exact
    mid = quat.nlerp(q, -r, 0.5)  # -r is the same rotation: still the short way
    assert quat.angle_between(mid, quat.from_axis_angle([0, 0, 1], 0.4)) < 1e-9
