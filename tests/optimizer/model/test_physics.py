"""(E.1) and (E.2) in every form ``optimizer.model.physics`` holds them agree with each other."""

from __future__ import annotations

import numpy as np
import pytest

from optimizer.model import physics

CT, CP, RHO, D = 0.1215, 0.0518, 1.225, 0.2032  # APC 8x4.5MR, ISA, 8 in


@pytest.mark.parametrize("omega", [50.0, 600.0, 1500.0])
def test_omega_forms_are_the_rev_s_laws(omega):
    n = omega / physics.TWO_PI
    assert physics.thrust_per_omega2(CT, RHO, D) * omega**2 == pytest.approx(
        physics.thrust_n(CT, RHO, n, D), rel=1e-13)  # (E.1)
    power = physics.propeller_power_w(CP, RHO, n, D)  # (E.2)
    assert physics.torque_per_omega2(CP, RHO, D) * omega**2 == pytest.approx(
        physics.hover_torque_nm(power, n), rel=1e-13)  # (E.3) Q = W / omega


def test_coefficients_invert_the_laws():
    n = np.array([20.0, 80.0, 150.0])
    force = physics.thrust_n(CT, RHO, n, D)
    np.testing.assert_allclose(physics.thrust_coefficient(force, RHO, n, D), CT, rtol=1e-14)
    np.testing.assert_allclose(physics.hover_speed_rev_s(force, CT, RHO, D), n, rtol=1e-14)
    torque = physics.hover_torque_nm(physics.propeller_power_w(CP, RHO, n, D), n)
    np.testing.assert_allclose(physics.power_coefficient(torque, RHO, n, D), CP, rtol=1e-14)


def test_full_throttle_thrust_is_e1_at_the_steady_speed():
    kt, r, volt = 1.0 / (920 * physics.TWO_PI / 60), 0.22, 12.0
    w = physics.full_throttle_speed_rad_s(volt, kt, r, CP, RHO, D)
    # steady state of (E.4)-(E.7): V = K_e w + R Q / K_t with Q = k_m w^2
    assert kt * w + r * physics.torque_per_omega2(CP, RHO, D) * w**2 / kt == pytest.approx(volt)
    assert physics.full_throttle_thrust_n(volt, kt, r, CT, CP, RHO, D) == pytest.approx(
        physics.thrust_per_omega2(CT, RHO, D) * w**2, rel=1e-13)
