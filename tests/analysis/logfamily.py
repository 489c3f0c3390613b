"""Test helper: synthetic logs shaped like the esc_test collection (RCbenchmark 1580, ESC32).

The column layout, units, empty cells and rates copy the structure of the shipped files
(``fixtures/data/esc_test``): the RCbenchmark stand logs a row every ~24 ms, thrust and
torque only every ~150 ms (6.6 Hz, the other cells empty), the ESC signal column empty
(the ESC was driven by hand); the ESC32 utility logs duty, amps, volts and RPM every
15 ms with millisecond timestamps. The plant is a first-order rotor (speed time constant
``tau_s``) and thrust = k_f w^2, torque = -k_q w^2 (the 1580's torque sign for this
rotation). Defects of the real family are switches: time steps back (two boards
interleaving rows), a concatenated file, a filled ESC signal column.
"""

from __future__ import annotations

import math
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

RCB_HEADER = ("Time (s),ESC signal (µs),Servo 1 (µs),Servo 2 (µs),Servo 3 (µs),AccX (g),"
              "AccY (g),AccZ (g),Torque (N·m),Thrust (gf),Voltage (V),Current (A),"
              "Motor Electrical Speed (RPM),Motor Optical Speed (RPM),Electrical Power (W),"
              "Mechanical Power (W),Motor Efficiency (%),Propeller Mech. Efficiency (gf/W),"
              "Overall Efficiency (gf/W),Vibration (g),App message,")
ESC32_HEADER = ("Timestamp,Amps,Batt. Volts,Motor Volts,RPM,Duty,Comm. Period,Bad Detects,"
                "ADC Window,Idle Time,State,Phase A Avg.,Phase B Avg.,Phase C Avg.,"
                "Composite Avg.,FET Step")
K_F = 1.1e-6  # N s^2 / rad^2 (thrust = K_F w^2)
K_Q = 1.4e-8  # N m s^2 / rad^2
RPM_PER_DUTY = 160.0  # steady rpm per % duty above the start


