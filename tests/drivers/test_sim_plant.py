"""The simulated plant against the thesis equations (E.1-E.7, C.1-C.3)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from drivers.sim.esc import EscSettings
from drivers.sim.plant import EscScheme, PlantParams, operating_point, steady_omega
from drivers.sim.rig import SimRig
from drivers.sim.sensor_params import SensorParams

QUIET = SensorParams(noise=False)


def settle(rig: SimRig, pulse: float, seconds: float, tick: float = 0.02) -> None:
    for _ in range(round(seconds / tick)):
        rig.esc.set_pulse_us(pulse)
        rig.clock.sleep(tick)


def test_steady_state_balances_motor_and_propeller_torque():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    settle(rig, 1650, 1.5)
    tr = rig.truth()
    p = tr.params
    n = tr.omega_rad_s / (2 * math.pi)
    assert tr.thrust_n == pytest.approx(p.ct * p.rho_kg_m3 * n**2 * p.diameter_m**4)  # (E.1)
    torque = p.cp * p.rho_kg_m3 * n**3 * p.diameter_m**5 / tr.omega_rad_s  # (E.2), (E.3)
    # (E.6), (E.7) at d omega / dt = 0, plus the bearing friction E.7 leaves out
    assert p.kt_nm_a * tr.current_winding_a == pytest.approx(torque + p.friction_nm, rel=1e-4)
    v_m = tr.duty * tr.voltage_bus_v - p.ke_v_s_rad * tr.omega_rad_s  # (E.4)
    assert tr.current_winding_a == pytest.approx(v_m / p.r_ohm, rel=2e-3)  # (E.5)
    assert tr.omega_rad_s == pytest.approx(steady_omega(p, tr.duty), rel=1e-4)


def test_hover_operating_point_of_the_thesis_rotor():
    """250 g per rotor on the 8x4.5 / 2212-920 set: about 5900 rpm and tau near 30 ms."""
    op = operating_point(PlantParams(), 0.25 * 9.81)
    assert 5500 < op.omega_rad_s * 60 / (2 * math.pi) < 6300
    assert 0.5 < op.duty < 0.8
    # C.3 with the propeller's torque slope in place of D (E.8): Table C.1 "from parameters"
    assert 0.025 < op.tau_drive_s < 0.035
    assert op.tau_coast_s > 3 * op.tau_drive_s


def test_small_step_time_constant_matches_linearisation():
    params = PlantParams()
    rig = SimRig(params=params, sensor_params=QUIET)
    rig.esc.arm()
    op = operating_point(params, 0.25 * 9.81)
    p0 = 1000 + op.duty * 1000
    settle(rig, p0, 1.0)
    w0 = rig.truth().omega_rad_s
    t_step = rig.clock.now()
    settle(rig, p0 + 5, 1.0, tick=0.0025)
    w1 = rig.truth().omega_rad_s
    traj = rig.plant.traj
    traj.flush()
    t, w = traj.arrays["t"], traj.arrays["omega"]
    target = w0 + (1 - math.exp(-1)) * (w1 - w0)
    t63 = np.interp(target, w[t > t_step], t[t > t_step])
    tau = t63 - t_step - params.esc_latency_s
    assert tau == pytest.approx(op.tau_drive_s, rel=0.05)


def test_complementary_brakes_with_reverse_current_diode_cannot():
    results = {}
    for scheme in (EscScheme.COMPLEMENTARY, EscScheme.DIODE):
        rig = SimRig(esc_mode=scheme, sensor_params=QUIET)
        rig.esc.arm()
        settle(rig, 1750, 1.0)
        i_min = math.inf
        for _ in range(40):
            rig.esc.set_pulse_us(1530)
            rig.clock.sleep(0.0025)
            i_min = min(i_min, rig.truth().current_winding_a)
        results[scheme] = (i_min, rig.truth().omega_rad_s)
    assert results[EscScheme.COMPLEMENTARY][0] < -1.0  # regenerative braking current
    assert results[EscScheme.DIODE][0] >= 0.0  # body diode: no reverse current
    # 100 ms after the step down the braked rotor is slower than the coasting one
    assert results[EscScheme.COMPLEMENTARY][1] < results[EscScheme.DIODE][1]


def test_inductance_is_negligible_as_paper_c_says():
    """C.1 vs C.2: with L = 80 uH the thrust response barely changes (tau_e << tau_m)."""
    traces = []
    for use_l in (False, True):
        rig = SimRig(params=replace(PlantParams(), use_inductance=use_l), sensor_params=QUIET)
        rig.esc.arm()
        trace = []
        for pulse in (1530, 1750, 1530):
            for _ in range(100):
                rig.esc.set_pulse_us(pulse)
                rig.clock.sleep(0.0025)
                trace.append(rig.truth().thrust_n)
        traces.append(np.array(trace))
    assert np.max(np.abs(traces[0] - traces[1])) < 0.02 * traces[0].max()


def test_supply_sags_under_load():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    settle(rig, 1900, 1.0)
    tr = rig.truth()
    p = tr.params
    assert tr.voltage_bus_v == pytest.approx(p.supply_v - p.supply_r_ohm * tr.current_bus_a)
    assert tr.voltage_bus_v < p.supply_v - 0.1


def test_static_map_from_truth_inverts():
    rig = SimRig(sensor_params=QUIET)
    tr = rig.truth()
    for thrust in (1.0, 2.45, 4.0):
        assert tr.steady_thrust_n(tr.pulse_for_thrust_us(thrust)) == pytest.approx(thrust, rel=1e-3)


@pytest.mark.parametrize("rate", [50.0, 490.0])
def test_frame_rate_extremes_still_integrate_accurately(rate):
    rig = SimRig(sensor_params=QUIET, esc_settings=EscSettings(frame_rate_hz=rate))
    rig.esc.arm()
    settle(rig, 1650, 1.5)
    tr = rig.truth()
    assert tr.omega_rad_s == pytest.approx(steady_omega(tr.params, tr.duty), rel=1e-3)


@pytest.mark.parametrize("scheme", list(EscScheme))
def test_vectorised_spans_equal_frame_by_frame_integration(scheme, monkeypatch):
    """Holding a duty, the plant solves runs of frames in closed form (numpy or Python
    floats); that must agree with stepping every frame (Riccati per substep or RK4)."""
    def trace(rig: SimRig) -> np.ndarray:
        rig.esc.arm()
        out = []
        for pulse in (1600, 1750, 1530, 1000, 1650):
            for _ in range(40):
                rig.esc.set_pulse_us(pulse)
                rig.clock.sleep(0.02)
                out.append(rig.truth().omega_rad_s)
        return np.array(out)

    fast = trace(SimRig(sensor_params=QUIET, esc_mode=scheme))
    slow_rig = SimRig(sensor_params=QUIET, esc_mode=scheme)
    monkeypatch.setattr(slow_rig.plant, "_continue_run", lambda duty, n_frames: 0)
    slow = trace(slow_rig)
    np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-9)
