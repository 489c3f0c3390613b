"""The simulated rig: one seeded plant, one sim clock, the ESC and the three sensors.

``SimRig`` is what ``drivers.factory.open_rig`` builds for a rig file whose devices are all
``sim://``. Advancing the clock advances the plant; sensors sample the same trajectory.
``truth()`` exposes the plant's true parameters and state for accuracy tests.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from drivers.contracts import Fault
from drivers.sim.acquisition import AcquisitionSnapshot, SampleClock, SimDaq
from drivers.sim.clock import SimClock
from drivers.sim.esc import EscModel, EscSettings, SimEsc
from drivers.sim.faults import FaultsSnapshot, FaultSwitches
from drivers.sim.plant import (
    EscScheme,
    OperatingPoint,
    Plant,
    PlantParams,
    operating_point,
    steady_omega,
)
from drivers.sim.sensor_params import SensorParams
from drivers.sim.sensors import (
    SimLoadCell,
    SimPowerSensor,
    SimRpmSensor,
    check_calibration,
)

ESC_FAULTS = (Fault.TIMEOUT, Fault.DISCONNECT)  # the faults the simulated ESC can show


@dataclass(frozen=True)
class PlantTruth:
    """The simulated plant's true parameters and current state (sim rigs only)."""

    params: PlantParams
    sensor_params: SensorParams
    esc: EscSettings
    esc_mode: str
    latency_s: float  # ESC input-to-duty latency (firmware), excluding the frame wait
    frame_period_s: float  # a command waits 0..1 frame before the ESC latches it
    filter_tau_s: float  # ESC input low-pass (stock firmware), 0 if none
    load_cell_delay_s: float  # low-frequency group delay of the load cell, 2 zeta / omega_n
    t_s: float
    omega_rad_s: float
    rpm: float
    thrust_n: float
    current_winding_a: float
    current_bus_a: float
    voltage_bus_v: float
    duty: float
    armed: bool
    failsafe: bool
    failsafe_count: int

    def operating_point(self, thrust_n: float) -> OperatingPoint:
        """Plant linearised around a steady thrust: duty, speed and tau (C.3, E.8)."""
        return operating_point(self.params, thrust_n)

    def tau_up_s(self, thrust_n: float) -> float:
        """Small-signal time constant at a steady thrust, motor driving (C.3 / E.8)."""
        return self.operating_point(thrust_n).tau_drive_s

    def tau_dn_s(self, thrust_n: float) -> float:
        """Small-signal time constant for a small decrease: the same as ``tau_up_s`` in
        every scheme while the winding current stays continuous. Large decreasing steps
        in the diode schemes are slower and not first order: see ``step_response``."""
        return self.operating_point(thrust_n).tau_drive_s

    def step_response(self, from_n: float, to_n: float, duration_s: float = 0.5,
                      settle_s: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
        """True thrust after a command step at t = 0 (noise-free plant, same ESC mode).

        The command is sent on a frame boundary, like the bench runner does; the result
        includes the ESC latency (and the stock filter) but no sensor dynamics.
        """
        rig = SimRig(params=self.params, sensor_params=replace(self.sensor_params, noise=False),
                     esc_settings=self.esc, esc_mode=self.esc_mode)
        frame = self.frame_period_s
        rig.esc.arm()
        for pulse, seconds in ((self.pulse_for_thrust_us(from_n), settle_s),
                               (self.pulse_for_thrust_us(to_n), duration_s)):
            for _ in range(round(seconds / frame)):
                rig.esc.set_pulse_us(pulse)
                rig.clock.sleep(frame)
        t_cmd = round(settle_s / frame) * frame
        t = t_cmd + np.arange(0.0, duration_s, 1e-4)
        omega = rig.plant.traj.sample(t, ("omega",))["omega"]
        return t - t_cmd, self.params.thrust_k * omega * omega

    def t63_s(self, from_n: float, to_n: float) -> float:
        """Time from the command to 63 % of a thrust step (latency included)."""
        t, f = self.step_response(from_n, to_n)
        progress = (f - f[0]) / (to_n - f[0])
        return float(t[np.argmax(progress >= 1.0 - np.exp(-1.0))])

    def steady_thrust_n(self, pulse_us: float) -> float:
        """Static thrust the plant settles at for a constant pulse (E.1, E.4-E.7)."""
        omega = steady_omega(self.params, self.esc.duty(pulse_us))
        return self.params.thrust_k * omega * omega

    def pulse_for_thrust_us(self, thrust_n: float) -> float:
        """Inverse of ``steady_thrust_n`` (static model, no measurement)."""
        duty = self.operating_point(thrust_n).duty
        return self.esc.min_us + duty * (self.esc.max_us - self.esc.min_us)


class Checkpoint(NamedTuple):
    """``SimRig.checkpoint``: the state of each part, for ``SimRig.restore``."""

    clock: int
    esc_model: tuple[object, ...]  # EscModel's fields by name (EscModel._STATE)
    plant: tuple[object, ...]  # Plant's fields by name, then its trajectory's snapshot
    acquisition: AcquisitionSnapshot
    esc: tuple[float, bool, FaultsSnapshot]
    sensors: tuple[tuple[int, bool, FaultsSnapshot], ...]


class SimRig:
    """One seeded plant plus its devices on a shared simulated clock."""

    def __init__(
        self,
        *,
        params: PlantParams | None = None,
        sensor_params: SensorParams | None = None,
        esc_settings: EscSettings | None = None,
        esc_mode: EscScheme | str = EscScheme.COMPLEMENTARY,
        seed: int = 0,
        urls: dict[str, str] | None = None,
        load_cell_cal: dict[str, float] | None = None,
        power_cal: dict[str, float] | None = None,
        rpm_cal: dict[str, float] | None = None,
    ) -> None:
        self.params = params or PlantParams()
        self.sensor_params = sensor_params or SensorParams()
        self.esc_settings = esc_settings or EscSettings()
        self.scheme = EscScheme.parse(esc_mode) if isinstance(esc_mode, str) else esc_mode
        self.seed = seed
        urls = {"esc": "sim://esc", "load_cell": "sim://load_cell", "power": "sim://power",
                "rpm": "sim://rpm", **(urls or {})}
        seeds = np.random.SeedSequence(seed).spawn(6)
        rngs = [np.random.default_rng(s) for s in seeds]
        self.clock = SimClock()
        self.esc_model = EscModel(self.esc_settings, self.scheme, self.params)
        self.plant = Plant(self.params, self.esc_model, self.scheme)
        self.sample_clock = SampleClock(self.sensor_params, int(rngs[0].integers(2**63)))
        self.daq = SimDaq(self.sensor_params, self.clock, self.plant, self.sample_clock,
                          seeds[5])
        self.acquisition = self.daq.acquisition
        self.clock.on_advance(self.plant.due)
        self.esc = SimEsc(urls["esc"], self.esc_model, self.clock,
                          FaultSwitches(urls["esc"], rngs[1], ESC_FAULTS))
        sp = self.sensor_params
        for role, cal in (("load_cell", load_cell_cal), ("power", power_cal), ("rpm", rpm_cal)):
            check_calibration(role, cal or {}, f"{urls[role]}:")
        lc = {"scale_n_per_v": 1.0 / sp.load_cell_v_per_n, "offset_v": 0.0, **(load_cell_cal or {})}
        pw = {"current_mv_per_a": sp.current_mv_per_a, "voltage_mv_per_v": sp.voltage_mv_per_v,
              "current_offset_mv": 0.0, **(power_cal or {})}
        magnets = int((rpm_cal or {}).get("magnets", sp.magnets))
        self.load_cell = SimLoadCell(self.daq, urls["load_cell"], seeds[2], **lc)
        self.power = SimPowerSensor(self.daq, urls["power"], seeds[3], **pw)
        self.rpm = SimRpmSensor(self.daq, urls["rpm"], seeds[4], magnets)
        self.sensors = {"load_cell": self.load_cell, "power": self.power, "rpm": self.rpm}

    def checkpoint(self) -> Checkpoint:
        """The whole simulated state (clock, ESC, plant, acquisition, devices) for
        ``restore``: a runner can run ticks ahead and take them back. O(1) in the length
        of the run (sample and trajectory buffers are kept by reference)."""
        return Checkpoint(self.clock.snapshot(), self.esc_model.snapshot(),
                          self.plant.snapshot(), self.acquisition.snapshot(),
                          self.esc.snapshot(),
                          tuple(s.snapshot() for s in self.sensors.values()))

    def restore(self, checkpoint: Checkpoint) -> None:
        """Back to the state of a ``checkpoint``; what ran since never happened."""
        clock, esc_model, plant, acquisition, esc, sensors = checkpoint
        self.clock.restore(clock)
        self.esc_model.restore(esc_model)
        self.plant.restore(plant)
        self.acquisition.restore(acquisition)
        self.esc.restore(esc)
        for sensor, snap in zip(self.sensors.values(), sensors, strict=True):
            sensor.restore(snap)

    def samples_taken(self) -> int:
        """How many samples the DAQ has taken by now (every sensor is on its clock)."""
        return self.sample_clock.index_end(self.clock.now_ns())

    def runs_alone(self, clock: object, devices: list[object]) -> bool:
        """Whether these are this rig's own clock and devices, none of them closed and no
        fault switched on: then ``checkpoint`` covers everything a run touches."""
        own = [self.esc, *self.sensors.values()]
        if clock is not self.clock or any(not any(d is o for o in own) for d in devices):
            return False
        return not any(d.closed or d.faults.switches for d in own)

    def trim(self) -> None:
        """Forget what every sensor has read (see ``SimDaq.trim``)."""
        self.daq.trim()

    def truth(self) -> PlantTruth:
        self.plant.advance_to(self.clock.now_ns())
        pl = self.plant
        sp = self.sensor_params
        wn = 2.0 * np.pi * sp.load_cell_fn_hz
        return PlantTruth(
            params=self.params,
            sensor_params=sp,
            esc=self.esc_settings,
            esc_mode=self.scheme.value,
            latency_s=self.params.latency_for(self.scheme),
            frame_period_s=self.esc_model.frame_ns * 1e-9,
            filter_tau_s=self.params.filter_tau_for(self.scheme),
            load_cell_delay_s=2.0 * sp.load_cell_zeta / wn,
            t_s=pl.t_ns * 1e-9,
            omega_rad_s=pl.omega,
            rpm=pl.omega * 60.0 / (2.0 * np.pi),
            thrust_n=self.params.thrust_k * pl.omega**2,
            current_winding_a=pl.i_w,
            current_bus_a=pl.i_bus,
            voltage_bus_v=pl.v_bus,
            duty=pl.duty,
            armed=self.esc_model.armed,
            failsafe=self.esc_model.failsafe,
            failsafe_count=self.esc_model.failsafe_count,
        )

    def close(self) -> None:
        self.esc.close()
        for s in self.sensors.values():
            s.close()
