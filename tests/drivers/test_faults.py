"""Fault switches on the simulated devices, set from code or from the rig file."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.rig.rig import DeviceConfig
from drivers.contracts import Fault
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.sim.rig import SimRig
from drivers.sim.sensor_params import SensorParams

QUIET = SensorParams(noise=False)


def spin(rig, pulse=1650, seconds=1.0, tick=0.02, read=("load_cell", "power", "rpm")):
    out = {k: [] for k in read}
    for _ in range(round(seconds / tick)):
        rig.esc.set_pulse_us(pulse)
        rig.clock.sleep(tick)
        for k in read:
            out[k].append(rig.sensors[k].read_block())
    return out


def cat(blocks, name):
    return (np.concatenate([b.t_s for b in blocks]),
            np.concatenate([b.values[name] for b in blocks]))


def test_dropout_loses_samples_or_fills_nan():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    rig.load_cell.inject(Fault.DROPOUT, at_s=0.2, until_s=0.4)
    rig.power.inject("dropout", probability=0.5, fill_nan=True)
    data = spin(rig, seconds=0.6)
    t, _ = cat(data["load_cell"], "thrust_n")
    assert not np.any((t > 0.2 + 1e-5) & (t < 0.4 - 1e-5))
    assert t.size == pytest.approx(0.4 * 25_000, abs=3)
    t_p, current = cat(data["power"], "current_a")
    assert t_p.size == pytest.approx(0.6 * 25_000, abs=2)  # rows kept
    assert np.mean(np.isnan(current)) == pytest.approx(0.5, abs=0.02)


def test_spikes_jump_to_full_scale():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    rig.load_cell.inject(Fault.SPIKES, probability=0.01)
    _, thrust = cat(spin(rig, seconds=0.4)["load_cell"], "thrust_n")
    full = rig.load_cell.describe().channels[0].high
    assert np.mean(thrust == full) == pytest.approx(0.01, abs=0.003)
    assert np.all((thrust == full) | (thrust < 10.0))


def test_stuck_freezes_the_last_good_value():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    rig.rpm.inject(Fault.STUCK, at_s=0.5, until_s=0.8)
    first = spin(rig, pulse=1700, seconds=0.6, read=("rpm",))["rpm"]
    then = spin(rig, pulse=1600, seconds=0.4, read=("rpm",))["rpm"]  # slows down meanwhile
    t, rpm = cat(first + then, "rpm")
    stuck = (t >= 0.5) & (t < 0.8)
    before = rpm[np.flatnonzero(stuck)[0] - 1]
    assert before > 0 and np.all(rpm[stuck] == before)
    assert rpm[-1] != before  # live again after the window


@pytest.mark.parametrize("fault,word", [(Fault.TIMEOUT, "timed out"),
                                        (Fault.DISCONNECT, "disconnected")])
def test_timeout_and_disconnect_raise_device_error_then_recover(fault, word):
    rig = SimRig(sensor_params=QUIET)
    rig.power.inject(fault, at_s=0.1, until_s=0.3)
    rig.clock.sleep(0.05)
    assert len(rig.power.read_block()) > 0
    rig.clock.sleep(0.1)
    with pytest.raises(DeviceError, match=f"sim://power: device {word}"):
        rig.power.read_block()
    rig.clock.sleep(0.2)
    block = rig.power.read_block()
    assert block.t_s[0] > 0.3 - 1e-4  # samples during the outage are lost


def test_disconnect_lasts_until_cleared():
    rig = SimRig(sensor_params=QUIET)
    rig.load_cell.inject(Fault.DISCONNECT)
    for _ in range(3):
        rig.clock.sleep(1.0)
        with pytest.raises(DeviceError, match="disconnected"):
            rig.load_cell.read_block()
    rig.load_cell.clear(Fault.DISCONNECT)
    rig.clock.sleep(0.01)
    assert len(rig.load_cell.read_block()) > 0


def test_esc_disconnect_raises_and_the_esc_fails_safe_to_idle():
    rig = SimRig(sensor_params=QUIET)
    rig.esc.arm()
    spin(rig, pulse=1750, seconds=1.0, read=())
    assert rig.truth().thrust_n > 2.0
    rig.esc.inject(Fault.DISCONNECT)
    with pytest.raises(DeviceError, match="sim://esc: device disconnected"):
        rig.esc.set_pulse_us(1750)
    rig.esc.disarm()  # must not raise, even though it cannot reach the ESC
    rig.clock.sleep(0.6)  # > timeout_s without a pulse arriving
    truth = rig.truth()
    assert truth.failsafe and truth.duty == 0.0
    rig.clock.sleep(3.0)
    assert rig.truth().thrust_n < 0.05


def test_esc_rejects_sample_faults():
    rig = SimRig()
    with pytest.raises(ValueError, match="not supported"):
        rig.esc.inject(Fault.SPIKES)


def test_faults_scheduled_in_the_rig_file(quiet_rig):
    devices = dict(quiet_rig.devices)
    lc = devices["load_cell"]
    devices["load_cell"] = DeviceConfig(lc.url, lc.channel, lc.calibration,
                                        {"faults": [{"kind": "disconnect", "at_s": 0.5}]})
    with open_rig(replace(quiet_rig, devices=devices)) as r:
        r.clock.sleep(0.4)
        r.sensors["load_cell"].read_block()
        r.clock.sleep(0.2)
        with pytest.raises(DeviceError, match="disconnected"):
            r.sensors["load_cell"].read_block()
    devices["load_cell"] = DeviceConfig(lc.url, lc.channel, lc.calibration,
                                        {"faults": [{"kind": "melted"}]})
    with pytest.raises(DeviceError, match="load_cell: bad fault spec"):
        open_rig(replace(quiet_rig, devices=devices))
    devices["load_cell"] = DeviceConfig(lc.url, lc.channel, lc.calibration, {"baud": 9600})
    with pytest.raises(DeviceError, match=r"load_cell: simulated devices take only .* 'baud'"):
        open_rig(replace(quiet_rig, devices=devices))
