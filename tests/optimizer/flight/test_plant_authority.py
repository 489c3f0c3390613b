"""The tilt authority an outside controller's rate loop sees (plant.tilt_authority)."""

from __future__ import annotations

import math

import pytest

from optimizer.flight.plant import ExternalPlant, tilt_authority
from optimizer.flight.vehicle import Vehicle


def _vehicle(omega_max: float) -> Vehicle:
    return Vehicle(label="v", n_rotors=4, layout="x", mass_kg=0.8,
                   inertia_kgm2=(0.008, 0.009, 0.016), arm_m=0.18, k_f=1.5e-5, k_m=2e-7,
                   omega_max_rad_s=omega_max)


@pytest.mark.parametrize("omega_max", [500.0, 1500.0])
def test_it_is_the_rolling_moment_of_a_differential_command(omega_max):
    """Flown on the plant: +-d on the QUADX mixer's roll column (motors 3, 4 left up)."""
    v = _vehicle(omega_max)
    u_h = v.hover_speed_rad_s / v.omega_max_rad_s
    d = 1e-4
    a = ExternalPlant(v, _actuator(), 1e-3)
    b = ExternalPlant(v, _actuator(), 1e-3)
    for plant, sign in ((a, 1.0), (b, -1.0)):
        plant.held = False
        plant.rotors.omega = [v.hover_speed_rad_s] * 4
        plant.step([u_h - sign * d, u_h - sign * d, u_h + sign * d, u_h + sign * d])
    p_dot = (a.state[10] - b.state[10]) / (2 * d * 1e-3)
    assert p_dot == pytest.approx(tilt_authority(v) * v.inertia_kgm2[0]
                                  / min(v.inertia_kgm2[:2]), rel=0.05)
    # 1 / u_hover = sqrt(thrust-to-weight): three times the speed, three times the gain
    assert tilt_authority(_vehicle(3 * omega_max)) == pytest.approx(3 * tilt_authority(v))
    assert math.isfinite(p_dot)


def _actuator():
    from optimizer.flight.actuators import ActuatorModel
    return ActuatorModel(tau_up_s=1e-6, tau_down_s=1e-6, frame_s=1e-3, levels=1_000_000)
