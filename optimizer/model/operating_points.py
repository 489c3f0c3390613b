"""Operating points of a drive (battery -> ESC -> motor -> propeller), as eCalc reports them.

The thesis evaluates hover only (E.19-E.35). A designer also asks what the drive does at
full throttle and in between. Definitions (those of eCalc's xcopterCalc "partial load"
and "motor @ maximum" sheets; docs/sizing.md cites them):

* throttle t is the ESC's duty cycle: the motor sees ``V_m = t V_b`` (linear throttle);
* motor steady state (E.4)-(E.7) with the no-load current: ``V_m = K_e omega + R I``,
  ``I = Q / K_t + I_0``, propeller torque ``Q = W / omega`` (E.3), ``W = C_p rho n^3 D^5``
  (E.2); thrust (E.1);
* battery current per drive ``I_b = t I`` (a lossless ESC: ``V_b I_b = V_m I``),
  electric power ``P = V_m I``; with the thesis' current model (``Drive.current_model =
  "thesis"``, (E.67)) the battery delivers the shaft power instead: ``I_b = W / V_b``,
  ``P = W`` (a loss-free motor, the reading of Papers D and E), so a sheet and the design
  model of one run share one current definition;
* efficiency in g/W: thrust in grams-force per watt of electric power;
* hover throttle: ``V_m`` needed at the hover speed over ``V_b``.

Every function broadcasts over the design grid. Propeller coefficients are constants or,
with measured data (``optimizer.model.propdata``), functions of the speed: ``coefficients``
then maps rpm to (C_t, C_p) and the speed is found by fixed-point iteration.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from optimizer.model import physics

#: Throttle rows of the partial-load table, percent (eCalc: 10 % steps).
THROTTLE_PCT = np.arange(10, 101, 10)

#: Fixed-point iterations when C_t, C_p depend on the speed (converges in < 10 for
#: the APC data: the coefficients change by a few percent per 1000 rpm).
ITERATIONS = 30

Coefficients = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Drive:
    """One drive (or a grid of them) in SI units; arrays broadcast."""

    ct: np.ndarray
    cp: np.ndarray
    diameter_m: np.ndarray
    kt: np.ndarray
    resistance_ohm: np.ndarray
    no_load_current_a: np.ndarray
    rho: float
    #: rpm -> (C_t, C_p) from measured data; None: the constants ct, cp
    coefficients: Coefficients | None = None
    #: what the battery delivers: "drive" (V_m I, winding loss included) or "thesis" (the
    #: shaft power, (E.67)); ``optimizer.catalogs.model_constants.ModelConstants.current_model``
    current_model: str = "drive"

    def coeffs(self, rpm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(C_t, C_p) at ``rpm`` (the constants without measured data)."""
        if self.coefficients is None:
            return np.asarray(self.ct, float), np.asarray(self.cp, float)
        return self.coefficients(np.asarray(rpm, float))


