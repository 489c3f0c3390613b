"""Rig files -> opened devices, whatever the bench: one opener, devices by role.

``open_rig(rig)`` takes a validated rig config (``bench.rig.rig.RigConfig``, of either bench,
seen as a ``drivers.rig_view.RigView`` so ``drivers`` does not import ``bench``) and returns
an :class:`OpenRig`: the clock and the devices by role (``esc``, ``load_cell``, ``power``,
``rpm``; ``hexapod``, ``imu``, ``reference_imu``).
Each device is opened by its entry in the protocol registry (``drivers.registry``, entries
in ``drivers.protocols``): a lookup by URL scheme, ``protocol`` option and role.

What a bench brings is its simulated world and the rule of which devices may mix
(``drivers.sim_worlds``):

- propulsion: ``sim://<role>`` devices (and ``replay://`` sensors) share one seeded
  ``SimRig`` on its own fast clock and cannot be mixed with hardware; the host ``sim`` of
  wire-level URLs (``serial://sim/msp``, ``can://sim/bench``...) starts peers driven by
  the same plant on the wall clock, next to real devices if need be;
- IMU bench: all simulated (``sim://``, ``tcp://sim``, ``serial://sim/...``, one
  ``SimImuRig``; on the wall clock when serial peers need it, option ``time_scale``) or
  all real: a real IMU cannot see a simulated hexapod's motion, nor the reverse.

Problems raise ``DeviceError`` naming the rig file, the device table and the field.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterator, Mapping, MutableMapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

import numpy as np

from drivers.contracts import Clock, Esc, Hexapod, MonotonicClock, Sensor
from drivers.device_context import DeviceContext
from drivers.device_options import DeviceUrl, parse_device
from drivers.errors import DeviceError
from drivers.registry import schemes
from drivers.rig_view import DeviceView, RigView
from drivers.sim.faults import FaultSwitches
from drivers.sim.rig import ESC_FAULTS, PlantTruth
from drivers.sim.sensors import SimSensor, check_calibration
from drivers.sim_worlds import (
    PROPULSION_SENSORS,
    build_sim_imu_rig,
    build_sim_rig,
    imu_world_process,
    sim_faults,
    wire_plant,
)

__all__ = [
    "IMU_ROLES",
    "ROLES",
    "SENSOR_ROLES",
    "OpenRig",
    "build_sim_rig",
    "device_specs",
    "open_hexapod",
    "open_rig",
    "validate_device",
]

log = logging.getLogger(__name__)

SENSOR_ROLES = PROPULSION_SENSORS
ROLES = ("esc", *SENSOR_ROLES)  # the propulsion stand, in opening order
IMU_ROLES = ("hexapod", "imu", "reference_imu")  # the IMU bench, in opening order
SIM_HOST = "sim"


@dataclass
class OpenRig:
    """Opened devices of one rig, by role. ``truth()`` gives the plant truth of a
    simulated propulsion rig (also behind wire-level simulated devices); ``sim`` is the
    simulated world of ``sim://`` devices; ``wire`` the owner of the simulated peers
    (propulsion: ``WireSims``; IMU bench: the simulated PI controller of ``tcp://sim``);
    ``peers`` the simulated serial devices of the IMU bench, by role.

    ``close()`` makes the actuators safe first (ESC disarmed, hexapod stopped), then
    closes everything; the errors are kept in ``close_errors``. A propulsion rig raises
    the first one (as a ``with`` block expects); the IMU bench's close never raises (its
    calibration records them).
    """

    clock: Clock
    devices: dict[str, Any]
    sim: Any = None
    wire: Any = None
    peers: dict[str, Any] = field(default_factory=dict)
    context: DeviceContext | None = field(default=None, repr=False)
    raise_close_errors: bool = True
    close_errors: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._sensor_roles = [r for r, d in self.devices.items() if isinstance(d, Sensor)]

    @property
    def esc(self) -> Esc:
        return self.devices["esc"]

    @esc.setter
    def esc(self, dev: Esc) -> None:  # a wrapper around the device (tests, instruments)
        self.devices["esc"] = dev

    @property
    def hexapod(self) -> Hexapod:
        return self.devices["hexapod"]

    @hexapod.setter
    def hexapod(self, dev: Hexapod) -> None:
        self.devices["hexapod"] = dev

    @property
    def imu(self) -> Sensor:
        return self.devices["imu"]

    @property
    def reference_imu(self) -> Sensor | None:
        return self.devices.get("reference_imu")

    @property
    def sensors(self) -> MutableMapping[str, Sensor]:
        """Every device that hands out sample blocks (a ``Sensor`` when opened), by role; a
        live view: ``rig.sensors["power"] = wrapped`` replaces the device of that role."""
        return _Sensors(self)

    @sensors.setter
    def sensors(self, sensors: Mapping[str, Sensor]) -> None:
        self.devices.update(sensors)
        self._sensor_roles = list(sensors)

    def truth(self) -> PlantTruth | None:
        if self.wire is not None and hasattr(self.wire, "plant"):
            return self.wire.plant.truth()
        return self.sim.truth() if self.sim is not None else None

    def close(self) -> list[str]:
        """Safe state, then close every device; safe to call more than once."""
        devs = list(self.devices.values())
        actions = [*(d.disarm for d in devs if isinstance(d, Esc)),
                   *(d.stop for d in devs if isinstance(d, Hexapod)),
                   *(d.close for d in devs)]
        if self.context is not None:
            actions.append(self.context.close)
        errors: list[Exception] = []
        for action in actions:
            try:
                action()
            except Exception as exc:  # every device gets closed
                errors.append(exc)
        self.close_errors = [f"{type(e).__name__}: {e}" for e in errors]
        if errors and self.raise_close_errors:
            raise errors[0]
        return self.close_errors

    def __enter__(self) -> OpenRig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Sensors(MutableMapping[str, Sensor]):
    """The sensor roles of an :class:`OpenRig`, read and written through its devices."""

    def __init__(self, rig: OpenRig) -> None:
        self._rig = rig

    def __getitem__(self, role: str) -> Sensor:
        if role not in self._rig._sensor_roles:
            raise KeyError(role)
        return self._rig.devices[role]

    def __setitem__(self, role: str, sensor: Sensor) -> None:
        self._rig.devices[role] = sensor
        if role not in self._rig._sensor_roles:
            self._rig._sensor_roles.append(role)

    def __delitem__(self, role: str) -> None:
        self._rig._sensor_roles.remove(role)
        del self._rig.devices[role]

    def __iter__(self) -> Iterator[str]:
        return iter(list(self._rig._sensor_roles))

    def __len__(self) -> int:
        return len(self._rig._sensor_roles)


def validate_device(rig_path: str | os.PathLike[str], role: str, dev: DeviceView) -> None:
    """Check a device's calibration and options as its opener will use them, before any
    device opens or run folder exists (``bench.rig.rig.load_rig`` calls this).

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
        sim_faults(probe, dict(getattr(dev, "options", {}) or {}), role, table)
    elif scheme == "nidaq" and role in SENSOR_ROLES:
        check_calibration(role, calibration, table)


