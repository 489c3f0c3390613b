"""Accuracy of the flight model's discretisation against tight references: the numbers in
docs/flight.md.

1. Roll pulse: Case I's vehicle (thesis-e, 4x P4+M1+B3) from hover, thrust = weight and a
   roll moment held for 0.2 s (10 deg of roll at its end), open loop. Lateral velocity at
   0.2 s from ``vehicle.step`` at dt = 4, 2, 1, 0.5 ms against the model's own
   ``derivative`` integrated by solve_ivp (rtol 1e-11); the error ratio per halving of dt
   is about 2 for a first-order step, 4 for a second-order one.
2. Rotor lag: the speeds ``RotorBank`` applies over each tick against the continuous
   first-order-plus-delay response to a speed step; the lead is the time by which the
   applied speeds' integral runs ahead of the continuous one.
3. Hover figure: ``fly``'s hover speed against the trim (N k_f omega^2 = m g) and the
   same closed loop flown 30 s, for Case I (123 ms) and P4+M1+B2 (127 ms).

    .venv/bin/python benchmarks/flight_integrator.py
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from optimizer.catalogs.catalog import load_catalog
from optimizer.flight.actuators import ActuatorModel, RotorBank
from optimizer.flight.design import design_index, gains_for, setup
from optimizer.flight.maneuvers import HOVER, fly
from optimizer.flight.reference import integrate_held, lag_mean, step_held
from optimizer.flight.vehicle import hover_state
from optimizer.model.design_model import evaluate_grid

CATALOG = "optimizer/data/catalogs/thesis-e"
PULSE_S = 0.2
PULSE_ROLL_RAD = math.radians(10.0)


def roll_pulse(catalog, grid) -> None:
    vehicle, _ = setup(catalog, grid, design_index(grid, "P4", "M1", "B3"))
    ixx = vehicle.inertia_kgm2[0]
    loads = (vehicle.mass_kg * vehicle.gravity_m_s2, ixx * 2 * PULSE_ROLL_RAD / PULSE_S ** 2,
             0.0, 0.0, 0.0, 0.0, 0.0)
    params = (1.0 / vehicle.mass_kg, *vehicle.inertia_kgm2, vehicle.gravity_m_s2, 0.0)
    segments = [(PULSE_S, loads)]
    ref = integrate_held(hover_state(), segments, params)[-1]
    print(f"roll pulse ({vehicle.label}): reference v_y = {ref[4]:.6f} m/s at {PULSE_S} s")
    last = None
    for dt in (4e-3, 2e-3, 1e-3, 5e-4):
        got = step_held(hover_state(), segments, params, dt)[-1]
        err = abs(got[4] - ref[4]) / abs(ref[4])
        state = float(np.max(np.abs(got - ref)))
        ratio = f", ratio {last / err:.2f}" if last else ""
        print(f"  dt {dt * 1e3:.1f} ms: v_y relative error {err:.2e}{ratio}; "
              f"largest state error {state:.1e}")
        last = err


def rotor_lead() -> None:
    dt, tau, ticks = 1e-3, 0.040, 400
    for latency in (0.0, 5e-3):
        model = ActuatorModel(tau, tau, latency_s=latency, frame_s=0.0, levels=1001,
                              idle_fraction=0.0)
        bank = RotorBank(model, 1, 1000.0, dt, 400.0)
        applied = np.array([bank.step([600.0])[0] for _ in range(ticks)])
        cont = lag_mean(ticks, dt, 400.0, 600.0, tau, latency)
        lead = float(np.sum(applied - cont)) * dt / (600.0 - 400.0)
        print(f"rotor lag (tau {tau * 1e3:.0f} ms, latency {latency * 1e3:.0f} ms): applied "
              f"speeds lead the continuous response by {lead * 1e3:.2e} ms "
              f"(largest tick difference {np.max(np.abs(applied - cont)):.2e} rad/s)")


def hover(catalog, grid) -> None:
    for battery in ("B3", "B2"):
        vehicle, actuator = setup(catalog, grid, design_index(grid, "P4", "M1", battery))
        gains = gains_for(actuator)
        rpm = 60.0 / (2.0 * math.pi)
        trim = vehicle.hover_speed_rad_s * rpm
        short = fly(vehicle, actuator, HOVER, gains=gains).figures["rpm"]
        long = fly(vehicle, actuator, dataclasses.replace(HOVER, duration_s=30.0),
                   gains=gains)
        settled = float(np.mean(long.omega[long.t >= 25.0])) * rpm
        print(f"hover {vehicle.label} (tau {actuator.tau_mean_s * 1e3:.1f} ms): reported "
              f"{short:.2f} rpm, trim {trim:.2f}, flown 25-30 s {settled:.2f}; reported - "
              f"trim {short / trim - 1:+.1e}, reported - settled {short / settled - 1:+.1e}")


def main() -> None:
    catalog = load_catalog(CATALOG)
    grid = evaluate_grid(catalog, 4)
    roll_pulse(catalog, grid)
    rotor_lead()
    hover(catalog, grid)


if __name__ == "__main__":
    main()
