"""Flight time from measured current (Paper E section 4, Table E.14).

"The actual flight times can be estimated by dividing the battery capacity (Ah) by the
measured current (A) when the step-responses have reached steady-state and by the number
of actuators." The current per actuator at the hover thrust comes from the measured
static curves (thrust and current against speed). A bench supply at another voltage than
the flight battery is rescaled at equal electrical power, as ``optimizer.model.measured`` does.
"""

from __future__ import annotations

import math

import numpy as np

from analysis.errors import LogError
from analysis.static_curves import StaticCurves

__all__ = ["flight_time_min", "hover_current_a"]


def hover_current_a(static: StaticCurves, thrust_n: float) -> float:
    """Supply current of one actuator at a steady thrust, from the static curves."""
    if static.current_poly is None or static.thrust_poly is None:
        raise LogError("hover current needs thrust and current against speed (a sweep)")
    w = float(static.omega_for_thrust(thrust_n))
    if not (static.omega[0] <= w <= static.omega[-1]):
        raise LogError(f"hover thrust {thrust_n:.3f} N is outside the measured thrust range "
                       f"{float(np.nanmin(static.thrust)):.3f}-"
                       f"{float(np.nanmax(static.thrust)):.3f} N")
    return float(static.current_at(w))


def flight_time_min(capacity_mah: float, current_per_actuator_a: float, n_actuators: int,
                    bench_voltage_v: float | None = None,
                    battery_voltage_v: float | None = None) -> float:
    """Capacity / (actuators x current per actuator), in minutes (Table E.14, T_e)."""
    if not (capacity_mah > 0 and current_per_actuator_a > 0 and n_actuators >= 1):
        raise ValueError("capacity, current and number of actuators must be positive")
    current = current_per_actuator_a
    if bench_voltage_v is not None and battery_voltage_v is not None:
        current *= bench_voltage_v / battery_voltage_v  # equal electrical power
    hours = capacity_mah * 1e-3 / (n_actuators * current)
    return hours * 60.0 if math.isfinite(hours) else math.nan
