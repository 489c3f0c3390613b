"""The simulated DAQ: every channel of the rig sampled at once on one sample clock.

Like the thesis' cRIO (Paper C section 2.2) one acquisition samples the load-cell bridge
and the two AttoPilot outputs as ADC volts and reads the hall period counter, at 25 kHz by
default. It runs once per read of any sensor, over all samples since the previous one,
vectorised: interpolation of the plant trajectory, the load cell's mechanics as a filter
with carried state (``drivers.sim.load_cell_filter``), noise, quantisation, the counter's
edge times.

:class:`SimDaq` is what the sensor drivers hold: the clocks, the acquisition and the trim
of what every reader has taken. It knows the plant and the sensor models but not the rig
or the drivers, so the rig builds on the drivers and the drivers on the DAQ, no circle.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Protocol, TypeAlias

import numpy as np

from drivers.sim.cell_errors import CellErrors, CellErrorState, apply_cell_errors
from drivers.sim.clock import SimClock
from drivers.sim.load_cell_filter import PartSnapshot, SecondOrderLowPass, bilinear_low_pass
from drivers.sim.plant import Plant
from drivers.sim.sensor_params import VIBRATION_REF_RPM, SensorParams
from drivers.worker import Worker


class SampleClock:
    """The DAQ's sample clock: index n -> nominal time n / fs plus jitter.

    The jitter of sample n is entry ``n mod 2**18`` of a table drawn once from the seed
    (it repeats every 10.5 s at 25 kHz): the same whatever the read slicing, and a slice
    of the table rather than a random draw per read.
    """

    TABLE = 1 << 18

    def __init__(self, params: SensorParams, seed: int) -> None:
        self.params = params
        self.dt_ns = round(1e9 / params.sample_rate_hz)
        half = math.sqrt(3.0) * params.jitter_s  # uniform with rms jitter_s
        rng = np.random.default_rng(seed)
        self._jitter = rng.uniform(-half, half, self.TABLE)

    def index_end(self, now_ns: int) -> int:
        """One past the last sample index taken at or before ``now_ns``."""
        return max(0, now_ns // self.dt_ns + 1)

    def nominal(self, n0: int, n1: int) -> np.ndarray:
        return np.arange(n0, n1, dtype=np.float64) * (self.dt_ns * 1e-9)

    def stamps(self, n0: int, n1: int, nominal: np.ndarray) -> np.ndarray:
        if not self.params.noise or self.params.jitter_s <= 0:
            return nominal
        a = n0 % self.TABLE
        if a + (n1 - n0) <= self.TABLE:
            return nominal + self._jitter[a : a + n1 - n0]
        return nominal + np.take(self._jitter, np.arange(n0, n1), mode="wrap")


#: ``ColumnBuffer.snapshot``: the buffer (by reference), its first index, its live range.
BufferSnapshot: TypeAlias = tuple[np.ndarray, int, int, int]


class ColumnBuffer:
    """Rows indexed by sample number, appended at the end and trimmed from the front."""

    def __init__(self, width: int, capacity: int = 1 << 15) -> None:
        self._buf = np.empty((width, capacity))
        self.first = 0  # sample index of column 0 of the live part
        self._start = 0
        self._end = 0

    @property
    def end(self) -> int:
        """One past the last sample index held."""
        return self.first + self._end - self._start

    def restart(self, n: int) -> None:
        """Forget everything; the next append starts at sample index ``n`` (in a new
        buffer: a snapshot may still refer to the old one)."""
        self._buf = np.empty_like(self._buf)
        self.first, self._start, self._end = n, 0, 0

    def snapshot(self) -> BufferSnapshot:
        """O(1): columns before ``_end`` are never written again (appends go after it or
        into a new buffer), so the buffer is kept by reference."""
        return self._buf, self.first, self._start, self._end

    def restore(self, snap: BufferSnapshot) -> None:
        self._buf, self.first, self._start, self._end = snap

    def append(self, rows: np.ndarray) -> None:
        k = rows.shape[1]
        if self._end + k > self._buf.shape[1]:
            live = self._end - self._start
            cap = self._buf.shape[1]
            if live + k > cap // 2:
                cap = max(2 * cap, 2 * (live + k))
            buf = np.empty((self._buf.shape[0], cap))
            buf[:, :live] = self._buf[:, self._start : self._end]
            self._buf, self._start, self._end = buf, 0, live
        self._buf[:, self._end : self._end + k] = rows
        self._end += k

    def window(self, n0: int, n1: int) -> np.ndarray:
        a = self._start + n0 - self.first
        return self._buf[:, a : a + n1 - n0]

    def trim_before(self, n: int) -> None:
        if n > self.first:
            cut = min(n - self.first, self._end - self._start)
            self._start += cut
            self.first += cut


# rows of the shared acquisition (ACC_X_M_S2 only when the rig has the vibration channel;
# the torque cell's bridge after it, when the rig has one: ``Acquisition.torque_row``)
T_S, BRIDGE_V, CURRENT_OUT_V, VOLTAGE_OUT_V, HALL_PERIOD_S, ACC_X_M_S2 = range(6)


#: loads put on a cell besides the rotor's (calibration weights): (from t_s, value, ramp_s)
Loads: TypeAlias = tuple[tuple[float, float, float], ...]
#: ``Cell.snapshot``: its filter's state, its hidden errors' state, the loads put on it.
CellSnapshot: TypeAlias = tuple[tuple[PartSnapshot, ...], CellErrorState, Loads]


def _ramps(t: np.ndarray, applied: Loads) -> np.ndarray:
    """The applied load at each sample time: ramps between the values set."""
    total = np.zeros_like(t)
    before = 0.0
    for start, value, ramp in applied:  # a few weights: one pass each
        total += (value - before) * np.clip((t - start) / ramp, 0.0, 1.0)
        before = value
    return total


class Cell:
    """A load or torque cell, in the unit of its load: the weights put on it besides the
    rotor, its mechanics (a filter with carried state) and its hidden errors. The load cell
    and the torque cell are two of these, so their paths cannot drift apart."""

    def __init__(self, b: np.ndarray, a: np.ndarray, errors: CellErrors, full_scale: float,
                 dt_s: float) -> None:
        self.filter = SecondOrderLowPass(b, a)
        self.errors = errors
        self.full_scale = full_scale
        self.dt_s = dt_s
        self.state = CellErrorState()
        self.applied: Loads = ()

    def apply(self, t_s: float, value: float, ramp_s: float) -> None:
        """From sim time ``t_s`` on, ``value`` acts besides the rotor's load, over ``ramp_s``."""
        self.applied = (*self.applied, (t_s, value, max(ramp_s, 1e-9)))

    def felt(self, load: np.ndarray, t: np.ndarray, n0: int) -> np.ndarray:
        """What the cell outputs for the rotor's ``load`` at samples ``t`` (n0, n0+1...)."""
        if self.applied:
            load = load + _ramps(t, self.applied)
        felt = self.filter(load)
        if self.errors.any:
            r = self.full_scale
            felt = r * apply_cell_errors(self.errors, self.state, felt / r, n0, self.dt_s)
        return felt

    def snapshot(self) -> CellSnapshot:
        return self.filter.snapshot(), self.state.copy(), self.applied

    def restore(self, snap: CellSnapshot) -> None:
        filt, state, self.applied = snap
        self.filter.restore(filt)
        self.state = state.copy()