@dataclass(frozen=True)
class OperatingPoint:
    """Per drive: thrust, speed, currents, powers at one throttle or thrust."""

    throttle: np.ndarray
    thrust_n: np.ndarray
    rpm: np.ndarray
    motor_current_a: np.ndarray
    battery_current_a: np.ndarray
    power_w: np.ndarray
    shaft_power_w: np.ndarray
    motor_voltage_v: np.ndarray

    @property
    def efficiency_g_per_w(self) -> np.ndarray:
        """Thrust in grams-force per watt of electric power (eCalc's g/W)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.power_w > 0, self.thrust_n / G0 * 1e3 / self.power_w, 0.0)


#: standard gravity for grams-force (eCalc reports thrust in g)
G0 = 9.80665


def _speed_rad_s(drive: Drive, v_motor: np.ndarray, cp: np.ndarray) -> np.ndarray:
    """Steady speed for motor voltage ``v_motor``: (E.4)-(E.7) with I_0.

    V - R I_0 = K_e omega + R c omega^2 / K_t is ``physics.full_throttle_speed_rad_s``
    at the voltage left after the no-load current's drop.
    """
    v_eff = np.maximum(v_motor - drive.resistance_ohm * drive.no_load_current_a, 0.0)
    return physics.full_throttle_speed_rad_s(
        v_eff, drive.kt, drive.resistance_ohm, cp, drive.rho, drive.diameter_m
    )


def _point(drive: Drive, omega: np.ndarray, ct, cp, v_batt) -> OperatingPoint:
    n = omega / physics.TWO_PI
    thrust = physics.thrust_n(ct, drive.rho, n, drive.diameter_m)  # (E.1)
    shaft = physics.propeller_power_w(cp, drive.rho, n, drive.diameter_m)  # (E.2)
    with np.errstate(divide="ignore", invalid="ignore"):
        torque = np.where(n > 0, physics.hover_torque_nm(shaft, np.where(n > 0, n, 1.0)), 0.0)
    current = np.where(
        omega > 0, physics.winding_current_a(torque, drive.kt, drive.no_load_current_a), 0.0
    )
    v_motor = np.where(omega > 0, omega * drive.kt + drive.resistance_ohm * current, 0.0)
    throttle = v_motor / v_batt
    if drive.current_model == "thesis":
        power = shaft  # (E.67): x18 = N x17 / B_V, the battery delivers the shaft power
    elif drive.current_model == "drive":
        power = v_motor * current  # lossless ESC: V_b I_b = V_m I
    else:
        raise ValueError(f"current_model: expected 'thesis' or 'drive', got "
                         f"{drive.current_model!r}")
    return OperatingPoint(
        throttle=throttle,
        thrust_n=thrust,
        rpm=n * 60.0,
        motor_current_a=current,
        battery_current_a=power / v_batt,
        power_w=power,
        shaft_power_w=shaft,
        motor_voltage_v=v_motor,
    )


def at_throttle(drive: Drive, throttle, v_batt) -> OperatingPoint:
    """The drive at duty cycle ``throttle`` (0-1) on a battery of ``v_batt`` volts."""
    v_motor = np.asarray(throttle, float) * np.asarray(v_batt, float)
    ct, cp = np.asarray(drive.ct, float), np.asarray(drive.cp, float)
    omega = _speed_rad_s(drive, v_motor, cp)
    if drive.coefficients is not None:
        for _ in range(ITERATIONS):
            ct, cp = drive.coeffs(omega * 60.0 / physics.TWO_PI)
            omega = _speed_rad_s(drive, v_motor, cp)
        ct, cp = drive.coeffs(omega * 60.0 / physics.TWO_PI)
    return _point(drive, omega, ct, cp, np.asarray(v_batt, float))


def speed_for_thrust(
    thrust_n, ct, cp, rho: float, diameter_m, coefficients: Coefficients | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n [rev/s], C_t, C_p) delivering ``thrust_n``: (E.1) solved for n (E.20).

    With ``coefficients`` (rpm -> C_t, C_p) by fixed-point iteration from the constants.
    """
    n = physics.hover_speed_rev_s(thrust_n, ct, rho, diameter_m)
    if coefficients is None:
        return n, np.asarray(ct, float), np.asarray(cp, float)
    for _ in range(ITERATIONS):
        ct, cp = coefficients(n * 60.0)
        n = physics.hover_speed_rev_s(thrust_n, ct, rho, diameter_m)
    ct, cp = coefficients(n * 60.0)
    return n, ct, cp


def at_thrust(drive: Drive, thrust_n, v_batt) -> OperatingPoint:
    """The drive delivering ``thrust_n`` (hover): speed from (E.1) solved for n (E.20)."""
    n, ct, cp = speed_for_thrust(thrust_n, drive.ct, drive.cp, drive.rho, drive.diameter_m,
                                 drive.coefficients)
    return _point(drive, n * physics.TWO_PI, ct, cp, np.asarray(v_batt, float))


def partial_load(drive: Drive, v_batt, throttle_pct=THROTTLE_PCT) -> list[dict[str, float]]:
    """eCalc's partial-load rows for one drive: throttle 10-100 % in 10 % steps."""
    pct = np.asarray(throttle_pct, float)
    op = at_throttle(drive, pct / 100.0, v_batt)
    eff = op.efficiency_g_per_w
    return [
        {
            "throttle_pct": float(p),
            "thrust_n": float(op.thrust_n[i]),
            "current_a": float(op.battery_current_a[i]),
            "motor_current_a": float(op.motor_current_a[i]),
            "power_w": float(op.power_w[i]),
            "rpm": float(op.rpm[i]),
            "efficiency_g_per_w": float(eff[i]),
        }
        for i, p in enumerate(pct)
    ]
