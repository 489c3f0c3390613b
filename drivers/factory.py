"""Rig-file URLs -> devices. The one place that decides which backend serves a device.

``open_rig(rig)`` takes a validated rig config (``bench.rig.RigConfig``, used duck-typed so
``drivers`` does not import ``bench``) and returns an ``OpenRig``: clock, ESC, sensors by role.
``sim://<role>`` devices come from one shared ``drivers.sim.rig.SimRig``; ``replay://`` sensors
read a recorded block list; ``serial://``, ``can://``, ``nidaq://`` and ``tcp://`` backends
arrive with the hardware drivers of a later issue and raise ``DeviceError`` until then.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

from drivers.contracts import Clock, Esc, Fault, Sensor
from drivers.errors import DeviceError
from drivers.sim.esc import EscSettings
from drivers.sim.plant import PlantParams
from drivers.sim.rig import PlantTruth, SimRig
from drivers.sim.sensors import SensorParams

SENSOR_ROLES = ("load_cell", "power", "rpm")
LATER_SCHEMES = {
    "serial": "serial devices (pyserial)",
    "can": "CAN devices (python-can)",
    "nidaq": "NI-DAQmx devices",
    "tcp": "TCP devices",
}


@dataclass
class OpenRig:
    """Opened devices of one rig. ``truth()`` gives the plant truth on simulated rigs."""

    clock: Clock
    esc: Esc
    sensors: dict[str, Sensor]
    sim: SimRig | None = None
    _closers: list[Callable[[], None]] = field(default_factory=list, repr=False)

    def truth(self) -> PlantTruth | None:
        return self.sim.truth() if self.sim is not None else None

    def close(self) -> None:
        """Disarm the ESC and close every device; safe to call more than once."""
        try:
            self.esc.disarm()
        finally:
            for close in [self.esc.close, *(s.close for s in self.sensors.values()),
                          *self._closers]:
                close()

    def __enter__(self) -> OpenRig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _later(url: str, role: str) -> DeviceError:
    scheme = urlsplit(url).scheme
    what = LATER_SCHEMES.get(scheme)
    if what is None:
        return DeviceError(f"{role}: {url!r}: unknown device URL scheme {scheme!r}")
    return DeviceError(
        f"{role}: {url!r}: the {scheme}:// backend ({what}) arrives with the hardware "
        "drivers in a later issue; use sim:// devices for now"
    )


def _sim_faults(device: Any, options: Mapping[str, Any], role: str) -> None:
    """Faults scheduled in a rig file: ``options.faults = [{kind = "dropout", at_s = 2}]``."""
    unknown = sorted(set(options) - {"faults"})
    if unknown:
        raise DeviceError(f"{role}: simulated devices take only the option 'faults', "
                          f"got {', '.join(map(repr, unknown))}")
    for spec in options.get("faults", []):
        spec = dict(spec)
        try:
            kind = Fault(spec.pop("kind"))
            device.inject(kind, **spec)
        except (KeyError, ValueError, TypeError) as exc:
            raise DeviceError(f"{role}: bad fault spec {spec!r}: {exc}") from None


def open_rig(rig: Any, *, seed: int | None = None) -> OpenRig:
    """Open every device the rig config names; sim rigs share one seeded plant."""
    devices = rig.devices
    schemes = {role: urlsplit(dev.url).scheme for role, dev in devices.items()}
    for role, scheme in schemes.items():
        if scheme not in ("sim", "replay"):
            raise _later(devices[role].url, role)
    if schemes.get("esc") != "sim":
        raise DeviceError(f"esc: {devices['esc'].url!r}: an ESC can only be simulated for now")
    try:
        params = PlantParams.with_overrides(dict(rig.sim.plant))
        sensor_params = SensorParams.with_overrides(
            {"noise": bool(rig.sim.noise), **dict(rig.sim.sensors)})
    except KeyError as exc:
        raise DeviceError(f"{rig.path}: [sim] unknown plant/sensor parameter {exc}") from None
    e = rig.esc
    esc_settings = EscSettings(e.frame_rate_hz, e.min_us, e.max_us, e.idle_us, e.arm_us,
                               e.timeout_s)
    sim = SimRig(
        params=params,
        sensor_params=sensor_params,
        esc_settings=esc_settings,
        esc_mode=rig.sim.esc_mode,
        seed=int(rig.sim.seed if seed is None else seed),
        urls={role: dev.url for role, dev in devices.items() if schemes[role] == "sim"},
        load_cell_cal=dict(devices["load_cell"].calibration),
        power_cal=dict(devices["power"].calibration),
        rpm_cal=dict(devices["rpm"].calibration),
    )
    sensors: dict[str, Sensor] = {}
    for role in SENSOR_ROLES:
        dev = devices[role]
        if schemes[role] == "sim":
            sensors[role] = sim.sensors[role]
        else:
            from drivers.replay import ReplaySensor

            sensors[role] = ReplaySensor.from_url(dev.url, sim.clock)
        if schemes[role] == "sim":
            _sim_faults(sensors[role], dev.options, role)
    _sim_faults(sim.esc, devices["esc"].options, "esc")
    return OpenRig(clock=sim.clock, esc=sim.esc, sensors=sensors, sim=sim)