def device_specs(rig: RigView) -> dict[str, DeviceUrl]:
    """Every device of the rig with its URL split and options merged (see device_options)."""
    return {role: parse_device(rig.path, role, dev) for role, dev in rig.devices.items()}


def is_imu_bench(rig: RigView) -> bool:
    """The IMU bench is the rig with a hexapod; every other rig is a propulsion stand."""
    return "hexapod" in rig.devices


def _simulated(spec: DeviceUrl) -> bool:
    """Simulated, or real firmware the bench launches and feeds the simulated world."""
    return spec.scheme == "sim" or spec.host == SIM_HOST or _launched(spec)


def _launched(spec: DeviceUrl) -> bool:
    return spec.scheme == "msp+tcp" and "launch" in spec.options


def _propulsion(rig: RigView, specs: dict[str, DeviceUrl], seed: int | None) -> DeviceContext:
    if {s.scheme for s in specs.values()} <= {"sim", "replay"}:
        sim = build_sim_rig(rig, seed=seed, calibrations=True,
                            urls={r: s.url for r, s in specs.items() if s.scheme == "sim"})
        ctx = DeviceContext(rig, sim.clock, specs, world=lambda: sim, seed=seed)
        ctx.one_world = True
        return ctx
    for spec in specs.values():
        if spec.scheme == "sim":
            raise spec.fail("", "sim:// devices run on the simulated clock and cannot be "
                                "mixed with hardware; use the wire-level simulated devices "
                                "(serial://sim/..., can://sim/...) instead")
    ctx = DeviceContext(rig, MonotonicClock(), specs, seed=seed)

    def world() -> Any:
        wire = wire_plant(rig, seed)
        ctx.on_close(wire.close)  # after every port and bus opened later
        return wire

    ctx.set_world(world)
    return ctx


def _time_scale(rig: RigView, specs: dict[str, DeviceUrl]) -> float | None:
    """``time_scale`` of the serial peers (they must agree); None without serial peers. A
    launched firmware (``launch``) runs on the wall clock: time scale 1."""
    scales = {role: s.number("time_scale", 1.0, lo=1e-3, hi=1e3)
              for role, s in specs.items() if s.scheme == "serial" and s.host == SIM_HOST}
    scales.update({role: 1.0 for role, s in specs.items() if _launched(s)})
    if len(set(scales.values())) > 1:
        raise DeviceError(f"{rig.path}: [devices.*] options.time_scale: the simulated serial "
                          f"devices must agree, got {scales}")
    return next(iter(scales.values()), None)


