"""Flight model (optimizer.flight): equilibrium, mixer inverse, conservation, actuators."""

from __future__ import annotations

import math

import numpy as np
import pytest

from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.actuators import ActuatorModel, RotorBank
from optimizer.flight.mixer import Mixer, allocation_matrix, mixing_matrix
from optimizer.flight.vehicle import Vehicle, derivative, hover_state, step, vehicle_from_grid
from optimizer.model.design_model import evaluate_grid
from tests.conftest import CATALOGS

CATALOG = CATALOGS / "thesis-e"


@pytest.fixture(scope="module")
def catalog():
    return load_catalog(CATALOG)


def _vehicle(catalog, n: int, layout: str, index=(3, 0, 1)) -> Vehicle:
    return vehicle_from_grid(catalog, evaluate_grid(catalog, n), index, layout)


def _loads(v: Vehicle, omega: np.ndarray) -> tuple[float, float, float, float]:
    x, y, spin = v.rotor_positions()
    f = v.k_f * omega**2
    return (float(f.sum()), float(y @ f), float(-x @ f), float(-(spin * v.k_m * omega**2).sum()))


@pytest.mark.parametrize("n", [4, 6, 8])
@pytest.mark.parametrize("layout", ["x", "plus"])
def test_hover_equilibrium_is_exact(catalog, n: int, layout: str) -> None:
    v = _vehicle(catalog, n, layout)
    omega = np.full(n, v.hover_speed_rad_s)
    thrust, mx, my, mz = _loads(v, omega)
    assert thrust == pytest.approx(v.mass_kg * v.gravity_m_s2, rel=1e-13)
    assert max(abs(mx), abs(my), abs(mz)) < 1e-12 * thrust * v.arm_m
    d = derivative(hover_state(), thrust, mx, my, mz, 0.0, 0.0, 0.0, 1.0 / v.mass_kg,
                   *v.inertia_kgm2, v.gravity_m_s2, 0.0)
    assert max(abs(a) for a in d) < 1e-12


def test_hover_speed_is_evaluates(catalog) -> None:
    grid = evaluate_grid(catalog, 4)
    for idx in np.ndindex(grid.shape):
        v = vehicle_from_grid(catalog, grid, idx)
        rpm = v.hover_speed_rad_s * 60 / (2 * math.pi)
        assert rpm == pytest.approx(grid.metrics["hover_rpm"][idx], rel=1e-9)


@pytest.mark.parametrize("n", [4, 6, 8])
@pytest.mark.parametrize("layout", ["x", "plus"])
def test_mixer_times_its_inverse_is_identity(catalog, n: int, layout: str) -> None:
    v = _vehicle(catalog, n, layout)
    a = allocation_matrix(*v.rotor_positions(), v.torque_ratio_m)
    assert a @ mixing_matrix(a) == pytest.approx(np.eye(4), abs=1e-12)
    if n == 4:  # (B.27): a true inverse both ways
        assert mixing_matrix(a) @ a == pytest.approx(np.eye(4), abs=1e-12)


def test_b11_signs_match_the_body_equations(catalog) -> None:
    """The allocation matrix gives the same moments as the rotor loads the model applies."""
    v = _vehicle(catalog, 6, "x")
    omega = v.hover_speed_rad_s * np.array([1.0, 1.1, 0.9, 1.05, 0.95, 1.02])
    a = allocation_matrix(*v.rotor_positions(), v.torque_ratio_m)
    thrust, mx, my, mz = _loads(v, omega)
    assert a @ (v.k_f * omega**2) == pytest.approx([mx, my, mz, thrust], rel=1e-12)


def test_saturation_rule_keeps_attitude_before_thrust_and_yaw(catalog) -> None:
    v = _vehicle(catalog, 4, "x")
    a = allocation_matrix(*v.rotor_positions(), v.torque_ratio_m)
    hover = v.mass_kg * v.gravity_m_s2
    f_max = hover / 4 * 1.3
    mixer = Mixer(a, 0.0, f_max)
    # inside the limits: the demand is met exactly
    f, sat = mixer.mix(0.01, -0.02, 0.001, hover)
    assert not sat
    assert a @ np.array(f) == pytest.approx([0.01, -0.02, 0.001, hover], rel=1e-12)
    # a roll demand that needs more than the top margin: roll kept, thrust gives way,
    # the yaw demand is dropped first
    mx = 0.8 * f_max * v.arm_m
    f, sat = mixer.mix(mx, 0.0, 0.05, hover)
    got = a @ np.array(f)
    assert sat
    assert max(f) <= f_max * (1 + 1e-12) and min(f) >= -1e-12
    assert got[0] == pytest.approx(mx, rel=1e-12)
    assert got[3] < hover
    assert abs(got[2]) < 0.05
    # roll and pitch beyond the whole range: scaled together, direction kept
    f, sat = mixer.mix(10.0, 5.0, 0.0, hover)
    got = a @ np.array(f)
    assert sat and got[0] / got[1] == pytest.approx(2.0, rel=1e-9)


