"""NI-DAQmx backend: the only module that imports ``nidaqmx``.

Recipes from architecture-anchors.md §3 (NI's own examples): analog inputs on a
hardware-timed continuous sample clock (up to 25 kHz here), the hall sensor on a counter
that counts edges *sampled by the AI sample clock* (``/<dev>/ai/SampleClock``, counter
started before the AI task) so speed lines up with force sample by sample, and the ESC
pulse train on a counter output channel defined by high/low time, updated on the fly with
``CounterWriter.write_one_sample_pulse_time``. The pulse train is finite and renewed by
the host (``NiPwmEsc``): a dead host stops the pulses within ``dead_host_s``. Closing the
output task stops the pulses; the line idles low and the ESC sees signal loss (its failsafe).

Reads never block: ``read_block`` takes what is in the DAQ buffer (``avail_samp_per_chan``)
into fresh arrays. DAQmx errors (buffer overrun, device gone) become ``DeviceError``.
Calibrations match the simulated sensors' rig-file keys (``scale_n_per_v``,
``current_mv_per_a``, ``voltage_mv_per_v``, ``magnets``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import nidaqmx
import nidaqmx.errors
import numpy as np
from nidaqmx.constants import AcquisitionType, Edge, Level, TerminalConfiguration
from nidaqmx.stream_readers import AnalogMultiChannelReader, CounterReader
from nidaqmx.stream_writers import CounterWriter

from drivers.contracts import Block, ChannelInfo, Clock, DeviceInfo, MonotonicClock
from drivers.errors import DeviceError

TaskFactory = Callable[[], Any]


def _daq(what: str, exc: Exception) -> DeviceError:
    return DeviceError(f"NI-DAQmx {what}: {exc}")


@dataclass(frozen=True)
class AiChannel:
    """One analog input: physical channel, column name of its raw voltage, range."""

    physical: str  # e.g. "Dev1/ai0"
    name: str  # e.g. "bridge_v"
    min_v: float = -10.0
    max_v: float = 10.0
    terminal: str = "DEFAULT"  # a TerminalConfiguration name: DEFAULT, DIFF, RSE, NRSE


@dataclass(frozen=True)
class AcquisitionConfig:
    """Hardware-timed acquisition of one device."""

    device: str  # e.g. "Dev1"
    ai: tuple[AiChannel, ...]
    rate_hz: float = 25_000.0
    counter: str | None = None  # e.g. "Dev1/ctr0": hall edges on the AI sample clock
    buffer_s: float = 10.0  # host buffer of the continuous task

    def __post_init__(self) -> None:
        if not self.ai:
            raise DeviceError(f"nidaq://{self.device}: at least one analog input is needed "
                              "(the counter runs on the AI sample clock)")
        for ch in self.ai:
            if ch.terminal not in TerminalConfiguration.__members__:
                raise DeviceError(f"nidaq://{ch.physical}: terminal {ch.terminal!r} not one of "
                                  f"{sorted(TerminalConfiguration.__members__)}")


class NiAcquisition:
    """The AI task (+ the edge-count task) and a non-blocking chunk reader."""

    def __init__(self, config: AcquisitionConfig, *, clock: Clock | None = None,
                 task_factory: TaskFactory = nidaqmx.Task) -> None:
        self.config = config
        self.clock = clock or MonotonicClock()
        self._lock = threading.Lock()
        self._n = 0  # samples read per channel so far
        self._ci: Any = None
        self._ai: Any = None
        try:
            self._ai = task_factory()
            for ch in config.ai:
                self._ai.ai_channels.add_ai_voltage_chan(
                    ch.physical, ch.name, terminal_config=TerminalConfiguration[ch.terminal],
                    min_val=ch.min_v, max_val=ch.max_v)
            buf = int(config.rate_hz * config.buffer_s)
            self._ai.timing.cfg_samp_clk_timing(config.rate_hz,
                                                sample_mode=AcquisitionType.CONTINUOUS,
                                                samps_per_chan=buf)
            if config.counter is not None:
                self._ci = task_factory()
                self._ci.ci_channels.add_ci_count_edges_chan(config.counter, "hall_count",
                                                             edge=Edge.RISING)
                self._ci.timing.cfg_samp_clk_timing(
                    config.rate_hz, source=f"/{config.device}/ai/SampleClock",
                    sample_mode=AcquisitionType.CONTINUOUS, samps_per_chan=buf)
                self._ci.start()  # waits for the AI clock, so it starts first
            self._ai_reader = AnalogMultiChannelReader(self._ai.in_stream)
            self._ci_reader = CounterReader(self._ci.in_stream) if self._ci is not None else None
            self._ai.start()
            self._t0 = self.clock.now()
        except nidaqmx.errors.DaqError as exc:
            self.close()
            raise _daq(f"setup of {config.device}", exc) from None

    def read(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Every sample in the buffer: times (s, rig clock) and raw columns (V, counts)."""
        names = [ch.name for ch in self.config.ai]
        with self._lock:
            try:
                n = int(self._ai.in_stream.avail_samp_per_chan)
                if self._ci is not None:
                    n = min(n, int(self._ci.in_stream.avail_samp_per_chan))
                cols: dict[str, np.ndarray] = {}
                if n > 0:
                    data = np.empty((len(names), n))
                    self._ai_reader.read_many_sample(data, n, timeout=0.0)
                    cols = {nm: data[k] for k, nm in enumerate(names)}
                    if self._ci_reader is not None:
                        counts = np.empty(n, dtype=np.uint32)
                        self._ci_reader.read_many_sample_uint32(counts, n, timeout=0.0)
                        cols["hall_count"] = counts
            except nidaqmx.errors.DaqError as exc:
                raise _daq(f"read from {self.config.device}", exc) from None
            t = self._t0 + (self._n + np.arange(n)) / self.config.rate_hz
            self._n += n
        if n == 0:
            return np.empty(0), {nm: np.empty(0) for nm in names}
        return t, cols

    def close(self) -> None:
        for task in (self._ai, self._ci):
            if task is None:
                continue
            try:
                task.stop()
            except nidaqmx.errors.DaqError:
                pass
            try:
                task.close()
            except nidaqmx.errors.DaqError:
                pass
        self._ai = self._ci = None