#: ``Acquisition.snapshot``: buffer, generator state, noise rows drawn ahead, the load and
#: torque cells, then magnet edges seen, the last edge's time and the period (RPM pickup).
AcquisitionSnapshot: TypeAlias = tuple[BufferSnapshot, Mapping[str, Any], np.ndarray,
                                       CellSnapshot, CellSnapshot, int, float, float]


class Acquisition:
    """The DAQ task: every channel of the rig sampled at once on the sample clock."""

    def __init__(self, params: SensorParams, plant: Plant, sample_clock: SampleClock,
                 seed: np.random.SeedSequence) -> None:
        p = self.params = params
        self.plant = plant
        self.sample_clock = sample_clock
        self.rng = np.random.Generator(np.random.SFC64(seed))  # fast bit generator
        # noise rows drawn ahead of need (see ``_noise``); the rng's state is after them
        self._ahead = np.empty((0, 3))
        self._drawing = Worker("sim-noise")
        self._rng_before: Mapping[str, Any] = {}  # the state before the rows being drawn
        self.rows = 6 if p.vibration else 5
        self.torque_row = self.rows if p.torque_cell else -1
        self.rows += 1 if p.torque_cell else 0
        self.buffer = ColumnBuffer(self.rows)
        # the accelerometer's noise by sample index (a table drawn once, like the clock's
        # jitter): the same whatever the read slicing, and the other channels' noise stream
        # is not touched, so a rig without vibration samples exactly as before
        self._acc_noise = np.random.default_rng(seed.spawn(1)[0]).standard_normal(
            SampleClock.TABLE) if p.vibration else np.empty(0)
        b, a = bilinear_low_pass(p.load_cell_fn_hz, p.load_cell_zeta, p.sample_rate_hz)
        self.cell_b, self.cell_a = b, a
        dt_s = 1.0 / p.sample_rate_hz
        self._cell = Cell(b, a, p.load_cell_errors, p.load_cell_range_n, dt_s)
        self._noise_sigma = np.array([
            [p.load_cell_noise_n * p.load_cell_v_per_n],
            [p.current_noise_a * p.current_mv_per_a * 1e-3],
            [p.voltage_noise_v * p.voltage_mv_per_v * 1e-3],
        ])
        self._noise_sigma_row = self._noise_sigma.T.copy()
        self._lsb = 2.0 * p.adc_range_v / 2**p.adc_bits
        # the torque cell: its own mechanics, errors and noise table (drawn once, like the
        # accelerometer's, so the other channels' noise stream is not touched)
        self._torque_cell = Cell(b, a, p.torque_cell_errors, p.torque_cell_range_nm, dt_s)
        self._torque_noise = np.random.default_rng(seed.spawn(1)[0]).standard_normal(
            SampleClock.TABLE) if p.torque_cell else np.empty(0)
        self._count: int = 0  # magnet edges seen so far
        self._last_edge: float = -math.inf
        self._period: float = math.inf

    def snapshot(self) -> AcquisitionSnapshot:
        # rows still being drawn are not waited for: the generator's state before them
        # goes into the snapshot, and a restore draws them again if they are needed
        rng = self._rng_before if self._drawing.pending else self.rng.bit_generator.state
        return (self.buffer.snapshot(), rng, self._ahead, self._cell.snapshot(),
                self._torque_cell.snapshot(), self._count, self._last_edge, self._period)

    def restore(self, snap: AcquisitionSnapshot) -> None:
        if self._drawing.pending:
            self._drawing.result()  # the thread must be done with the generator
        (buffer, rng, self._ahead, cell, torque_cell, self._count, self._last_edge,
         self._period) = snap
        self.buffer.restore(buffer)
        self.rng.bit_generator.state = rng
        self._cell.restore(cell)
        self._torque_cell.restore(torque_cell)

    # Reads at least this long (samples) draw the next read's noise in the background.
    DRAW_AHEAD = 4096

    def _noise(self, n: int) -> np.ndarray:
        """The next ``n`` rows of the noise stream (one row per sample, every channel).

        The rows are the same however they are drawn: in one go, in pieces, or partly
        ahead. A long read (a batch of ticks: 25,000 samples, 1 ms of the generator on the
        development machine) has the next read's rows drawn meanwhile in a thread, since
        numpy's generator lets go of the GIL while it fills an array; they are collected
        when that read needs them. The rows drawn ahead are part of ``snapshot`` and are
        never written to."""
        if len(self._ahead) < n and self._drawing.pending:
            drawn = self._drawing.result()
            self._ahead = np.concatenate((self._ahead, drawn)) if len(self._ahead) else drawn
        ahead = self._ahead
        if len(ahead) >= n:
            rows, self._ahead = ahead[:n], ahead[n:]
        else:
            rows = np.concatenate((ahead, self.rng.standard_normal((n - len(ahead), 3))))
            self._ahead = ahead[:0]
        if n >= self.DRAW_AHEAD and len(self._ahead) < n and not self._drawing.pending:
            self._rng_before = self.rng.bit_generator.state
            self._drawing.submit(self.rng.standard_normal, (n - len(self._ahead), 3))
        return rows

    def acquire_to(self, n1: int, now_ns: int, n_floor: int) -> None:
        """Sample every channel up to (not including) index ``n1``."""
        buf = self.buffer
        n0 = buf.end
        if n0 < n_floor:  # older samples would have been overwritten in the DAQ's ring
            buf.restart(n_floor)
            n0 = n_floor
        if n1 <= n0:
            return
        self.plant.advance_to(now_ns)
        clock = self.sample_clock
        t = clock.nominal(n0, n1)
        rows = np.empty((self.rows, n1 - n0))
        rows[T_S] = clock.stamps(n0, n1, t)
        self._analog(t, rows, n0)
        rows[HALL_PERIOD_S] = self._counter(t)
        if self.params.vibration:
            rows[ACC_X_M_S2] = self._vibration(n0, n1, t)
        if self.torque_row >= 0:
            rows[self.torque_row] = self._torque(n0, n1, t)
        buf.append(rows)

    def apply_force(self, t_s: float, force_n: float, ramp_s: float = 0.5) -> None:
        """From sim time ``t_s`` on, ``force_n`` (a calibration weight's) acts on the cell
        besides the rotor's thrust (0 takes it off), reached linearly over ``ramp_s``: a
        weight lowered by hand or by a fixture, not dropped (a drop rings the cell past
        its load, onto the other branch of its hysteresis)."""
        self._cell.apply(t_s, force_n, ramp_s)

    def apply_torque(self, t_s: float, torque_nm: float, ramp_s: float = 0.5) -> None:
        """As ``apply_force``, for weights hung on the torque cell's calibration arm."""
        self._torque_cell.apply(t_s, torque_nm, ramp_s)

    def _adc(self, volts: np.ndarray) -> np.ndarray:
        """The ADC's codes as volts, in place: ``volts`` clipped to its bipolar range and
        quantised to its LSB."""
        lsb, top = self._lsb, self.params.adc_range_v
        np.minimum(np.maximum(volts, -top, out=volts), top - lsb, out=volts)
        return np.multiply(np.rint(volts * (1.0 / lsb), out=volts), lsb, out=volts)

    def _analog(self, t: np.ndarray, rows: np.ndarray, n0: int) -> None:
        p = self.params
        plant = self.plant
        traj = plant.traj
        traj.flush()
        t_tr = traj.column("t")
        omega = np.interp(t, t_tr, traj.column("omega"))
        i_bus = np.interp(t, t_tr, traj.column("i_bus"))
        felt = self._cell.felt(plant.params.thrust_k * omega * omega, t, n0)  # (E.1)
        out = rows[BRIDGE_V : VOLTAGE_OUT_V + 1]
        np.multiply(felt, p.load_cell_v_per_n, out=out[0])
        out[0] += p.load_cell_offset_v
        pp = plant.params
        np.multiply(i_bus, p.current_mv_per_a * 1e-3, out=out[1])
        # the bus voltage is linear in the bus current: V = V_0 - R_s I
        np.multiply(i_bus, -pp.supply_r_ohm * p.voltage_mv_per_v * 1e-3, out=out[2])
        out[2] += pp.supply_v * p.voltage_mv_per_v * 1e-3
        if p.noise:  # one draw per sample for all channels: independent of read slicing
            noise = self._noise(t.size) * self._noise_sigma_row
            out += noise.T
        # AttoPilot outputs swing 0-3.3 V only (unidirectional); then the ADC
        top = min(p.sensor_out_max_v, p.adc_range_v - self._lsb)
        pos = out[1:]
        np.minimum(np.maximum(pos, 0.0, out=pos), top, out=pos)
        self._adc(out)

    def _torque(self, n0: int, n1: int, t: np.ndarray) -> np.ndarray:
        """The torque cell's bridge: the rotor's reaction torque k_q w^2 (E.2) and any
        weights on its arm, through the cell's mechanics and hidden errors, its noise and
        the ADC."""
        p = self.params
        traj = self.plant.traj
        omega = np.interp(t, traj.column("t"), traj.column("omega"))
        felt = self._torque_cell.felt(self.plant.params.torque_k * omega * omega, t, n0)  # (E.2)
        bridge = felt * p.torque_cell_v_per_nm + p.torque_cell_offset_v
        if p.noise and p.torque_cell_noise_nm > 0:
            bridge += (p.torque_cell_noise_nm * p.torque_cell_v_per_nm) * np.take(
                self._torque_noise, np.arange(n0, n1), mode="wrap")
        return self._adc(bridge)

    def _vibration(self, n0: int, n1: int, t: np.ndarray) -> np.ndarray:
        """Radial acceleration of the mount: imbalance at the rotor angle, the blades' pass
        at ``blades`` x the angle, both growing with speed^2, plus the accelerometer's noise."""
        p = self.params
        traj = self.plant.traj
        t_tr = traj.column("t")
        theta = np.interp(t, t_tr, traj.column("theta"))
        omega = np.interp(t, t_tr, traj.column("omega"))
        scale = (omega * (30.0 / math.pi / VIBRATION_REF_RPM)) ** 2
        acc = scale * (p.vibration_imbalance_m_s2 * np.sin(theta)
                       + p.vibration_blade_pass_m_s2 * np.sin(int(p.vibration_blades) * theta))
        if p.noise and p.vibration_noise_m_s2 > 0:
            acc += p.vibration_noise_m_s2 * np.take(self._acc_noise, np.arange(n0, n1),
                                                    mode="wrap")
        return acc

    def _crossing_times(self, angles: np.ndarray) -> np.ndarray:
        """When the rotor reaches each angle: omega is linear between integration points
        (the plant integrates theta with the trapezoid rule), so theta is quadratic there."""
        traj = self.plant.traj
        t_tr, th_tr, w_tr = traj.column("t"), traj.column("theta"), traj.column("omega")
        k = np.searchsorted(th_tr, angles, side="left") - 1
        np.minimum(np.maximum(k, 0, out=k), t_tr.size - 2, out=k)
        t0 = t_tr[k]
        h = t_tr[k + 1] - t0
        w0 = w_tr[k]
        a = (w_tr[k + 1] - w0) / (2.0 * h)
        d_th = angles - th_tr[k]
        denom = w0 + np.sqrt(np.maximum(w0 * w0 + 4.0 * a * d_th, 0.0))
        tau = 2.0 * d_th / np.maximum(denom, 1e-12)  # the rotor is turning at every edge
        return t0 + np.minimum(np.maximum(tau, 0.0, out=tau), h, out=tau)

    def _counter(self, t: np.ndarray) -> np.ndarray:
        """Hall sensor + FPGA period counter: at each magnet edge the counter latches the
        time since the previous edge (in counter ticks); the DAQ reads the latest latch.

        A read takes the edges latched at or before its last sample. Which magnets those
        are is decided on the edge times themselves (the rotor's quadratic angle between
        integration points), not on the linearly interpolated angle at the last sample:
        the two differ by a hair, and an edge in between used to be seen one read late,
        so the samples depended on how the run sliced its reads."""
        p = self.params
        traj = self.plant.traj
        pitch = 2.0 * math.pi / p.magnets
        th_tr = traj.column("theta")
        theta_end = float(np.interp(t[-1], traj.column("t"), th_tr))
        count_end = min(math.floor(theta_end / pitch) + 1,  # one edge more, if reached
                        math.floor(float(th_tr[-1]) / pitch))
        t_edge = np.empty(0)
        if count_end > self._count:
            angles = np.arange(self._count + 1, count_end + 1) * pitch
            tick = 1.0 / p.counter_hz
            t_edge = np.round(self._crossing_times(angles) / tick) * tick
            t_edge = t_edge[: int(np.searchsorted(t_edge, t[-1], side="right"))]
            count_end = self._count + t_edge.size
        if t_edge.size:
            edges = np.concatenate(([self._last_edge], t_edge))
            gaps = np.diff(edges)
            periods = np.concatenate(([self._period], gaps))
            # each sample holds the latest edge at or before it: runs between edges
            runs = np.diff(np.concatenate(([0], np.searchsorted(t, t_edge), [t.size])))
            period = np.repeat(periods, runs)
            self._count = count_end
            self._last_edge = float(t_edge[-1])
            self._period = float(periods[-1])
            quiet = max(float(gaps.max()), t[-1] - self._last_edge) <= p.rpm_timeout_s
            last = None if quiet else np.repeat(edges, runs)
        else:
            period = np.full(t.size, self._period)
            last = np.full(t.size, self._last_edge)
        if last is not None:  # no edge for a while: the counter reads "stopped"
            stale = t - last > p.rpm_timeout_s
            if stale.any():
                period[stale] = math.inf
                if stale[-1]:
                    self._period = math.inf
        err = p.counter_timebase_error
        return period * (1.0 + err) if err else period


