"""The sensor models of the simulated rig: what the DAQ, the load cell, the AttoPilot and the
hall counter are like (rates, noise, ranges, buffer), with their sources.

Its own module because the acquisition (``drivers.sim.acquisition``) and the sensor drivers
(``drivers.sim.sensors``) both need it and the drivers build on the acquisition: here
neither has to import the other's home.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

from drivers.sim.cell_errors import CellErrors

VIBRATION_REF_RPM = 10_000.0  # speed at which the vibration amplitudes are given


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
    current_mv_per_a: float = 36.60  # AttoPilot 90 A current scale (datasheet)
    voltage_mv_per_v: float = 63.69  # AttoPilot 90 A voltage scale (datasheet)
    sensor_out_max_v: float = 3.3  # AttoPilot output swing, unidirectional (0-3.3 V)
    current_noise_a: float = 0.15  # PWM ripple + sensor noise at 25 kHz (assumption)
    voltage_noise_v: float = 0.02  # (assumption)
    adc_bits: int = 16  # NI 9215-class ADC, 16 bit (assumption)
    adc_range_v: float = 10.0  # +-10 V input range
    magnets: int = 14  # hall sensor sees the 14 rotor magnets (Paper C 2.2)
    counter_hz: float = 40e6  # FPGA counter timebase of the cRIO (NI-9401 on a 40 MHz FPGA)
    # its crystal's error (relative): running fast by this much, it counts every period
    # long and the speed reads low by it (0: exact; a crystal is good to +-50 ppm)
    counter_timebase_error: float = 0.0
    rpm_timeout_s: float = 0.1  # no hall edge for this long -> the counter reports 0 rpm
    buffer_s: float = 30.0  # DAQ buffer: a sensor not read for this long overruns
    # Optional accelerometer on the load-cell mount (channel acc_x_m_s2, radial, at the
    # sample rate): a rotor imbalance at the rotor frequency and the blades' pass at blades x
    # rotor frequency, amplitudes at VIBRATION_REF_RPM growing with speed^2 (a centrifugal
    # force m e w^2), plus white noise. Both amplitudes 0 (the default): no channel.
    vibration_imbalance_m_s2: float = 0.0  # (assumption; a few m/s^2 is a typical stand)
    vibration_blade_pass_m_s2: float = 0.0  # (assumption)
    vibration_noise_m_s2: float = 0.05  # accelerometer noise per sample (assumption)
    vibration_blades: int = 2  # propeller blades: blade-pass = blades x rotor frequency
    # An optional torque cell beside the load cell (a two-axis thrust/torque stand, channel
    # torque_nm of the load-cell device): 0 (the default) has none. It feels the rotor's
    # reaction torque k_q w^2 (E.2) and weights hung on a calibration arm.
    torque_cell_range_nm: float = 0.0
    torque_cell_v_per_nm: float = 2.0  # bridge + amplifier sensitivity (assumption)
    torque_cell_offset_v: float = -0.004  # zero offset of its bridge
    torque_cell_noise_nm: float = 0.004  # white noise at 25 kHz (assumption)
    torque_cell_error_seed: int = -1  # its hidden errors, drawn as the load cell's
    # The load cell's hidden errors (drivers.sim.cell_errors), what a calibration finds:
    # drawn from load_cell_error_seed (>= 0), else the four values below (0: a perfect cell).
    load_cell_error_seed: int = -1
    load_cell_scale_error: float = 0.0  # sensitivity's relative error
    load_cell_nonlinearity: float = 0.0  # fractions of full scale (load_cell_range_n)
    load_cell_hysteresis: float = 0.0
    load_cell_creep: float = 0.0

    @classmethod
    def with_overrides(cls, overrides: dict[str, float]) -> SensorParams:
        known = {f.name for f in fields(cls)}
        for name in overrides:
            if name not in known:
                raise KeyError(name)
        return replace(cls(), **overrides)

    @property
    def load_cell_errors(self) -> CellErrors:
        """The load cell's hidden errors (see the fields above)."""
        if self.load_cell_error_seed >= 0:
            return CellErrors.drawn(int(self.load_cell_error_seed))
        return CellErrors(self.load_cell_scale_error, self.load_cell_nonlinearity,
                          self.load_cell_hysteresis, self.load_cell_creep)

    @property
    def torque_cell_errors(self) -> CellErrors:
        """The torque cell's hidden errors (none unless ``torque_cell_error_seed`` >= 0)."""
        if self.torque_cell_error_seed >= 0:
            return CellErrors.drawn(int(self.torque_cell_error_seed))
        return CellErrors()

    @property
    def torque_cell(self) -> bool:
        return self.torque_cell_range_nm > 0.0

    @property
    def vibration(self) -> bool:
        """Whether the load cell has the vibration (accelerometer) channel."""
        return self.vibration_imbalance_m_s2 > 0.0 or self.vibration_blade_pass_m_s2 > 0.0