class RpmFromEdges:
    """Edge counts sampled on the AI clock -> rpm per sample (vectorised, stateful).

    The period is taken over the last ``magnets`` edges (one revolution), which hides
    uneven magnet spacing; no edge for ``timeout_s`` reads as stopped (0 rpm).
    """

    def __init__(self, magnets: int, timeout_s: float = 0.25) -> None:
        if magnets < 1:
            raise DeviceError(f"rpm: magnets must be >= 1, got {magnets}")
        self.magnets = magnets
        self.timeout_s = timeout_s
        self._last_count: int | None = None
        self._edges = np.empty(0)  # recent edge times, at most `magnets` + 1 kept

    def update(self, t: np.ndarray, counts: np.ndarray) -> np.ndarray:
        c = counts.astype(np.int64)
        prev = c[0] if self._last_count is None else self._last_count
        inc = np.diff(np.concatenate(([prev], c))) % (1 << 32)  # the counter wraps at 2**32
        self._last_count = int(c[-1]) if c.size else self._last_count
        edges = np.concatenate((self._edges, np.repeat(t, inc)))
        if edges.size == 0:
            return np.zeros(t.size)
        k = np.searchsorted(edges, t, side="right") - 1  # last edge at or before each sample
        m = self.magnets
        ok = k >= m
        period = np.full(t.size, math.inf)
        kk = k[ok]
        period[ok] = edges[kk] - edges[kk - m]  # one revolution
        last_edge = np.where(k >= 0, edges[np.maximum(k, 0)], -math.inf)
        period[t - last_edge > self.timeout_s] = math.inf
        self._edges = edges[-(m + 1):]
        with np.errstate(divide="ignore"):
            return 60.0 / period  # rev/s -> rpm; inf period -> 0


class NiSensor:
    """A ``Sensor`` over the shared acquisition: calibrated columns of one role.

    ``convert(t, raw) -> {column: array}``; every role's ``read_block`` returns the
    samples that arrived since *its* previous read (the acquisition is read once per
    poll and fanned out).
    """

    def __init__(self, hub: NiHub, role: str, channels: tuple[ChannelInfo, ...],
                 convert: Callable[[np.ndarray, Mapping[str, np.ndarray]], dict[str, np.ndarray]],
                 url: str) -> None:
        self.hub = hub
        self.role = role
        self._channels = channels
        self.convert = convert
        self.url = url
        hub.register(role)

    def describe(self) -> DeviceInfo:
        return DeviceInfo(kind=self.role, model="NI-DAQmx", url=self.url, channels=self._channels,
                          extra={"rate_hz": self.hub.acq.config.rate_hz})

    def read_block(self) -> Block:
        t, raw = self.hub.take(self.role)
        names = tuple(c.name for c in self._channels)
        if t.size == 0:
            return Block.empty(names)
        return Block(t, self.convert(t, raw))

    def close(self) -> None:
        self.hub.release(self.role)