class _Reader(Protocol):
    @property
    def next_n(self) -> int: ...


class SimDaq:
    """The rig's DAQ as its sensor drivers see it: the sim clock, the sample clock, the
    acquisition, and the readers whose cursors decide what may be forgotten."""

    def __init__(self, params: SensorParams, clock: SimClock, plant: Plant,
                 sample_clock: SampleClock, seed: np.random.SeedSequence) -> None:
        self.params = params
        self.clock = clock
        self.plant = plant
        self.sample_clock = sample_clock
        self.acquisition = Acquisition(params, plant, sample_clock, seed)
        self.readers: list[_Reader] = []

    def trim(self) -> None:
        """Forget acquired samples every reader has read, and plant history before the
        acquisition's end (the acquisition never looks back)."""
        acq = self.acquisition
        if acq.buffer.end - acq.buffer.first < 8192:
            return  # amortised: a few hundred ms of samples are cheap to keep
        n_floor = self.sample_clock.index_end(
            self.clock.now_ns() - round(self.params.buffer_s * 1e9))
        cursors = [r.next_n for r in self.readers]
        acq.buffer.trim_before(max(n_floor, min(cursors)) if cursors else n_floor)
        self.plant.traj.trim_before((acq.buffer.end - 1) * self.sample_clock.dt_ns * 1e-9)
