"""Rig-file URLs -> devices. The one place that decides which backend serves a device.

``open_rig(rig)`` takes a validated rig config (``bench.rig.RigConfig``, used duck-typed so
``drivers`` does not import ``bench``) and returns an ``OpenRig``: clock, ESC, sensors by role.

- ``sim://<role>`` devices come from one shared ``drivers.sim.rig.SimRig`` on its own fast
  simulated clock; ``replay://`` sensors read a recorded block list;
- ``serial://``, ``can://`` and ``nidaq://`` devices are real backends
  (``drivers.backends``, imported lazily by ``drivers.device_openers``) on the host's
  monotonic clock; ``tcp://`` is the PI GCS hexapod of the IMU bench (``open_hexapod``);
- the host ``sim`` in those URLs (``serial://sim/msp``, ``serial://sim/loadcell``,
  ``can://sim/bench``) starts the wire-level simulated device (``drivers.wire_sim``) on a
  pty or python-can's virtual bus, driven by the rig's ``[sim]`` plant in real time
  (``drivers.wire_rig``), and points the real backend at it.

Problems raise ``DeviceError`` naming the rig file, the device table and the field.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from drivers.contracts import Clock, Esc, Fault, MonotonicClock, Sensor
from drivers.device_options import DeviceUrl, parse_device
from drivers.errors import DeviceError
from drivers.sim.esc import EscSettings
from drivers.sim.faults import FaultSwitches
from drivers.sim.plant import PlantParams
from drivers.sim.rig import ESC_FAULTS, PlantTruth, SimRig
from drivers.sim.sensors import SensorParams, SimSensor, check_calibration

__all__ = [
    "SENSOR_ROLES",
    "OpenRig",
    "build_sim_rig",
    "device_specs",
    "open_hexapod",
    "open_rig",
    "validate_device",
]

SENSOR_ROLES = ("load_cell", "power", "rpm")
ROLES = ("esc", *SENSOR_ROLES)
HARDWARE_SCHEMES = ("serial", "can", "nidaq")


@dataclass
class OpenRig:
    """Opened devices of one rig. ``truth()`` gives the plant truth on simulated rigs
    (and on rigs of wire-level simulated devices, whose plant runs on the wall clock)."""

    clock: Clock
    esc: Esc
    sensors: dict[str, Sensor]
    sim: SimRig | None = None
    _closers: list[Callable[[], None]] = field(default_factory=list, repr=False)
    wire: Any = None  # drivers.wire_rig.WireSims on rigs of wire-level simulated devices

    def truth(self) -> PlantTruth | None:
        if self.wire is not None:
            return self.wire.plant.truth()
        return self.sim.truth() if self.sim is not None else None

    def close(self) -> None:
        """Disarm the ESC and close every device; safe to call more than once."""
        try:
            self.esc.disarm()
        finally:
            closers = [self.esc.close, *(s.close for s in self.sensors.values()),
                       *self._closers]
            self._closers = []
            errors = []
            for close in closers:
                try:
                    close()
                except Exception as exc:  # every device gets closed
                    errors.append(exc)
            if errors:
                raise errors[0]

    def __enter__(self) -> OpenRig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _sim_faults(device: Any, options: Mapping[str, Any], role: str, table: str = "") -> None:
    """Faults scheduled in a rig file: ``options.faults = [{kind = "dropout", at_s = 2}]``.

    ``table`` (``<rig file>: [devices.<role>]``) makes the messages name file and key.
    """
    unknown = sorted(set(options) - {"faults"})
    if unknown:
        where = f"{table} options.{unknown[0]}" if table else role
        raise DeviceError(f"{where}: simulated devices take only the option 'faults', "
                          f"got {', '.join(map(repr, unknown))}")
    faults = options.get("faults", [])
    if not isinstance(faults, list | tuple):
        raise DeviceError(f"{table or role} options.faults: expected a list of tables, "
                          f"got {faults!r}")
    for spec in faults:
        try:
            kwargs = dict(spec)
            kind = Fault(kwargs.pop("kind"))
            device.inject(kind, **kwargs)
        except (KeyError, ValueError, TypeError) as exc:
            where = f"{table} options.faults" if table else role
            raise DeviceError(f"{where}: bad fault spec {spec!r}: {exc}") from None


def validate_device(rig_path: Any, role: str, dev: Any) -> None:
    """Check a device's calibration and options as its opener will use them, before any
    device opens or run folder exists (``bench.rig.load_rig`` calls this).

    Covers ``sim://`` devices (calibration keys and values, ``options.faults``) and the
    calibration of ``nidaq://`` sensors (same keys and values; a missing key is reported
    when the NI opener needs it). Raises ``DeviceError`` naming the rig file,
    ``[devices.<role>]`` and the key.
    """
    scheme = urlsplit(str(dev.url)).scheme
    table = f"{rig_path}: [devices.{role}]"
    calibration = dict(getattr(dev, "calibration", {}) or {})
    if scheme == "sim":
        check_calibration(role, calibration, table)
        allowed = ESC_FAULTS if role == "esc" else SimSensor.allowed_faults
        probe = FaultSwitches(str(dev.url), np.random.default_rng(0), allowed)
        _sim_faults(probe, dict(getattr(dev, "options", {}) or {}), role, table)
    elif scheme == "nidaq" and role in SENSOR_ROLES:
        check_calibration(role, calibration, table)


def build_sim_rig(rig: Any, *, seed: int | None = None, urls: dict[str, str] | None = None,
                  calibrations: bool = False) -> SimRig:
    """The seeded simulated rig of a rig file's ``[sim]`` and ``[esc]`` tables.

    ``calibrations``: take the sensors' calibration tables from the rig's devices (the
    ``sim://`` rig); wire-level peers report calibrated values like their firmware.
    """
    try:
        params = PlantParams.with_overrides(dict(rig.sim.plant))
        sensor_params = SensorParams.with_overrides(
            {"noise": bool(rig.sim.noise), **dict(rig.sim.sensors)})
    except KeyError as exc:
        raise DeviceError(f"{rig.path}: [sim] unknown plant/sensor parameter {exc}") from None
    e = rig.esc
    esc_settings = EscSettings(e.frame_rate_hz, e.min_us, e.max_us, e.idle_us, e.arm_us,
                               e.timeout_s)
    devices = rig.devices
    cal = {role: dict(devices[role].calibration) if calibrations else {}
           for role in SENSOR_ROLES}
    return SimRig(
        params=params,
        sensor_params=sensor_params,
        esc_settings=esc_settings,
        esc_mode=rig.sim.esc_mode,
        seed=int(rig.sim.seed if seed is None else seed),
        urls=urls,
        load_cell_cal=cal["load_cell"],
        power_cal=cal["power"],
        rpm_cal=cal["rpm"],
    )


def device_specs(rig: Any) -> dict[str, DeviceUrl]:
    """Every device of the rig with its URL split and options merged (see device_options)."""
    return {role: parse_device(rig.path, role, dev) for role, dev in rig.devices.items()}


def open_rig(rig: Any, *, seed: int | None = None) -> OpenRig:
    """Open every device the rig config names; see the module docstring."""
    devices = rig.devices
    schemes = {role: urlsplit(dev.url).scheme for role, dev in devices.items()}
    for role, scheme in schemes.items():
        if scheme not in ("sim", "replay", "tcp", *HARDWARE_SCHEMES):
            raise DeviceError(f"{rig.path}: [devices.{role}] url {devices[role].url!r}: "
                              f"unknown device URL scheme {scheme!r}")
    if any(s in HARDWARE_SCHEMES or s == "tcp" for s in schemes.values()):
        return _open_hardware_rig(rig, seed)
    if schemes.get("esc") != "sim":
        raise DeviceError(f"{rig.path}: [devices.esc] url {devices['esc'].url!r}: a replay "
                          "cannot drive a motor; use sim://esc or a hardware ESC")
    sim = build_sim_rig(rig, seed=seed, calibrations=True,
                        urls={r: d.url for r, d in devices.items() if schemes[r] == "sim"})
    sensors: dict[str, Sensor] = {}
    for role in SENSOR_ROLES:
        dev = devices[role]
        if schemes[role] == "sim":
            sensors[role] = sim.sensors[role]
            _sim_faults(sensors[role], dev.options, role)
        else:
            from drivers.replay import ReplaySensor

            sensors[role] = ReplaySensor.from_url(dev.url, sim.clock)
    _sim_faults(sim.esc, devices["esc"].options, "esc")
    return OpenRig(clock=sim.clock, esc=sim.esc, sensors=sensors, sim=sim)


def _open_hardware_rig(rig: Any, seed: int | None) -> OpenRig:
    from drivers.device_openers import DeviceOpener

    specs = device_specs(rig)
    for spec in specs.values():
        if spec.scheme == "sim":
            raise spec.fail("", "sim:// devices run on the simulated clock and cannot be "
                                "mixed with hardware; use the wire-level simulated devices "
                                "(serial://sim/..., can://sim/...) instead")
    clock = MonotonicClock()
    opener = DeviceOpener(rig, clock, seed)
    opener.plan_nidaq(list(specs.values()))
    esc: Esc | None = None
    sensors: dict[str, Sensor] = {}
    try:
        esc = opener.open_esc(specs["esc"])
        for role in SENSOR_ROLES:
            spec = specs[role]
            if spec.scheme == "replay":
                from drivers.replay import ReplaySensor

                sensors[role] = ReplaySensor.from_url(spec.url, clock)
            else:
                sensors[role] = opener.open_sensor(spec)
    except BaseException:
        for dev in [*sensors.values(), *([esc] if esc is not None else [])]:
            try:
                dev.close()
            except Exception:  # already failing: close the rest
                pass
        try:
            opener.close()
        except Exception:
            pass
        raise
    return OpenRig(clock=clock, esc=esc, sensors=sensors, _closers=[opener.close],
                   wire=opener.wire)


def open_hexapod(url: str, *, where: str = "hexapod", timeout_s: float = 2.0) -> Any:
    """``tcp://host[:50000]`` -> a connected PI GCS client (``drivers.backends.pi_hexapod``).

    The hexapod is an IMU-bench device (``drivers.imu_factory``); this entry point serves
    scripts and checks. The wave-table upload syntax is not in protocols.md: see
    docs/devices.md before running trajectories on a real controller.
    """
    parts = urlsplit(url)
    if parts.scheme != "tcp" or not parts.hostname:
        raise DeviceError(f"{where}: {url!r}: expected tcp://<host>[:port]")
    from drivers.backends import pi_hexapod
    from drivers.codecs.gcs import PORT

    sock = pi_hexapod.open_tcp(parts.hostname, parts.port or PORT, timeout_s)
    try:
        return pi_hexapod.PiHexapod(sock, url=url)
    except BaseException:
        sock.close()
        raise