@dataclass
class NiHub:
    """Reads the acquisition once and keeps per-role queues, so roles read independently."""

    acq: NiAcquisition
    _queues: dict[str, list[tuple[np.ndarray, Mapping[str, np.ndarray]]]] = field(
        default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def register(self, role: str) -> None:
        with self._lock:
            self._queues[role] = []

    def release(self, role: str) -> None:
        with self._lock:
            self._queues.pop(role, None)
            last = not self._queues
        if last:
            self.acq.close()

    def take(self, role: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        t, raw = self.acq.read()
        with self._lock:
            if t.size:
                for q in self._queues.values():
                    q.append((t, raw))
            chunks, self._queues[role] = self._queues[role], []
        if not chunks:
            return np.empty(0), {}
        t_all = np.concatenate([c[0] for c in chunks])
        return t_all, {k: np.concatenate([c[1][k] for c in chunks]) for k in chunks[0][1]}


def load_cell(hub: NiHub, column: str, scale_n_per_v: float, offset_v: float = 0.0,
              url: str = "nidaq://load_cell") -> NiSensor:
    """thrust_n = (V - offset_v) * scale_n_per_v (the sim rig's calibration keys)."""
    return NiSensor(hub, "load_cell", (ChannelInfo("thrust_n", "N", hub.acq.config.rate_hz),),
                    lambda t, raw: {"thrust_n": (raw[column] - offset_v) * scale_n_per_v}, url)


def power_sensor(hub: NiHub, current_column: str, voltage_column: str, current_mv_per_a: float,
                 voltage_mv_per_v: float, current_offset_mv: float = 0.0,
                 url: str = "nidaq://power") -> NiSensor:
    """AttoPilot-type outputs (protocols.md §8.3 mV/A, mV/V) -> current_a, voltage_v."""
    fs = hub.acq.config.rate_hz
    return NiSensor(
        hub, "power", (ChannelInfo("current_a", "A", fs), ChannelInfo("voltage_v", "V", fs)),
        lambda t, raw: {"current_a": (raw[current_column] * 1e3 - current_offset_mv)
                        / current_mv_per_a,
                        "voltage_v": raw[voltage_column] * (1e3 / voltage_mv_per_v)}, url)


def rpm_sensor(hub: NiHub, magnets: int, timeout_s: float = 0.25,
               url: str = "nidaq://rpm") -> NiSensor:
    if hub.acq.config.counter is None:
        raise DeviceError(f"{url}: the acquisition has no counter for the hall sensor")
    est = RpmFromEdges(magnets, timeout_s)
    return NiSensor(hub, "rpm", (ChannelInfo("rpm", "rpm", hub.acq.config.rate_hz),),
                    lambda t, raw: {"rpm": est.update(t, raw["hall_count"])}, url)


@dataclass(frozen=True)
class PwmSettings:
    """The ESC pulse train (rig-file ``[esc]``): frame rate and pulse limits.

    ``dead_host_s`` is the length of one finite pulse train: when the host stops renewing
    it (killed, frozen, crashed) the counter stops within this time and the line idles
    low, which the ESC treats as signal loss.
    """

    counter: str  # e.g. "Dev1/ctr1"
    frame_rate_hz: float = 400.0
    min_us: float = 1000.0
    max_us: float = 2000.0
    idle_us: float = 1000.0
    host_timeout_s: float = 0.5  # host silent this long -> idle pulses
    dead_host_s: float = 0.25  # pulses last this long after the last renewal

    def __post_init__(self) -> None:
        if self.max_us * 1e-6 >= 1.0 / self.frame_rate_hz:
            raise DeviceError(f"nidaq://{self.counter}: a {self.max_us} us pulse does not fit "
                              f"a {self.frame_rate_hz} Hz frame")
        if not 4.0 / self.frame_rate_hz <= self.dead_host_s <= 10.0:
            raise DeviceError(f"nidaq://{self.counter}: dead_host_s must be 4 frames .. 10 s, "
                              f"got {self.dead_host_s}")

    @property
    def train_pulses(self) -> int:
        """Pulses in one finite train (``dead_host_s`` of frames)."""
        return max(4, math.floor(self.dead_host_s * self.frame_rate_hz))


class NiPwmEsc:
    """ESC pulse train on a counter output, pulse width updated on the fly (``Esc``).

    The width is clamped here, not only by the caller. The counter generates a *finite*
    train of ``train_pulses`` pulses (``dead_host_s``); a renewal thread restarts it every
    ``dead_host_s / 3`` with the width in force. A process that dies (kill -9, a crash of
    the live view) or freezes stops renewing, so the pulses end at most ``dead_host_s``
    after the last renewal: the line idles low and the ESC's signal-loss failsafe stops
    the motor. A continuous train would go on at the last width by itself. Each renewal
    is a stop and a start of the task: at most one frame is lost. When the host has not
    commanded for ``host_timeout_s`` (a stuck control loop in a live process) the train
    goes on at idle until the next command.
    """

    def __init__(self, settings: PwmSettings, *, task_factory: TaskFactory = nidaqmx.Task,
                 url: str | None = None) -> None:
        self.settings = settings
        self.url = url or f"nidaq://{settings.counter}"
        self.period_s = 1.0 / settings.frame_rate_hz
        self.renew_s = settings.dead_host_s / 3.0
        self._lock = threading.Lock()
        self._armed = False
        self._stalled = False
        self._last_host_t = time.monotonic()
        self._pulse_us = settings.idle_us
        self._closed = False
        self.renewals = 0
        self.error: DeviceError | None = None
        try:
            self._task = task_factory()
            high = settings.idle_us * 1e-6
            self._chan = self._task.co_channels.add_co_pulse_chan_time(
                settings.counter, idle_state=Level.LOW, initial_delay=0.0,
                low_time=self.period_s - high, high_time=high)
            self._task.timing.cfg_implicit_timing(sample_mode=AcquisitionType.FINITE,
                                                  samps_per_chan=settings.train_pulses)
            self._writer = CounterWriter(self._task.out_stream)
            self._task.start()
        except nidaqmx.errors.DaqError as exc:
            raise _daq(f"setup of {settings.counter}", exc) from None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._guard, name=f"pwm-guard-{self.url}",
                                        daemon=True)
        self._thread.start()

    def describe(self) -> DeviceInfo:
        s = self.settings
        return DeviceInfo(kind="esc", model="NI counter output (PWM)", url=self.url,
                          channels=(ChannelInfo("throttle_us", "us", s.frame_rate_hz, s.min_us,
                                                s.max_us),),
                          extra={"frame_rate_hz": s.frame_rate_hz, "idle_us": s.idle_us,
                                 "dead_host_s": s.dead_host_s,
                                 "train_pulses": s.train_pulses})

    def _write(self, pulse_us: float) -> None:
        high = pulse_us * 1e-6
        self._pulse_us = pulse_us
        try:
            # nidaqmx leaves timeout unannotated (its default 10 reads as an int); it takes s
            self._writer.write_one_sample_pulse_time(
                high, self.period_s - high, timeout=0.1)  # pyright: ignore[reportArgumentType]
        except nidaqmx.errors.DaqError as exc:
            raise _daq(f"pulse update on {self.settings.counter}", exc) from None

    def _renew(self) -> None:
        """Restart the finite train with the width in force (lock held)."""
        high = self._pulse_us * 1e-6
        try:
            self._task.stop()
            self._chan.co_pulse_high_time = high
            self._chan.co_pulse_low_time = self.period_s - high
            self._task.start()
        except nidaqmx.errors.DaqError as exc:
            raise _daq(f"pulse train renewal on {self.settings.counter}", exc) from None
        self.renewals += 1

    def arm(self) -> None:
        with self._lock:
            self._raise_pending()
            self._armed = True
            self._last_host_t = time.monotonic()
            self._write(self.settings.idle_us)

    def set_pulse_us(self, pulse_us: float) -> None:
        pulse = float(pulse_us)
        if not math.isfinite(pulse):
            raise DeviceError(f"{self.url}: pulse width must be finite, got {pulse_us!r}")
        s = self.settings
        with self._lock:
            if self._closed:
                raise DeviceError(f"{self.url}: ESC output is closed")
            self._raise_pending()
            self._last_host_t = time.monotonic()
            self._stalled = False
            if self._armed:
                self._write(min(s.max_us, max(s.min_us, pulse)))

    def disarm(self) -> None:
        """Idle pulses; never raises."""
        with self._lock:
            self._armed = False
            if self._closed:
                return
            try:
                self._write(self.settings.idle_us)
            except DeviceError:
                pass

    def _raise_pending(self) -> None:
        if self.error is not None:
            err, self.error = self.error, None
            raise err

    def _guard(self) -> None:
        while not self._stop.wait(self.renew_s):
            with self._lock:
                if self._closed:
                    return
                try:
                    silent = time.monotonic() - self._last_host_t > self.settings.host_timeout_s
                    if self._armed and silent and not self._stalled:
                        self._write(self.settings.idle_us)
                        self._stalled = True  # the next set_pulse_us resumes
                    self._renew()
                except DeviceError as exc:
                    self.error = exc  # raised by the host's next command; the train ends

    def close(self) -> None:
        """Idle, then stop the pulses (line low: the ESC's signal-loss failsafe)."""
        self.disarm()
        self._stop.set()
        self._thread.join(timeout=1.0)
        with self._lock:
            if self._closed:
                return
            self._closed = True
            for step in (self._task.stop, self._task.close):
                try:
                    step()
                except nidaqmx.errors.DaqError:
                    pass
