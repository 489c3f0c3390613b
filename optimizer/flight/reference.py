"""Tight references for the flight model's discretisations (what ``step`` and the rotor
bank are checked against).

- ``integrate_held``: the model's own ``vehicle.derivative`` integrated by
  ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-11) with the loads held over segments,
  as ``fly`` holds them over a tick. ``step`` must approach it at the order its docstring
  claims; ``step_held`` flies the same segments with ``step``.
- ``lag_mean``: the tick means of the continuous first-order-plus-delay response to a
  speed step (Paper C, C.2-C.4), which the rotor bank's applied speeds must equal.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.integrate import solve_ivp

from optimizer.flight.vehicle import derivative, step

#: One held segment: duration (s) and loads (thrust, mx, my, mz, fx, fy, fz), SI.
Segment = tuple[float, Sequence[float]]


def integrate_held(s0: Sequence[float], segments: Sequence[Segment],
                   params: Sequence[float], rtol: float = 1e-11) -> np.ndarray:
    """The state after each segment; ``params`` = (1/m, ixx, iyy, izz, g, c_d)."""
    s = np.asarray(s0, float)
    out = []
    for duration, loads in segments:
        args = (*loads, *params)
        sol = solve_ivp(lambda _t, y, a=args: derivative(list(y), *a), (0.0, duration), s,
                        method="DOP853", rtol=rtol, atol=rtol * 1e-3)
        s = sol.y[:, -1]
        out.append(s)
    return np.array(out)


def step_held(s0: Sequence[float], segments: Sequence[Segment], params: Sequence[float],
              dt: float) -> np.ndarray:
    """The same segments flown by ``vehicle.step`` at ``dt`` (each a whole number of ticks)."""
    s = list(s0)
    out = []
    for duration, loads in segments:
        ticks = round(duration / dt)
        if not math.isclose(ticks * dt, duration, rel_tol=1e-9):
            raise ValueError(f"segment of {duration} s is not a whole number of {dt} s ticks")
        for _ in range(ticks):
            s = step(s, dt, *loads, *params)
        out.append(s)
    return np.array(out)


def lag_mean(ticks: int, dt: float, omega0: float, target: float, tau: float,
             delay: float = 0.0) -> np.ndarray:
    """Mean over each tick [k dt, (k+1) dt] of omega(t) = target + (omega0 - target)
    exp(-(t - delay) / tau) for t > delay (omega0 before): a step commanded at t = 0."""
    edges = np.arange(ticks + 1) * dt
    late = np.maximum(edges - delay, 0.0)
    # integral from 0 to each edge: omega0 up to the delay, then the exponential's
    integral = omega0 * np.minimum(edges, delay) + target * late \
        - (target - omega0) * tau * -np.expm1(-late / tau)
    return np.diff(integral) / dt
