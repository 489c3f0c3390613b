"""Simulated sensors: load cell, AttoPilot current/voltage sensor and hall RPM counter.

The sensor drivers slice their channels out of the rig's shared acquisition
(``drivers.sim.acquisition``: every channel on one 25 kHz sample clock, like the thesis'
cRIO) and convert volts and counter periods to units with their rig-file calibration, so
the columns line up sample for sample. Each ``read_block`` returns every sample up to the
current simulated time since the previous read.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Unpack

import numpy as np

from drivers.contracts import Block, ChannelInfo, DeviceInfo, Fault
from drivers.errors import DeviceError
from drivers.sim.acquisition import (
    ACC_X_M_S2,
    BRIDGE_V,
    CURRENT_OUT_V,
    HALL_PERIOD_S,
    T_S,
    VOLTAGE_OUT_V,
    SimDaq,
)
from drivers.sim.faults import FaultOptions, FaultsSnapshot, FaultSwitches
from drivers.sim.sensor_params import SensorParams

__all__ = ["CALIBRATION_KEYS", "SensorParams", "SimLoadCell", "SimPowerSensor", "SimRpmSensor",
           "SimSensor", "check_calibration"]


def _positive(v: float) -> bool:
    return math.isfinite(v) and v > 0.0


def _finite(v: float) -> bool:
    return math.isfinite(v)


def _whole_at_least_one(v: float) -> bool:
    return math.isfinite(v) and v >= 1 and v == int(v)


# The rig-file calibration keys of each role: key -> (test, what is expected). A scale of 0
# or below would hide thrust and current from the limits, so scales must be positive.
CALIBRATION_KEYS: dict[str, dict[str, tuple[Callable[[float], bool], str]]] = {
    "esc": {},
    "load_cell": {"scale_n_per_v": (_positive, "a number of N/V > 0"),
                  "offset_v": (_finite, "a number of V"),
                  "torque_scale_nm_per_v": (_positive, "a number of N m/V > 0"),
                  "torque_offset_v": (_finite, "a number of V")},
    "power": {"current_mv_per_a": (_positive, "a number of mV/A > 0"),
              "voltage_mv_per_v": (_positive, "a number of mV/V > 0"),
              "current_offset_mv": (_finite, "a number of mV")},
    "rpm": {"magnets": (_whole_at_least_one, "a whole number of magnets >= 1")},
}


def check_calibration(role: str, calibration: Mapping[str, float], where: str,
                      required: tuple[str, ...] = ()) -> None:
    """Refuse a calibration the sensor of ``role`` cannot use, before any device opens.

    Raises ``DeviceError`` as ``<where> calibration.<key>: <problem>``; unknown keys are
    refused (a typo must not fall back to a default). The NI-DAQ backend converts with
    the same keys, so its opener checks them here too (with ``required``).
    """
    known = CALIBRATION_KEYS.get(role, {})
    for key in sorted(calibration):
        if key not in known:
            expected = f"expected one of {', '.join(known)}" if known else \
                f"the {role} takes no calibration"
            raise DeviceError(f"{where} calibration.{key}: unknown key; {expected}")
        value = calibration[key]
        ok, what = known[key]
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not number or not ok(value):
            got = f"{value:g}" if number else repr(value)
            raise DeviceError(f"{where} calibration.{key}: expected {what}, got {got}")
    for key in required:
        if key not in calibration:
            raise DeviceError(f"{where} calibration.{key}: missing; expected "
                              f"{known[key][1]}")


class SimSensor:
    """Common part of the simulated sensors: cursor into the acquisition, faults, describe."""

    kind = "sensor"
    model = "simulated"
    allowed_faults = (Fault.DROPOUT, Fault.SPIKES, Fault.STUCK, Fault.TIMEOUT, Fault.DISCONNECT)

    def __init__(self, daq: SimDaq, url: str, seed: np.random.SeedSequence) -> None:
        self.daq = daq
        self.url = url
        self.params = daq.params
        self.faults = FaultSwitches(url, np.random.default_rng(seed), self.allowed_faults)
        self.next_n = 0
        self.closed = False
        self._channels = self.channels()
        self._names = tuple(c.name for c in self._channels)
        daq.readers.append(self)

    # subclasses fill these
    def channels(self) -> tuple[ChannelInfo, ...]:
        raise NotImplementedError

    def convert(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        """Acquisition rows (volts, periods) -> calibrated columns."""
        raise NotImplementedError

    def describe(self) -> DeviceInfo:
        return DeviceInfo(
            kind=self.kind, model=self.model, url=self.url, channels=self._channels,
            extra={"sample_rate_hz": self.params.sample_rate_hz, "noise": self.params.noise},
        )

    def read_block(self) -> Block:
        if self.closed:
            raise DeviceError(f"{self.url}: sensor is closed")
        daq = self.daq
        now_ns = daq.clock.now_ns()
        n1 = daq.sample_clock.index_end(now_ns)
        n0 = self.next_n
        n_floor = daq.sample_clock.index_end(now_ns - round(self.params.buffer_s * 1e9))
        if n0 < n_floor:
            self.next_n = n_floor
            raise DeviceError(
                f"{self.url}: DAQ buffer overrun, {n_floor - n0} samples lost; "
                f"read at least every {self.params.buffer_s:g} s"
            )
        try:
            self.faults.check(now_ns * 1e-9, "read_block")
        except DeviceError:
            self.next_n = n1  # samples during an outage are lost
            raise
        if n1 <= n0:
            return Block.empty(self._names)
        daq.acquisition.acquire_to(n1, now_ns, n_floor)
        raw = daq.acquisition.buffer.window(n0, n1)
        block = Block(raw[T_S].copy(), self.convert(raw))
        self.next_n = n1
        daq.trim()
        if not self.faults.switches:
            return block
        return self.faults.apply(block, {c.name: c.high for c in self._channels})

    def close(self) -> None:
        self.closed = True

    def snapshot(self) -> tuple[int, bool, FaultsSnapshot]:
        return self.next_n, self.closed, self.faults.snapshot()

    def restore(self, snap: tuple[int, bool, FaultsSnapshot]) -> None:
        self.next_n, self.closed, faults = snap
        self.faults.restore(faults)

    def inject(self, fault: Fault | str, **kwargs: Unpack[FaultOptions]) -> None:
        """Switch a fault on for a window of sim time, see ``FaultSwitches.inject``."""
        self.faults.inject(fault, **kwargs)

    def clear(self, fault: Fault | str | None = None) -> None:
        self.faults.clear(fault)


class SimLoadCell(SimSensor):
    """Load cell under the motor: 2nd-order mechanics, noise, bridge offset, calibration."""

    kind = "load_cell"
    model = "simulated Phidget micro load cell 5 kg"

    def __init__(self, daq: SimDaq, url: str, seed: np.random.SeedSequence,
                 scale_n_per_v: float, offset_v: float,
                 torque_scale_nm_per_v: float | None = None,
                 torque_offset_v: float = 0.0) -> None:
        super().__init__(daq, url, seed)
        self.scale_n_per_v = scale_n_per_v
        self.offset_v = offset_v
        # the torque cell's datasheet scale unless the rig file gives its own
        self.torque_scale_nm_per_v = (torque_scale_nm_per_v if torque_scale_nm_per_v
                                      else 1.0 / self.params.torque_cell_v_per_nm)
        self.torque_offset_v = torque_offset_v

    def channels(self) -> tuple[ChannelInfo, ...]:
        r = self.params.load_cell_range_n
        fs = self.params.sample_rate_hz
        out = [ChannelInfo("thrust_n", "N", fs, -r, r)]
        if self.params.vibration:
            # the optional accelerometer on the mount, +-16 g (drivers.sim.sensor_params)
            out.append(ChannelInfo("acc_x_m_s2", "m/s²", fs, -16 * 9.80665, 16 * 9.80665))
        if self.params.torque_cell:  # the optional torque cell of a two-axis stand
            rt = self.params.torque_cell_range_nm
            out.append(ChannelInfo("torque_nm", "N m", fs, -rt, rt))
        return tuple(out)

    def describe(self) -> DeviceInfo:
        """The base description and the cells' mechanics (one filter for both cells), so a
        run can declare them and a step fit model them (``analysis.cell_response``)."""
        info = super().describe()
        dyn = {"natural_frequency_hz": self.params.load_cell_fn_hz,
               "damping_ratio": self.params.load_cell_zeta, "u_rel": 0.0,
               "source": "the simulator's cell model"}
        cells = {c.name: dyn for c in self._channels if c.name in ("thrust_n", "torque_nm")}
        return replace(info, extra={**info.extra, "cell_dynamics": cells})

    def convert(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        out = {"thrust_n": (raw[BRIDGE_V] - self.offset_v) * self.scale_n_per_v}
        if self.params.vibration:
            out["acc_x_m_s2"] = raw[ACC_X_M_S2].copy()
        row = self.daq.acquisition.torque_row
        if row >= 0:
            out["torque_nm"] = (raw[row] - self.torque_offset_v) * self.torque_scale_nm_per_v
        return out


class SimPowerSensor(SimSensor):
    """AttoPilot 90 A: bus current and voltage as 0-3.3 V signals read by the ADC."""

    kind = "power_sensor"
    model = "simulated AttoPilot 90 A"

    def __init__(self, daq: SimDaq, url: str, seed: np.random.SeedSequence,
                 current_mv_per_a: float, voltage_mv_per_v: float,
                 current_offset_mv: float = 0.0) -> None:
        self.current_mv_per_a = current_mv_per_a
        self.voltage_mv_per_v = voltage_mv_per_v
        self.current_offset_mv = current_offset_mv
        super().__init__(daq, url, seed)

    def channels(self) -> tuple[ChannelInfo, ...]:
        fs = self.params.sample_rate_hz
        top = self.params.sensor_out_max_v * 1000.0
        return (
            ChannelInfo("current_a", "A", fs, 0.0, top / self.current_mv_per_a),
            ChannelInfo("voltage_v", "V", fs, 0.0, top / self.voltage_mv_per_v),
        )

    def convert(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        return {
            "current_a": (raw[CURRENT_OUT_V] * 1e3 - self.current_offset_mv)
            / self.current_mv_per_a,
            "voltage_v": raw[VOLTAGE_OUT_V] * (1e3 / self.voltage_mv_per_v),
        }


class SimRpmSensor(SimSensor):
    """Hall sensor on the rotor magnets + period counter: rpm = 60 / (magnets * period)."""

    kind = "rpm_sensor"
    model = "simulated hall sensor + period counter"

    def __init__(self, daq: SimDaq, url: str, seed: np.random.SeedSequence, magnets: int) -> None:
        if magnets < 1:
            raise DeviceError(f"{url}: magnets must be >= 1, got {magnets}")
        self.magnets = magnets
        super().__init__(daq, url, seed)

    def channels(self) -> tuple[ChannelInfo, ...]:
        return (ChannelInfo("rpm", "rpm", self.params.sample_rate_hz, 0.0, 60_000.0),)

    def convert(self, raw: np.ndarray) -> dict[str, np.ndarray]:
        return {"rpm": 60.0 / (self.magnets * raw[HALL_PERIOD_S])}  # 60 / inf = 0