def test_without_control_momentum_and_energy_are_conserved() -> None:
    """Free tumbling under gravity, no rotor thrust: energy, angular momentum (navigation
    frame) and horizontal momentum stay constant to integration tolerance over 10 s."""
    inertia = (0.02, 0.03, 0.045)
    m, g, dt = 1.3, 9.81, 1e-3
    s = hover_state(5.0)
    s[3:6] = [0.4, -0.2, 1.0]
    s[10:13] = [1.5, -0.7, 2.2]

    def invariants(s):
        w = np.array(s[10:13])
        qw, qx, qy, qz = s[6:10]
        r = np.array([
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
            [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
            [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)]])
        energy = (0.5 * w @ (np.array(inertia) * w) + 0.5 * m * np.dot(s[3:6], s[3:6])
                  + m * g * s[2])
        return energy, r @ (np.array(inertia) * w), np.array(s[3:5])

    e0, l0, p0 = invariants(s)
    for _ in range(10_000):
        s = step(s, dt, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1 / m, *inertia, g, 0.0)
    e1, l1, p1 = invariants(s)
    assert e1 == pytest.approx(e0, rel=1e-6)
    assert np.linalg.norm(l1 - l0) < 1e-5 * np.linalg.norm(l0)
    assert p1 == pytest.approx(p0, abs=1e-12)
    assert abs(s[6] ** 2 + sum(x * x for x in s[7:10]) - 1) < 1e-12


def test_actuator_rises_and_falls_with_their_own_time_constants() -> None:
    dt = 1e-4
    model = ActuatorModel(0.030, 0.060, latency_s=0.005, frame_s=0.0, levels=100_000,
                          idle_fraction=0.0)
    for target, tau in ((800.0, 0.030), (200.0, 0.060)):
        bank = RotorBank(model, 1, 1000.0, dt, 500.0)
        t63 = None
        for k in range(20_000):
            w = bank.step([target])[0]
            if t63 is None and abs(w - 500.0) >= (1 - math.exp(-1)) * abs(target - 500.0):
                t63 = (k + 1) * dt
        assert t63 == pytest.approx(0.005 + tau, abs=3 * dt)


def test_actuator_quantises_holds_frames_and_limits() -> None:
    dt = 1e-3
    model = ActuatorModel(0.001, 0.001, frame_s=0.004, levels=11, idle_fraction=0.1)
    bank = RotorBank(model, 2, 1000.0, dt, 500.0)
    bank.step([512.0, 5000.0])  # quantised to the nearest of 100, 190, ... 1000 rad/s; capped
    assert bank.held == pytest.approx([550.0, 1000.0])  # nearest level
    bank.step([100.0, 0.0])  # no new frame for 4 ticks
    assert bank.held == pytest.approx([550.0, 1000.0])  # nearest level
    for _ in range(3):
        bank.step([100.0, 0.0])
    assert bank.held == pytest.approx([100.0, 100.0])  # idle floor


def test_linear_drag_slows_a_free_body_as_its_law_says() -> None:
    """m v_dot = -c_d v (2.40 with drag, no thrust, no gravity): v(t) = v0 exp(-c_d t / m)."""
    inertia, m, cd, dt = (0.02, 0.02, 0.04), 1.5, 0.6, 1e-3
    s = hover_state()
    s[3:6] = [2.0, -1.0, 0.5]
    for _ in range(1000):
        s = step(s, dt, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1 / m, *inertia, 0.0, cd)
    decay = math.exp(-cd * 1.0 / m)
    assert s[3:6] == pytest.approx([2.0 * decay, -1.0 * decay, 0.5 * decay], rel=1e-3)
    # position: the integral of the decaying speed, v0 m / c_d (1 - decay)
    assert s[0] == pytest.approx(2.0 * m / cd * (1 - decay), rel=1e-3)


def test_hover_shortfall_names_the_speeds(catalog) -> None:
    v = _vehicle(catalog, 4, "x")
    assert v.hover_shortfall() == ""
    from dataclasses import replace

    weak = replace(v, omega_max_rad_s=0.9 * v.hover_speed_rad_s)
    note = weak.hover_shortfall()
    rpm = 60 / (2 * math.pi)
    assert note == (f"cannot hover: needs {v.hover_speed_rad_s * rpm:.0f} rpm, full throttle "
                    f"{0.9 * v.hover_speed_rad_s * rpm:.0f} rpm")
