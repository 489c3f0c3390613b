"""One contract suite for every Sensor and Esc implementation (simulated and replayed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.contracts import Block, DeviceInfo, Esc, MonotonicClock, Sensor
from drivers.errors import DeviceError
from drivers.factory import open_rig
from drivers.replay import ReplaySensor
from drivers.sim.clock import SimClock


def _sim_sensor(role):
    def make(rig_config):
        rig = open_rig(rig_config)
        rig.esc.arm()
        rig.esc.set_pulse_us(1600)
        return rig.sensors[role], rig.clock

    return make


def _replay_sensor(rig_config):
    """Record a second of the sim load cell and power sensor, replay it on a fresh clock."""
    rig = open_rig(rig_config)
    rig.esc.arm()
    blocks = []
    for _ in range(50):
        rig.esc.set_pulse_us(1600)
        rig.clock.sleep(0.02)
        a, b = rig.sensors["load_cell"].read_block(), rig.sensors["power"].read_block()
        blocks.append(Block(a.t_s, {**a.values, **b.values}))
    clock = SimClock()
    return ReplaySensor.from_blocks("replay://memory", blocks, clock), clock


SENSORS = {
    "sim-load_cell": _sim_sensor("load_cell"),
    "sim-power": _sim_sensor("power"),
    "sim-rpm": _sim_sensor("rpm"),
    "replay": _replay_sensor,
}


@pytest.fixture(params=sorted(SENSORS))
def sensor(request, default_rig):
    dev, clock = SENSORS[request.param](default_rig)
    yield dev, clock
    dev.close()


def test_sensor_satisfies_protocol_and_describes_itself(sensor):
    dev, _ = sensor
    assert isinstance(dev, Sensor)
    info = dev.describe()
    assert isinstance(info, DeviceInfo) and info.url and info.channels
    for ch in info.channels:
        assert ch.name.endswith(("_n", "_a", "_v", "rpm", "_us")), ch.name
        assert ch.unit and ch.rate_hz > 0 and ch.low < ch.high


def test_sensor_blocks_hold_exactly_the_new_samples(sensor):
    dev, clock = sensor
    names = {ch.name for ch in dev.describe().channels}
    seen = []
    for _ in range(4):
        clock.sleep(0.01)
        block = dev.read_block()
        assert isinstance(block, Block)
        assert set(block.values) == names
        assert all(v.shape == block.t_s.shape for v in block.values.values())
        assert len(block) > 0
        assert np.all(np.diff(block.t_s) > 0)
        assert block.t_s[-1] <= clock.now() + 1e-5
        seen.append(block.t_s)
    stamps = np.concatenate(seen)
    assert np.all(np.diff(stamps) > 0)  # no sample handed out twice, none out of order
    rate = dev.describe().channels[0].rate_hz
    assert len(stamps) == pytest.approx(0.04 * rate, abs=2)
    assert len(dev.read_block()) == 0  # no time passed: nothing new


def test_sensor_read_after_close_raises_device_error(sensor):
    dev, clock = sensor
    dev.close()
    clock.sleep(0.01)
    with pytest.raises(DeviceError, match="closed"):
        dev.read_block()


ESCS = {"sim-esc": lambda cfg: open_rig(cfg)}


@pytest.fixture(params=sorted(ESCS))
def esc_rig(request, default_rig):
    rig = ESCS[request.param](default_rig)
    yield rig
    rig.close()


def test_esc_satisfies_protocol_and_describes_limits(esc_rig):
    esc = esc_rig.esc
    assert isinstance(esc, Esc)
    info = esc.describe()
    (ch,) = info.channels
    assert ch.name == "throttle_us" and (ch.low, ch.high) == (1000.0, 2000.0)
    assert 50 <= info.extra["frame_rate_hz"] <= 490
    assert info.extra["timeout_s"] > 0


def test_esc_disarm_is_always_safe(esc_rig):
    esc = esc_rig.esc
    esc.disarm()  # before arming
    esc.arm()
    esc.set_pulse_us(1500)
    esc.disarm()
    esc.disarm()  # repeatedly
    esc.close()
    esc.disarm()  # after close
    with pytest.raises(DeviceError, match="closed"):
        esc.set_pulse_us(1500)


def test_esc_rejects_non_finite_and_clamps_range(esc_rig):
    esc = esc_rig.esc
    esc.arm()
    with pytest.raises(DeviceError, match="finite"):
        esc.set_pulse_us(math.nan)
    esc.set_pulse_us(2500)
    assert esc.last_pulse_us == 2000
    esc.set_pulse_us(500)
    assert esc.last_pulse_us == 1000


CLOCKS = {"sim": SimClock, "monotonic": MonotonicClock}


@pytest.mark.parametrize("name", sorted(CLOCKS))
def test_clock_moves_forward_by_at_least_the_sleep(name):
    clock = CLOCKS[name]()
    t0 = clock.now()
    clock.sleep(0.002)
    t1 = clock.now()
    assert t1 - t0 >= 0.002 - 1e-9
    clock.sleep(0.0)
    assert clock.now() >= t1


@pytest.mark.parametrize("name", sorted(CLOCKS))
def test_clock_sleep_of_zero_or_less_returns_at_once(name):
    clock = CLOCKS[name]()
    t0 = clock.now()
    clock.sleep(-1e-12)
    clock.sleep(-0.5)
    assert clock.now() - t0 < 0.1
