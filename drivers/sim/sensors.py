"""Simulated sensors: load cell, AttoPilot current/voltage sensor and hall RPM counter.

All three sample the plant trajectory on one shared sample clock (25 kHz by default, like
the thesis' cRIO, Paper C section 2.2), so their columns line up sample for sample. Each
``read_block`` returns every sample up to the current simulated time since the previous
read; everything is vectorised over the block (interpolation, ``scipy.signal.lfilter``
with carried state for the load cell's mechanics, noise, quantisation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy import signal

from drivers.contracts import Block, ChannelInfo, DeviceInfo, Fault
from drivers.errors import DeviceError
from drivers.sim.faults import FaultSwitches

if TYPE_CHECKING:
    from drivers.sim.rig import SimRig


@dataclass(frozen=True)
class SensorParams:
    """Sensor models of the simulated rig; sources in docs/sim-rig.md."""

    sample_rate_hz: float = 25_000.0  # load cell and current sampled at 25 kHz (Paper C 2.2)
    jitter_s: float = 1e-6  # timestamp jitter, uniform +-sqrt(3) sigma (assumption)
    noise: bool = True  # master switch for every random noise term
    load_cell_fn_hz: float = 150.0  # mechanical natural frequency, cell + mount (assumption)
    load_cell_zeta: float = 0.25  # its damping ratio (assumption)
    load_cell_v_per_n: float = 0.1  # bridge + amplifier sensitivity (assumption)
    load_cell_offset_v: float = 0.012  # zero offset of the bridge (so a tare matters)
    load_cell_noise_n: float = 0.03  # white force noise at 25 kHz (assumption, ~3 g)
    load_cell_range_n: float = 49.0  # Phidget micro load cell 0-5 kg (Paper C 2.2)
    current_mv_per_a: float = 36.60  # AttoPilot 90 A current scale (issue 3 / datasheet)
    voltage_mv_per_v: float = 63.69  # AttoPilot 90 A voltage scale (issue 3 / datasheet)
    sensor_out_max_v: float = 3.3  # AttoPilot output swing, unidirectional (0-3.3 V)
    current_noise_a: float = 0.15  # PWM ripple + sensor noise at 25 kHz (assumption)
    voltage_noise_v: float = 0.02  # (assumption)
    adc_bits: int = 16  # NI 9215-class ADC, 16 bit (assumption)
    adc_range_v: float = 10.0  # +-10 V input range
    magnets: int = 14  # hall sensor sees the 14 rotor magnets (Paper C 2.2)
    counter_hz: float = 40e6  # FPGA counter timebase of the cRIO (NI-9401 on a 40 MHz FPGA)
    rpm_timeout_s: float = 0.1  # no hall edge for this long -> the counter reports 0 rpm
    buffer_s: float = 30.0  # DAQ buffer: a sensor not read for this long overruns

    @classmethod
    def with_overrides(cls, overrides: dict[str, float]) -> SensorParams:
        known = {f.name for f in fields(cls)}
        for name in overrides:
            if name not in known:
                raise KeyError(name)
        return replace(cls(), **overrides)


def quantise(volts: np.ndarray, params: SensorParams) -> np.ndarray:
    """ADC: clip to the input range and round to the LSB."""
    lsb = 2.0 * params.adc_range_v / 2**params.adc_bits
    v = np.clip(volts, -params.adc_range_v, params.adc_range_v - lsb)
    return np.round(v / lsb) * lsb


def _splitmix64(x: np.ndarray) -> np.ndarray:
    """Counter-based hash (SplitMix64 finaliser): uint64 index -> uniform uint64 bits."""
    with np.errstate(over="ignore"):
        z = x + np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


class SampleClock:
    """The DAQ's shared sample clock: index n -> nominal time n / fs plus jitter.

    The jitter of sample n is a hash of (seed, n), so every sensor on the clock sees the
    same timestamps whatever order or block sizes they read in, and no buffer is kept.
    """

    def __init__(self, params: SensorParams, seed: int) -> None:
        self.params = params
        self.dt_ns = round(1e9 / params.sample_rate_hz)
        self._key = np.uint64(int(seed) & 0xFFFFFFFFFFFFFFFF)
        self._memo: tuple[tuple[int, int], np.ndarray] = ((-1, -1), np.empty(0))

    def index_end(self, now_ns: int) -> int:
        """One past the last sample index taken at or before ``now_ns``."""
        return now_ns // self.dt_ns + 1

    def nominal(self, n0: int, n1: int) -> np.ndarray:
        return np.arange(n0, n1, dtype=np.float64) * (self.dt_ns * 1e-9)

    def stamps(self, n0: int, n1: int, nominal: np.ndarray) -> np.ndarray:
        if not self.params.noise or self.params.jitter_s <= 0:
            return nominal
        if self._memo[0] == (n0, n1):  # the sensors on this clock usually read together
            return self._memo[1].copy()
        bits = _splitmix64(np.arange(n0, n1, dtype=np.uint64) ^ self._key)
        u = (bits >> np.uint64(11)).astype(np.float64) * (1.0 / 2**53)  # uniform [0, 1)
        half = math.sqrt(3.0) * self.params.jitter_s
        out = nominal + (2.0 * u - 1.0) * half
        self._memo = ((n0, n1), out)
        return out.copy()


class SimSensor:
    """Common part of the simulated sensors: cursor on the sample clock, faults, describe."""

    kind = "sensor"
    model = "simulated"
    allowed_faults = (Fault.DROPOUT, Fault.SPIKES, Fault.STUCK, Fault.TIMEOUT, Fault.DISCONNECT)

    def __init__(self, rig: SimRig, url: str, seed: np.random.SeedSequence) -> None:
        self.rig = rig
        self.url = url
        fault_seed, *channel_seeds = seed.spawn(3)
        # one generator per channel: the noise does not depend on how reads are sliced
        self.rngs = [np.random.default_rng(s) for s in channel_seeds]
        self.params = rig.sensor_params
        self.faults = FaultSwitches(url, np.random.default_rng(fault_seed), self.allowed_faults)
        self.next_n = 0
        self.closed = False

    # subclasses fill these
    def channels(self) -> tuple[ChannelInfo, ...]:
        raise NotImplementedError

    def measure(self, n0: int, n1: int, t: np.ndarray) -> dict[str, np.ndarray]:
        raise NotImplementedError

    def describe(self) -> DeviceInfo:
        return DeviceInfo(
            kind=self.kind, model=self.model, url=self.url, channels=self.channels(),
            extra={"sample_rate_hz": self.params.sample_rate_hz, "noise": self.params.noise},
        )

    def read_block(self) -> Block:
        if self.closed:
            raise DeviceError(f"{self.url}: sensor is closed")
        now_ns = self.rig.clock.now_ns()
        clock = self.rig.sample_clock
        n1 = clock.index_end(now_ns)
        n0 = self.next_n
        n_floor = clock.index_end(now_ns - round(self.params.buffer_s * 1e9))
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
            self.rig.trim()
            raise
        if n1 <= n0:
            return Block.empty(tuple(c.name for c in self.channels()))
        self.rig.plant.advance_to(now_ns)
        t_nominal = self.rig.sample_clock.nominal(n0, n1)
        values = self.measure(n0, n1, t_nominal)
        block = Block(self.rig.sample_clock.stamps(n0, n1, t_nominal), values)
        self.next_n = n1
        self.rig.trim()
        if not self.faults.switches:
            return block
        full_scale = {c.name: c.high for c in self.channels()}
        return self.faults.apply(block, full_scale)

    def close(self) -> None:
        self.closed = True

    def inject(self, fault: Fault | str, **kwargs: float) -> None:
        """Switch a fault on for a window of sim time, see ``FaultSwitches.inject``."""
        self.faults.inject(fault, **kwargs)

    def clear(self, fault: Fault | str | None = None) -> None:
        self.faults.clear(fault)

    def _noise(self, sigma: float, n: int, channel: int = 0) -> np.ndarray | float:
        if not self.params.noise or sigma <= 0:
            return 0.0
        return self.rngs[channel].standard_normal(n) * sigma


class SimLoadCell(SimSensor):
    """Load cell under the motor: 2nd-order mechanics, noise, bridge offset, calibration."""

    kind = "load_cell"
    model = "simulated Phidget micro load cell 5 kg"

    def __init__(self, rig: SimRig, url: str, seed: np.random.SeedSequence,
                 scale_n_per_v: float, offset_v: float) -> None:
        super().__init__(rig, url, seed)
        p = self.params
        wn = 2.0 * math.pi * p.load_cell_fn_hz
        b, a = signal.bilinear([wn * wn], [1.0, 2.0 * p.load_cell_zeta * wn, wn * wn],
                               fs=p.sample_rate_hz)
        self._b, self._a = b, a
        self._zi = np.zeros(max(len(a), len(b)) - 1)
        self.scale_n_per_v = scale_n_per_v
        self.offset_v = offset_v

    def channels(self) -> tuple[ChannelInfo, ...]:
        r = self.params.load_cell_range_n
        return (ChannelInfo("thrust_n", "N", self.params.sample_rate_hz, -r, r),)

    def measure(self, n0: int, n1: int, t: np.ndarray) -> dict[str, np.ndarray]:
        p = self.params
        omega = self.rig.plant.traj.sample(t, ("omega",))["omega"]
        force = self.rig.plant.params.thrust_k * omega * omega  # (E.1)
        felt, self._zi = signal.lfilter(self._b, self._a, force, zi=self._zi)
        force_noisy = felt + self._noise(p.load_cell_noise_n, t.size)
        volts = quantise(force_noisy * p.load_cell_v_per_n + p.load_cell_offset_v, p)
        return {"thrust_n": (volts - self.offset_v) * self.scale_n_per_v}


class SimPowerSensor(SimSensor):
    """AttoPilot 90 A: bus current and voltage as 0-3.3 V signals read by the ADC."""

    kind = "power_sensor"
    model = "simulated AttoPilot 90 A"

    def __init__(self, rig: SimRig, url: str, seed: np.random.SeedSequence,
                 current_mv_per_a: float, voltage_mv_per_v: float,
                 current_offset_mv: float = 0.0) -> None:
        super().__init__(rig, url, seed)
        self.current_mv_per_a = current_mv_per_a
        self.voltage_mv_per_v = voltage_mv_per_v
        self.current_offset_mv = current_offset_mv

    def channels(self) -> tuple[ChannelInfo, ...]:
        fs = self.params.sample_rate_hz
        top = self.params.sensor_out_max_v * 1000.0
        return (
            ChannelInfo("current_a", "A", fs, 0.0, top / self.current_mv_per_a),
            ChannelInfo("voltage_v", "V", fs, 0.0, top / self.voltage_mv_per_v),
        )

    def measure(self, n0: int, n1: int, t: np.ndarray) -> dict[str, np.ndarray]:
        p = self.params
        s = self.rig.plant.traj.sample(t, ("i_bus", "v_bus"))
        n = t.size
        vi = (s["i_bus"] + self._noise(p.current_noise_a, n)) * p.current_mv_per_a * 1e-3
        vv = (s["v_bus"] + self._noise(p.voltage_noise_v, n, 1)) * p.voltage_mv_per_v * 1e-3
        vi = quantise(np.clip(vi, 0.0, p.sensor_out_max_v), p)  # unidirectional output
        vv = quantise(np.clip(vv, 0.0, p.sensor_out_max_v), p)
        return {
            "current_a": (vi * 1e3 - self.current_offset_mv) / self.current_mv_per_a,
            "voltage_v": vv * 1e3 / self.voltage_mv_per_v,
        }


class SimRpmSensor(SimSensor):
    """Hall sensor on the rotor magnets + FPGA period counter, sampled on the shared clock.

    At every hall edge the counter latches the time since the previous edge (quantised to
    the counter timebase); the DAQ loop reads the latest value at each sample, so the
    column holds rpm = 60 / (magnets * period) of the last completed magnet pitch.
    """

    kind = "rpm_sensor"
    model = "simulated hall sensor + period counter"

    def __init__(self, rig: SimRig, url: str, seed: np.random.SeedSequence, magnets: int) -> None:
        super().__init__(rig, url, seed)
        if magnets < 1:
            raise DeviceError(f"{url}: magnets must be >= 1, got {magnets}")
        self.magnets = magnets
        self._count = 0  # magnet edges seen so far
        self._last_edge = -math.inf
        self._rpm = 0.0

    def channels(self) -> tuple[ChannelInfo, ...]:
        return (ChannelInfo("rpm", "rpm", self.params.sample_rate_hz, 0.0, 60_000.0),)

    def _crossing_times(self, angles: np.ndarray) -> np.ndarray:
        """When the rotor reaches each angle: omega is linear between integration points
        (the plant integrates theta with the trapezoid rule), so theta is quadratic there."""
        arr = self.rig.plant.traj.arrays
        t_tr, th_tr, w_tr = arr["t"], arr["theta"], arr["omega"]
        k = np.clip(np.searchsorted(th_tr, angles, side="left") - 1, 0, t_tr.size - 2)
        h = t_tr[k + 1] - t_tr[k]
        w0, w1 = w_tr[k], w_tr[k + 1]
        a = (w1 - w0) / (2.0 * h)
        d_th = angles - th_tr[k]
        root = np.sqrt(np.maximum(w0 * w0 + 4.0 * a * d_th, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            tau = np.where(w0 + root > 0, 2.0 * d_th / (w0 + root), 0.0)
        return t_tr[k] + np.clip(tau, 0.0, h)

    def measure(self, n0: int, n1: int, t: np.ndarray) -> dict[str, np.ndarray]:
        traj = self.rig.plant.traj
        traj.flush()
        t_tr, th_tr = traj.arrays["t"], traj.arrays["theta"]
        pitch = 2.0 * math.pi / self.magnets
        theta_end = float(np.interp(t[-1], t_tr, th_tr))
        count_end = math.floor(theta_end / pitch)
        if count_end > self._count:
            # edges: the rotor angle passes a magnet; theta(t) is monotone, so invert it
            angles = np.arange(self._count + 1, count_end + 1) * pitch
            tick = 1.0 / self.params.counter_hz
            t_edge = np.round(self._crossing_times(angles) / tick) * tick
            edges = np.concatenate(([self._last_edge], t_edge))
            rpm_edge = 60.0 / (self.magnets * np.diff(edges))  # first may be 60/inf = 0
            rpm_edge = np.concatenate(([self._rpm], rpm_edge))
            # each sample holds the latest edge at or before it (0: carried from before)
            which = np.searchsorted(t_edge, t, side="right")
            rpm = rpm_edge[which]
            last = edges[which]
            self._count = count_end
            self._last_edge = float(t_edge[-1])
            self._rpm = float(rpm_edge[-1])
        else:
            rpm = np.full(t.size, self._rpm)
            last = np.full(t.size, self._last_edge)
        stale = t - last > self.params.rpm_timeout_s
        if stale.any():
            rpm[stale] = 0.0
            if stale[-1]:
                self._rpm = 0.0
        return {"rpm": rpm}
