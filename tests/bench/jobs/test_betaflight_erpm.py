"""The plant's rotor speeds put on a Betaflight log's clock (``bench.jobs.betaflight_erpm``):
found after a short or a long wait to arm (which the plant's trace holds and the log does
not), and refused, with a note, for a log of other outputs."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.flightlogs.flight_log import FlightLog
from bench.jobs.betaflight_erpm import add_plant_erpm


def _flight(wait_s: float, offset_s: float = 12.5):
    """A plant trace at 1 kHz: ``wait_s`` disarmed (outputs 1000 us), then 6 s armed with
    the four outputs wandering; and the firmware's log of the armed part on its own clock
    (``offset_s`` behind the plant's wall clock)."""
    rng = np.random.default_rng(3)
    dt = 1e-3
    armed = 6.0
    n_wait, n_arm = round(wait_s / dt), round(armed / dt)
    wall = 100.0 + dt * np.arange(n_wait + n_arm)
    walk = np.cumsum(rng.normal(0.0, 1.0, (n_arm, 4)), axis=0)  # ~70 us as flown
    fly = np.clip(1400.0 + walk - walk.mean(axis=0), 1055.0, 2000.0)
    out_us = np.vstack([np.full((n_wait, 4), 1000.0), fly])
    omega = (out_us - 1000.0) * 2.0
    t_log = wall[n_wait:] - wall[n_wait] + 0.3
    log = FlightLog({"t_s": t_log, **{f"motor{k + 1}_us": fly[:, k] for k in range(4)}}, {})
    return log, {"wall_s": wall, "motor_us": out_us, "omega_rad_s": omega}, wall[n_wait] - 0.3


@pytest.mark.parametrize("wait_s", [0.2, 12.0])
def test_the_speeds_land_on_the_log_whatever_the_wait_to_arm(wait_s):
    log, trace, offset = _flight(wait_s)
    add_plant_erpm(log, trace)
    syn = log.meta.get("synthesized")
    assert syn is not None, log.meta.get("notes")
    assert syn["clock_offset_s"] == pytest.approx(offset, abs=1e-3)
    assert syn["motor_output_residual_us"] < 1.0
    rpm = log.columns["motor1_rpm"]
    want = trace["omega_rad_s"][-rpm.size:, 0] * 60.0 / (2.0 * np.pi)
    flown = np.isfinite(rpm)
    assert flown.sum() > rpm.size - 5  # the last row is past the plant's last tick
    assert np.allclose(rpm[flown], want[flown], rtol=0.0, atol=5.0)  # within a 2.5 us step


def test_a_log_of_another_flight_gets_no_speeds_and_a_note_why():
    _, trace, _ = _flight(1.0)
    other, _, _ = _flight(1.0)
    rng = np.random.default_rng(9)
    for k in range(4):  # the same shape of log, other outputs
        other.columns[f"motor{k + 1}_us"] = rng.permutation(other.columns[f"motor{k + 1}_us"])
    add_plant_erpm(other, trace)
    assert "synthesized" not in other.meta and "motor1_rpm" not in other.columns
    assert "did not line up" in other.meta["notes"][-1]
