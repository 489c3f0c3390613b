"""Measured actuator constants that replace modelled ones in the design grid.

Paper E notes after (E.39) that measured time constants, where available for a
combination, should replace the datasheet estimates. A bench run of one propeller on one
motor (optionally with a given ESC mode) yields a ``MeasuredActuator``: its 63 % time
constant and its current at a set of thrusts.
``optimizer.model.design_model.evaluate_grid`` uses them for every design built from that
pair and marks those cells as measured.

Extrapolation rule (no measured number is ever extended beyond what was measured):
- the current is interpolated linearly between measured (thrust, current) points only;
  a hover thrust outside ``[hover_thrust_n[0], hover_thrust_n[-1]]`` keeps the modelled
  current (E.67) and the cell is *not* marked measured (``design_sources`` says why);
- a hover thrust above the measured top thrust ``max_thrust_n`` makes the design
  infeasible through the grid check "measured max thrust" (the rotor was seen not to
  reach it), for batteries whose voltage is at most ``TOP_THRUST_VOLTAGE_MARGIN`` above
  the bench supply voltage (a higher voltage could spin the rotor faster: not checked);
- the time constant is one measured number per actuator, used for every battery.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from optimizer.errors import RequestError

#: The measured top thrust bounds batteries up to this fraction above the bench voltage.
TOP_THRUST_VOLTAGE_MARGIN = 0.05
#: The flight constants that may carry an uncertainty, and the field holding it.
STD_OF = {"tau_up_s": "tau_up_std_s", "tau_down_s": "tau_down_std_s",
          "latency_s": "latency_std_s", "k_f_n_s2": "k_f_std_n_s2",
          "k_m_nm_s2": "k_m_std_nm_s2"}


@dataclass(frozen=True)
class MeasuredActuator:
    """Bench-measured constants of one (propeller, motor[, ESC mode]) actuator.

    ``time_constant_s``: measured time constant (replaces eq. (E.35)).
    ``hover_thrust_n`` / ``hover_current_a``: current drawn by one actuator at each thrust
    (ascending thrusts); interpolated linearly at the design's hover thrust, it replaces
    the per-actuator current N_a W / (N_a B_V) of eq. (E.67). Hover thrusts outside the
    measured range keep the modelled current (no extrapolation).
    ``supply_voltage_v``: bench supply voltage; if given, the current is rescaled to the
    in-flight battery voltage at equal electrical power.
    ``max_thrust_n``: the highest thrust the sweep reached (default: the last current
    point); the grid's "measured max thrust" check compares the hover thrust with it.
    ``time_constant_source`` / ``current_source``: the run each number came from (shown
    in the optimizer's per-design ``sources``); ``source`` describes both.
    """

    propeller_id: str
    motor_id: str
    esc_mode: str | None = None
    time_constant_s: float | None = None
    hover_thrust_n: Sequence[float] = ()
    hover_current_a: Sequence[float] = ()
    supply_voltage_v: float | None = None
    source: str = ""
    max_thrust_n: float | None = None
    time_constant_source: str = ""
    current_source: str = ""
    # Flight model (optimizer.flight) extras, all optional: Paper C's separate rising and
    # falling time constants and latency, and the static curves' k_f, k_m (F = k_f w^2).
    tau_up_s: float | None = None
    tau_down_s: float | None = None
    latency_s: float | None = None
    k_f_n_s2: float | None = None
    k_m_nm_s2: float | None = None
    # Their uncertainty, optional (None: none known, the value is flown as it is): the
    # spread (sample standard deviation) of one measurement, not the standard error of
    # the mean: one edge of the step run for the time constants and the latency (pooled
    # over rising and falling edges), one speed level of the sweep for k_f and k_m.
    # ``optimizer.flight.uncertainty`` draws flown samples from them.
    tau_up_std_s: float | None = None
    tau_down_std_s: float | None = None
    latency_std_s: float | None = None
    k_f_std_n_s2: float | None = None
    k_m_std_nm_s2: float | None = None

    def __post_init__(self) -> None:
        label = f"measured actuator ({self.propeller_id}, {self.motor_id}, {self.esc_mode})"
        tc = self.time_constant_s
        if tc is not None and not (math.isfinite(tc) and tc > 0):
            raise RequestError(f"{label}: time_constant_s must be > 0, got {float(tc):g}")
        thrust = np.asarray(self.hover_thrust_n, float)
        current = np.asarray(self.hover_current_a, float)
        if thrust.shape != current.shape or thrust.ndim != 1:
            raise RequestError(f"{label}: hover_thrust_n and hover_current_a differ in length")
        if thrust.size == 1:
            raise RequestError(f"{label}: need at least two (thrust, current) points")
        if thrust.size and (
            not np.all(np.isfinite(thrust))
            or not np.all(np.isfinite(current))
            or np.any(current < 0)
            or np.any(np.diff(thrust) <= 0)
        ):
            raise RequestError(
                f"{label}: thrusts must be finite and strictly ascending, currents finite >= 0"
            )
        for name in ("tau_up_s", "tau_down_s", "k_f_n_s2", "k_m_nm_s2"):
            x = getattr(self, name)
            if x is not None and not (math.isfinite(x) and x > 0):
                raise RequestError(f"{label}: {name} must be > 0, got {float(x):g}")
        lat = self.latency_s
        if lat is not None and not (math.isfinite(lat) and lat >= 0):
            raise RequestError(f"{label}: latency_s must be >= 0, got {float(lat):g}")
        for name, std in STD_OF.items():
            x = getattr(self, std)
            if x is None:
                continue
            if not (math.isfinite(x) and x >= 0):
                raise RequestError(f"{label}: {std} must be finite and >= 0, got {float(x):g}")
            if getattr(self, name) is None:
                raise RequestError(f"{label}: {std} is given without {name}")
        v = self.supply_voltage_v
        if v is not None and not (math.isfinite(v) and v > 0):
            raise RequestError(f"{label}: supply_voltage_v must be > 0, got {float(v):g}")
        top = self.max_thrust_n
        if top is not None:
            if not (math.isfinite(top) and top > 0):
                raise RequestError(f"{label}: max_thrust_n must be > 0, got {float(top):g}")
            if thrust.size and top < thrust[-1]:
                raise RequestError(
                    f"{label}: max_thrust_n {top:g} N is below the highest current point "
                    f"{thrust[-1]:g} N"
                )

    @property
    def top_thrust_n(self) -> float | None:
        """The measured top thrust (``max_thrust_n``, else the last current point)."""
        if self.max_thrust_n is not None:
            return float(self.max_thrust_n)
        return float(self.hover_thrust_n[-1]) if self.has_current else None

    def top_thrust_applies(self, voltage_v: np.ndarray) -> np.ndarray:
        """Where the measured top thrust bounds a design with battery voltage ``voltage_v``."""
        voltage_v = np.asarray(voltage_v, float)
        if self.supply_voltage_v is None:
            return np.ones(voltage_v.shape, bool)
        return voltage_v <= self.supply_voltage_v * (1.0 + TOP_THRUST_VOLTAGE_MARGIN)

    def run_of(self, quantity: str) -> str:
        """The run a quantity ('time_constant' or 'current') was measured in."""
        own = self.time_constant_source if quantity == "time_constant" else self.current_source
        return own or self.source or "(run not recorded)"

    @property
    def has_current(self) -> bool:
        return len(self.hover_thrust_n) >= 2

    def current_at(
        self, thrust_n: np.ndarray, voltage_v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per-actuator current at the given hover thrusts, and where it is measured."""
        thrust = np.asarray(self.hover_thrust_n, float)
        current = np.asarray(self.hover_current_a, float)
        inside = (thrust_n >= thrust[0]) & (thrust_n <= thrust[-1])
        value = np.interp(thrust_n, thrust, current)
        if self.supply_voltage_v is not None:
            value = value * self.supply_voltage_v / voltage_v
        return value, inside


def select_overrides(
    overrides: Iterable[MeasuredActuator] | None, esc_mode: str | None
) -> dict[tuple[str, str], MeasuredActuator]:
    """Pick one override per (propeller, motor) for the requested ESC mode.

    An override for the requested mode wins over a mode-less one; overrides for another
    mode are ignored. Two overrides for the same key are an error.
    """
    chosen: dict[tuple[str, str], MeasuredActuator] = {}
    seen: set[tuple[str, str, str | None]] = set()
    for item in overrides or ():
        if not isinstance(item, MeasuredActuator):
            raise RequestError(f"overrides: expected MeasuredActuator, got {type(item).__name__}")
        key3 = (item.propeller_id, item.motor_id, item.esc_mode)
        if key3 in seen:
            raise RequestError(f"overrides: two entries for {key3}")
        seen.add(key3)
        if item.esc_mode is not None and item.esc_mode != esc_mode:
            continue
        key = (item.propeller_id, item.motor_id)
        if key not in chosen or item.esc_mode is not None:
            chosen[key] = item
    return chosen
