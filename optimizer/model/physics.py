"""Hover physics of Papers D and E as numpy functions that broadcast.

Every function takes SI arrays of any broadcastable shape, so ``optimizer.model.design_model`` can
evaluate the whole (propeller, motor, battery) product at once. Equation numbers refer to
the thesis: Øyvind Magnussen, "Multirotor Design Optimization: The Mechatronic Approach",
PhD thesis, University of Agder, 2015.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def arm_length_m(diameter_m, n_actuators: int, clearance_m: float, arm_length: str):
    """Distance from the centre to a motor axis.

    (D.4): neighbouring motors sit one propeller diameter (+ tip gap Delta) apart, so the
    motor circle has radius (D + Delta) / (2 sin(pi/N)); L = D / sin(pi/N) of (D.4) is its
    diameter. ``arm_length="diagonal"`` uses L itself as the arm length (Paper D reading).
    """
    chord = np.asarray(diameter_m, float) + clearance_m
    diagonal = chord / np.sin(np.pi / n_actuators)  # (D.4)
    return diagonal if arm_length == "diagonal" else diagonal / 2.0


def frame_mass_kg(arm_m, n_actuators: int, linear_density_kg_m: float):
    """(E.26) x8 = m_F N_a L_f: N arms of one tube each (Paper D section 2.6)."""
    return linear_density_kg_m * n_actuators * np.asarray(arm_m, float)


def hover_speed_rev_s(thrust_n, ct, rho: float, diameter_m):
    """(E.1) solved for n: n = sqrt(F / (C_t rho D^4)) (E.20, E.33)."""
    return np.sqrt(thrust_n / (ct * rho * diameter_m**4))


def propeller_power_w(cp, rho: float, n_rev_s, diameter_m):
    """(E.2) W = C_p rho n^3 D^5 (E.60-E.63)."""
    return cp * rho * n_rev_s**3 * diameter_m**5


def thrust_n(ct, rho: float, n_rev_s, diameter_m):
    """(E.1) F = C_t rho n^2 D^4."""
    return ct * rho * n_rev_s**2 * diameter_m**4


def thrust_per_omega2(ct, rho: float, diameter_m):
    """(E.1) with n = omega / 2 pi: F = k_f omega^2, k_f = C_t rho D^4 / (2 pi)^2."""
    return ct * rho * diameter_m**4 / TWO_PI**2


def torque_per_omega2(cp, rho: float, diameter_m):
    """(E.2)-(E.3) with n = omega / 2 pi: Q = W / omega = k_m omega^2,
    k_m = C_p rho D^5 / (2 pi)^3."""
    return rho * cp * diameter_m**5 / TWO_PI**3


def thrust_coefficient(force_n, rho: float, n_rev_s, diameter_m):
    """(E.1) solved for C_t: C_t = F / (rho n^2 D^4) (APC's convention, n in rev/s)."""
    return force_n / (rho * n_rev_s**2 * diameter_m**4)


def power_coefficient(torque_nm, rho: float, n_rev_s, diameter_m):
    """(E.2) with W = 2 pi n Q (E.3) solved for C_p: C_p = 2 pi Q / (rho n^2 D^5)."""
    return TWO_PI * torque_nm / (rho * n_rev_s**2 * diameter_m**5)


def propeller_damping(cp, rho: float, n_rev_s, diameter_m):
    """(E.8), (E.34): D_omega = T / omega = W / omega^2 with omega = 2 pi n (E.3)."""
    return propeller_power_w(cp, rho, n_rev_s, diameter_m) / (TWO_PI * n_rev_s) ** 2


def torque_constant(kv_rad_s_per_v):
    """K_t = K_e = 1 / K_v with K_v in rad/s/V.

    (2.37) prints k_e = (2 pi / 60) / k_v with k_v in rpm/V; the dimensionally consistent
    form, used here, is k_e = 60 / (2 pi k_v[rpm/V]) = 1 / k_v[rad/s/V].
    """
    return 1.0 / np.asarray(kv_rad_s_per_v, float)


def hover_torque_nm(power_w, n_rev_s):
    """(E.3) shaft torque Q = W / omega, omega = 2 pi n."""
    return power_w / (TWO_PI * np.asarray(n_rev_s, float))


def winding_current_a(torque_nm, kt, no_load_current_a: np.ndarray | float = 0.0):
    """Motor winding (torque) current I_w = Q / K_t + I_0.

    (E.5)-(E.7): the motor torque is K_t I; the no-load current I_0 (friction and iron
    losses, datasheet "Io") flows on top of the current that makes the shaft torque.
    Unlike the battery-side x18 / N of (E.67), I_w grows as K_t falls: a high-K_v motor
    turning a large propeller slowly draws far more winding current than it takes from
    the battery.
    """
    return torque_nm / kt + no_load_current_a


def time_constant_s(resistance_ohm, inertia_kgm2, kt, damping):
    """(E.8), (E.35): t_r = J R_a / (K_t^2 + D_omega R_a)."""
    return resistance_ohm * inertia_kgm2 / (kt**2 + damping * resistance_ohm)


def hollow_rotor_inertia_kgm2(diameter_m, length_m, wall_m, density_kg_m3):
    """Motor rotor (bell) as a thick-walled tube: outer diameter D_m, length S_l, wall S_w.

    J = 1/2 m (r_o^2 + r_i^2), m = rho pi (r_o^2 - r_i^2) S_l (Table E.5 geometry).
    """
    r_o = np.asarray(diameter_m, float) / 2.0
    r_i = r_o - wall_m
    mass = density_kg_m3 * np.pi * (r_o**2 - r_i**2) * length_m
    return 0.5 * mass * (r_o**2 + r_i**2)


def arm_axis_sums(n_actuators: int) -> tuple[float, float]:
    """Sum over the N arms of sin^2 and cos^2 of the arm angle (roll, pitch).

    Arms at (2k+1) pi / N (roll axis between two arms). The squared distances from the
    roll and pitch axes are R^2 sin^2 and R^2 cos^2 (E.42-E.45); both sums equal N/2 for
    a regular N >= 3 layout, so roll and pitch inertias are equal.
    """
    angles = (2 * np.arange(n_actuators) + 1) * np.pi / n_actuators
    return float(np.sum(np.sin(angles) ** 2)), float(np.sum(np.cos(angles) ** 2))


def body_inertia_kgm2(actuator_mass_kg, frame_arm_mass_kg, arm_m, axis_sum: float):
    """Roll or pitch inertia: point-mass actuators plus rods about their end.

    (D.9) I_m = m_a L_ai^2 per actuator and (D.10) I_f = 1/3 m_f L^2 per arm, summed with
    the squared distance to the axis (E.46-E.59). Battery and payload sit at the centre
    and add nothing (Paper D assumption 3).
    """
    r2 = np.asarray(arm_m, float) ** 2
    return axis_sum * r2 * (actuator_mass_kg + frame_arm_mass_kg / 3.0)


def full_throttle_speed_rad_s(voltage_v, kt, resistance_ohm, cp, rho: float, diameter_m):
    """Steady state of (E.4)-(E.7) at full supply voltage.

    With T = c omega^2, c = rho C_p D^5 / (2 pi)^3 from (E.2)-(E.3):
    V = K_e omega + R_a c omega^2 / K_t, solved for omega > 0.
    """
    c = torque_per_omega2(cp, rho, diameter_m)
    a = resistance_ohm * c / kt
    # Root of a w^2 + K_e w - V = 0 in the form that stays finite as a -> 0.
    return 2.0 * voltage_v / (kt + np.sqrt(kt**2 + 4.0 * a * voltage_v))


def full_throttle_thrust_n(voltage_v, kt, resistance_ohm, ct, cp, rho: float, diameter_m):
    """(E.1) at the full-throttle speed of :func:`full_throttle_speed_rad_s`: the most
    thrust one actuator gives on ``voltage_v``."""
    omega = full_throttle_speed_rad_s(voltage_v, kt, resistance_ohm, cp, rho, diameter_m)
    return thrust_n(ct, rho, omega / TWO_PI, diameter_m)
