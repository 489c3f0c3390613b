"""The static thrust map: fitting a slow ramp and inverting it for thrust setpoints."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bench.errors import RigError
from bench.plans.thrust_map import StaticThrustMap, fit_sweep


def ramp(noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    us = np.linspace(1100.0, 1900.0, 40_000)
    thrust = 8e-6 * (us - 1050.0) ** 2  # a quadratic command -> thrust law
    rpm = 12.0 * (us - 1050.0)
    current = 1e-7 * rpm**2
    return pd.DataFrame({"throttle_us": us, "thrust_n": thrust + noise * rng.normal(size=us.size),
                         "current_a": current, "rpm": rpm})


def test_fit_recovers_a_known_map_and_inverts_it():
    fit = fit_sweep(ramp(noise=0.03))
    tm = fit.thrust_map
    for us in (1200.0, 1500.0, 1800.0):
        assert tm.thrust_at(us) == pytest.approx(8e-6 * (us - 1050.0) ** 2, rel=0.01)
        assert tm.command_for(8e-6 * (us - 1050.0) ** 2) == pytest.approx(us, abs=2.0)
    assert fit.residual_rms_n < 0.01
    w = 1500.0 * 2 * np.pi / 60  # Fig. C.14: current against speed
    assert fit.current_poly_w(w) == pytest.approx(1e-7 * 1500.0**2, rel=1e-3)


def test_setpoint_outside_the_measured_range_is_refused():
    tm = StaticThrustMap(np.array([1100.0, 1500.0]), np.array([0.1, 2.0]), "rig.csv")
    with pytest.raises(RigError, match=r"rig.csv: setpoint 3.000 N outside"):
        tm.command_for(3.0)


@pytest.mark.parametrize("cmd,thr", [([1100.0], [0.1]), ([1100.0, 1000.0], [0.1, 0.2]),
                                     ([1100.0, 1200.0], [0.3, 0.2]),
                                     ([1100.0, 1200.0], [0.1, np.nan])])
def test_bad_maps_are_refused(cmd, thr):
    with pytest.raises(RigError):
        StaticThrustMap(np.array(cmd), np.array(thr))


def test_a_ramp_that_never_spins_is_refused():
    df = ramp()
    df["thrust_n"] = 0.0
    with pytest.raises(RigError, match="sweep a wider range"):
        fit_sweep(df)
