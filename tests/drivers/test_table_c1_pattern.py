"""Paper C Table C.1 pattern, identified from the simulated rig like the thesis did it.

Step 1 (175 g <-> 325 g, i.e. hover of a 1 kg quad +-30 %, 20 repeats) runs on the default
rig in each ESC mode; the commands come from the rig's measured thrust map; the 20 load-cell
responses are averaged per 2.5 ms ESC period and a first-order-plus-delay model is fitted
to each direction. Only the pattern is asserted (Table C.1: delay 15-20 ms; tau_up ~ tau_dn
in complementary mode; tau_dn much slower with the diode scheme and the stock firmware).
"""

from __future__ import annotations

import pytest

from drivers.factory import open_rig

G = 9.81


@pytest.fixture(scope="module")
def fits(request):
    from bench.rig.rig import default_rig_path, load_rig

    stepfit = __import__("sys").modules["rotorbench_tests_drivers_stepfit"]
    rig = load_rig(default_rig_path())
    lo = rig.thrust_map.command_for(0.175 * G)
    hi = rig.thrust_map.command_for(0.325 * G)
    out = {}
    for mode in ("complementary", "diode", "stock"):
        with open_rig(rig.with_esc_mode(mode)) as r:
            up, down, fs = stepfit.run_step1(r, lo, hi, repeats=20, hold_s=1.0, tick_s=0.02)
            truth = r.truth()
        out[mode] = (stepfit.average_and_fit(up, fs), stepfit.average_and_fit(down, fs), truth)
    return out


def test_complementary_rises_and_falls_alike(fits):
    up, down, truth = fits["complementary"]
    assert 0.8 < down.tau_s / up.tau_s < 1.25
    # the fitted time constant is the plant's linearised one at hover (C.3 / E.8)
    assert up.tau_s == pytest.approx(truth.tau_up_s(0.25 * G), rel=0.15)
    assert down.tau_s == pytest.approx(truth.tau_dn_s(0.25 * G), rel=0.15)


@pytest.mark.parametrize("mode", ["diode", "stock"])
def test_diode_schemes_fall_much_slower(fits, mode):
    up, down, _ = fits[mode]
    comp_down = fits["complementary"][1]
    assert down.tau_s > 1.3 * up.tau_s
    assert down.tau_s > 1.6 * comp_down.tau_s


def test_stock_firmware_is_slower_and_later(fits):
    stock_up, stock_down, _ = fits["stock"]
    diode_up, diode_down, _ = fits["diode"]
    assert stock_up.tau_s > 1.15 * diode_up.tau_s
    assert stock_up.delay_s > diode_up.delay_s + 0.003
    assert stock_down.tau_s >= diode_down.tau_s


@pytest.mark.parametrize("mode", ["complementary", "diode"])
def test_fitted_delay_is_the_true_latency_chain(fits, mode):
    up, _, truth = fits[mode]
    # commands leave on frame boundaries, so the ESC latches them at once: the dead time is
    # the firmware latency plus the load cell's group delay (the fit sees a little more)
    expected = truth.latency_s + truth.load_cell_delay_s
    assert expected - 0.001 < up.delay_s < expected + 0.004
    assert 0.010 < up.delay_s < 0.020



@pytest.mark.parametrize("mode", ["complementary", "diode", "stock"])
def test_fitted_delay_plus_tau_is_the_true_63_percent_time(fits, mode):
    """The identified model reaches 63 % when the noise-free plant does (plus the load
    cell's group delay): the fit recovers the truth, not a table."""
    up, down, truth = fits[mode]
    lo, hi = 0.175 * G, 0.325 * G
    lag = truth.load_cell_delay_s
    assert up.delay_s + up.tau_s == pytest.approx(truth.t63_s(lo, hi) + lag, abs=0.004)
    assert down.delay_s + down.tau_s == pytest.approx(truth.t63_s(hi, lo) + lag, abs=0.005)