def _imu_bench(rig: RigView, specs: dict[str, DeviceUrl], seed: int | None) -> DeviceContext:
    real = [r for r, s in specs.items() if not _simulated(s)]
    if real and len(real) != len(specs):
        sims = [r for r in specs if r not in real]
        raise DeviceError(f"{rig.path}: [devices] {', '.join(real)} real but "
                          f"{', '.join(sims)} simulated: a real hexapod needs a real IMU "
                          "under test (and a real IMU a real hexapod: neither sees the other's "
                          "motion); make them all real or all simulated (sim://, "
                          f"tcp://{SIM_HOST}, serial://{SIM_HOST}/...)")
    if real:
        return DeviceContext(rig, MonotonicClock(), specs, seed=seed)
    time_scale = _time_scale(rig, specs)
    if time_scale is not None and all(s.is_wire_sim for s in specs.values()):
        return _imu_world_process(rig, specs, seed, time_scale)
    sim = build_sim_imu_rig(rig, seed, time_scale)
    ctx = DeviceContext(rig, sim.clock, specs, world=lambda: sim, seed=seed)
    ctx.one_world = True
    return ctx


def _imu_world_process(rig: RigView, specs: dict[str, DeviceUrl], seed: int | None,
                       time_scale: float) -> DeviceContext:
    """Every device wire-level: the world and its devices run in a process of their own
    (``drivers.wire_sim.imu_world``), started when the first device opens."""
    from drivers.wire_sim.imu_world import HostPacedClock

    clock = HostPacedClock(time_scale)
    ctx = DeviceContext(rig, clock, specs, seed=seed)

    def world() -> Any:
        remote = imu_world_process(rig, seed, clock)
        ctx.on_close(remote.close)  # after every port opened later
        return remote

    ctx.set_world(world)
    ctx.one_world = True
    return ctx


def open_context(rig: RigView, *, seed: int | None = None) -> DeviceContext:
    """The device context of a rig (clock, simulated world), before any device opens."""
    specs = device_specs(rig)
    known = schemes()
    for spec in specs.values():
        if spec.scheme not in known:
            raise spec.fail("", f"unknown device URL scheme {spec.scheme!r}")
    if is_imu_bench(rig):
        return _imu_bench(rig, specs, seed)
    return _propulsion(rig, specs, seed)


def open_rig(rig: RigView, *, seed: int | None = None) -> OpenRig:
    """Open every device the rig config names; see the module docstring."""
    return open_devices(open_context(rig, seed=seed))


def open_devices(ctx: DeviceContext) -> OpenRig:
    """Open every device of a context, in the bench's order; all or nothing."""
    imu = is_imu_bench(ctx.rig)
    order = [r for r in (IMU_ROLES if imu else ROLES) if r in ctx.specs]
    order += [r for r in ctx.specs if r not in order]
    devices: dict[str, Any] = {}
    log.info("rig %s: opening %s", getattr(ctx.rig, "path", "?"), ", ".join(
        f"{r} {ctx.specs[r].url}" for r in order))
    try:
        for role in order:
            devices[role] = ctx.open(ctx.specs[role])
            log.info("%s answered: %s", role, ctx.answers.get(role) or type(devices[role])
                     .__name__)
    except BaseException as exc:
        log.info("rig not opened: %s", exc or type(exc).__name__)
        for dev in reversed(devices.values()):
            try:
                if isinstance(dev, Hexapod):
                    dev.stop()
                dev.close()
            except Exception:  # already failing: close the rest
                pass
        try:
            ctx.close()
        except Exception:
            pass
        raise
    sim = ctx.built_world if imu or any(s.scheme == "sim" for s in ctx.specs.values()) else None
    return OpenRig(ctx.clock, devices, sim=sim, wire=ctx.wire, peers=ctx.peers, context=ctx,
                   raise_close_errors=not imu)


def open_hexapod(url: str, *, where: str = "hexapod", timeout_s: float = 2.0) -> Any:
    """``tcp://host[:50000]`` -> a connected PI GCS client (``drivers.backends.pi_hexapod``).

    The hexapod of an IMU-bench rig opens with ``open_rig``; this entry point serves
    scripts and checks. The wave-table upload syntax is not in protocols.md: see
    docs/devices.md before running trajectories on a real controller.
    """
    parts = urlsplit(url)
    if parts.scheme != "tcp" or not parts.hostname:
        raise DeviceError(f"{where}: {url!r}: expected tcp://<host>[:port]")
    from drivers.backends import pi_hexapod
    from drivers.codecs.gcs import PORT

    return pi_hexapod.PiHexapod(pi_hexapod.open_tcp(parts.hostname, parts.port or PORT,
                                                    timeout_s), url=url)