def duty_profile(t: np.ndarray, hold_s: float = 5.0, top: float = 70.0) -> np.ndarray:
    """Hand-set 5 % duty steps up to ``top``, then down to 0 in 25 % steps."""
    up = np.arange(5.0, top + 1e-9, 5.0)
    levels = [0.0, *up.tolist(), top / 2, 0.0]
    k = np.clip((t // hold_s).astype(int), 0, len(levels) - 1)
    return np.asarray(levels)[k]


def rotor_rpm(t: np.ndarray, duty: np.ndarray, tau_s: float, startup_s: float = 0.0
              ) -> np.ndarray:
    """Exact first-order response of the speed to the piecewise-constant duty; a rotor at
    rest stays at rest for ``startup_s`` after the duty rises (an ESC's start-up routine)."""
    target = np.where(duty > 2.0, RPM_PER_DUTY * duty, 0.0)
    rpm = np.empty_like(t)
    y = 0.0
    rpm[0] = y
    start_at = math.inf
    for i in range(1, t.size):  # a few thousand rows: test-data generation only
        if y == 0.0 and target[i - 1] > 0 and startup_s > 0:
            start_at = min(start_at, t[i - 1] + startup_s)
            if t[i] < start_at:
                rpm[i] = 0.0
                continue
            dt = t[i] - start_at
        else:
            dt = t[i] - t[i - 1]
        start_at = math.inf
        a = math.exp(-dt / tau_s)
        y = target[i - 1] + (y - target[i - 1]) * a
        rpm[i] = y
    return rpm


def rcbenchmark_log(path: Path, *, seconds: float = 90.0, seed: int = 0, tau_s: float = 0.05,
                    steps_back: int = 0, back_ms: tuple[float, float] = (1.0, 9.0),
                    concatenated: bool = False, esc_signal: bool = False,
                    thrust_period_s: float = 0.15) -> Path:
    """An RCbenchmark 1580 log of hand-set duty steps; see the module doc for switches."""
    rng = np.random.default_rng(seed)
    dt = rng.uniform(0.007, 0.040, int(seconds / 0.02))
    t = np.concatenate(([0.0, 0.0], np.cumsum(dt)))  # the stand writes two rows at 0
    t = t[t <= seconds]
    duty = duty_profile(t)
    rpm = rotor_rpm(t, duty, tau_s) + rng.normal(0, 15.0, t.size) * (duty > 0)
    rpm = np.maximum(np.round(rpm), 0.0)
    w = rpm * 2 * math.pi / 60
    thrust_gf = K_F * w**2 / 9.80665e-3 + rng.normal(0, 3.0, t.size) - 10.0 * (rpm == 0)
    torque = -K_Q * w**2 + rng.normal(0, 2e-3, t.size)
    load = np.zeros(t.size, bool)  # the load cells update every ~150 ms
    next_t = 0.12
    for i, ti in enumerate(t):
        if ti >= next_t:
            load[i] = True
            next_t = ti + thrust_period_s
    current = 2.5e-7 * rpm**2 * (rpm > 0) + rng.normal(0, 0.02, t.size)
    volts = 16.0 - 0.01 * current
    esc = 1000.0 + 10.0 * duty
    t_file = t.copy()
    if steps_back:  # a row of the second board stamped a few ms before its predecessor
        places = rng.choice(np.arange(10, t.size - 10), steps_back, replace=False)
        for i in places:
            t_file[i] = t_file[i - 1] - rng.uniform(*back_ms) * 1e-3
    if concatenated:  # a second log appended: time restarts near zero half-way
        t_file[t.size // 2:] -= t_file[t.size // 2] - 0.5
    rows = []
    for i in range(t.size):
        cells = [f"{t_file[i]:.15g}", f"{esc[i]:g}" if esc_signal else "", "", "", "",
                 "0", "0.03", "-1.05",
                 f"{torque[i]:.12g}" if load[i] else "", f"{thrust_gf[i]:.12g}" if load[i] else "",
                 f"{volts[i]:.12g}", f"{current[i]:.12g}", f"{rpm[i]:g}", "0",
                 f"{volts[i] * current[i]:.12g}", "", "0", "", "", "0.0625", "", ""]
        rows.append(",".join(cells))
    path.write_text("\ufeff" + RCB_HEADER + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def esc32_log(path: Path, *, seconds: float = 90.0, seed: int = 0, tau_s: float = 0.06,
              delay_s: float = 0.0, hold_s: float = 5.0, startup_s: float = 0.0) -> Path:
    """An ESC32 telemetry log of hand-set duty steps, a row every 15 ms (ms stamps); the
    first step starts the rotor from rest after ``startup_s``."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 0.015) + rng.uniform(0, 0.002, int(np.ceil(seconds / 0.015)))
    t = np.sort(np.round(t, 3))
    duty = duty_profile(t, hold_s=hold_s)
    rpm = rotor_rpm(t - delay_s, duty_profile(np.maximum(t - delay_s, 0), hold_s), tau_s,
                    startup_s)
    rpm = np.maximum(np.round(rpm + rng.normal(0, 10.0, t.size) * (rpm > 0)), 0.0)
    start = datetime(2019, 11, 5, 17, 14, 8, 947000)
    rows = []
    for ti, d, r in zip(t, duty, rpm, strict=True):
        stamp = start + timedelta(seconds=float(ti))
        s = stamp.strftime("%Y-%m-%d %H:%M:%S:") + f"{stamp.microsecond // 1000:03d}"
        amps = 2.5e-7 * r**2
        rows.append(f"{s},{amps:.6g},15.78,{0.16 * d:.4g},{r:g},{d:g},34,0,0,95.6,"
                    f"{3 if r > 0 else 0},0,0,0,0,5")
    path.write_text(ESC32_HEADER + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path
