"""The plant's rotor speeds put into the firmware's log as its eRPM: synthesized, and said.

The SITL logs no eRPM (it has no DShot, so no telemetry), yet a log's in-flight motor
response (``analysis.motor_response``) needs each motor's speed beside its command. The
plant knows the speed: each tick the flight loop records the wall-clock time, the motor
outputs the firmware answered and the rotors' speeds. The log's clock is the firmware's,
the host's monotonic clock from its own start, an offset the bench never learns; the same
motor outputs are in the log (``motor[]``), so the offset is where the two series of
outputs line up (``analysis.log_alignment``). Each log row then gets the plant's speed at
its instant, ``motorN_rpm`` as a real eRPM would give, marked in the run's metadata as
synthesized from the plant (``flight.synthesized`` and each column's source). Rows the
plant did not fly (it skipped a host stall, waited for a silent firmware, or had stopped)
are NaN.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from analysis.log_alignment import clock_offset

__all__ = ["MAX_RESIDUAL_US", "add_plant_erpm"]

#: the outputs line up when, at the offset found, the plant took what the log holds: a
#: median difference of 0.36-0.46 us on 11 flights, tens of us at a wrong offset. (The
#: correlation at the offset is no test of it: 0.54-0.84 on those flights, 0.38 on two
#: others whose offset was not checked.)
MAX_RESIDUAL_US = 2.0
#: plant ticks further apart than this (wall clock) are a hole: no speed between them
MAX_HOLE_S = 0.005
MOTORS = 4


def add_plant_erpm(flight: Any, trace: dict[str, np.ndarray]) -> None:
    """Add ``motor1_rpm`` .. ``motor4_rpm`` to ``flight`` (an ``analysis.flightlogs``
    ``FlightLog``) from the plant's ``trace`` (``wall_s``, ``motor_us``, ``omega_rad_s``),
    or a note why not."""
    meta = flight.meta
    cols = flight.columns
    names = [f"motor{k + 1}_us" for k in range(MOTORS)]
    wall, out_us, omega = (trace.get(k) for k in ("wall_s", "motor_us", "omega_rad_s"))
    if (wall is None or out_us is None or omega is None or wall.size < 100
            or any(n not in cols for n in names)):
        meta.setdefault("notes", []).append("no eRPM synthesized: no plant trace or no "
                                            "motor outputs in the log")
        return
    t = np.asarray(cols["t_s"], float)
    log_us = np.column_stack([cols[n] for n in names])
    ok = np.isfinite(t) & np.all(np.isfinite(log_us), axis=1)
    found = clock_offset(wall, out_us, t[ok], log_us[ok])
    at = t + found.offset_s
    # a log row between two plant ticks further apart than MAX_HOLE_S (the plant skipped
    # a host stall or waited for the firmware) or outside them has no speed of its own
    idx = np.searchsorted(wall, at)
    inside = (idx > 0) & (idx < wall.size)
    idx = np.clip(idx, 1, wall.size - 1)
    flown = inside & (wall[idx] - wall[idx - 1] <= MAX_HOLE_S)
    # what the plant took against what the firmware logged, on the log's rows
    taken = np.column_stack([np.interp(at, wall, out_us[:, k]) for k in range(MOTORS)])
    agree = flown & ok
    residual = float(np.median(np.abs(taken[agree] - log_us[agree]))) if agree.any() \
        else math.nan
    if not (residual <= MAX_RESIDUAL_US):
        meta.setdefault("notes", []).append(
            f"no eRPM synthesized: the plant's motor outputs and the log's did not line up "
            f"(median difference {residual:.1f} us at the best offset, correlation "
            f"{found.r:.2f})")
        return
    for k in range(MOTORS):
        rpm = np.interp(at, wall, omega[:, k]) * 60.0 / (2.0 * math.pi)
        flight.add(f"motor{k + 1}_rpm", np.where(flown, rpm, np.nan), "rpm",
                   f"synthesized: the plant's rotor {k + 1} speed (the SITL logs no eRPM), "
                   "put on the log's clock by its motor outputs")
    meta["synthesized"] = {
        "columns": [f"motor{k + 1}_rpm" for k in range(MOTORS)],
        "from": "the plant (optimizer.flight.plant: the design's rotors driven by the "
                "firmware's motor outputs); the SITL has no DShot telemetry, so no eRPM",
        "clock_offset_s": found.offset_s,
        "alignment_r": found.r,
        "motor_output_residual_us": residual,
        "rows_without_plant": int(np.count_nonzero(~flown)),
    }
